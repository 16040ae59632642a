#!/usr/bin/env python
"""Read and write throughput of the AMC reader/writer (a script, not a test).

    python benchmarks/bench_amc_io.py [FOLDER] [--repeat N] [--check]

Reads every AMC file under FOLDER (default: ../shared/data/cmu/01 next to the repository)
with `read_amc`, writes each back with `write_amc` into a temporary folder, and prints MB/s
and frames/s for both. Each pass is timed `--repeat` times and the best is kept, so the
figures describe the code rather than a cold disk cache or a busy neighbour.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from mocapzip.formats.amc import read_amc, write_amc

REPO = Path(__file__).resolve().parents[1]
DEFAULT = REPO.parent / "shared" / "data" / "cmu" / "01"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", nargs="?", default=str(DEFAULT), help=f"folder of AMC files (default {DEFAULT})")
    parser.add_argument("--repeat", type=int, default=3, help="timed passes, best kept (default 3)")
    parser.add_argument("--check", action="store_true", help="also re-read the written files and compare values")
    parser.add_argument("--verbose", action="store_true", help="one line per file")
    args = parser.parse_args(argv)

    folder = Path(args.folder)
    files = sorted(p for p in folder.rglob("*") if p.is_file() and p.suffix.lower() == ".amc")
    if not files:
        print(f"no AMC files under {folder}", file=sys.stderr)
        return 1
    in_bytes = sum(p.stat().st_size for p in files)

    warnings.simplefilter("ignore")  # truncated last frames are reported once below, not timed
    best_read = best_write = float("inf")
    with tempfile.TemporaryDirectory() as tmp:
        out_paths = [Path(tmp) / f"{i:04d}.amc" for i in range(len(files))]
        for _ in range(max(1, args.repeat)):
            t0 = time.perf_counter()
            motions = [read_amc(p) for p in files]
            best_read = min(best_read, time.perf_counter() - t0)
            t0 = time.perf_counter()
            for motion, out in zip(motions, out_paths):
                write_amc(motion, out)
            best_write = min(best_write, time.perf_counter() - t0)
        out_bytes = sum(p.stat().st_size for p in out_paths)
        identical = sum(p.read_bytes() == q.read_bytes() for p, q in zip(files, out_paths))
        if args.verbose:
            for p, m, q in zip(files, motions, out_paths):
                print(f"  {p.name}: {m.n_frames} frames, {p.stat().st_size} B, style {m.style.number_format}"
                      f"{' identical' if p.read_bytes() == q.read_bytes() else ''}")
        if args.check:
            for m, q in zip(motions, out_paths):
                again = read_amc(q)
                assert again.bones == m.bones and np.array_equal(again.values, m.values), q

    frames = sum(m.n_frames for m in motions)
    print(f"{len(files)} AMC files, {in_bytes / 1e6:.1f} MB, {frames} frames in {folder}")
    print(f"read : {in_bytes / 1e6 / best_read:7.1f} MB/s  {frames / best_read:10.0f} frames/s  ({best_read:.3f} s)")
    print(f"write: {out_bytes / 1e6 / best_write:7.1f} MB/s  {frames / best_write:10.0f} frames/s  ({best_write:.3f} s)")
    print(f"written files byte-identical to their source: {identical}/{len(files)}"
          + ("; values re-read equal" if args.check else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
