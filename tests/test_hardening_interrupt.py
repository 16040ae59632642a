"""Interrupted runs (issue 5, item 4): Ctrl-C (SIGINT) or SIGTERM in the middle of `mcz compress`
or `mcz decompress` leaves no .mcz, no temporary file and no half-written AMC, exits non-zero
and says so in one line.

Three kinds of run: a plain `mcz compress` killed while it works on a real folder, runs whose
file writing is slowed down (in the child only) so that the signal lands exactly while a
temporary file is half written: the clean-up is then proven, not just likely, and a run whose
signal lands in numba's compiled code.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mocapzip.archive import decompress

GOLDEN_LOSSLESS = Path(__file__).parent / "golden" / "lossless_v1.mcz"  # decoded by worker processes (-j 2)
GOLDEN_LOSSY = Path(__file__).parent / "golden" / "lossy_v4.mcz"  # decoded by threads (-j 2)
ARCHIVES = pytest.mark.parametrize("archive", [GOLDEN_LOSSLESS, GOLDEN_LOSSY], ids=["lossless", "lossy"])
MCZ = Path(sys.executable).with_name("mcz")
TIMEOUT = 60

# Runs the real `mcz` in the child, with one write slowed down: it writes half its data, creates the
# marker file (so the test knows the temporary file is half written) and waits to be interrupted.
SLOW_CHILD = r"""
import os, stat, sys, time
from pathlib import Path
from mocapzip.formats import mcz
from mocapzip.cli.main import main

marker = Path(os.environ["MCZ_TEST_MARKER"])

def wait_for_signal():
    marker.touch()
    time.sleep(60)

if sys.argv[1] == "compress":
    real_payload = mcz._write_payload
    def slow_payload(dataset, values):
        real_payload(dataset, values[: len(values) // 2])
        dataset.file.flush()
        wait_for_signal()
    mcz._write_payload = slow_payload
else:
    real_write, files = os.write, []
    def slow_write(fd, data):
        status = os.fstat(fd)
        if not stat.S_ISREG(status.st_mode):  # the pipes to and from worker processes (-j 2)
            return real_write(fd, data)
        inode = status.st_ino  # descriptors are reused from file to file; inodes are not
        if inode not in files:
            files.append(inode)
        if len(files) < 3:
            return real_write(fd, data)
        real_write(fd, data[: len(data) // 2])
        wait_for_signal()
    os.write = slow_write
main(prog_name="mcz")
"""


# Runs the real `mcz` with one function held: its first call, in whichever process makes it, creates
# the marker file and waits for the test's release file (or for the signal, in the main process).
# With MCZ_TEST_HOLD_IN_WORKER set, only a call away from the main process's main thread is held: a
# worker process's (compress; with -j, the main process runs the first item itself, before forking:
# `parallel.imap`) or a decoding thread's (decompress: `parallel.thread_imap`).
# HELD_CHILD.format(module=..., name=...) holds `module.name` (a function or a method).
HELD_CHILD = r"""
import importlib, os, sys, threading, time
from pathlib import Path
from mocapzip.cli.main import main

marker = Path(os.environ["MCZ_TEST_MARKER"])
main_pid = os.getpid()
owner = importlib.import_module("{module}")
for part in "{name}".split(".")[:-1]:
    owner = getattr(owner, part)
real = getattr(owner, "{name}".split(".")[-1])

def held(*args, **kwargs):
    in_main = os.getpid() == main_pid and threading.current_thread() is threading.main_thread()
    if os.environ.get("MCZ_TEST_HOLD_IN_WORKER") and in_main:
        return real(*args, **kwargs)
    if not marker.exists():
        marker.touch()
        release = marker.with_suffix(".release")
        for _ in range(6000):
            if release.exists():
                break
            time.sleep(0.01)
    return real(*args, **kwargs)

setattr(owner, "{name}".split(".")[-1], held)
main(prog_name="mcz")
"""
CODING_CHILD = HELD_CHILD.format(module="mocapzip.ratecontrol.encode", name="code_clip")  # a clip's coding
DECODING_CHILD = HELD_CHILD.format(module="mocapzip.archive.reader", name="Archive.file_blocks")  # a file's decoding


# Runs the real `mcz compress` with the coding of its first clip replaced by compiled code that
# allocates until the process receives a signal (creating the marker file first): the signal lands in
# numba's code, as it may in the codec's kernels, whose dispatcher then raises a SystemError caused
# by it. Python runs the signal's handler only when the kernel returns; a thread sees the signal
# arrive (`signal.set_wakeup_fd`) and tells the kernel to return.
COMPILED_CHILD = r"""
import os, signal, threading
from pathlib import Path
import numpy as np
from numba import njit
from mocapzip.ratecontrol import encode
from mocapzip.cli.main import main

@njit(nogil=True)
def allocating(stop):
    total = 0.0
    while not stop[0]:
        row = np.empty(8)
        row[0] = 1.0
        total += row[0]
    return np.zeros(2) + total, np.zeros(2, np.int64)  # a tuple with int64s, as `markers_to_channels`

stop = np.zeros(1, np.bool_)
allocating(np.ones(1, np.bool_))
received, sent = os.pipe()
os.set_blocking(sent, False)
signal.set_wakeup_fd(sent)
threading.Thread(target=lambda: (os.read(received, 1), stop.fill(True)), daemon=True).start()

def coded_until_a_signal(*args, **kwargs):
    Path(os.environ["MCZ_TEST_MARKER"]).touch()
    return allocating(stop)

encode.code_clip = coded_until_a_signal
main(prog_name="mcz")
"""


def start(args: list, env: dict | None = None) -> subprocess.Popen:
    # SIGINT may be ignored by whatever started the test run (a background job); the child gets Python's default.
    return subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def interrupt(proc: subprocess.Popen, signum: int) -> str:
    """Send `signum` to a running child; return its stderr after checking the exit and the message."""
    assert proc.poll() is None, "the run ended before it could be interrupted"
    proc.send_signal(signum)
    _, stderr = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 1, (proc.returncode, stderr)
    name = signal.Signals(signum).name
    assert stderr.splitlines() == [f"mcz: error: interrupted ({name}); no partial file was left behind"], stderr
    return stderr


SIGNALS = pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])


def wait_for(marker: Path, proc: subprocess.Popen) -> None:
    deadline = time.monotonic() + TIMEOUT
    while not marker.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the child never reached the slowed write"
        time.sleep(0.02)


@SIGNALS
def test_compress_interrupted_in_compiled_code(shared_data, tmp_path, signum):
    """Before: a traceback ending in `SystemError: CPUDispatcher(...) returned a result with an
    exception set` (`mcz compress --model tensor` of HDM05, Ctrl-C in `markers_to_channels`)."""
    out, marker = tmp_path / "out", tmp_path / "marker"
    out.mkdir()
    proc = start([sys.executable, "-c", COMPILED_CHILD, "compress", shared_data / "cmu" / "09", "-o", out / "db.mcz",
                  "-j", "1"], {**os.environ, "MCZ_TEST_MARKER": str(marker)})
    wait_for(marker, proc)
    interrupt(proc, signum)
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("signum, jobs", [(signal.SIGINT, "1"), (signal.SIGTERM, "2")], ids=["SIGINT", "SIGTERM-j2"])
def test_compress_of_a_real_folder_interrupted_mid_run(shared_data, tmp_path, signum, jobs):
    """The signal comes while the codec (and, with -j 2, its worker processes) code clips: the child
    holds its first clip coding until the test has sent it (a state, not a clock)."""
    out, marker = tmp_path / "out", tmp_path / "marker"
    out.mkdir()
    env = {**os.environ, "MCZ_TEST_MARKER": str(marker), **({"MCZ_TEST_HOLD_IN_WORKER": "1"} if jobs == "2" else {})}
    proc = start([sys.executable, "-c", CODING_CHILD, "compress", shared_data / "cmu" / "09", "-o", out / "db.mcz",
                  "-j", jobs], env)
    wait_for(marker, proc)
    assert proc.poll() is None, "the run ended before it could be interrupted"
    proc.send_signal(signum)
    marker.with_suffix(".release").touch()  # a worker process holding its clip may go on
    _, stderr = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 1, (proc.returncode, stderr)
    name = signal.Signals(signum).name
    assert stderr.splitlines() == [f"mcz: error: interrupted ({name}); no partial file was left behind"], stderr
    assert os.listdir(out) == []


@SIGNALS
def test_compress_interrupted_while_writing_the_archive(shared_data, tmp_path, signum):
    out, marker = tmp_path / "out", tmp_path / "marker"
    out.mkdir()
    env = {**os.environ, "MCZ_TEST_MARKER": str(marker)}
    proc = start([sys.executable, "-c", SLOW_CHILD, "compress", shared_data / "cmu" / "09" / "09_01.amc",
                  "--lossless", "-o", out / "db.mcz"], env)
    wait_for(marker, proc)
    (temporary,) = os.listdir(out)
    assert temporary.startswith(".db.mcz.tmp-") and (out / temporary).stat().st_size > 0
    interrupt(proc, signum)
    assert os.listdir(out) == []


@SIGNALS
@pytest.mark.parametrize("jobs", ["1", "2"], ids=["j1", "j2"])
@ARCHIVES
def test_decompress_interrupted_while_writing_an_amc(tmp_path, signum, jobs, archive):
    """The third file is half written when the signal comes: it must vanish, the two before stay whole.
    With -j 2 the workers (or threads) decoding the files ahead are stopped too (the run ends, within
    TIMEOUT)."""
    reference, out, marker = tmp_path / "reference", tmp_path / "out", tmp_path / "marker"
    decompress(archive, reference)
    env = {**os.environ, "MCZ_TEST_MARKER": str(marker)}
    proc = start([sys.executable, "-c", SLOW_CHILD, "decompress", archive, "-o", out, "-j", jobs], env)
    wait_for(marker, proc)
    assert any(name.startswith(".mcz-") and name.endswith(".tmp") for name in os.listdir(out))
    interrupt(proc, signum)
    left = {p.name: p.read_bytes() for p in out.iterdir()}
    assert len(left) == 2 and all(not name.startswith(".") for name in left), sorted(left)
    assert left == {name: (reference / name).read_bytes() for name in left}
    assert len(os.listdir(reference)) >= 3


@pytest.mark.parametrize("command, archive", [("compress", None), ("decompress", GOLDEN_LOSSLESS),
                                              ("decompress", GOLDEN_LOSSY)], ids=["compress", "lossless", "lossy"])
def test_ctrl_c_in_a_terminal_stops_every_worker_in_one_line(shared_data, tmp_path, command, archive):
    """Ctrl-C in a terminal sends SIGINT to the whole process group, workers included (-j 2): the
    parent alone answers, in one line (no worker traceback), and leaves nothing behind. The signal
    comes while a worker process (compress, lossless decompress) or a decoding thread (lossy
    decompress) holds its first clip (a state, not a clock)."""
    out, marker = tmp_path / "out", tmp_path / "marker"
    out.mkdir()
    env = {**os.environ, "MCZ_TEST_MARKER": str(marker), "MCZ_TEST_HOLD_IN_WORKER": "1"}
    if command == "compress":
        args = [CODING_CHILD, "compress", shared_data / "cmu" / "09", "-o", out / "db.mcz"]
    else:
        args = [DECODING_CHILD, "decompress", archive, "-o", out]
    proc = subprocess.Popen([sys.executable, "-c", *args, "-j", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, start_new_session=True,  # a process group of its own, as in a terminal
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    wait_for(marker, proc)
    assert proc.poll() is None, "the run ended before it could be interrupted"
    os.killpg(proc.pid, signal.SIGINT)
    marker.with_suffix(".release").touch()  # the worker holding its clip may go on
    _, stderr = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 1, (proc.returncode, stderr)
    assert stderr.splitlines() == ["mcz: error: interrupted (SIGINT); no partial file was left behind"], stderr
    assert_only_whole_files(out, tmp_path, command, archive)


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="finds the workers through /proc (Linux)")
@pytest.mark.parametrize("command", ["compress", "decompress"])
def test_a_worker_killed_mid_run_ends_the_run_in_one_line(shared_data, tmp_path, command):
    """A worker of compress -j 2, or of decompress -j 2 of a lossless archive, killed (as the OOM
    killer would) while it holds its first clip: the parent says so in one line, exits 1, and leaves
    no file behind."""
    out, marker = tmp_path / "out", tmp_path / "marker"
    out.mkdir()
    env = {**os.environ, "MCZ_TEST_MARKER": str(marker), "MCZ_TEST_HOLD_IN_WORKER": "1"}
    if command == "compress":
        args = [CODING_CHILD, "compress", shared_data / "cmu" / "09", "-o", out / "db.mcz"]
    else:
        args = [DECODING_CHILD, "decompress", GOLDEN_LOSSLESS, "-o", out]
    proc = start([sys.executable, "-c", *args, "-j", "2"], env)
    wait_for(marker, proc)
    workers = [int(entry) for entry in os.listdir("/proc") if entry.isdigit() and _parent_of(int(entry)) == proc.pid]
    assert len(workers) == 2, workers
    for pid in workers:
        os.kill(pid, signal.SIGKILL)
    _, stderr = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 1, (proc.returncode, stderr)
    assert stderr.splitlines() == ["mcz: error: a worker process ended abruptly (killed, or out of memory); "
                                   "no partial file was left behind"], stderr
    assert_only_whole_files(out, tmp_path, command)


def assert_only_whole_files(out: Path, tmp_path: Path, command: str, archive: Path = GOLDEN_LOSSLESS) -> None:
    """Nothing half written is left behind. Decompress keeps whole files written before the one held
    (as with -j 1: the workers decode ahead, and which of them the test holds is a race)."""
    left = sorted(out.iterdir()) if out.exists() else []
    if command == "compress":
        assert left == []
        return
    reference = tmp_path / "reference"
    decompress(archive, reference)
    assert all(p.read_bytes() == (reference / p.name).read_bytes() for p in left), left
    assert len(left) < len(os.listdir(reference))


def _parent_of(pid: int) -> int | None:
    try:
        return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
    except (OSError, IndexError, ValueError):
        return None
