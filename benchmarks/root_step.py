"""How finely to code the root track: archive size against the root step / pose step ratio.

    python benchmarks/root_step.py [DIR ...] [-e CM] [-j N] [--ratios 1,0.5,...]

Compresses the folders (default: CMU subjects 02, 07, 13 and 35 of ../shared/data) once per
ratio with the default settings otherwise, and prints bytes per frame and the worst clip
error. Every archive meets the same error target, so the smallest one has the best ratio;
`encode.ROOT_STEP_RATIO` is set from this table (docs/architecture.md).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from mocapzip.ratecontrol import encode
from mocapzip.archive import Settings, compress

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"
SUBJECTS = ("02", "07", "13", "35")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("inputs", nargs="*", type=Path, default=[DATA / s for s in SUBJECTS])
    parser.add_argument("-e", "--error", type=float, default=1.0)
    parser.add_argument("-j", "--jobs", type=int, default=2)
    parser.add_argument("--ratios", default="1,0.5,0.35,0.25,0.2,0.15,0.1")
    args = parser.parse_args(argv)
    default = encode.ROOT_STEP_RATIO
    print("| root step / pose step | bytes/frame | worst clip error (cm) |")
    print("|---|---|---|")
    try:
        for ratio in (float(r) for r in args.ratios.split(",")):
            encode.ROOT_STEP_RATIO = ratio  # read at call time, also by forked workers
            with tempfile.TemporaryDirectory() as work:
                summary = compress(args.inputs, Path(work) / "root.mcz", Settings(error_cm=args.error),
                                   jobs=args.jobs)
            mark = " (default)" if ratio == default else ""
            print(f"| {ratio:g}{mark} | {summary['bytes_per_frame']:.3f} | {summary['worst_error_cm']:.3f} |",
                  flush=True)
    finally:
        encode.ROOT_STEP_RATIO = default


if __name__ == "__main__":
    main()
