"""Solved bones (format 4): archive size with and without the axes that joint positions fix,
and the axis weight that suits the axes left.

    python benchmarks/solved_bones.py [DIR ...] [-e CM] [-j N] [--weights 5,8,12]

Compresses the folders (default: CMU subjects 02, 07, 13, 35 and 64 of ../shared/data) with
the default settings but for two: once storing every bone's axis with the format-3 axis
weight (`axes_from_positions` false, `axis_weight_cm` 5), then leaving out the axes of
solved bones (`representations.positions.solved_bones`) with each axis weight of
`--weights`. Prints bytes per frame, pose width, class-basis bytes, the clips whose rows
need twist flips and the worst clip error; every archive meets the same target.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from mocapzip.archive import Archive, Settings, compress

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"
SUBJECTS = ("02", "07", "13", "35", "64")
FORMAT_3_WEIGHT = 5.0


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("inputs", nargs="*", type=Path, default=[DATA / s for s in SUBJECTS])
    parser.add_argument("-e", "--error", type=float, default=1.0)
    parser.add_argument("-j", "--jobs", type=int, default=2)
    parser.add_argument("--weights", default="5,8,12")
    args = parser.parse_args(argv)
    default = Settings()
    runs = [(False, FORMAT_3_WEIGHT)] + [(True, float(w)) for w in args.weights.split(",")]
    print("| axes stored | axis weight (cm) | pose width | bytes/frame | class bases (bytes) "
          "| clips with twist flips | worst clip error (cm) |")
    print("|---|---|---|---|---|---|---|")
    for solved, weight in runs:
        settings = Settings(error_cm=args.error, axes_from_positions=solved, axis_weight_cm=weight)
        with tempfile.TemporaryDirectory() as work:
            path = Path(work) / "solved.mcz"
            summary = compress(args.inputs, path, settings, jobs=args.jobs)
            with Archive(path) as archive:
                bases = sum(size for name, size in archive.stream_sizes().items() if name.startswith("class/"))
                width = len(archive.basis(0).mean)
                flipped = sum("twist_flips" in row for row in archive.clips)
        label = "all but solved bones'" if solved else "every bone's"
        mark = " (default)" if (solved, weight) == (default.axes_from_positions, default.axis_weight_cm) else ""
        print(f"| {label}{mark} | {weight:g} | {width} | {summary['bytes_per_frame']:.3f} | {bases:,} "
              f"| {flipped} of {summary['clips']} | {summary['worst_error_cm']:.3f} |", flush=True)


if __name__ == "__main__":
    main()
