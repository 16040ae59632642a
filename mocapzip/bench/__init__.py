"""`mcz bench`: real archives measured end to end beside xz, zstd and Hou et al. 2015
(`runner`: the runs and the report), and the Hou et al. baseline itself (`baselines`)."""
