"""`mcz inspect`: parse every clip under the inputs and summarise it (frames, dof, duration);
with `--check`, also list the glitches in it (`inputs.glitches`)."""

from __future__ import annotations

import os

from mocapzip.defaults import DEFAULT_FPS
from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.formats.errors import MocapFormatError
from mocapzip.inputs.clip import clip_frame_rate
from mocapzip.inputs.discover import find_clips
from mocapzip.inputs.glitches import find_glitches
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.progress import progress



def inspect_paths(paths, asf=None, fps: float | None = None, check: bool = False) -> dict:
    """A JSON-ready report: one row per clip and the totals; with `check`, each clip's glitches
    (`inputs.glitches`: needs its skeleton). Each clip's frame rate is `fps` if given, else the one
    its files state, else 120 (`inputs.clip.clip_frame_rate`). Raises MocapFormatError on bad input."""
    clips = find_clips(paths, asf=asf, require_skeleton=False)
    if not clips:
        raise MocapFormatError("no AMC clips found", ", ".join(map(os.fspath, paths)))
    skeletons, models = {}, {}
    rows = []
    for clip in progress(clips, desc="inspect", unit="clip"):
        skeleton = None
        if clip.asf is not None:
            if clip.asf not in skeletons:
                skeletons[clip.asf] = read_asf(clip.asf)
            skeleton = skeletons[clip.asf]
        motion = read_amc(clip.amc, skeleton)
        rate = clip_frame_rate(motion, skeleton, fps or DEFAULT_FPS, from_files=fps is None)
        rows.append({
            "path": clip.relpath,
            "frames": motion.n_frames,
            "dof": int(motion.values.shape[1]),
            "fps": rate,
            "seconds": motion.n_frames / rate,
            "skeleton": None if clip.asf is None else os.fspath(clip.asf),
            "bytes": os.path.getsize(clip.amc),
        })
        if check and skeleton is not None:
            if clip.asf not in models:
                models[clip.asf] = SkeletonModel.from_asf(skeleton)
            model = models[clip.asf]
            positions = forward(model, motion.values, motion).positions
            rows[-1]["glitches"] = [g.as_dict() for g in find_glitches(skeleton, model, motion, positions, rate)]
    total = {
        "clips": len(rows),
        "frames": sum(r["frames"] for r in rows),
        "seconds": sum(r["seconds"] for r in rows),
        "skeletons": len(skeletons),
        "bytes": sum(r["bytes"] for r in rows),
    }
    return {"fps": fps, "clips": rows, "total": total}  # fps None: each clip's own
