"""The input formats: each kind of clip file mcz reads and writes back, declared in one place.

A format (`InputFormat`) names the suffixes of its clip files and where a clip's skeleton is (a
file beside it, as an AMC's ASF, or the clip's own file, as a BVH file's hierarchy); it reads a
skeleton from its text (`SourceSkeleton`) and a clip into the one shape the codec takes
(`SourceMotion`), and writes a decoded clip back as its file. Everything else asks a clip's
format here, never its suffix or its skeleton's type: discovery (`inputs.discover`), reading
(`inputs.clip.ClipReader`), `mcz inspect`, compress (`archive.writer`: the skeletons' texts and
their entries in meta), meta's checks (`archive.meta`) and decompress (`archive.reader`). An
archive tells a clip's format by its skeleton's entry in meta: `format` names it, and an entry
without one is an ASF, whose clips are AMC files (as before format 8).

ASF/AMC (`AMC`) and BVH (`BVH`) are registered here; their parsers live in `mocapzip.formats`.
A new format is its parser and one `register(InputFormat(...))`: a name, suffixes, the skeleton's
text, a skeleton reader, a clip reader and a writer (tests/test_input_registry.py registers one
in a test). What only some formats need (a row field of their own and fields of their skeletons'
entries, with their JSON Schemas, which meta's schema takes from here; rules meta checks; what
`mcz info` says of their skeletons; how the API's `Clip` reads their clips; an extra root kept
exactly) has defaults that do nothing.
"""

from __future__ import annotations

import os
import re
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from dataclasses import asdict, dataclass, field, replace
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from mocapzip.formats.amc import AmcStyle, Motion, amc_blocks, format_amc, read_amc
from mocapzip.formats.asf import Skeleton, parse_asf, read_asf_bytes
from mocapzip.defaults import UNITS_CM
from mocapzip.formats.bvh import MAX_MOTION_CHARS, NUMBER_STYLES, Bvh, BvhStyle, motion_lines_problem, parse_hierarchy
from mocapzip.formats.bvh import format_bvh, joint_columns, read_bvh, read_hierarchy, split_header
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.text import as_printed, detect_encoding
from mocapzip.motion.bvh_skeleton import BvhSkeleton, bvh_skeleton, file_layout, file_pose, file_positions, point_names
from mocapzip.motion.bvh_skeleton import point_parents, unmodelled
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.schema import NEWLINE, record

if TYPE_CHECKING:
    from pathlib import Path

    from mocapzip.archive.reader import Archive
    from mocapzip.inputs.discover import ClipSource


@dataclass(frozen=True, eq=False)
class SourceSkeleton:
    """A skeleton as read from its file (`InputFormat.read_skeleton`), and what an archive keeps of it."""

    skeleton: Any  # the format's own: an ASF `Skeleton`, a `BvhSkeleton`
    model: SkeletonModel | None  # None: only lossless coding takes its clips (`unmodelled` says why)
    text: bytes  # what the archive's skeletons stream keeps: the ASF file, a BVH file's hierarchy
    fields: dict = field(default_factory=dict)  # its entry in meta beyond name and format (BVH: encoding, units...)
    unmodelled: MocapFormatError | None = None  # why it has no model (lossless reading keeps such a skeleton)


@dataclass(frozen=True)
class SourceMotion:
    """A clip as read from its files (`InputFormat.read`): the channels the codec takes, and what
    `inspect`, the glitch search and the frame rate need to know of the files."""

    skeleton: Any  # the format's skeleton (`SourceSkeleton.skeleton`); None: a clip read without one
    model: SkeletonModel | None
    motion: Motion  # the channels the codec takes (a BVH clip's: `BvhSkeleton.motion`)
    stated_fps: float | None  # the frame rate the files state (BVH `Frame Time`, an AMC header, an ASF's documentation)
    angle_unit: str | None  # of its rotation channels, "deg" or "rad", as its row in meta says (None: no skeleton)
    channels_in_file: int  # values per frame in its file (a lossy BVH clip codes fewer)
    limits: Skeleton | None = None  # the ASF whose limits the glitch search checks (None: the format states none)
    parsed: Any = None  # the format's own parse of the file (a `Bvh`), for its `extras`


class Extras(NamedTuple):
    """What an archive keeps of a clip beside its coded channels (`InputFormat.extras`)."""

    row: dict  # fields of its row in meta (format 8 on: a BVH clip's `bvh`, its text between the numbers)
    extra_root: np.ndarray | None  # channels kept exactly, stream extra_root/NNNNN (a lossy BVH clip's extra root)



class ClipApi(NamedTuple):
    """What the API's `Clip` (`mocapzip.api`) does the format's own way (`InputFormat.api`). The hooks
    take what they need: `clip` the API's clip, `row` its row in meta, `stored` and `model` its
    skeleton as the archive reads it (`Archive.stored_skeleton`), `entry` the skeleton's entry in meta."""

    file: str  # the clip's attribute that is its file as decompress writes it, read back: `motion`, `bvh`
    file_type: type  # that file's type (`Motion`, `Bvh`): what `Clip.shell_error` takes already read
    also_has: tuple[str, ...]  # the clip's other attributes that only this format's clips have (`asf_text`)
    skeleton: Callable  # (stored) -> `Clip.skeleton`: an ASF `Skeleton`, a BVH file's joints
    decoded: Callable  # (archive, index) -> the clip's values in its file's channels, before they are printed
    printed: Callable  # (row, decoded values) -> those values as its file prints them, read back
    # (clip, row, the frames of the whole clip before a range's, skeleton text as stored, entry) -> its `file`,
    # made without its text
    make_file: Callable
    labels: Callable  # (row, stored, model) -> `Clip.channel_labels`
    joint_names: Callable  # (stored, model) -> the joints of `Clip.positions`, in order
    parents: Callable  # (stored, model) -> each joint's parent among them (-1: none)
    positions: Callable  # (clip, model, entry) -> (frames, joints, 3) positions in cm
    rotations: Callable  # (clip, model, entry) -> (frames, joints, 3, 3) world rotations, on row vectors
    own_files: Callable  # (clip) -> the bytes `Clip.save` writes in its own format: its file, then its skeleton's
    read_source: Callable  # (clip, path) -> a source file of the clip, read as `file_type`
    posed: Callable  # (the clip's model, a file of `file_type`, entry) -> (model, the channels `forward` takes)


@dataclass(frozen=True, eq=False)
class InputFormat:
    """One kind of clip file (see the module doc). The hooks take what they need as arguments."""

    name: str  # what an archive's meta calls it: its skeletons' `format` (left out for ASF)
    suffixes: tuple[str, ...]  # of its clip files, lower case, with the dot
    # the text an archive keeps of the skeleton file at a path (MocapFormatError or OSError if it cannot be read)
    skeleton_text: Callable[[Path], bytes]
    # (that text, the path it names in messages, the units of lengths if given, lossless) -> SourceSkeleton;
    # MocapFormatError if it is no skeleton of this format
    read_skeleton: Callable[[bytes, str, str | None, bool], SourceSkeleton]
    # (clip, its skeleton or None, lossless) -> SourceMotion; MocapFormatError or OSError if it cannot be read
    read: Callable[[ClipSource, SourceSkeleton | None, bool], SourceMotion]
    # (archive, clip index) -> the clip's file as decompress writes it, in blocks of whole frames: a clip
    # at the size limits (100 MB of text) is never one string
    write: Callable[[Archive, int], Iterable[bytes]]
    # its clips pair with skeleton files of this suffix (an AMC with an .asf); None: a clip's file holds its skeleton
    skeleton_suffix: str | None = None
    skeleton_kind: str = "skeleton"  # what messages call one of its skeletons
    # (stored text, entry in meta, lossless) -> (skeleton, model) of an archive's skeleton; ValueError saying what
    # is wrong. None: `read_skeleton` of the text
    stored_skeleton: Callable[[bytes, dict, bool], tuple] | None = None
    extras: Callable[[SourceMotion, ClipSource, bool], Extras] = lambda read, source, lossless: Extras({}, None)
    row_field: str | None = None  # a field of the clip rows in meta that only this format's clips have
    row_schema: dict | None = None  # its JSON Schema, in meta's schema (`archive.meta.schema`)
    # `SourceSkeleton.fields`' names, which every entry of its skeletons has, and their JSON Schemas
    entry_schema: dict[str, dict] = field(default_factory=dict)
    # of those, what `mcz info` reports of each of its skeletons (its JSON, `<name>_skeletons`), beside its name
    info_fields: tuple[str, ...] = ()
    # (its skeletons, as `mcz info --json` reports them) -> what `mcz info` says of them
    describe_skeletons: Callable[[list[dict]], str] | None = None
    # (row, index, fail) -> streams the row needs beyond its clip's: meta's rules for this format's rows
    check_row: Callable[[dict, int, Callable], list[str]] = lambda row, index, fail: []
    # (entry, index, lossless, fail): meta's rules for the fields of this format's skeleton entries
    check_entry: Callable[[dict, int, bool, Callable], None] = lambda entry, index, lossless, fail: None
    # `mcz inspect` without --check reads its clips as lossless coding does: every channel of the file,
    # no model needed (BVH); else as lossy coding does (an AMC's cut last frame dropped)
    inspects_lossless: bool = False
    api: ClipApi | None = None  # how the API's `Clip` reads its clips (None: the API shows only what every clip has)

    def __post_init__(self):
        if (self.row_field is None) != (self.row_schema is None):
            raise ValueError(f"input format {self.name!r}: a row field comes with its schema")

    @property
    def entry_fields(self) -> frozenset[str]:
        """The fields of its skeletons' entries in meta beyond name and format."""
        return frozenset(self.entry_schema)

    def info(self, entries: list[dict]) -> list[dict] | None:
        """What `mcz info` reports of its skeletons, the `entries` in meta of this format (None: an
        ASF's, which are reported as the skeletons of no other format, as before format 8)."""
        if self.asf_skeletons:
            return None
        return [{k: entry[k] for k in ("name", *self.info_fields)} for entry in entries]

    def described(self, skeletons: list[dict]) -> str:
        """What `mcz info` says of `skeletons` (as `info` reports them): how many, and more if the format says."""
        if self.describe_skeletons is not None:
            return self.describe_skeletons(skeletons)
        return f"{len(skeletons):,} {self.skeleton_kind}{'' if len(skeletons) == 1 else 's'}"

    @property
    def asf_skeletons(self) -> bool:
        """Whether its skeletons are ASF files: their entries in meta name no format (as before
        format 8), and the skeletons stream predicts their numbers as an ASF's (`archive.skeletons`)."""
        return self.name == DEFAULT_FORMAT

    def entry(self, name: str, skeleton: SourceSkeleton) -> dict:
        """A skeleton's entry in meta: its file's name, this format's name (but for ASF) and its own fields."""
        return {"name": name, **({} if self.asf_skeletons else {"format": self.name}), **skeleton.fields}

    def stored(self, text: bytes, entry: dict, lossless: bool) -> tuple:
        """(skeleton, model) of an archive's skeleton, its `text` as stored and its `entry` in meta;
        ValueError saying what is wrong with it."""
        if self.stored_skeleton is not None:
            return self.stored_skeleton(text, entry, lossless)
        try:
            read = self.read_skeleton(text, entry["name"], None, lossless)
        except (MocapFormatError, ValueError) as exc:
            raise ValueError(f"is not a valid {self.skeleton_kind} ({exc})") from exc
        return read.skeleton, read.model


DEFAULT_FORMAT = "amc"  # the input format of a skeleton whose entry in meta names none: ASF/AMC
_FORMATS: dict[str, InputFormat] = {}


def register(input_format: InputFormat) -> InputFormat:
    """Make `input_format` one mcz reads and writes (ValueError if its name or a suffix is taken)."""
    taken = {suffix for known in _FORMATS.values() for suffix in known.suffixes}
    if input_format.name in _FORMATS or taken & set(input_format.suffixes):
        raise ValueError(f"input format {input_format.name!r}: its name or a suffix is another format's")
    _FORMATS[input_format.name] = input_format
    return input_format


def unregister(name: str) -> None:
    """Forget the format called `name` (a test's)."""
    del _FORMATS[name]


def input_formats() -> list[InputFormat]:
    """Every format, in the order they were registered."""
    return list(_FORMATS.values())


def clip_format(name: str) -> InputFormat | None:
    """The format of a clip file called `name` (by its suffix, in any case), or None: not a clip."""
    lower = name.lower()
    return next((f for f in _FORMATS.values() if lower.endswith(f.suffixes)), None)


def stored_format(entry: dict) -> InputFormat | None:
    """The format of an archive's skeleton, from its `entry` in meta (None: one mcz does not know);
    the format of its clips too."""
    found = _FORMATS.get(entry.get("format", DEFAULT_FORMAT))
    return None if found is None or ("format" in entry) == found.asf_skeletons else found


def clip_suffixes() -> list[str]:
    """The suffixes of clip files, every format's."""
    return [suffix for f in _FORMATS.values() for suffix in f.suffixes]


# --------------------------------------------------------------------------- ASF/AMC


def _read_asf(text: bytes, path: str, units: str | None, lossless: bool) -> SourceSkeleton:
    skeleton = parse_asf(text, os.fspath(path))
    return SourceSkeleton(skeleton, SkeletonModel.from_asf(skeleton), text)


def _read_amc(source: ClipSource, skeleton: SourceSkeleton | None, lossless: bool) -> SourceMotion:
    """An AMC on its ASF (checked against it), its truncated last frame refused if `lossless`, else
    dropped; without a skeleton (`mcz inspect` of an AMC that pairs with none), its frames alone."""
    asf = None if skeleton is None else skeleton.skeleton
    motion = read_amc(source.motion, asf, partial_last_frame="error" if lossless else "drop")
    model = None if skeleton is None else skeleton.model
    return SourceMotion(asf, model, motion, motion.frame_rate or (None if asf is None else asf.frame_rate),
                        None if model is None else model.layout(motion).angle_unit, motion.values.shape[1], asf)


def _write_amc(archive: Archive, index: int) -> Iterator[bytes]:
    motion = archive.decode(index)
    archive.check_range(index, motion.values)
    for text in amc_blocks(motion):
        yield text.encode(motion.style.encoding)


def _check_amc_row(row: dict, index: int, fail) -> list[str]:
    # An AMC line of ASCII digits is a frame number (`formats.amc`).
    if any(b.isascii() and b.isdigit() for b in row["bones"]):
        raise fail(f"clips[{index}].bones", "a bone name of digits only would read back as a frame number")
    return []


def _decoded_amc(archive: Archive, index: int) -> np.ndarray:
    """An AMC clip's values as decoded, checked to be values a reader takes back."""
    values = archive.decode(index).values
    archive.check_range(index, values)
    return values


def _labels_amc(row: dict, skeleton: Skeleton, model: SkeletonModel) -> tuple[str, ...]:
    """Each AMC value's "bone.dof" ("lfemur.rx", "root.tx")."""
    return tuple(f"{bone}.{''.join(model.channels[model.index[bone]][k])}"
                 for bone, count in zip(row["bones"], row["counts"]) for k in range(count))


def _made_amc(clip, row: dict, start: int, text: str, entry: dict) -> Motion:
    first = row["first_frame"] + start
    return Motion(row["bones"], row["counts"], clip.channels, np.arange(first, first + clip.frames),
                  row["header"], row["path"], AmcStyle(**row["style"]))


def _printed_amc(row: dict, values: np.ndarray) -> np.ndarray:
    style = AmcStyle(**row["style"])
    return as_printed(values, style.notation, style.digits)


_AMC_API = ClipApi(
    "motion", Motion, ("asf_text",),
    skeleton=lambda stored: stored,
    decoded=_decoded_amc,
    printed=_printed_amc,
    make_file=_made_amc,
    labels=_labels_amc,
    joint_names=lambda stored, model: model.names,
    parents=lambda stored, model: np.asarray(model.parents),
    positions=lambda clip, model, entry: forward(model, clip.channels, clip.motion, turns=False).positions,
    rotations=lambda clip, model, entry: forward(model, clip.channels, clip.motion).rotations,
    own_files=lambda clip: [format_amc(clip.motion).encode(clip.motion.style.encoding),
                            clip.asf_text.encode("latin-1")],
    read_source=lambda clip, path: read_amc(path, clip.skeleton),
    posed=lambda model, motion, entry: (model, motion))


AMC = register(InputFormat(
    DEFAULT_FORMAT, (".amc",), read_asf_bytes, _read_asf, _read_amc, _write_amc, skeleton_suffix=".asf",
    skeleton_kind="ASF", check_row=_check_amc_row, api=_AMC_API,
    describe_skeletons=lambda skeletons: f"{len(skeletons):,} ASF skeleton{'' if len(skeletons) == 1 else 's'}"))


# --------------------------------------------------------------------------- BVH


def _bvh_hierarchy(path: Path) -> bytes:
    """A BVH file's hierarchy, as its bytes (`formats.bvh.read_hierarchy`)."""
    text, encoding = read_hierarchy(path)
    return text.encode(encoding)


def _read_hierarchy_text(text: bytes, path: str, units: str | None, lossless: bool) -> SourceSkeleton:
    """A BVH hierarchy and its model (`motion.bvh_skeleton`); for lossless coding, which keeps
    every value as it is, also one that has no model (`unmodelled`)."""
    encoding = detect_encoding(text)
    joints = parse_hierarchy(text.decode(encoding), path)
    try:
        skeleton, why = bvh_skeleton(joints, units, path), None
    except MocapFormatError as exc:
        if not lossless:
            raise
        skeleton, why = unmodelled(joints, units, path), exc
    fields = {"encoding": encoding, "units": skeleton.units,
              "units_inferred": units is None and skeleton.units is not None}
    return SourceSkeleton(skeleton, skeleton.model, text, fields, why)


def _read_bvh(source: ClipSource, skeleton: SourceSkeleton, lossless: bool) -> SourceMotion:
    """A BVH clip as the codec takes it (`BvhSkeleton.motion`), on the hierarchy read before."""
    bvh = read_bvh(source.motion)
    if split_header(bvh.header)[0] != skeleton.text.decode(skeleton.fields["encoding"]):
        raise MocapFormatError("its hierarchy is not the one read before (the file changed?)", source.motion)
    motion = skeleton.skeleton.motion(bvh, lossless)
    return SourceMotion(skeleton.skeleton, skeleton.model, motion, bvh.fps, "deg", bvh.values.shape[1], parsed=bvh)


_OPTIONAL_STYLE = {"final_line_end": True, "after": ""}  # a BVH row's style leaves these out where they hold


def _bvh_extras(read: SourceMotion, source: ClipSource, lossless: bool) -> Extras:
    """A BVH clip's text beside its values (row field `bvh`: its MOTION lines and how its frame lines
    are written) and, lossy, its extra root's channels where any is not 0 (`BvhSkeleton.above`)."""
    bvh = read.parsed
    if lossless and bvh.style.format(bvh.values) != bvh.frames_text:
        raise MocapFormatError("its frame lines are not all written alike (numbers, blanks, line ends), so "
                               "--lossless could not give the same bytes back", source.motion)
    # lossless: the frames as written; lossy: numbers as the file's (`BvhSkeleton.motion`)
    numbers = read.motion.style
    style = bvh.style if lossless else replace(bvh.style, number=f"{numbers.notation}{numbers.digits}")
    stated = {k: v for k, v in asdict(style).items() if k not in _OPTIONAL_STYLE or v != _OPTIONAL_STYLE[k]}
    text = {"motion": split_header(bvh.header)[1], "style": stated}
    problem = motion_lines_problem(text["motion"], bvh.n_frames)  # what an archive's reader checks
    if problem:
        raise MocapFormatError(f"its MOTION lines cannot be kept: {problem}", source.motion)
    extra_root = None if lossless else read.skeleton.above_values(bvh)
    if extra_root is not None:
        text["extra_root"] = True
    return Extras({"bvh": text}, extra_root)


def _stored_hierarchy(text: bytes, entry: dict, lossless: bool) -> tuple[BvhSkeleton, SkeletonModel | None]:
    """An archive's BVH hierarchy and its model (none for a lossless archive, which needs only its joints)."""
    try:
        hierarchy = text.decode(entry["encoding"])
        if not hierarchy.endswith(("\n", "\r")):
            raise ValueError("it does not end with a line end, before which MOTION would begin")
        joints = parse_hierarchy(hierarchy, entry["name"])
    except (MocapFormatError, ValueError) as exc:
        raise ValueError(f"is not a valid BVH hierarchy ({exc})") from exc
    if lossless:
        return unmodelled(joints, entry["units"], entry["name"]), None
    try:
        skeleton = bvh_skeleton(joints, entry["units"], entry["name"])
    except MocapFormatError as exc:
        raise ValueError(f"has no model ({exc})") from exc
    return skeleton, skeleton.model


def _write_bvh(archive: Archive, index: int) -> Iterator[bytes]:
    """A BVH clip's file: its hierarchy, MOTION lines and frames (docs/format.md, "Decoding a BVH clip")."""
    row, k = archive.clips[index], archive.clips[index]["skeleton"]
    values = bvh_file_values(archive, index)
    encoding = archive.meta["skeletons"][k]["encoding"]
    yield archive.skeleton_text(k).encode("latin-1")  # the hierarchy's bytes
    yield row["bvh"]["motion"].encode(encoding)
    for text in BvhStyle(**row["bvh"]["style"]).blocks(values):
        yield text.encode(encoding)


def bvh_file_values(archive: Archive, index: int) -> np.ndarray:
    """A BVH clip's frame values as decoded, in its file's channels, before they are printed
    (what `_write_bvh` writes, and the Python API reads without the text)."""
    row, k = archive.clips[index], archive.clips[index]["skeleton"]
    skeleton = archive.stored_skeleton(k)[0]
    lossless = archive.settings.lossless
    # lossless: the values as the file had them, no model needed
    layout = file_layout(skeleton.joints) if lossless else (list(skeleton.bones), list(skeleton.counts))
    if (row["bones"], row["counts"]) != layout:
        raise archive.damaged(index, "its bones and counts are not its hierarchy's")
    values = archive.decode(index).values
    if not lossless:
        extra_root = None  # none, or all 0
        if "extra_root" in row["bvh"]:
            if not len(skeleton.above):
                raise archive.damaged(index, "an extra root stream, but its hierarchy has no extra root")
            extra_root = archive.extra_root(index, len(skeleton.above))
        values = skeleton.file_values(values, extra_root)
    archive.check_range(index, values)
    return values


def _check_bvh_entry(entry: dict, index: int, lossless: bool, fail) -> None:
    if entry["units"] is None:  # the unit compress could not tell
        if not lossless:
            raise fail(f"skeletons[{index}].units", "null only in a lossless archive: a lossy clip's decode needs "
                                                    "the unit of its lengths")
        if entry["units_inferred"]:
            raise fail(f"skeletons[{index}].units_inferred", "true, but units is null: no unit was inferred")


def _check_bvh_row(row: dict, index: int, fail) -> list[str]:
    where = f"clips[{index}]"
    problem = motion_lines_problem(row["bvh"]["motion"], row["frames"])
    if problem:
        raise fail(f"{where}.bvh.motion", problem)
    if row["header"] or row["first_frame"] != 1 or row["angle_unit"] != "deg":
        raise fail(where, "a BVH clip's header is empty, its first_frame 1 and its angle_unit deg")
    if not row["path"].lower().endswith(".bvh"):
        raise fail(f"{where}.path", "a BVH clip's path ends in .bvh")
    return [f"extra_root/{index:05d}"] if "extra_root" in row["bvh"] else []


# a BVH clip's text beside its values (format 8 on): its MOTION lines, and how its frame lines are written
_BVH_ROW = record({
    "motion": {"type": "string", "maxLength": MAX_MOTION_CHARS},
    "style": record({
        "number": {"enum": list(NUMBER_STYLES)},
        "separator": {"enum": [" ", "\t"]},
        "trailing": {"type": "string", "pattern": "^[ \t]{0,16}$"},
        "line_end": NEWLINE,
    }, {"final_line_end": {"type": "boolean"}, "after": {"type": "string", "pattern": "^[ \t\r\n]{0,64}$"}}),
}, {"extra_root": {"enum": [True]}})  # lossy: the extra root's channels are in stream extra_root/NNNNN

_HIERARCHY_ENTRY = {"encoding": {"enum": ["utf-8", "latin-1"]},  # of its text
                    "units": {"enum": [*UNITS_CM, None]}, "units_inferred": {"type": "boolean"}}


def _described_hierarchies(skeletons: list[dict]) -> str:
    """How many BVH hierarchies of each unit, and whether compress inferred it (`mcz info`)."""
    units = Counter((s["units"], s["units_inferred"]) for s in skeletons)
    return ", ".join(f"{n:,} BVH {'hierarchy' if n == 1 else 'hierarchies'} (units: {unit}, "
                     f"{'inferred from the skeleton' if inferred else 'given by --units' if unit else 'not known'})"
                     for (unit, inferred), n in sorted(units.items(), key=str))


def _posed_bvh(model: SkeletonModel | None, bvh: Bvh, entry: dict) -> tuple[SkeletonModel, Motion]:
    """A BVH file's model and channels, its lengths in the archive's units (`BvhSkeleton.motion`, lossy)."""
    skeleton = bvh_skeleton(bvh.joints, entry.get("units"), bvh.path)
    return skeleton.model, skeleton.motion(bvh, lossless=False)


def _printed_bvh(row: dict, values: np.ndarray) -> np.ndarray:
    number = row["bvh"]["style"].get("number", "g6")
    return values.copy() if number == "repr" else as_printed(values, number[0], int(number[1:]))


def _made_bvh(clip, row: dict, start: int, text: str, entry: dict) -> Bvh:
    """A BVH clip's file from its header (hierarchy and MOTION lines) and style as stored."""
    motion = row["bvh"]["motion"]
    frame_time = re.search(r"Frame Time:[ \t]*([^ \t\r\n]+)", motion, re.IGNORECASE)
    hierarchy = text.encode("latin-1").decode(entry["encoding"])
    return Bvh(list(clip.skeleton), float(frame_time[1]), clip.channels, hierarchy + motion,
               BvhStyle(**row["bvh"]["style"]), None, entry["encoding"], clip.path)


_BVH_API = ClipApi(
    "bvh", Bvh, (),
    skeleton=lambda stored: stored.joints,
    decoded=bvh_file_values,
    printed=_printed_bvh,
    make_file=_made_bvh,
    labels=lambda row, stored, model: tuple(f"{stored.joints[j].name}.{name}"
                                            for j, name in joint_columns(stored.joints)),
    joint_names=lambda stored, model: point_names(stored.joints),
    parents=lambda stored, model: point_parents(stored.joints),
    positions=lambda clip, model, entry: file_positions(clip.bvh, entry["units"]),
    rotations=lambda clip, model, entry: file_pose(clip.bvh, entry["units"])[0],
    own_files=lambda clip: [format_bvh(clip.bvh).encode(clip.bvh.encoding)],
    read_source=lambda clip, path: read_bvh(path),
    posed=_posed_bvh)


BVH = register(InputFormat(
    "bvh", (".bvh",), _bvh_hierarchy, _read_hierarchy_text, _read_bvh, _write_bvh, skeleton_kind="BVH hierarchy",
    stored_skeleton=_stored_hierarchy, extras=_bvh_extras, row_field="bvh", row_schema=_BVH_ROW,
    entry_schema=_HIERARCHY_ENTRY, info_fields=("units", "units_inferred"),
    describe_skeletons=_described_hierarchies, check_row=_check_bvh_row, check_entry=_check_bvh_entry,
    inspects_lossless=True, api=_BVH_API))
