"""The `mcz` command line (installed as `mocapzip.cli`): its commands and options (`main`),
`mcz bench` and `mcz classify` (`bench`, `classify`), `mcz plot` and `mcz view` (`plots`), the
option choices it offers without importing NumPy (`choices`), and how every command fails, in
one line (`errors`).

mcz parallelises with worker processes (`-j`), so BLAS threads inside each process only
contend for the same cores: measured on a loaded 2-CPU machine, a 180 x 180 eigendecomposition
took 3 ms with one BLAS thread and 325 ms with two. One thread per process is therefore the
default, set before numpy is first imported; an explicit environment setting wins.
"""

import atexit
import gc
import os
import sys
from contextlib import contextmanager

from mocapzip.defaults import BLAS_THREAD_VARIABLES

for _var in BLAS_THREAD_VARIABLES:
    os.environ.setdefault(_var, "1")


def _interrupted(kind, value, traceback, previous=sys.excepthook):
    """Ctrl-C that no command caught (while the imports run, before `reports_errors` takes over):
    one line, not a traceback. Python then ends the process by SIGINT, exit status 130."""
    if issubclass(kind, KeyboardInterrupt):
        sys.stderr.write("mcz: error: interrupted (SIGINT)\n")
    else:
        previous(kind, value, traceback)


sys.excepthook = _interrupted  # installed here, before main.py imports click and the rest

# The interpreter's last garbage collection, at exit, walks every object still alive: numba's
# type registries and compiled kernels make that about 0.25 s of each run, an eighth of a
# `mcz decompress` of the shared CMU set. Frozen objects are left out of it; their memory goes
# back with the process, and the files were written and closed before exit.
atexit.register(gc.freeze)


@contextmanager
def importing():
    """Around a command's imports: the garbage collector off while they run, and what they made
    frozen after them (`reports_errors` unfreezes it when the command ends). numpy, numba, scipy
    and the rest make a few hundred thousand objects that live for the whole run. Collections while
    they were made walked them again and again, 0.13 s of the 1.7 s a `mcz decompress` of the
    shared CMU set took; the first collection after them would walk them all once more, 0.05 s.
    Frozen, they are left out of every later collection."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if enabled:
            gc.enable()
