"""Solved bones (format 4): archive size with and without the axes that joint positions fix.

    python benchmarks/solved_bones.py [DIR ...] [-e CM] [-j N]

Compresses the folders (default: CMU subjects 02, 07, 13, 35 and 64 of ../shared/data)
twice with the default settings, once storing every bone's axis (`axes_from_positions`
false, as formats 1 to 3 did) and once leaving out the axes of solved bones
(`representations.positions.solved_bones`, the default). Prints bytes per frame, pose
width, class-basis bytes and the worst clip error; every archive meets the same target.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from mocapzip.archive import Archive, Settings, compress

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"
SUBJECTS = ("02", "07", "13", "35", "64")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("inputs", nargs="*", type=Path, default=[DATA / s for s in SUBJECTS])
    parser.add_argument("-e", "--error", type=float, default=1.0)
    parser.add_argument("-j", "--jobs", type=int, default=2)
    args = parser.parse_args(argv)
    print("| axes | pose width | bytes/frame | class bases (bytes) | clips with twist flips | worst clip error (cm) |")
    print("|---|---|---|---|---|---|")
    for solved in (False, True):
        with tempfile.TemporaryDirectory() as work:
            path = Path(work) / "solved.mcz"
            summary = compress(args.inputs, path, Settings(error_cm=args.error, axes_from_positions=solved),
                               jobs=args.jobs)
            with Archive(path) as archive:
                sizes = archive.stream_sizes()
                width = archive._basis(0).components.shape[0]
                flipped = sum("twist_flips" in row for row in archive.clips)
        bases = sum(size for name, size in sizes.items() if name.startswith("class/"))
        label = "solved bones left out (default)" if solved else "every bone's axis"
        print(f"| {label} | {width} | {summary['bytes_per_frame']:.3f} | {bases:,} | {flipped} of "
              f"{summary['clips']} | {summary['worst_error_cm']:.3f} |", flush=True)


if __name__ == "__main__":
    main()
