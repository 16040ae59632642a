"""Where the glitch thresholds (`mocapzip.inputs.glitches`) come from: real motion's extremes.

    python benchmarks/glitch_thresholds.py [DIR ...] [--fps 120]

For the clips under DIR (default: the shared CMU set), prints the percentiles of every joint's
move between two frames (cm, and m/s at --fps), and how many runs of frames pass their ASF
limits by more than each margin, in how many clips: normal motion sits below a threshold,
broken motion above it (docs/fidelity.md).
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.inputs.glitches import beyond_limits
from mocapzip.inputs.discover import find_clips
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"
MARGINS = (0.0, 30.0, 60.0, 90.0, 120.0)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("inputs", nargs="*", type=Path, default=[DATA])
    parser.add_argument("--fps", type=float, default=120.0)
    args = parser.parse_args(argv)
    moves, limit_runs = [], {m: [0, set()] for m in MARGINS}
    for source in find_clips(args.inputs):
        skeleton = read_asf(source.skeleton)
        model = SkeletonModel.from_asf(skeleton)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a last frame cut short is dropped, as compress does
            motion = read_amc(source.motion, skeleton)
        positions = forward(model, motion.values, motion).positions
        moves.append(np.linalg.norm(np.diff(positions, axis=0), axis=2).ravel())
        for margin in MARGINS:
            runs = beyond_limits(skeleton, model, motion, margin)
            limit_runs[margin][0] += len(runs)
            if runs:
                limit_runs[margin][1].add(source.relpath)
    moves = np.concatenate(moves)
    print("| percentile of joint moves between frames | cm | m/s |\n|---|---:|---:|")
    for q in (99, 99.9, 99.99, 99.999, 100):
        cm = float(np.percentile(moves, q))
        print(f"| {q:g} | {cm:.1f} | {cm * args.fps / 100:.1f} |")
    print("\n| beyond the ASF limits by more than (deg) | runs of frames | clips |\n|---:|---:|---:|")
    for margin, (runs, clips) in limit_runs.items():
        print(f"| {margin:g} | {runs:,} | {len(clips)} |")


if __name__ == "__main__":
    main()
