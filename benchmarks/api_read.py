"""Read speed of the Python API and of `mcz decompress` (issue 43's targets), for one or more code trees.

    python benchmarks/api_read.py ARCHIVE [--code DIR ...] [--repeats 3]

ARCHIVE: an .mcz of AMC clips (issue 43: `mcz compress ../shared/data/cmu -o cmu.mcz`, -e 1).
Each `--code` (default: this checkout) is measured in child processes started with
PYTHONPATH=DIR, one measure after the other for every tree, so a "before" and an "after" tree
see the same machine load. Measures, each the best of `--repeats` runs:

- channels: every clip's `channels` through the API, one process (after one warm-up clip, numba's
  compiled code loaded from its cache); frames/s per core: frames over the process's CPU time
  (all its threads'), beside the wall time;
- positions: every clip's `positions()`, the same way;
- first clip: a fresh interpreter's `import mocapzip; mocapzip.open(ARCHIVE)[0].channels`, wall time
  of the child including interpreter start-up;
- `mcz decompress -j 2` of the whole archive against `xz -d -T1` of the same files (its output,
  tarred, xz -6) in the same run: their times and ratio (above 1: mcz is faster).

The API's children set no BLAS variable: limiting threads is the API's job. `uptime` is
printed before and after: the machine may be shared.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

READ_ALL = """
import json, sys, time, mocapzip
what = sys.argv[2]
with mocapzip.open(sys.argv[1]) as archive:
    clips = list(archive)
    getattr(clips[0], what) if what == "channels" else clips[0].positions()  # warm-up: numba's cache loaded
    started, cpu = time.perf_counter(), time.process_time()
    with mocapzip.open(sys.argv[1]) as again:
        frames = 0
        for clip in again:
            frames += len(clip.channels if what == "channels" else clip.positions())
    print(json.dumps({"seconds": time.perf_counter() - started, "cpu": time.process_time() - cpu,
                      "frames": frames}))
"""


def child(code: str, *args: str, env_code: str, timeout: float = 600) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    env["PYTHONPATH"] = env_code
    return subprocess.run([sys.executable, *code, *args], env=env, cwd=env_code, capture_output=True, text=True,
                          timeout=timeout, check=True)


def read_all(tree: str, archive: str, what: str) -> dict:
    return json.loads(child(["-c", READ_ALL], archive, what, env_code=tree).stdout)


def first_clip(tree: str, archive: str) -> float:
    started = time.perf_counter()
    child(["-c", "import sys, mocapzip; mocapzip.open(sys.argv[1])[0].channels"], archive, env_code=tree)
    return time.perf_counter() - started


def decompress(tree: str, archive: str, out: Path) -> float:
    started = time.perf_counter()
    child(["-c", "from mocapzip.cli.main import main; main()", "decompress", archive, "-o", str(out), "-j", "2",
           "-f", "-q"], env_code=tree)
    return time.perf_counter() - started


def uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("archive")
    parser.add_argument("--code", action="append", help="a code tree (PYTHONPATH) to measure; repeat to compare")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    trees = [os.path.abspath(t) for t in (args.code or [str(REPO)])]
    archive = os.path.abspath(args.archive)
    print(f"before: {uptime()}")
    rows: dict[str, dict[str, float]] = {t: {} for t in trees}
    with tempfile.TemporaryDirectory() as tmp:
        tar_xz = Path(tmp) / "clips.tar.xz"
        decompress(trees[0], archive, Path(tmp) / "out")  # also warms the compiled-code cache
        with tarfile.open(Path(tmp) / "clips.tar", "w") as tar:
            tar.add(Path(tmp) / "out", arcname="out")
        subprocess.run(["xz", "-6", "-T1", "-k", str(Path(tmp) / "clips.tar")], check=True)
        for what in ("channels", "positions"):
            for tree in trees:
                runs = [read_all(tree, archive, what) for _ in range(args.repeats)]
                best = min(runs, key=lambda r: r["seconds"])
                rows[tree][f"{what} s"] = best["seconds"]
                rows[tree][f"{what} frames/s/core"] = best["frames"] / best["cpu"]  # CPU time: every thread's
                rows[tree]["frames"] = best["frames"]
        for tree in trees:
            rows[tree]["first open+clip s"] = min(first_clip(tree, archive) for _ in range(args.repeats))
        xz_runs = []
        for tree in trees:
            times = []
            for _ in range(args.repeats):
                times.append(decompress(tree, archive, Path(tmp) / "out"))
                started = time.perf_counter()
                subprocess.run(["xz", "-d", "-T1", "-c", str(tar_xz)], stdout=subprocess.DEVNULL, check=True)
                xz_runs.append(time.perf_counter() - started)
            rows[tree]["decompress -j 2 s"] = min(times)
        xz = min(xz_runs)
        for tree in trees:
            rows[tree]["xz -d s"] = xz
            rows[tree]["xz -d / decompress"] = xz / rows[tree]["decompress -j 2 s"]
    print(f"after: {uptime()}\n")
    names = list(rows[trees[0]])
    print("| measure | " + " | ".join(trees) + " |\n|---|" + "---:|" * len(trees))
    for name in names:
        print(f"| {name} | " + " | ".join(f"{rows[t][name]:,.3f}" if rows[t][name] < 1000 else f"{rows[t][name]:,.0f}"
                                          for t in trees) + " |")


if __name__ == "__main__":
    main()
