"""Where the planted-foot thresholds (`mocapzip.motion.contacts`) come from.

    python benchmarks/contact_thresholds.py [DIR ...] [--fps 120]

For the foot joints of the clips under DIR (default: the shared CMU set): how high above its
own lowest level each is (percentiles), how fast it moves across the floor while within
CONTACT_HEIGHT_CM of that level (percentiles, and a histogram: the planted feet's peak, then
the swing), and the share of frames with some foot planted (docs/fidelity.md).
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.inputs.discover import find_clips
from mocapzip.motion.contacts import CONTACT_HEIGHT_CM, contacts, foot_joints, horizontal_speed
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("inputs", nargs="*", type=Path, default=[DATA])
    parser.add_argument("--fps", type=float, default=120.0)
    args = parser.parse_args(argv)
    heights, speeds, planted_frames, frames = [], [], 0, 0
    for source in find_clips(args.inputs):
        model = SkeletonModel.from_asf(read_asf(source.skeleton))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a last frame cut short is dropped, as compress does
            motion = read_amc(source.motion)
        positions = forward(model, motion.values, motion).positions
        feet = foot_joints(model)
        height = positions[:, feet, 1] - np.percentile(positions[:, feet, 1], 1, axis=0)
        low = height < CONTACT_HEIGHT_CM
        heights.append(height.ravel())
        speeds.append(horizontal_speed(positions[:, feet], args.fps)[low])
        planted_frames += int(contacts(model, positions, args.fps).any(axis=1).sum())
        frames += len(positions)
    height, speed = np.concatenate(heights), np.concatenate(speeds)
    quantiles = (10, 25, 50, 75, 90)
    print("| foot joints | " + " | ".join(f"p{q}" for q in quantiles) + " |\n|---|" + "---:|" * len(quantiles))
    print("| height above its lowest level (cm) | " + " | ".join(f"{np.percentile(height, q):.1f}" for q in quantiles)
          + " |")
    print(f"| speed across the floor when within {CONTACT_HEIGHT_CM:g} cm of it (cm/s) | "
          + " | ".join(f"{np.percentile(speed, q):.1f}" for q in quantiles) + " |")
    counts, edges = np.histogram(speed, bins=[0, 5, 10, 20, 40, 80, 160, 320, np.inf])
    print("\n| speed (cm/s) | " + " | ".join(f"{a:g}-{b:g}" for a, b in zip(edges[:-1], edges[1:])) + " |")
    print("|---|" + "---:|" * len(counts) + "\n| share of low foot-joint frames | "
          + " | ".join(f"{c / counts.sum():.1%}" for c in counts) + " |")
    print(f"\nFrames with a foot planted: {planted_frames / frames:.1%} of {frames:,}.")


if __name__ == "__main__":
    main()
