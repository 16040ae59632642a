"""Seed 002's time warping on real takes: do aligned steps land on the same foot, and how much
faster is the multiscale search than plain DTW?

    python benchmarks/timewarp.py [--data ../shared/data] [--repeat 20]

1. Steps. HDM05 takes of one motion with the same steps and starting foot, by three actors
   (jogLeftCircle4StepsRstart, sneak2StepsLStart), each aligned to the first take. A step is the
   start of a foot's contact run (`contacts.foot_strikes`); each step of
   a take is mapped into the reference's time and matched to the reference's nearest step. The
   table counts steps matched to a step of the same foot, with the physics features
   (centre-of-mass acceleration and the hands' and feet's angular momenta) and with the
   centre-of-mass acceleration alone (the seed's Figure 2: alone, it cannot tell the feet apart).
2. Speed. Plain and multiscale DTW on the physics features of real clips of about 300 and
   about 3,000 frames (the seed: about 10x and 100x faster): the median time of `--repeat`
   runs each (compiled code warmed up first), and the cells of the cost matrix each fills.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np

from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.motion.contacts import foot_strikes
from mocapzip.motion.kinematics import forward
from mocapzip.motion.physics import physics_features
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.motion.timewarp import dtw, multiscale_dtw

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
FPS = 120.0
MOTIONS = ("jogLeftCircle4StepsRstart", "sneak2StepsLStart")
SPEED_PAIRS = (("cmu/07/07_01.amc", "cmu/07/07_02.amc"), ("cmu/135/135_03.amc", "cmu/135/135_06.amc"))


def loaded(path: Path) -> tuple[np.ndarray, dict[str, list[int]]]:
    """(physics features, steps per foot) of an AMC clip, with the ASF in its folder."""
    skeleton = read_asf(next(path.parent.glob("*.asf")))
    model = SkeletonModel.from_asf(skeleton)
    clip = read_amc(path, skeleton)
    pose = forward(model, clip.values, clip)
    return physics_features(model, pose.positions, pose.rotations, FPS), foot_strikes(model, pose.positions, FPS)


def same_foot(reference, take, features) -> tuple[int, int, float]:
    """(steps on the same foot, steps, mean distance in frames to the matched step)."""
    (ref_features, ref_steps), (take_features, take_steps) = reference, take
    warping = multiscale_dtw(ref_features[:, features], take_features[:, features], FPS)
    in_reference = warping.carried(np.arange(len(ref_features)), onto=1)
    matched, distances = 0, []
    for side, frames in take_steps.items():
        for frame in frames:
            distance, nearest = min((abs(in_reference[frame] - f), s) for s, fs in ref_steps.items() for f in fs)
            matched += nearest == side
            distances.append(distance)
    return matched, len(distances), float(np.mean(distances))


def timed(function, repeat: int) -> float:
    function()  # compiled on first use (or loaded from the cache): not timed
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help=f"the shared data folder (default {DATA})")
    parser.add_argument("--repeat", type=int, default=20, help="timed runs of each search (median kept)")
    args = parser.parse_args(argv)

    print("Steps matched to a step of the same foot (multiscale DTW; each take against the first)\n")
    print("| motion | take | steps | physics features | mean distance (frames) | centre-of-mass acceleration alone "
          "| mean distance (frames) |\n|---|---|---:|---:|---:|---:|---:|")
    totals = np.zeros(3, int)
    for motion in MOTIONS:
        takes = sorted(args.data.glob(f"hdm05/*/*{motion}*"))
        clips = [loaded(path) for path in takes]
        for path, take in zip(takes[1:], clips[1:]):
            every, count, distance = same_foot(clips[0], take, slice(None))
            alone, _, distance_alone = same_foot(clips[0], take, slice(0, 1))
            totals += (count, every, alone)
            print(f"| {motion} | {path.name} | {count} | {every} | {distance:.1f} | {alone} | {distance_alone:.1f} |")
    print(f"| all | | {totals[0]} | {totals[1]} | | {totals[2]} | |")

    print(f"\nPlain and multiscale DTW on physics features (median of {args.repeat} runs; load average "
          f"{os.getloadavg()[0]:.1f} at start)\n")
    print("| clips | frames | plain ms | multiscale ms | speed-up | plain cells | multiscale cells | cell ratio |"
          "\n|---|---|---:|---:|---:|---:|---:|---:|")
    for first, second in SPEED_PAIRS:
        a, b = loaded(args.data / first)[0], loaded(args.data / second)[0]
        plain, multiscale = dtw(a, b), multiscale_dtw(a, b, FPS)
        plain_s = timed(lambda: dtw(a, b), args.repeat)
        multiscale_s = timed(lambda: multiscale_dtw(a, b, FPS), args.repeat)
        print(f"| {Path(first).name}, {Path(second).name} | {len(a)} x {len(b)} | {1e3 * plain_s:.2f} | "
              f"{1e3 * multiscale_s:.3f} | {plain_s / multiscale_s:.1f} | {plain.cells:,} | {multiscale.cells:,} | "
              f"{plain.cells / multiscale.cells:.0f} |")
    print(f"\nload average {os.getloadavg()[0]:.1f} at the end")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
