"""`mcz` in a child process under an address-space limit and a timeout, for the hostile-input
and hostile-archive tests: a regression that hangs or exhausts memory fails its test instead of
stopping the suite or the machine. The limits only catch such faults: no case comes near them."""

from __future__ import annotations

import os
import resource
import subprocess
import sys

from mocapzip.defaults import BLAS_THREAD_VARIABLES

MEMORY_LIMIT = 2 << 30  # bytes of address space per child
TIMEOUT = 60.0  # seconds


def run_mcz(*args, cwd=None, memory: int = MEMORY_LIMIT, setup: str = "") -> subprocess.CompletedProcess:
    """`mcz ARGS` (run in `cwd`), its address space limited to `memory` bytes and its time to TIMEOUT;
    `setup`, Python run in the child first (a module constant made small for the test)."""

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (memory, memory))

    env = {**os.environ, **dict.fromkeys(BLAS_THREAD_VARIABLES, "1")}
    code = f"{setup}\nfrom mocapzip.cli.main import main; main()"
    return subprocess.run([sys.executable, "-c", code, *map(os.fspath, args)],
                          cwd=cwd, capture_output=True, text=True, timeout=TIMEOUT, preexec_fn=limit, env=env)
