"""Random access through the Python API: one clip read from an archive, against the whole archive.

    python benchmarks/api_read_one.py [ARCHIVE] [--clips N]

ARCHIVE (default: the shared CMU set compressed at 1 cm into a temporary file, 118 clips) is
opened once per measurement, as a user opening it to read one clip would, and one clip's
`channels` decoded; the whole archive is decoded the same way, clip after clip, in one
process (`mcz decompress` spreads it over -j workers instead). Prints the median time of one
clip over `--clips` clips spread across the archive, the time of all clips, and their ratio
(issue 18's target: under 5 %). One process, after one warm-up read (numba's compiled code
loaded from its cache).
"""

from __future__ import annotations

import os

from mocapzip.defaults import BLAS_THREAD_VARIABLES  # imports nothing: numpy is not loaded yet

for _var in BLAS_THREAD_VARIABLES:  # before numpy: as `mcz` runs (cli/__init__.py)
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import mocapzip  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def read_one(archive_path, index: int) -> float:
    started = time.perf_counter()
    with mocapzip.open(archive_path) as archive:
        archive[index].channels
    return time.perf_counter() - started


def read_all(archive_path) -> float:
    started = time.perf_counter()
    with mocapzip.open(archive_path) as archive:
        for clip in archive:
            clip.channels
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("archive", nargs="?", help="an .mcz archive (default: the shared CMU set at 1 cm)")
    parser.add_argument("--clips", type=int, default=9, help="clips timed one at a time (default 9)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = args.archive
        if path is None:
            path = os.path.join(tmp, "cmu.mcz")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                mocapzip.compress(DATA / "cmu", path, error=1.0, jobs=os.cpu_count() or 1)
        with mocapzip.open(path) as archive:
            count, frames = len(archive), sum(clip.frames for clip in archive)
        read_one(path, 0)  # warm-up
        picks = sorted({round(k * (count - 1) / max(1, args.clips - 1)) for k in range(args.clips)})
        one = statistics.median(read_one(path, k) for k in picks)
        whole = read_all(path)
    print(f"`python benchmarks/api_read_one.py{'' if args.archive is None else ' ' + args.archive}` "
          f"({os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}): {count} clips, {frames:,} frames.\n")
    print("| read | seconds | share of the whole archive |\n|---|---:|---:|")
    print(f"| one clip: open the archive, decode one clip (median of {len(picks)}) | {one:.3f} | {one / whole:.1%} |")
    print(f"| every clip, one after the other | {whole:.3f} | 100% |")


if __name__ == "__main__":
    main()
