"""Defaults the command line and the Python API share. No imports: `mcz --help` and
`import mocapzip` read them without loading NumPy."""

# compress's default bound on every joint, as a multiple of the mean target (-e): the tightest that
# costs at most 15 % over the mean alone (shared CMU set: 5 x -e took 13.6 % more bytes at -e 1 and
# 9.6 % at -e 0.5, 4 x 26.7 % and 19.7 %; docs/fidelity.md, from `python benchmarks/max_error.py`)
MAX_TO_MEAN = 5.0
# a clip's frame rate where nothing sets it (ASF/AMC have no field for one): CMU's and HDM05's
DEFAULT_FPS = 120.0
# the environment variables that set BLAS thread counts (OpenBLAS, OpenMP, MKL): mcz's processes want one
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
# ACL's default shell distance (`track_desc_transformf::shell_distance`, 3 in the clip's units;
# Unreal Engine's are cm): its error metric's vertices stand for a skinned mesh's, 3 cm from the bone
ACL_SHELL_CM = 3.0
UNITS_CM = {"cm": 1.0, "mm": 0.1, "m": 100.0, "in": 2.54}  # BVH length units (`--units`) -> cm
# memory (MB) for clips kept between compress's passes (`inputs.clip.ClipReader`): the shared CMU set
# (143,495 frames) holds 535 MB; at 512 some of its clips were read again, 5 % of compress's time
DEFAULT_CACHE_MB = 1024
# compress's default representation: resolved by the error asked for (`archive.settings.chosen_representation`)
AUTO_REPRESENTATION = "auto"
# `channels` codes CMU in fewer bytes than `aligned` where -e x fps is below CHANNELS_BELOW_CM_HZ,
# or --max-vertex-error x fps below CHANNELS_BELOW_VERTEX_CM_HZ; `aligned` elsewhere. The crossover
# of 20 CMU clips, with the default joint bound or none: -e x fps 1.3 to 1.6 at 24, 30, 60 and 120
# fps; with every vertex within 2.5 x -e, vertex x fps 12 (3.5 and 5 x -e: 8 to 8.6). These two
# keep every measured pick within 1.5 % of the smaller archive but one (docs/fidelity.md,
# "Representation by error").
CHANNELS_BELOW_CM_HZ = 1.5
CHANNELS_BELOW_VERTEX_CM_HZ = 12.0
