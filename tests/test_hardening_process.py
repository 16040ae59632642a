"""Process faults (issue 13): the archive never replaces an input, and no worker outlives its parent.

Real clips from ../shared/data; every child runs the installed `mcz`.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

MCZ = Path(sys.executable).with_name("mcz")
DEADLINE = 120.0  # seconds: only a hang reaches it


def mcz(*args) -> subprocess.CompletedProcess:
    return subprocess.run([MCZ, *map(os.fspath, args)], capture_output=True, text=True, timeout=DEADLINE)


@pytest.fixture
def subject(shared_data, tmp_path) -> Path:
    """Two real CMU clips and their skeleton in a folder of the test's own, so inputs may be at stake."""
    folder = tmp_path / "09"
    folder.mkdir()
    for name in ("09.asf", "09_01.amc", "09_02.amc"):
        shutil.copyfile(shared_data / "cmu" / "09" / name, folder / name)
    return folder


@pytest.mark.parametrize("victim", ["09_01.amc", "09.asf", "hard link to 09_02.amc", "classes.csv"])
def test_output_naming_an_input_is_refused_even_with_force(subject, victim):
    classes = subject.parent / "classes.csv"
    classes.write_text("09_01.amc,walk\n09_02.amc,walk\n")
    if victim.startswith("hard link"):
        os.link(subject / "09_02.amc", subject.parent / "link.mcz")
        output, original = subject.parent / "link.mcz", subject / "09_02.amc"
    else:
        output = original = classes if victim == "classes.csv" else subject / victim
    before = original.read_bytes()
    result = mcz("compress", subject, "-o", output, "-f", "--lossless", "-c", classes)
    assert result.returncode == 1, result.stderr
    assert result.stderr.splitlines() == [
        f"mcz: error: {output}: is also an input ({original}); refusing to replace it, even with -f"]
    assert original.read_bytes() == before


def _children(pid: int) -> set[int]:
    """Processes whose parent is `pid`, from /proc."""
    found = set()
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                found.add(int(entry))
    return found


def _alive(pid: int) -> bool:
    """Running, not a zombie waiting for a parent (in a container, PID 1 may never reap it)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="finds the workers through /proc (Linux)")
def test_workers_exit_when_compress_is_killed(shared_data, tmp_path):
    """kill -9 of `compress -j 2` runs none of its clean-up; its workers must still go."""
    proc = subprocess.Popen([MCZ, "compress", shared_data / "cmu" / "09", "-o", tmp_path / "db.mcz", "-j", "2", "-q"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + DEADLINE
    workers: set[int] = set()
    while len(workers) < 2:
        assert proc.poll() is None, f"compress ended before it started its workers: {proc.stderr.read()}"
        assert time.monotonic() < deadline, "compress never started its workers"
        workers = _children(proc.pid)
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=DEADLINE)
    deadline = time.monotonic() + DEADLINE
    while any(_alive(pid) for pid in workers):
        assert time.monotonic() < deadline, f"workers {sorted(workers)} outlived their parent"
        time.sleep(0.1)
