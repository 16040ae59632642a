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

Names (docs/bvh.md, "Names"): a name is written as it is where both formats hold it and it holds no
%XX; else it is escaped (`_escaped`), so that no two names are written alike. ASF -> BVH escapes
(`_bvh_name`) what BVH -> ASF decodes (`_asf_name`): the source ASF's names come back as they
were. BVH -> ASF: an ASF keeps the BVH name of each bone that would not come back by itself in a
`bvh-name` line of its documentation, which a conversion back to BVH restores.

Every file is read back, as written, by mcz's own readers before anything is written: one they
would refuse (a hierarchy past a limit of `mocapzip.limits`) or read as anything else, or with a
joint moved by more than READ_BACK_CM, stops the clip's conversion (`_bvh_read_back`,
`_asf_amc_read_back`).

Joint positions agree within TOLERANCE_CM: a BVH is written with 6 decimals (`%.6f`: an angle
unwrapped far past 360 keeps its precision), an AMC with 6 significant digits, each with more
(`BVH_NUMBERS`, `AMC_DIGITS`) where these would move a joint by more than READ_BACK_CM (an AMC
angle of 12,345.678 degrees, a root 1,234,567.891 cm from the origin). Every clip is read and
converted before any file is written, each file is written whole
(`formats.text.write_file_atomically`), into folders that are folders (`formats.text.check_folders`);
no input is ever written over.
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
from mocapzip.formats.text import NUMBER, check_folders, write_file_atomically
from mocapzip.inputs.clip import ClipReader, clip_frame_rate
from mocapzip.inputs.discover import find_clips, no_clips, record_skip
from mocapzip.inputs.registry import AMC, BVH
from mocapzip.motion.bvh_skeleton import bvh_skeleton, file_positions
from mocapzip.motion.kinematics import forward
from mocapzip.motion.rotations import euler_angles
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.progress import progress

TOLERANCE_CM = 0.01  # joint positions after a conversion, against the source's
READ_BACK_CM = TOLERANCE_CM / 2  # how far a joint may move as the files written are read back: half of it
AMC_DIGITS = (6, 17)  # significant digits of an AMC's values: CMU's, else every float64 read back as itself
BVH_NUMBERS = ("f6", "repr")  # a BVH's values: 6 decimals (an angle is within 180), else Python's repr
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
    written = _asf_names(bvh.joints)
    hierarchy = bvh_skeleton([replace(joint, name=name) for joint, name in zip(bvh.joints, written)], units, bvh.path)
    hierarchy.check_fixed(bvh, why="an ASF skeleton's bones keep their length")
    if hierarchy.above_values(bvh) is not None:
        raise MocapFormatError(f"its extra root '{bvh.joints[0].name}' moves: an ASF skeleton has one root", bvh.path)
    model, motion = hierarchy.model, hierarchy.motion(bvh, lossless=False)
    bvh_names = {name: joint.name for joint, name in zip(bvh.joints, written)}
    records = [f"{NAME_RECORD} {asf_name} {json.dumps(bvh_names[name], ensure_ascii=False)}"
               for name, asf_name in zip(model.names, [ROOT, *model.names[1:]])
               if name in bvh_names and bvh_names[name] != _bvh_name(asf_name)]  # link bones stand for no joint
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
                        hierarchy=[(p if p != model.names[0] else ROOT, kids) for p, kids in hierarchy])
    names = [ROOT if b == model.names[0] else b for b in motion.bones]
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
                raise MocapFormatError(f"two clips would be written to {target} (also {plans[target].motion})",
                                       source.motion)
            plans[target] = source
    check_folders((out / target).parent for target in plans)
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


def _targets(source) -> list[str]:
    """The files a clip becomes, relative to the output folder: x.amc -> x.bvh; x.bvh -> x.amc, x.asf."""
    if source.format not in _BECOMES:
        raise MocapFormatError(f"mcz convert turns AMC clips into BVH and BVH into ASF/AMC, not "
                               f"{source.format.name.upper()} clips", source.motion)
    stem = source.relpath[: -len(".amc")]  # .amc and .bvh alike; "take.1.amc" stays "take.1"
    return [stem + suffix for suffix in _BECOMES[source.format]]


def _converted(source, reader: ClipReader, units: str | None) -> list[bytes]:
    """The bytes of the files a clip becomes (`_targets`), each checked to read back as written."""
    targets = _targets(source)
    if source.format is BVH:
        skeleton, motion = bvh_to_amc(read_bvh(source.motion), units)
        name_bytes = motion.n_frames * sum(len(name.encode("utf-8")) + 1 for name in motion.bones)
        if name_bytes > MAX_AMC_BYTES:  # refused before the text is made: names are repeated in every frame
            raise MocapFormatError(f"cannot be converted: its joint names alone would take {name_bytes:,} bytes of "
                                   f"its AMC file, which may have {MAX_AMC_BYTES:,}", source.motion)
        asf = format_asf(skeleton).encode("utf-8")
        positions = _asf_positions(skeleton, motion)
        for digits in AMC_DIGITS:
            written = replace(motion, style=AmcStyle(digits=digits))
            files = [format_amc(written).encode("utf-8"), asf]
            moved = _asf_amc_read_back(files, targets, skeleton, written, positions, source.motion)
            if moved <= READ_BACK_CM:
                return files
        raise _moved(moved, source.motion)
    read = reader.motion(source)
    bvh = amc_to_bvh(read.skeleton, read.motion, clip_frame_rate(read.stated_fps, DEFAULT_FPS))
    positions = file_positions(bvh, "cm")
    for number in BVH_NUMBERS:
        written = replace(bvh, style=replace(bvh.style, number=number))
        files = [format_bvh(written).encode(written.encoding)]
        moved = _bvh_read_back(files[0], targets[0], written, positions, source.motion)
        if moved <= READ_BACK_CM:
            return files
    raise _moved(moved, source.motion)


def _asf_positions(skeleton: Skeleton, motion: Motion) -> np.ndarray:
    """(frames, joints, 3) cm: the joints of `motion` on `skeleton`, in its model's order (the root first)."""
    return forward(SkeletonModel.from_asf(skeleton), motion.values, motion).positions


def _moved(moved: float, source) -> MocapFormatError:
    return MocapFormatError(f"cannot be converted: mcz would read a joint back {moved:.3g} cm from where it is in the "
                            f"files it becomes (more than {READ_BACK_CM:g} cm)", source)


def _asf_amc_read_back(files: list[bytes], targets: list[str], skeleton: Skeleton, motion: Motion,
                       positions: np.ndarray, source) -> float:
    """How far (cm) a joint of `positions` (`skeleton` and `motion`'s) moves as mcz reads `files`
    (AMC, ASF) back; MocapFormatError naming `source` unless it reads them as the skeleton's bones
    and hierarchy and the clip's bones, values per bone and frames."""
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
    """How far (cm) a joint or End Site of `positions` (`bvh`'s) moves as mcz reads `data` back;
    MocapFormatError naming `source` unless it reads it as `bvh`'s joints and frames."""
    try:
        read = parse_bvh(data, target)
    except MocapFormatError as exc:
        raise MocapFormatError(f"cannot be converted: mcz would refuse the file it becomes ({exc})", source) from exc
    if ([(j.name, j.parent, j.channels) for j in read.joints] != [(j.name, j.parent, j.channels) for j in bvh.joints]
            or read.n_frames != bvh.n_frames):
        raise MocapFormatError(f"cannot be converted: {target} would not read back as its joints", source)
    return _farthest(file_positions(read, "cm"), positions)


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
