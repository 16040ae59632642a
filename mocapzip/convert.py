"""`mcz convert`: ASF/AMC to BVH and back, with the same joint positions (docs/bvh.md, "Converting").

ASF/AMC -> BVH. Each ASF bone becomes a BVH joint at the bone's start (its parent's end) whose
rotation is the bone's: its OFFSET is the parent bone's vector, a leaf's End Site its own vector,
so every ASF joint position (the root and each bone's end) is a BVH joint or End Site. The root
has 6 channels (Xposition Yposition Zposition Zrotation Xrotation Yrotation), every other joint
3 (Zrotation Xrotation Yrotation): a bone's rotation in its parent's frame, whatever its dofs.
Lengths in cm, angles in degrees; the rest pose (all channels 0) is the ASF's base pose; the
frame rate is the clip's (`inputs.clip.clip_frame_rate`).

BVH -> ASF/AMC. The codec's model of the hierarchy (`motion.bvh_skeleton`) is an Acclaim
skeleton already: its bones (links named "P>child") become ASF bones, lengths in cm
(`:units length 2.54`: file units per inch, as CMU's 0.45 is). Dofs are in the order CMU's files
and most readers take them, the root's `TX TY TZ RX RY RZ` and a bone's `rx ry rz` (x turns
first), while a BVH joint's rotation channels turn in their own order (Bandai's and CMU's
`Zrotation Xrotation Yrotation`: y, then x, then z). A bone whose channels turn in another order
keeps the BVH's angles, in the order of its axes, and gets an `axis` (multiples of 90 degrees)
that makes them turn as the BVH's (`_bone_in_acclaim_order`); the root, whose frame readers take
to be the identity, gets the same turn's `rx ry rz` angles (`_root_in_acclaim_order`). The clip
must be what lossy coding takes: an extra root above the hips that stands still at 0, and no
position channels moving but the root's.

Names (docs/bvh.md, "Names"): a name is written as it is where both formats hold it and it holds no
%XX; else it is escaped (`_escaped`), so that no two names are written alike. ASF -> BVH escapes
(`_bvh_name`) what BVH -> ASF decodes (`_asf_name`): the source ASF's names come back as they
were. BVH -> ASF: an ASF keeps the BVH name of each bone that would not come back by itself in a
`bvh-name` line of its documentation, which a conversion back to BVH restores.

Every file is read back, as written, by mcz's own readers before anything is written: one they
would refuse (a hierarchy past a limit of `mocapzip.limits`) or read as anything else, or with a
joint more than READ_BACK_CM from where the source clip has it, stops the clip's conversion
(`_bvh_read_back`, `_asf_amc_read_back`).

Joint positions agree within TOLERANCE_CM: a BVH is written with 6 decimals (`%.6f`: an angle
unwrapped far past 360 keeps its precision), an AMC with 6 significant digits, each with more
(`BVH_NUMBERS`, `AMC_DIGITS`) where these would move a joint by more than READ_BACK_CM (a root's
angles unwrapped to -1,470 degrees, an AMC angle of 12,345.678 degrees, a root 1,234,567.891 cm
from the origin). Every clip is read and converted before any file is written, each file is
written whole (`formats.text.write_file_atomically`), into folders that are folders
(`formats.text.check_folders`) and inside the output folder (`formats.text.check_inside`: not through
a symbolic link there); no input is ever written over.
"""

from __future__ import annotations

import json
import os
import re
import unicodedata
from dataclasses import replace
from pathlib import Path

import numpy as np

from mocapzip.defaults import DEFAULT_FPS
from mocapzip.formats.amc import MAX_AMC_BYTES, AmcStyle, Motion, format_amc, parse_amc
from mocapzip.formats.asf import ROOT, Bone, Skeleton, format_asf, parse_asf
from mocapzip.formats.bvh import Bvh, BvhJoint, BvhStyle, format_bvh, parse_bvh, read_bvh
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.text import NUMBER, check_folders, check_inside, check_not_folders, write_file_atomically
from mocapzip.inputs.clip import ClipReader, clip_frame_rate
from mocapzip.inputs.discover import find_clips, no_clips, record_skip
from mocapzip.inputs.registry import AMC, BVH
from mocapzip.motion.bvh_skeleton import BvhSkeleton, bvh_skeleton, file_positions, point_names
from mocapzip.motion.kinematics import forward
from mocapzip.motion.rotations import euler_angles, euler_matrix
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.progress import progress

TOLERANCE_CM = 0.01  # joint positions after a conversion, against the source's
READ_BACK_CM = TOLERANCE_CM / 2  # how far a joint may move as the files written are read back: half of it
# significant digits of an AMC's values: CMU's; 7 (a Bandai dance: its root's angles, turned into `rx ry rz` and
# unwrapped to -1,470 degrees, moved a joint by 0.0067 cm with 6); else every float64 read back as itself
AMC_DIGITS = (6, 7, 17)
BVH_NUMBERS = ("f6", "repr")  # a BVH's values: 6 decimals (an angle is within 180), else Python's repr
ACCLAIM_ORDER = ("tx", "ty", "tz", "rx", "ry", "rz")  # an ASF's dofs as CMU's files have them
# An ASF's units: `length` is file units per inch (CMU's 0.45), cm = value x 2.54 / length: at 2.54, values are cm
ACCLAIM_UNITS = {"mass": "1.0", "length": "2.54", "angle": "deg"}
NAME_RECORD = "bvh-name"  # an ASF documentation line `bvh-name <bone> <the BVH joint's name, as a JSON string>`
# Whole names a format cannot hold: BVH's keywords, as BVH writes them; in any case, an ASF's root and
# the words that open and close its blocks (a link bone to an End Site is "P>end")
_BVH_KEYWORDS = frozenset({"HIERARCHY", "ROOT", "JOINT", "End", "Site", "OFFSET", "CHANNELS", "MOTION"})
_ASF_WORDS = frozenset({"ROOT", "BEGIN", "END"})
_ESCAPE = re.compile(rb"%([0-9A-F]{2})")


def amc_to_bvh(skeleton: Skeleton, motion: Motion, fps: float) -> Bvh:
    """The BVH clip with `motion`'s joint positions on `skeleton`, at `fps` frames per second."""
    model = SkeletonModel.from_asf(skeleton)
    pose = forward(model, motion.values, motion)
    children = {j: [k for k in range(model.n_joints) if model.parents[k] == j] for j in range(model.n_joints)}
    joints, columns = [], []
    for j, name in enumerate(_bvh_names(model.names, _recorded_names(skeleton))):
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
    """The ASF skeleton and AMC clip with `bvh`'s joint positions (lengths in cm, `ACCLAIM_UNITS`),
    the dofs in the order CMU's files have them (`_root_in_acclaim_order`, `_bone_in_acclaim_order`)."""
    if not bvh.n_frames:
        raise MocapFormatError("no frames to convert", bvh.path)
    written, hierarchy = _asf_hierarchy(bvh, units)
    hierarchy.check_fixed(bvh, why="an ASF skeleton's bones keep their length")
    if hierarchy.above_values(bvh) is not None:
        raise MocapFormatError(f"its extra root '{bvh.joints[0].name}' moves: an ASF skeleton has one root", bvh.path)
    model, motion = hierarchy.model, hierarchy.motion(bvh, lossless=False)
    bvh_names = {name: joint.name for joint, name in zip(bvh.joints, written)}
    records = [f"{NAME_RECORD} {asf_name} {json.dumps(bvh_names[name], ensure_ascii=False)}"
               for name, asf_name in zip(model.names, [ROOT, *model.names[1:]])
               if name in bvh_names and bvh_names[name] != _bvh_name(asf_name)]  # link bones stand for no joint
    dofs, bone_axis, columns = {}, {}, []
    for name, values in zip(motion.bones, np.split(motion.values, np.cumsum(motion.counts)[:-1], axis=1)):
        channels = model.channels[model.index[name]]
        if name == model.names[0]:
            dofs[name], acclaim = _root_in_acclaim_order(channels, values)
        else:
            dofs[name], bone_axis[name], acclaim = _bone_in_acclaim_order(channels, values)
        columns.append(acclaim * np.array([model.cm_per_unit if c[0] == "t" else 1.0 for c in dofs[name]]))  # cm
    bones = []
    for j, name in enumerate(model.names[1:], start=1):
        length = float(np.linalg.norm(model.offsets[j]))
        direction = model.offsets[j] / length if length else np.zeros(3)
        bones.append(Bone(name, j, direction, length, bone_axis.get(name, np.zeros(3)), "XYZ", dofs.get(name, ())))
    hierarchy = [(model.names[p], [model.names[k] for k in range(model.n_joints) if model.parents[k] == p])
                 for p in range(model.n_joints) if any(model.parents == p)]
    skeleton = Skeleton(name=_skeleton_name(bvh.path), version="1.10", units=dict(ACCLAIM_UNITS),
                        documentation=[f"fps:{bvh.fps!r}", "converted from BVH by mcz convert", *records],
                        root_order=tuple(c.upper() for c in dofs[model.names[0]]), bones=bones,
                        hierarchy=[(p if p != model.names[0] else ROOT, kids) for p, kids in hierarchy])
    names = [ROOT if b == model.names[0] else b for b in motion.bones]
    frames = np.arange(1, motion.n_frames + 1)
    return skeleton, Motion(names, [len(dofs[b]) for b in motion.bones], np.concatenate(columns, axis=1), frames,
                            [":FULLY-SPECIFIED", ":DEGREES"], bvh.path)


def _asf_hierarchy(bvh: Bvh, units: str | None) -> tuple[list[str], BvhSkeleton]:
    """The ASF name of each of `bvh`'s joints (`_asf_names`), and the model of its hierarchy under
    those names (`motion.bvh_skeleton`), which its ASF is."""
    written = _asf_names(bvh.joints)
    try:
        return written, bvh_skeleton([replace(joint, name=name) for joint, name in zip(bvh.joints, written)], units,
                                     bvh.path)
    except MocapFormatError:
        bvh_skeleton(bvh.joints, units, bvh.path)  # the same refusal, naming the file's joints, not their ASF names
        raise


def _root_in_acclaim_order(channels: tuple[str, ...], values: np.ndarray) -> tuple[tuple[str, ...], np.ndarray]:
    """The root's model `channels` ('tx', 'ry', ...; rotations in turning order) and their `values`
    (frames, channels; degrees) as an ASF's root `order` and its AMC values: `TX TY TZ`, then
    `RX RY RZ`. Rotations already turning x, y, z (or some of them) keep their angles; others (BVH's
    `Zrotation Xrotation Yrotation` turns y, x, z) are the same turn as `rx ry rz` angles, frame by
    frame, each frame's nearest the previous frame's (`motion.rotations.euler_angles`). The root's
    frame stays the identity (`orientation 0 0 0`), which readers of CMU's files take it to be."""
    translations = [k for c in ACCLAIM_ORDER[:3] for k, held in enumerate(channels) if held == c]
    turns = [k for k, c in enumerate(channels) if c[0] == "r"]
    axes = "".join(channels[k][1] for k in turns)
    if axes == "".join(sorted(axes)):
        return tuple(channels[k] for k in translations + turns), values[:, translations + turns]
    angles = np.degrees(euler_angles(euler_matrix(np.radians(values[:, turns]), axes), "xyz"))
    return tuple(channels[k] for k in translations) + ACCLAIM_ORDER[3:], np.hstack([values[:, translations], angles])


def _bone_in_acclaim_order(channels: tuple[str, ...], values: np.ndarray) -> tuple[tuple[str, ...], np.ndarray,
                                                                                   np.ndarray]:
    """A bone's model `channels` (rotations in turning order: BVH's `Zrotation Xrotation Yrotation`
    is 'ry', 'rx', 'rz') and their `values` (frames, channels; degrees) as the bone's ASF dofs, in
    the order x, y, z, its `axis` (degrees, XYZ order) and its AMC values.

    The bone's axis frame C turns the BVH's axes into the dofs': an Acclaim bone turns by
    C^-1 M C, M its dofs' turn, and C^-1 R_t(s a) C = R_u(a) where row t of C is s e_u (the unit
    vector of axis u, s = +-1). So the i-th channel in turning order, about axis u by angle a, is
    the i-th dof in x, y, z order, about the axis t of C's row s e_u, by s a; the one row left (2
    dofs) takes the axis left, and a sign makes C a rotation. Every angle is the BVH's, or its
    negative: exact, with no gimbal lock the BVH has not (Bandai's shoulders, turned about y by
    about 90 degrees, would be at the gimbal lock of `rx ry rz` about the parent's axes)."""
    axes = "".join(c[1] for c in channels)
    dofs = "".join(sorted(axes))
    if axes == dofs:
        return channels, np.zeros(3), values
    c = np.zeros((3, 3))
    rows = dofs + "".join(t for t in "xyz" if t not in dofs)
    for t, u in zip(rows, axes + "".join(u for u in "xyz" if u not in axes)):
        c["xyz".index(t), "xyz".index(u)] = 1.0
    signs = np.ones(len(axes))
    if np.linalg.det(c) < 0:  # a reflection: made a rotation by turning the last row (the axis left, or z)
        c["xyz".index(rows[-1])] *= -1.0
        if len(axes) == 3:  # z is a dof: its angles turn too
            signs[-1] = -1.0
    axis = np.round(np.degrees(euler_angles(c[None], "xyz")[0])) + 0.0  # multiples of 90 degrees; no -0
    return tuple("r" + t for t in dofs), axis, values * signs


def _skeleton_name(path: str | None) -> str:
    """The `:name` of an ASF made of the BVH file at `path`: its stem on one line (the name ends at
    the line's end), a byte of it that is no UTF-8 as U+FFFD (the ASF is UTF-8)."""
    if path is None:
        return "bvh"
    stem = Path(path).stem.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
    return " ".join(stem.split())


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
                raise MocapFormatError(f"two clips would be written to {target} (also {plans[target].motion})",
                                       source.motion)
            plans[target] = source
    check_inside(out, (out / target for target in plans))
    check_folders((out / target).parent for target in plans)
    check_not_folders(out / target for target in plans)
    inputs_read = {os.path.realpath(p) for s in sources for p in (s.motion, s.skeleton) if p is not None}
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


_BECOMES = {AMC: [".bvh"], BVH: [".amc", ".asf"]}  # the suffixes of the files a clip of each format becomes
# what the API's `Clip.save` converts a clip to: (its format, the other) -> (clip, its skeleton's entry in meta,
# the names of the files) -> their bytes, as `mcz convert` makes them
SAVE_CONVERSIONS = {
    (AMC, BVH): lambda clip, entry, targets: amc_as_bvh(clip.skeleton, clip.motion, clip.fps, targets[0], clip.path),
    (BVH, AMC): lambda clip, entry, targets: bvh_as_asf_amc(clip.bvh, entry["units"], targets, clip.path),
}


def _targets(source) -> list[str]:
    """The files a clip becomes, relative to the output folder: x.amc -> x.bvh; x.bvh -> x.amc, x.asf."""
    if source.format not in _BECOMES:
        raise MocapFormatError(f"mcz convert turns AMC clips into BVH and BVH into ASF/AMC, not "
                               f"{source.format.name.upper()} clips", source.motion)
    stem = source.relpath[: -len(".amc")]  # .amc and .bvh alike; "take.1.amc" stays "take.1"
    return [stem + suffix for suffix in _BECOMES[source.format]]


def _converted(source, reader: ClipReader, units: str | None) -> list[bytes]:
    """The bytes of the files a clip becomes (`_targets`), each checked to read back as written and
    with the source clip's joint positions."""
    targets = _targets(source)
    if source.format is BVH:
        return bvh_as_asf_amc(read_bvh(source.motion), units, targets, source.motion)
    read = reader.motion(source)
    return amc_as_bvh(read.skeleton, read.motion, clip_frame_rate(read.stated_fps, DEFAULT_FPS), targets[0],
                      source.motion)


def bvh_as_asf_amc(bvh: Bvh, units: str | None, targets: list[str], source) -> list[bytes]:
    """The bytes of the AMC and ASF files (`targets`: their names) `bvh` becomes, checked to read back
    with its joint positions; MocapFormatError naming `source` if they cannot."""
    skeleton, motion = bvh_to_amc(bvh, units)
    name_bytes = motion.n_frames * sum(len(name.encode("utf-8")) + 1 for name in motion.bones)
    if name_bytes > MAX_AMC_BYTES:  # refused before the text is made: names are repeated in every frame
        raise MocapFormatError(f"cannot be converted: its joint names alone would take {name_bytes:,} bytes of "
                               f"its AMC file, which may have {MAX_AMC_BYTES:,}", source)
    asf = format_asf(skeleton).encode("utf-8")
    positions = _asf_joints_in_bvh(bvh, units)
    for digits in AMC_DIGITS:
        written = replace(motion, style=AmcStyle(digits=digits))
        files = [format_amc(written).encode("utf-8"), asf]
        moved = _asf_amc_read_back(files, targets, skeleton, written, positions, source)
        if moved <= READ_BACK_CM:
            return files
    raise _moved(moved, source)


def amc_as_bvh(skeleton: Skeleton, motion: Motion, fps: float, target: str, source) -> list[bytes]:
    """The bytes of the BVH file (named `target`) an AMC clip becomes, checked to read back with its
    joint positions; MocapFormatError naming `source` if it cannot."""
    bvh = amc_to_bvh(skeleton, motion, fps)
    positions = _asf_positions(skeleton, motion)
    for number in BVH_NUMBERS:
        written = replace(bvh, style=replace(bvh.style, number=number))
        files = [format_bvh(written).encode(written.encoding)]
        moved = _bvh_read_back(files[0], target, written, positions, source)
        if moved <= READ_BACK_CM:
            return files
    raise _moved(moved, source)


def _asf_positions(skeleton: Skeleton, motion: Motion) -> np.ndarray:
    """(frames, joints, 3) cm: the joints of `motion` on `skeleton`, in its model's order (the root first)."""
    return forward(SkeletonModel.from_asf(skeleton), motion.values, motion).positions


def _asf_joints_in_bvh(bvh: Bvh, units: str | None) -> np.ndarray:
    """(frames, joints, 3) cm: the points of `bvh` that are the joints of its ASF (`bvh_to_amc`), in
    the ASF model's order, where the BVH's channels put them."""
    _, hierarchy = _asf_hierarchy(bvh, units)
    at = {name: k for k, name in enumerate(point_names(hierarchy.joints))}
    return file_positions(bvh, hierarchy.units)[:, [at[point] for point in hierarchy.model.points]]


def _bvh_points_of_asf(joints: list[BvhJoint]) -> list[int]:
    """Where each ASF joint is among the points (`point_names`) of the BVH `amc_to_bvh` made of it,
    whose joint k is the ASF's joint k: the root at the root, a bone's end at its first child or at
    its End Site."""
    starts = np.cumsum([0] + [1 + (joint.end_site is not None) for joint in joints])
    first_child = {}
    for k in reversed(range(len(joints))):
        first_child[joints[k].parent] = k
    return [0 if j == 0 else int(starts[first_child[j]]) if j in first_child else int(starts[j]) + 1
            for j in range(len(joints))]


def _moved(moved: float, source) -> MocapFormatError:
    return MocapFormatError(f"cannot be converted: mcz would read a joint back {moved:.3g} cm from where the clip "
                            f"has it (more than {READ_BACK_CM:g} cm)", source)


def _asf_amc_read_back(files: list[bytes], targets: list[str], skeleton: Skeleton, motion: Motion,
                       positions: np.ndarray, source) -> float:
    """How far (cm) a joint moves from `positions` (the source clip's, `_asf_joints_in_bvh`) as mcz
    reads `files` (AMC, ASF) back; MocapFormatError naming `source` unless it reads them as the
    skeleton's bones and hierarchy and the clip's bones, values per bone and frames."""
    amc, asf = files
    try:
        skeleton_read = parse_asf(asf, targets[1])
        motion_read = parse_amc(amc, targets[0], skeleton_read, partial_last_frame="error")
    except MocapFormatError as exc:
        raise MocapFormatError(f"cannot be converted: mcz would refuse the files it becomes ({exc})", source) from exc
    if ([(b.name, b.dof) for b in skeleton_read.bones] != [(b.name, b.dof) for b in skeleton.bones]
            or skeleton_read.parents() != skeleton.parents()):
        raise MocapFormatError(f"cannot be converted: {targets[1]} would not read back as its bones", source)
    if (motion_read.bones, motion_read.counts, motion_read.n_frames) != (motion.bones, motion.counts, motion.n_frames):
        raise MocapFormatError(f"cannot be converted: {targets[0]} would not read back as its frames", source)
    return _farthest(_asf_positions(skeleton_read, motion_read), positions)


def _bvh_read_back(data: bytes, target: str, bvh: Bvh, positions: np.ndarray, source) -> float:
    """How far (cm) a joint of the source ASF moves from `positions` (its, in model order) as mcz
    reads `data` back (`_bvh_points_of_asf`); MocapFormatError naming `source` unless it reads it as
    `bvh`'s joints and frames."""
    try:
        read = parse_bvh(data, target)
    except MocapFormatError as exc:
        raise MocapFormatError(f"cannot be converted: mcz would refuse the file it becomes ({exc})", source) from exc
    if ([(j.name, j.parent, j.channels) for j in read.joints] != [(j.name, j.parent, j.channels) for j in bvh.joints]
            or read.n_frames != bvh.n_frames):
        raise MocapFormatError(f"cannot be converted: {target} would not read back as its joints", source)
    return _farthest(file_positions(read, "cm")[:, _bvh_points_of_asf(read.joints)], positions)


def _farthest(read: np.ndarray, meant: np.ndarray) -> float:
    """The largest distance between two (frames, joints, 3) arrays; inf where one is not finite."""
    distance = float(np.sqrt(((read - meant) ** 2).sum(axis=-1)).max(initial=0.0))
    return distance if np.isfinite(distance) else np.inf


# --------------------------------------------------------------------------- names


def _holds_asf(name: str) -> bool:
    """Whether an ASF and its AMC hold `name` as a bone's, as any reader would read them: one of
    `_asf_reads`, printable, with no '>' (a link bone's) and not a word of `_ASF_WORDS` in any case."""
    return _asf_reads(name) and name.isprintable() and ">" not in name and name.upper() not in _ASF_WORDS


def _asf_reads(name: str) -> bool:
    """Whether mcz's ASF and AMC readers read `name` as a bone's: one word, not led by ':' (a
    section) or '#' (a comment), not `root` (the root's), and not a number: the AMC reader takes a
    line of ASCII digits for a frame's number and refuses a bone line led by any other `NUMBER`
    (`１２３` and `²` are names)."""
    return _one_word(name) and name[0] not in ":#" and name != ROOT and not NUMBER.match(name.encode("utf-8"))


def _holds_bvh(name: str) -> bool:
    """Whether a BVH holds `name` as a joint's, as any reader would read it: one of `_bvh_reads`,
    printable, with no brace and not a keyword."""
    return _bvh_reads(name) and name.isprintable() and "{" not in name and "}" not in name and name not in _BVH_KEYWORDS


def _bvh_reads(name: str) -> bool:
    """Whether mcz's BVH reader reads `name` as a joint's: one word but a lone brace."""
    return _one_word(name) and name not in ("{", "}")


def _one_word(name: str) -> bool:
    """Whether mcz's readers read `name` as one word: not empty, no white space (which splits words)
    and no control character or lone surrogate."""
    return bool(name) and not any(c.isspace() or unicodedata.category(c) in ("Cc", "Cs") for c in name)


def _escaped(name: str, holds, special: str) -> str:
    """`name` escaped for a format that `holds` names: each character of `special`, '%',
    whitespace and any unprintable one as %XX (its UTF-8 bytes), and the first one too where
    that escapes nothing or leaves a name the format cannot hold (a number, a keyword); the
    empty name as '%'. Decoding each %XX (`_unescaped`) gives `name` back."""
    parts = [_percent(c) if c in special or c == "%" or c.isspace() or not c.isprintable() else c for c in name]
    if parts and ("".join(parts) == name or not holds("".join(parts))):
        parts[0] = _percent(name[0])
    return "".join(parts) or "%"


def _percent(character: str) -> str:
    return "".join(f"%{byte:02X}" for byte in character.encode("utf-8"))


def _unescaped(text: str) -> str | None:
    """`text` with each %XX decoded; None where a '%' starts no %XX or the bytes are no UTF-8."""
    raw = text.encode("utf-8")
    if raw.count(b"%") != len(_ESCAPE.findall(raw)):
        return None
    try:
        return _ESCAPE.sub(lambda m: bytes([int(m[1], 16)]), raw).decode("utf-8")
    except UnicodeDecodeError:
        return None


def _bvh_name(asf_name: str) -> str:
    """The BVH joint name of an ASF bone that records none: the name itself where both formats
    hold it and it holds no %XX, else escaped (with '>', which an ASF keeps for link bones). No two
    names escape alike, and `_asf_name` takes each back; the ASF's root is `root` in both."""
    if asf_name == ROOT or (_holds_bvh(asf_name) and _holds_asf(asf_name) and not _ESCAPE.search(asf_name.encode())):
        return asf_name
    return _escaped(asf_name, _holds_bvh, "{}>")


def _asf_name(bvh_name: str) -> str:
    """The ASF bone name of a BVH joint (before `_unique`): the ASF name `_bvh_name` escaped to
    `bvh_name`, where mcz reads it, as its source ASF held it; else the name itself where an ASF
    holds it, else escaped."""
    original = _unescaped(bvh_name)
    if original is not None and original != bvh_name and _bvh_name(original) == bvh_name and _asf_reads(original):
        return original
    return bvh_name if _holds_asf(bvh_name) else _escaped(bvh_name, _holds_asf, ">")


def _asf_names(joints: list[BvhJoint]) -> list[str]:
    """The ASF bone name of each joint (`_asf_name`, `_unique`), the root's `root` (the ASF's root,
    which no bone takes). A name with '>' that a link bone may also have ("P>child", "P>end":
    `motion.bvh_skeleton`) is escaped, until none is."""
    taken = {ROOT}
    written = [ROOT if joint.parent < 0 else _unique(_asf_name(joint.name), taken) for joint in joints]
    while True:
        links = {f"{written[joint.parent]}>{name}" for joint, name in zip(joints, written) if joint.parent >= 0}
        links |= {f"{name}>end" for joint, name in zip(joints, written) if joint.end_site is not None}
        clashing = [k for k, name in enumerate(written) if name in links]
        if not clashing:
            return written
        for k in clashing:  # escaped, it holds no '>': it clashes with nothing again
            written[k] = _unique(_escaped(written[k], _holds_asf, ">"), taken)


def _bvh_names(asf_names, recorded: dict[str, str]) -> list[str]:
    """The BVH joint name of each ASF bone: the name `recorded` for it (`_recorded_names`), where
    mcz's BVH reader reads it, else `_bvh_name`; where two would be the same, a recorded one keeps it."""
    wanted = [recorded[name] if _bvh_reads(recorded.get(name, "")) else _bvh_name(recorded.get(name, name))
              for name in asf_names]
    taken: set[str] = set()
    restored = {k: _unique(wanted[k], taken) for k, name in enumerate(asf_names) if name in recorded}
    return [restored[k] if k in restored else _unique(wanted[k], taken) for k in range(len(asf_names))]


def _unique(name: str, taken: set[str]) -> str:
    """`name`, or `name~2`, `name~3`, ... where an earlier name took it (the name is then taken)."""
    candidate, k = name, 1
    while candidate in taken:
        k += 1
        candidate = f"{name}~{k}"
    taken.add(candidate)
    return candidate


def _recorded_names(skeleton: Skeleton) -> dict[str, str]:
    """{bone: the BVH joint name it was written for} of an ASF's `bvh-name` documentation lines;
    other lines are the documentation's free text."""
    recorded = {}
    for line in skeleton.documentation:
        words = line.split(None, 2)
        if len(words) == 3 and words[0] == NAME_RECORD and words[2].startswith('"'):  # a JSON string, nothing deeper
            try:
                original = json.loads(words[2])
            except ValueError:
                continue
            if isinstance(original, str):
                recorded[words[1]] = original
    return recorded
