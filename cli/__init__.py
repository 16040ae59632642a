"""The `mcz` command line (installed as `mocapzip.cli`).

mcz parallelises with worker processes (`-j`), so BLAS threads inside each process only
contend for the same cores: measured on a loaded 2-CPU machine, a 180 x 180 eigendecomposition
took 3 ms with one BLAS thread and 325 ms with two. One thread per process is therefore the
default, set before numpy is first imported; an explicit environment setting wins.
"""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
