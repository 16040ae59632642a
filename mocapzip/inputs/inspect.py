"""`mcz inspect`: parse every clip under the inputs and summarise it (frames, dof, duration);
with `--check`, also list the glitches in it (`inputs.glitches`)."""

from __future__ import annotations

import os

from mocapzip.defaults import DEFAULT_FPS
from mocapzip.inputs.clip import ClipReader, clip_frame_rate
from mocapzip.inputs.discover import find_clips, no_clips
from mocapzip.inputs.glitches import find_glitches
from mocapzip.motion.kinematics import forward
from mocapzip.progress import progress


def inspect_paths(paths, asf=None, fps: float | None = None, check: bool = False, units: str | None = None) -> dict:
    """A JSON-ready report: one row per clip and the totals; with `check`, each clip's glitches
    (`inputs.glitches`: needs its skeleton). Each clip's frame rate is `fps` if given, else the one
    its files state, else 120 (`inputs.clip.clip_frame_rate`). `units`: of BVH lengths, where
    they cannot be inferred (`ClipReader`). Raises MocapFormatError on bad input."""
    clips = find_clips(paths, asf=asf, require_skeleton=False)
    if not clips:
        raise no_clips(paths)
    reader = ClipReader(None, units=units)
    rows = []
    for clip in progress(clips, desc="inspect", unit="clip"):
        if clip.skeleton is None:  # an AMC without a skeleton: its frames, not its joints
            read = clip.format.read(clip, None, False)
        else:
            # an AMC's cut last frame dropped (with a warning); a BVH clip's channels all, or with --check
            # the joints, as lossy coding sees them
            read = reader.motion(clip, lossless=clip.format.inspects_lossless and not check)
        motion = read.motion
        rate = clip_frame_rate(read.stated_fps, fps or DEFAULT_FPS, from_files=fps is None)
        rows.append({
            "path": clip.relpath,
            "frames": motion.n_frames,
            "dof": int(read.channels_in_file),
            "fps": rate,
            "seconds": motion.n_frames / rate,
            "skeleton": None if clip.skeleton is None else os.fspath(clip.skeleton),
            "bytes": os.path.getsize(clip.motion),
        })
        if check and clip.skeleton is not None:
            positions = forward(read.model, motion.values, motion).positions
            rows[-1]["glitches"] = [g.as_dict() for g in find_glitches(read.limits, read.model, motion, positions, rate)]
    total = {
        "clips": len(rows),
        "frames": sum(r["frames"] for r in rows),
        "seconds": sum(r["seconds"] for r in rows),
        "skeletons": len({id(reader.skeleton(c)) for c in clips if c.skeleton is not None}),  # BVH: hierarchies
        "bytes": sum(r["bytes"] for r in rows),
    }
    return {"fps": fps, "clips": rows, "total": total}  # fps None: each clip's own
