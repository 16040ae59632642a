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

Names (docs/bvh.md, "Names"): a joint name the target cannot hold (`_holds_asf`, `_holds_bvh`) is
written escaped (`_escaped`); an ASF keeps the BVH name each of its bones was written for in a
`bvh-name` line of its documentation, which a conversion back to BVH restores.

Every file is read back, as written, by mcz's own readers before anything is written: one they
would refuse (a hierarchy past a limit of `mocapzip.limits`) or read as anything else stops
the clip's conversion (`_check_bvh_reads_back`, `_check_asf_amc_read_back`).

Joint positions agree within TOLERANCE_CM: a BVH is written with 6 decimals (`%.6f`: an angle
unwrapped far past 360 keeps its precision), an AMC as the reader's values, 6 significant digits.
Every clip is read and converted before any file is written, and each file is written whole
(`formats.text.write_file_atomically`); no input is ever written over.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from mocapzip.defaults import DEFAULT_FPS
from mocapzip.formats.amc import MAX_AMC_BYTES, Motion, format_amc, parse_amc
from mocapzip.formats.asf import Bone, Skeleton, format_asf, parse_asf
from mocapzip.formats.bvh import Bvh, BvhJoint, BvhStyle, format_bvh, parse_bvh, read_bvh
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.text import NUMBER, write_file_atomically
from mocapzip.inputs.clip import ClipReader, clip_frame_rate
from mocapzip.inputs.discover import find_clips, is_bvh, no_clips, record_skip
from mocapzip.motion.bvh_skeleton import bvh_skeleton
from mocapzip.motion.kinematics import forward
from mocapzip.motion.rotations import euler_angles
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.progress import progress

TOLERANCE_CM = 0.01  # joint positions after a conversion, against the source's (6 significant digits)
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
    """The ASF skeleton and AMC clip with `bvh`'s joint positions (lengths in cm)."""
    if not bvh.n_frames:
        raise MocapFormatError("no frames to convert", bvh.path)
    taken: set[str] = set()
    written = [_unique(_escaped(_bvh_meaning(joint.name), _holds_asf, ">"), taken) for joint in bvh.joints]
    hierarchy = bvh_skeleton([replace(joint, name=name) for joint, name in zip(bvh.joints, written)], units, bvh.path)
    hierarchy.check_fixed(bvh, why="an ASF skeleton's bones keep their length")
    if hierarchy.above_values(bvh) is not None:
        raise MocapFormatError(f"its extra root '{bvh.joints[0].name}' moves: an ASF skeleton has one root", bvh.path)
    model, motion = hierarchy.model, hierarchy.motion(bvh, lossless=False)
    bvh_names = {name: joint.name for joint, name in zip(bvh.joints, written)}
    records = [f"{NAME_RECORD} {asf_name} {json.dumps(bvh_names[name], ensure_ascii=False)}"
               for name, asf_name in zip(model.names, ["root", *model.names[1:]])
               if bvh_names.get(name, asf_name) != asf_name]  # link bones stand for no joint
    values = np.array(motion.values)
    values[:, [k for k, c in enumerate(model.channels[0]) if c[0] == "t"]] *= model.cm_per_unit  # the ASF is in cm
    bones = []
    for j in range(1, model.n_joints):
        length = float(np.linalg.norm(model.offsets[j]))
        direction = model.offsets[j] / length if length else np.zeros(3)
        bones.append(Bone(model.names[j], j, direction, length, np.zeros(3), "XYZ", model.channels[j]))
    hierarchy = [(model.names[p], [model.names[k] for k in range(model.n_joints) if model.parents[k] == p])
                 for p in range(model.n_joints) if any(model.parents == p)]
    skeleton = Skeleton(name=_skeleton_name(bvh.path), version="1.10",
                        units={"mass": "1.0", "length": "cm", "angle": "deg"},
                        documentation=[f"fps:{bvh.fps!r}", "converted from BVH by mcz convert", *records],
                        root_order=tuple(c.upper() for c in model.channels[0]), bones=bones,
                        hierarchy=[(p if p != model.names[0] else "root", kids) for p, kids in hierarchy])
    names = ["root" if b == model.names[0] else b for b in motion.bones]
    frames = np.arange(1, motion.n_frames + 1)
    return skeleton, Motion(names, list(motion.counts), values, frames, [":FULLY-SPECIFIED", ":DEGREES"], bvh.path)


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
    """The bytes of the files a clip becomes (`_targets`), each checked to read back as written."""
    targets = _targets(source)
    if is_bvh(source.amc.name):
        skeleton, motion = bvh_to_amc(read_bvh(source.amc), units)
        name_bytes = motion.n_frames * sum(len(name.encode("utf-8")) + 1 for name in motion.bones)
        if name_bytes > MAX_AMC_BYTES:  # refused before the text is made: names are repeated in every frame
            raise MocapFormatError(f"cannot be converted: its joint names alone would take {name_bytes:,} bytes of "
                                   f"its AMC file, which may have {MAX_AMC_BYTES:,}", source.amc)
        files = [format_amc(motion).encode(motion.style.encoding), format_asf(skeleton).encode("utf-8")]
        _check_asf_amc_read_back(files, targets, skeleton, motion, source.amc)
        return files
    read = reader.motion(source)
    bvh = amc_to_bvh(read.skeleton, read.motion, clip_frame_rate(read.stated_fps, DEFAULT_FPS))
    files = [format_bvh(bvh).encode(bvh.encoding)]
    _check_bvh_reads_back(files[0], targets[0], bvh, source.amc)
    return files


def _check_asf_amc_read_back(files: list[bytes], targets: list[str], skeleton: Skeleton, motion: Motion,
                             source) -> None:
    """MocapFormatError naming `source` unless mcz reads `files` (AMC, ASF) back as the
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


def _check_bvh_reads_back(data: bytes, target: str, bvh: Bvh, source) -> None:
    """MocapFormatError naming `source` unless mcz reads `data` back as `bvh`'s joints and frames."""
    try:
        read = parse_bvh(data, target)
    except MocapFormatError as exc:
        raise MocapFormatError(f"cannot be converted: mcz would refuse the file it becomes ({exc})", source) from exc
    if ([(j.name, j.parent, j.channels) for j in read.joints] != [(j.name, j.parent, j.channels) for j in bvh.joints]
            or read.n_frames != bvh.n_frames):
        raise MocapFormatError(f"cannot be converted: {target} would not read back as its joints", source)


# --------------------------------------------------------------------------- names


def _holds_asf(name: str) -> bool:
    """Whether an ASF and its AMC hold `name` as a bone's: one printable word, not a number (an AMC
    frame's), not led by ':' (a section) or '#' (a comment), no '>' (a link bone's), not a word of
    `_ASF_WORDS`."""
    return (_one_word(name) and name[0] not in ":#" and ">" not in name and name.upper() not in _ASF_WORDS
            and not NUMBER.match(name.encode("utf-8")))


def _holds_bvh(name: str) -> bool:
    """Whether a BVH holds `name` as a joint's: one printable word, no brace, not a keyword."""
    return _one_word(name) and "{" not in name and "}" not in name and name not in _BVH_KEYWORDS


def _one_word(name: str) -> bool:
    return bool(name) and name.isprintable() and not any(c.isspace() for c in name)


def _escaped(name: str, holds, special: str) -> str:
    """`name` where `holds` it, else escaped: each character of `special`, '%', whitespace and any
    unprintable one as %XX (its UTF-8 bytes), and the first one too if the whole name is one a
    format cannot hold (a number, a keyword); the empty name as '%'. `_unescaped` reverses it."""
    if holds(name):
        return name
    text = "".join(_percent(c) if c in special or c == "%" or c.isspace() or not c.isprintable() else c for c in name)
    if not text:
        return "%"
    return text if holds(text) else _percent(text[0]) + text[1:]


def _percent(character: str) -> str:
    return "".join(f"%{byte:02X}" for byte in character.encode("utf-8"))


def _unescaped(text: str) -> str | None:
    """The name `_escaped` wrote as `text` (but the empty one); None where `text` is no such escape."""
    raw = text.encode("utf-8")
    if raw.count(b"%") != len(_ESCAPE.findall(raw)):
        return None
    try:
        return _ESCAPE.sub(lambda m: bytes([int(m[1], 16)]), raw).decode("utf-8")
    except UnicodeDecodeError:
        return None


def _bvh_meaning(name: str) -> str:
    """The name a BVH joint's name stands for: the one convert escaped to it (a name a BVH cannot
    hold, from an ASF), else itself."""
    original = _unescaped(name)
    escape = original is not None and original != name and _escaped(original, _holds_bvh, "{}") == name
    return original if escape else name


def _bvh_names(asf_names, recorded: dict[str, str]) -> list[str]:
    """The BVH joint name of each ASF bone: the name `recorded` for it (`_recorded_names`), else its
    own, escaped where a BVH cannot hold it; where two would be the same, a recorded one keeps it."""
    wanted = [_escaped(recorded.get(name, name), _holds_bvh, "{}") for name in asf_names]
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
