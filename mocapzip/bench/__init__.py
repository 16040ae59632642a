"""`mcz bench`: real archives measured end to end beside xz, zstd and Hou et al. 2015
(`runner`: the runs and their measures; `report`: the text, CSV and plot people read), and the
Hou et al. baseline itself (`baselines`)."""
