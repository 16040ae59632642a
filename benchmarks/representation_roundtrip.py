"""Round trip of every representation over every shared clip: channels -> encode -> decode -> channels.

For each representation, prints the worst joint-position error (cm) and the worst
bone world-rotation error (rad) between forward kinematics of the original and
of the reconstructed channels, over all frames of all clips, and the clip where
each occurs. Lossless representations should show float round-off only.

    python benchmarks/representation_roundtrip.py [DATA_DIR] [--step N]

AMC files pair with the ASF in their folder; cmu-edited/<subject>/ clips with
cmu/<subject>/<subject>.asf (README of the data). Clips with no skeleton are
listed as skipped.
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np

from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.inputs.discover import find_clips
from mocapzip.motion.kinematics import forward
from mocapzip.representations import get_representation
from mocapzip.stages import stage_ids
from mocapzip.motion.rotations import rotation_angle
from mocapzip.motion.skeleton import SkeletonModel

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def skeleton_path(clip, data: Path) -> Path | None:
    if clip.skeleton is not None:
        return clip.skeleton
    parts = Path(clip.relpath).parts
    if parts[0] == "cmu-edited":
        candidate = data / "cmu" / parts[1] / f"{parts[1]}.asf"
        return candidate if candidate.is_file() else None
    return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", nargs="?", type=Path, default=DATA)
    parser.add_argument("--step", type=int, default=1, help="use every N-th frame (default: all)")
    args = parser.parse_args()

    worst = {name: {"pos": (0.0, "-"), "rot": (0.0, "-")} for name in stage_ids("representation")}
    seconds = dict.fromkeys(stage_ids("representation"), 0.0)
    models: dict[Path, SkeletonModel] = {}
    skipped, n_clips, n_frames = [], 0, 0
    for clip in find_clips([args.data], require_skeleton=False):
        asf = skeleton_path(clip, args.data)
        if asf is None:
            skipped.append(clip.relpath)
            continue
        if asf not in models:
            models[asf] = SkeletonModel.from_asf(read_asf(asf))
        model = models[asf]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a cut-short last frame is dropped by the reader
            motion = read_amc(clip.motion)
        motion.values = motion.values[:: args.step]
        n_clips += 1
        n_frames += motion.n_frames
        original = forward(model, motion.values, motion)
        for name in stage_ids("representation"):
            rep = get_representation(name)
            start = time.perf_counter()
            values = rep.inverse(model, rep.forward(model, motion), motion)
            seconds[name] += time.perf_counter() - start
            back = forward(model, values, motion)
            pos = float(np.linalg.norm(back.positions - original.positions, axis=-1).max())
            rot = float(rotation_angle(back.rotations, original.rotations).max())
            if pos > worst[name]["pos"][0]:
                worst[name]["pos"] = (pos, clip.relpath)
            if rot > worst[name]["rot"][0]:
                worst[name]["rot"] = (rot, clip.relpath)

    print(f"{n_clips} clips, {n_frames} frames (step {args.step}); skipped (no skeleton): {len(skipped)}")
    for path in skipped:
        print(f"  skipped {path}")
    print(f"{'representation':15s} {'worst pos (cm)':>15s} {'worst rot (rad)':>16s} {'encode+decode':>14s}  worst clips (pos / rot)")
    for name in stage_ids("representation"):
        (pos, pos_clip), (rot, rot_clip) = worst[name]["pos"], worst[name]["rot"]
        print(f"{name:15s} {pos:15.3e} {rot:16.3e} {seconds[name]:13.1f}s  {pos_clip} / {rot_clip}")


if __name__ == "__main__":
    main()
