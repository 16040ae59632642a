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

Joint positions agree within TOLERANCE_CM: a BVH is written with 6 decimals (`%.6f`: an angle
unwrapped far past 360 keeps its precision), an AMC as the reader's values, 6 significant digits.
Every clip is read and converted before any file is written, and each file is written whole
(`formats.text.write_file_atomically`); no input is ever written over.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from mocapzip.defaults import DEFAULT_FPS
from mocapzip.formats.amc import Motion, format_amc
from mocapzip.formats.asf import Bone, Skeleton, format_asf
from mocapzip.formats.bvh import Bvh, BvhJoint, BvhStyle, format_bvh, read_bvh
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.text import write_file_atomically
from mocapzip.inputs.clip import ClipReader, clip_frame_rate
from mocapzip.inputs.discover import find_clips, is_bvh, no_clips, record_skip
from mocapzip.motion.bvh_skeleton import bvh_skeleton
from mocapzip.motion.kinematics import forward
from mocapzip.motion.rotations import euler_angles
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.progress import progress

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
    return Bvh(joints, 1.0 / fps, values, style=BvhStyle("f6", " ", "", "\n"), path=motion.path)


def bvh_to_amc(bvh: Bvh, units: str | None = None) -> tuple[Skeleton, Motion]:
    """The ASF skeleton and AMC clip with `bvh`'s joint positions (lengths in cm)."""
    if not bvh.n_frames:
        raise MocapFormatError("no frames to convert", bvh.path)
    hierarchy = bvh_skeleton(bvh.joints, units, bvh.path)
    hierarchy.check_fixed(bvh, why="an ASF skeleton's bones keep their length")
    if hierarchy.above_values(bvh) is not None:
        raise MocapFormatError(f"its extra root '{bvh.joints[0].name}' moves: an ASF skeleton has one root", bvh.path)
    model, motion = hierarchy.model, hierarchy.motion(bvh, lossless=False)
    if "root" in model.names[1:]:
        raise MocapFormatError("a joint named 'root' that is not the root: ASF keeps that name for its root", bvh.path)
    values = np.array(motion.values)
    values[:, [k for k, c in enumerate(model.channels[0]) if c[0] == "t"]] *= model.cm_per_unit  # the ASF is in cm
    bones = []
    for j in range(1, model.n_joints):
        length = float(np.linalg.norm(model.offsets[j]))
        direction = model.offsets[j] / length if length else np.zeros(3)
        bones.append(Bone(model.names[j], j, direction, length, np.zeros(3), "XYZ", model.channels[j]))
    hierarchy = [(model.names[p], [model.names[k] for k in range(model.n_joints) if model.parents[k] == p])
                 for p in range(model.n_joints) if any(model.parents == p)]
    stem = Path(bvh.path).stem if bvh.path else "bvh"
    skeleton = Skeleton(name=stem, version="1.10", units={"mass": "1.0", "length": "cm", "angle": "deg"},
                        documentation=[f"fps:{bvh.fps!r}", "converted from BVH by mcz convert"],
                        root_order=tuple(c.upper() for c in model.channels[0]), bones=bones,
                        hierarchy=[(p if p != model.names[0] else "root", kids) for p, kids in hierarchy])
    names = ["root" if b == model.names[0] else b for b in motion.bones]
    frames = np.arange(1, motion.n_frames + 1)
    return skeleton, Motion(names, list(motion.counts), values, frames, [":FULLY-SPECIFIED", ":DEGREES"], bvh.path)


def convert(inputs, output, asf=None, units: str | None = None, force: bool = False, skip_bad: bool = False) -> dict:
    """Write every clip under `inputs` in the other format under the folder `output`, at its
    relative path: an AMC as a .bvh file, a BVH file as .amc beside an .asf of the same name.

    Every clip is converted before a file is written: one that cannot be stops the run with
    nothing written (with `skip_bad`, it is left out and listed). Existing files are replaced only
    with `force`, and an input never. Returns {"clips", "written": [paths], "skipped": [...]}."""
    sources = find_clips(inputs, asf=asf)
    if not sources:
        raise no_clips(inputs)
    out, reader, skipped = Path(output), ClipReader(None, units=units), []
    plans = {}  # target path -> source
    for source in sources:
        for target in _targets(source):
            if target in plans:
                raise MocapFormatError(f"two clips would be written to {target} (also {plans[target].amc})", source.amc)
            plans[target] = source
    inputs_read = {os.path.realpath(p) for s in sources for p in (s.amc, s.asf) if p is not None}
    for target in plans:
        path = out / target
        if os.path.realpath(path) in inputs_read:
            raise MocapFormatError("is an input: convert never writes over one (choose another -o)", path)
        if os.path.lexists(path) and not force:
            raise FileExistsError(None, "already exists", os.fspath(path))
    converted = []
    for source in progress(sources, desc="convert", unit="clip"):
        try:
            converted.append((source, _converted(source, reader, units)))
        except (MocapFormatError, OSError) as exc:
            if not skip_bad:
                raise
            record_skip(skipped, source, exc)
    written = []
    for source, files in converted:
        for target, data in zip(_targets(source), files):
            write_file_atomically(out / target, data)
            written.append(target)
    return {"clips": len(converted), "written": written, "skipped": skipped}


def _targets(source) -> list[str]:
    """The files a clip becomes, relative to the output folder: x.amc -> x.bvh; x.bvh -> x.amc, x.asf."""
    stem = source.relpath[: -len(".amc")]  # .amc and .bvh alike; "take.1.amc" stays "take.1"
    return [stem + ".amc", stem + ".asf"] if is_bvh(source.amc.name) else [stem + ".bvh"]


def _converted(source, reader: ClipReader, units: str | None) -> list[bytes]:
    """The bytes of the files a clip becomes (`_targets`)."""
    if is_bvh(source.amc.name):
        skeleton, motion = bvh_to_amc(read_bvh(source.amc), units)
        return [format_amc(motion).encode(motion.style.encoding), format_asf(skeleton).encode("utf-8")]
    read = reader.motion(source)
    bvh = amc_to_bvh(read.skeleton, read.motion, clip_frame_rate(read.stated_fps, DEFAULT_FPS))
    return [format_bvh(bvh).encode(bvh.encoding)]
