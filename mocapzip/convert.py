"""`mcz convert`: ASF/AMC to BVH and back, with the same joint positions (docs/bvh.md, "Converting").

ASF/AMC -> BVH. Each ASF bone becomes a BVH joint at the bone's start (its parent's end) whose
rotation is the bone's: its OFFSET is the parent bone's vector, a leaf's End Site its own vector,
so every ASF joint position (the root and each bone's end) is a BVH joint or End Site. The root
has 6 channels (Xposition Yposition Zposition Zrotation Xrotation Yrotation), every other joint
3 (Zrotation Xrotation Yrotation): a bone's rotation in its parent's frame, whatever its dofs.
Lengths in cm, angles in degrees; the rest pose (all channels 0) is the ASF's base pose; the
frame rate is the clip's (`inputs.clip.clip_frame_rate`).

BVH -> ASF/AMC. The codec's model of the hierarchy (`motion.bvh_skeleton`) is an Acclaim
skeleton already: its bones (links named "P>child") become ASF bones in cm with identity
axes, the BVH rotation channels their dofs, in reverse order (the BVH file's turn order). The
clip must be what lossy coding takes: an extra root above the hips that stands still at 0, and
no position channels moving but the root's.

Both ways, values are written with 6 significant digits: joint positions agree within
TOLERANCE_CM (tests/test_convert.py measures every shared clip it converts).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from mocapzip.defaults import DEFAULT_FPS
from mocapzip.formats.amc import Motion, write_amc
from mocapzip.formats.asf import Bone, Skeleton, write_asf
from mocapzip.formats.bvh import Bvh, BvhJoint, BvhStyle, read_bvh, write_bvh
from mocapzip.formats.errors import MocapFormatError
from mocapzip.inputs.clip import ClipReader, clip_frame_rate
from mocapzip.inputs.discover import find_clips, is_bvh
from mocapzip.motion.bvh_skeleton import bvh_skeleton
from mocapzip.motion.kinematics import forward
from mocapzip.motion.rotations import euler_angles
from mocapzip.motion.skeleton import SkeletonModel

TOLERANCE_CM = 0.01  # joint positions after a conversion, against the source's (6 significant digits)


def amc_to_bvh(skeleton: Skeleton, motion: Motion, fps: float) -> Bvh:
    """The BVH clip with `motion`'s joint positions on `skeleton`, at `fps` frames per second."""
    model = SkeletonModel.from_asf(skeleton)
    pose = forward(model, motion.values, motion)
    children = {j: [k for k in range(model.n_joints) if model.parents[k] == j] for j in range(model.n_joints)}
    joints, columns = [], []
    for j, name in enumerate(model.names):
        parent = int(model.parents[j])
        offset = np.zeros(3) if parent <= 0 else model.offsets[parent]
        rotation = pose.rotations[:, j]
        if parent >= 0:  # the bone's rotation in its parent's frame (row vectors: R_j = L_j R_p)
            rotation = rotation @ np.swapaxes(pose.rotations[:, parent], -1, -2)
        # BVH `Zrotation Xrotation Yrotation` is Rz Rx Ry on columns, Ry Rx Rz on rows
        angles = np.degrees(euler_angles(rotation, "yxz"))[:, ::-1]
        channels = ("Zrotation", "Xrotation", "Yrotation")
        if parent < 0:
            channels = ("Xposition", "Yposition", "Zposition", *channels)
            columns.append(pose.positions[:, 0])
        columns.append(angles)
        end_site = None if children[j] else model.offsets[j]
        joints.append(BvhJoint(name, parent, offset, channels, end_site))
    values = np.concatenate(columns, axis=1)
    return Bvh(joints, 1.0 / fps, values, style=BvhStyle("g6", " ", "", "\n"), path=motion.path)


def bvh_to_amc(bvh: Bvh, units: str | None = None) -> tuple[Skeleton, Motion]:
    """The ASF skeleton and AMC clip with `bvh`'s joint positions (lengths in cm)."""
    model_of = bvh_skeleton(bvh.joints, units, bvh.path)
    motion = model_of.motion(bvh, lossless=False)  # MocapFormatError where a fixed channel moves
    if model_of.above_values(bvh) is not None:
        raise MocapFormatError(f"its extra root '{bvh.joints[0].name}' moves: an ASF skeleton has one root", bvh.path)
    model = model_of.model
    bones = []
    for j in range(1, model.n_joints):
        length = float(np.linalg.norm(model.offsets[j]))
        direction = model.offsets[j] / length if length else np.zeros(3)
        bones.append(Bone(model.names[j], j, direction, length, np.zeros(3), "XYZ", model.channels[j]))
    hierarchy = [(model.names[p], [model.names[k] for k in range(model.n_joints) if model.parents[k] == p])
                 for p in range(model.n_joints) if any(model.parents == p)]
    stem = Path(bvh.path).stem if bvh.path else "bvh"
    skeleton = Skeleton(name=stem, version="1.10", units={"mass": "1.0", "length": "cm", "angle": "deg"},
                        documentation=[f"fps:{bvh.fps:g}", "converted from BVH by mcz convert"],
                        root_order=tuple(c.upper() for c in model.channels[0]), bones=bones,
                        hierarchy=[(p if p != model.names[0] else "root", kids) for p, kids in hierarchy])
    names = ["root" if b == model.names[0] else b for b in motion.bones]
    frames = np.arange(1, motion.n_frames + 1)
    return skeleton, Motion(names, list(motion.counts), np.asarray(motion.values), frames,
                            [":FULLY-SPECIFIED", ":DEGREES"], bvh.path)


def convert(inputs, output, asf=None, units: str | None = None, force: bool = False) -> dict:
    """Write every clip under `inputs` in the other format under the folder `output`, at its
    relative path: an AMC as a .bvh file, a BVH file as .amc beside an .asf of the same stem.
    Existing files are replaced only with `force`; return {"clips", "written": [paths]}."""
    sources = find_clips(inputs, asf=asf)
    if not sources:
        raise MocapFormatError("no clips found (.amc, .bvh)", ", ".join(map(os.fspath, inputs)))
    reader, out, written = ClipReader(None, units=units), Path(output), []
    plans = []
    for source in sources:
        stem = Path(source.relpath).with_suffix("")
        targets = [stem.with_suffix(".amc"), stem.with_suffix(".asf")] if is_bvh(source.amc.name) else \
            [stem.with_suffix(".bvh")]
        plans.append((source, targets))
    clashing = [out / t for _, targets in plans for t in targets if (out / t).exists() and not force]
    if clashing:
        raise FileExistsError(None, "already exists", os.fspath(clashing[0]))
    for source, targets in plans:
        if is_bvh(source.amc.name):
            skeleton, motion = bvh_to_amc(read_bvh(source.amc), units)
            (out / targets[0]).parent.mkdir(parents=True, exist_ok=True)
            write_amc(motion, out / targets[0])
            write_asf(skeleton, out / targets[1])
        else:
            read = reader.motion(source)
            fps = clip_frame_rate(read.stated_fps, DEFAULT_FPS)
            (out / targets[0]).parent.mkdir(parents=True, exist_ok=True)
            write_bvh(amc_to_bvh(read.skeleton, read.motion, fps), out / targets[0])
        written += [t.as_posix() for t in targets]
    return {"clips": len(sources), "written": written}
