"""BVH reading and writing speed (formats/bvh.py) on every shared BVH file.

    python benchmarks/bvh_io.py [--repeat 3]

Reads each file's bytes once, then times `parse_bvh` on all of them, and writing each one from
its values (`format_bvh` of the clip with its frame text dropped: every number formatted in the
file's style), the best of `--repeat` rounds, in MB/s of BVH text (issue 18's target for
reading: 100 MB/s). Every file written is checked to be the file read, byte for byte.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace
from pathlib import Path

from mocapzip.formats.bvh import format_bvh, parse_bvh

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    files = sorted(DATA.glob("cmu-bvh/*/*.bvh")) + sorted(DATA.glob("bvh-bandai/*.bvh"))
    raw = [(p.read_bytes(), os.fspath(p)) for p in files]
    total = sum(len(data) for data, _ in raw)
    read, write = [], []
    for _ in range(args.repeat):
        started = time.perf_counter()
        parsed = [parse_bvh(data, name) for data, name in raw]
        middle = time.perf_counter()
        texts = [format_bvh(replace(bvh, frames_text=None)).encode(bvh.encoding) for bvh in parsed]
        read.append(middle - started)
        write.append(time.perf_counter() - middle)
        assert texts == [data for data, _ in raw], "a file did not come back byte for byte"
    print(f"`python benchmarks/bvh_io.py` ({os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}): "
          f"{len(files)} files, {total / 1e6:.1f} MB, best of {args.repeat}, every file back byte for byte.\n")
    print("| | seconds | MB/s |\n|---|---:|---:|")
    print(f"| read (parse_bvh) | {min(read):.2f} | {total / 1e6 / min(read):.1f} |")
    print(f"| write from the values (format_bvh) | {min(write):.2f} | {total / 1e6 / min(write):.1f} |")


if __name__ == "__main__":
    main()
