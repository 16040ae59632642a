"""Acclaim Skeleton File (ASF): read and write.

The parsed `Skeleton` keeps everything needed to write the file back (header comments,
units, documentation, bone order, hierarchy order, unknown bone keywords), so a decoded
archive gives other ASF readers the file they expect.

Accepted input: sections `:version`, `:name`, `:units` (mass, length, angle deg|rad; numbers,
or units' names as some exporters write them: `mass kg`, `length m`),
`:documentation`, `:root` (order, axis, position, orientation), `:bonedata` (begin/end
blocks with id, name, direction, length, axis + order, dof in any order and subset, limits
with `inf`), `:hierarchy` (begin, `parent child...` lines, end); `#` comments anywhere;
CRLF, LF or CR line ends, mixed; tabs. Unknown sections are skipped with a warning naming
file and line. Every fault raises `MocapFormatError` with file and line: malformed numbers,
wrong value counts, a bone without `end`, duplicate bones, hierarchy lines naming unknown
bones, bones with two parents, cycles, bones missing from the hierarchy; a `:units length`
outside `UNITS_LENGTH_RANGE` and bones longer than `MAX_BONE_CM` (no body has them, and
their positions could not be coded to a centimetre). All checks are linear in the file size.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from mocapzip.limits import MAX_BONES_PER_SKELETON
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.text import (check_size, decode_text, integer, number, read_regular_file, split_lines,
                                   stated_frame_rate)

__all__ = ["Bone", "Skeleton", "read_asf", "parse_asf", "format_asf", "write_asf"]

ROOT = "root"
KNOWN_SECTIONS = {"version", "name", "units", "documentation", "root", "bonedata", "hierarchy"}
DOF_NAMES = ("rx", "ry", "rz", "tx", "ty", "tz", "l")
ROOT_CHANNELS = ("TX", "TY", "TZ", "RX", "RY", "RZ")
UNITS_LENGTH_RANGE = (1e-6, 1e6)  # `:units length` (file units per inch); real files: 0.45 (CMU, HDM05), 1 (Blade)
# `:units length` given as a unit's name instead of a factor (some exporters: `length m`): cm per file unit
NAMED_LENGTHS = {"m": 100.0, "meter": 100.0, "meters": 100.0, "metre": 100.0, "metres": 100.0,
                 "cm": 1.0, "centimeter": 1.0, "centimeters": 1.0, "centimetre": 1.0, "centimetres": 1.0,
                 "mm": 0.1, "millimeter": 0.1, "millimeters": 0.1, "millimetre": 0.1, "millimetres": 0.1,
                 "in": 2.54, "inch": 2.54, "inches": 2.54}
MAX_BONE_CM = 1e4  # 100 m; the longest bone of the shared data is 50 cm
MAX_ASF_BYTES = 1 << 24  # 16 MiB, refused unread: 1,024 bones take about 200 KB, the shared files at most 7 KB


@dataclass
class Bone:
    """One `begin ... end` block of `:bonedata`, values as written in the file."""

    name: str
    id: int | None = None
    direction: np.ndarray = field(default_factory=lambda: np.zeros(3))
    length: float = 0.0
    axis: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axis_order: str = "XYZ"
    dof: tuple[str, ...] = ()
    limits: list[tuple[float, float]] = field(default_factory=list)
    extra: list[str] = field(default_factory=list)  # unknown keyword lines, kept verbatim


@dataclass
class Skeleton:
    """A parsed ASF file. `bones` keeps file order; `hierarchy` keeps the file's parent lines."""

    name: str | None = None
    version: str | None = None
    units: dict[str, str] = field(default_factory=dict)
    documentation: list[str] = field(default_factory=list)
    root_order: tuple[str, ...] = ("TX", "TY", "TZ", "RX", "RY", "RZ")
    root_axis: str = "XYZ"
    root_position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    root_orientation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bones: list[Bone] = field(default_factory=list)
    hierarchy: list[tuple[str, list[str]]] = field(default_factory=list)
    comments: list[str] = field(default_factory=list)  # leading '#' lines
    path: str | None = None

    @property
    def frame_rate(self) -> float | None:
        """The frame rate the :documentation states (`fps:30`) or a leading comment, else None."""
        return stated_frame_rate([*self.comments, *self.documentation])

    @property
    def angle_unit(self) -> str:
        """'deg' or 'rad': the unit of axis, limits and AMC angles."""
        return "rad" if self.units.get("angle", "deg").lower().startswith("rad") else "deg"

    @property
    def length_scale(self) -> float:
        """The `:units length` factor: file lengths are (inches x this factor); a named unit's equivalent."""
        length = self.units.get("length", "1")
        return 2.54 / NAMED_LENGTHS[length.lower()] if length.lower() in NAMED_LENGTHS else float(length)

    @property
    def cm_per_unit(self) -> float:
        """Centimetres per file length unit: 2.54 / the `:units length` factor (CMU: 2.54 / 0.45), or
        what a unit named there measures (`length m`: 100)."""
        length = self.units.get("length", "1")
        return NAMED_LENGTHS[length.lower()] if length.lower() in NAMED_LENGTHS else 2.54 / float(length)

    def bone(self, name: str) -> Bone:
        for bone in self.bones:
            if bone.name == name:
                return bone
        raise KeyError(name)

    def parents(self) -> dict[str, str]:
        """Map child bone name -> parent name ('root' for the root's children)."""
        return {child: parent for parent, children in self.hierarchy for child in children}

    def dof_of(self, name: str) -> tuple[str, ...]:
        """The channels an AMC line for `name` carries, in file order."""
        if name == ROOT:
            return tuple(c.lower() for c in self.root_order)
        return self.bone(name).dof

    def dof_map(self) -> dict[str, tuple[str, ...]]:
        """`dof_of` for every bone and the root at once (a lookup per bone stays O(1))."""
        return {ROOT: self.dof_of(ROOT), **{bone.name: bone.dof for bone in self.bones}}


def read_asf(path: str | os.PathLike) -> Skeleton:
    """Parse an ASF file; raise MocapFormatError naming file and line on bad input."""
    path = os.fspath(path)
    return _AsfParser(split_lines(decode_text(read_asf_bytes(path), path)), path, stacklevel=4).parse()


def read_asf_bytes(path: str | os.PathLike) -> bytes:
    """The bytes of the ASF file at `path`, at most MAX_ASF_BYTES (MocapFormatError, unread, if more)."""
    return read_regular_file(path, MAX_ASF_BYTES, "an ASF file")


def parse_asf(data: bytes, path: str | None = None) -> Skeleton:
    """Parse ASF bytes (`path` only names the source in messages and in `Skeleton.path`)."""
    if isinstance(data, str):
        data = data.encode("utf-8")
    check_size(len(data), MAX_ASF_BYTES, "an ASF file", path)
    return _AsfParser(split_lines(decode_text(data, path)), path, stacklevel=4).parse()


class _AsfParser:
    def __init__(self, lines: list[str], path: str | None, stacklevel: int):
        self.stacklevel = stacklevel  # of warnings: the caller of read_asf / parse_asf
        self.lines = lines
        self.path = path
        self.skel = Skeleton(path=path)
        self.bone: Bone | None = None
        self.bone_line = 0  # line of the open bone's 'begin'
        self.bone_lines: dict[str, int] = {}  # bone name -> line of its 'name'
        self.length_lines: dict[str, int] = {}  # bone name -> line of its 'length'
        self.length_line: int | None = None  # of the open bone
        self.limits_open = False  # the previous bone line was 'limits' (or a continuation)
        self.hierarchy_lines: list[int] = []
        self.hierarchy_state = None  # None, 'open' after 'begin', 'closed' after 'end'
        self.hierarchy_line = 0
        self.seen: dict[str, int] = {}  # section -> first line

    def fail(self, message: str, lineno: int | None):
        raise MocapFormatError(message, self.path, lineno)

    def num(self, word: str, lineno: int, what: str = "value") -> float:
        return number(word, self.path, lineno, what=what)

    def parse(self) -> Skeleton:
        section = handler = None
        for lineno, raw in enumerate(self.lines, start=1):
            line = raw.strip()
            if not line:
                continue
            if line.startswith("#"):
                if section is None:
                    self.skel.comments.append(raw.rstrip())
                continue
            if line.startswith(":"):
                section = self.start_section(line, lineno)
                handler = getattr(self, f"line_{section}", None)
                continue
            if section is None:
                self.fail(f"expected a ':section' or '#' comment, got {line[:40]!r}", lineno)
            if handler is not None:
                handler(line.split(), line, lineno)
        self.finish(len(self.lines))
        return self.skel

    # ------------------------------------------------------------------ sections

    def start_section(self, line: str, lineno: int) -> str:
        words = line[1:].split(None, 1)
        key = words[0].lower() if words else ""
        rest = words[1].strip() if len(words) > 1 else ""
        if self.bone is not None:
            self.fail(f"bone '{self.bone.name or '?'}' (begin at line {self.bone_line}) has no 'end' before ':{key}'", lineno)
        if self.hierarchy_state == "open":
            self.fail(f"':hierarchy' (begin at line {self.hierarchy_line}) has no 'end' before ':{key}'", lineno)
        if key in KNOWN_SECTIONS and key in self.seen:
            self.fail(f"section ':{key}' appears twice (first at line {self.seen[key]})", lineno)
        self.seen.setdefault(key, lineno)
        if key == "version":
            self.skel.version = rest
        elif key == "name":
            self.skel.name = rest
        elif key not in KNOWN_SECTIONS:
            warnings.warn(f"{self.path}:{lineno}: unknown ASF section ':{key}' skipped", stacklevel=self.stacklevel)
            return "unknown"
        elif key == "documentation" and rest:
            self.skel.documentation.append(rest)
        elif rest:
            self.fail(f"unexpected text after ':{key}': {rest[:40]!r}", lineno)
        return key

    def line_version(self, words, line, lineno):
        self.fail(f"unexpected line in ':version': {line[:40]!r}", lineno)

    line_name = line_version

    def line_units(self, words, line, lineno):
        if len(words) != 2:
            self.fail(f"units line needs 'name value', got {line[:40]!r}", lineno)
        key, value = words[0].lower(), words[1]
        if key == "angle":
            if value.lower() not in ("deg", "rad", "degree", "degrees", "radian", "radians"):
                self.fail(f"angle unit must be 'deg' or 'rad', got {value!r}", lineno)
        elif key == "length" and value.lower() in NAMED_LENGTHS:
            pass  # `length m`: the unit itself (Skeleton.cm_per_unit)
        elif key != "length" and value.isalpha():
            pass  # `mass kg`: a unit's name, which nothing here uses
        else:
            scale = self.num(value, lineno, what=f"units {key}")
            low, high = UNITS_LENGTH_RANGE
            if key == "length" and not low <= scale <= high:
                self.fail(f"units length {value} is outside [{low:g}, {high:g}] "
                          "(file lengths are inches x this factor)", lineno)
        self.skel.units[key] = value

    def line_documentation(self, words, line, lineno):
        self.skel.documentation.append(line)

    def line_root(self, words, line, lineno):
        key = words[0].lower()
        skel = self.skel
        if key == "order":
            order = tuple(w.upper() for w in words[1:])
            bad = [c for c in order if c not in ROOT_CHANNELS]
            if bad:
                self.fail(f"unknown root channel {bad[0]!r} (expected TX TY TZ RX RY RZ)", lineno)
            if len(set(order)) != len(order):
                self.fail("root order names a channel twice", lineno)
            skel.root_order = order
        elif key == "axis":
            if len(words) != 2 or sorted(words[1].upper()) != ["X", "Y", "Z"]:
                self.fail(f"root axis must be an order of X, Y, Z, got {' '.join(words[1:])[:40]!r}", lineno)
            skel.root_axis = words[1].upper()
        elif key in ("position", "orientation"):
            if len(words) != 4:
                self.fail(f"root {key} needs 3 numbers, got {len(words) - 1}", lineno)
            setattr(skel, f"root_{key}", np.array([self.num(w, lineno) for w in words[1:]]))
        else:
            self.fail(f"unknown root keyword {words[0]!r}", lineno)

    def line_bonedata(self, words, line, lineno):
        key = words[0].lower()
        if key == "begin":
            if self.bone is not None:
                self.fail(f"'begin' inside bone '{self.bone.name or '?'}' (begin at line {self.bone_line}; missing 'end')", lineno)
            if len(words) > 1:
                self.fail(f"unexpected text after 'begin': {line[:40]!r}", lineno)
            self.bone, self.bone_line, self.limits_open, self.length_line = Bone(name=""), lineno, False, None
            return
        bone = self.bone
        if bone is None:
            self.fail(f"{words[0]!r} outside a begin/end block", lineno)
        if key == "end":
            self.end_bone(lineno)
            return
        continuation = line.startswith("(")
        if continuation and not self.limits_open:
            self.fail("limits continuation line without 'limits'", lineno)
        self.limits_open = key == "limits" or (continuation and self.limits_open)
        if key == "name":
            if len(words) != 2:
                self.fail(f"bone name must be one word, got {' '.join(words[1:])[:40]!r}", lineno)
            if bone.name:
                self.fail(f"bone '{bone.name}' has a second name {words[1]!r}", lineno)
            bone.name = words[1]
            if bone.name == ROOT:
                self.fail("a bone in ':bonedata' may not be called 'root'", lineno)
            if bone.name in self.bone_lines:
                self.fail(f"duplicate bone '{bone.name}' (first at line {self.bone_lines[bone.name]})", lineno)
            self.bone_lines[bone.name] = lineno
        elif key == "id":
            if len(words) != 2:
                self.fail(f"id needs 1 integer, got {len(words) - 1} values", lineno)
            bone.id = integer(words[1], self.path, lineno, what="bone id")
        elif key == "direction":
            if len(words) != 4:
                self.fail(f"direction needs 3 numbers, got {len(words) - 1}", lineno)
            bone.direction = np.array([self.num(w, lineno) for w in words[1:]])
        elif key == "length":
            if len(words) != 2:
                self.fail(f"length needs 1 number, got {len(words) - 1}", lineno)
            bone.length = self.num(words[1], lineno)
            self.length_line = lineno
        elif key == "axis":
            if len(words) not in (4, 5):
                self.fail(f"axis needs 3 angles and an order, got {line[:40]!r}", lineno)
            bone.axis = np.array([self.num(w, lineno) for w in words[1:4]])
            order = words[4].upper() if len(words) == 5 else "XYZ"
            if sorted(order) != ["X", "Y", "Z"]:
                self.fail(f"axis order must be an order of X, Y, Z, got {words[4]!r}", lineno)
            bone.axis_order = order
        elif key == "dof":
            dof = tuple(w.lower() for w in words[1:])
            bad = [d for d in dof if d not in DOF_NAMES]
            if bad:
                self.fail(f"unknown dof {bad[0]!r} in bone '{bone.name or '?'}' (expected rx ry rz tx ty tz l)", lineno)
            if len(set(dof)) != len(dof):
                self.fail(f"bone '{bone.name or '?'}' names a dof twice", lineno)
            if bone.dof:
                self.fail(f"bone '{bone.name or '?'}' has a second 'dof' line", lineno)
            bone.dof = dof
        elif key == "limits" or continuation:
            self.add_limits(bone, line[len(words[0]) :] if key == "limits" else line, lineno)
        else:
            bone.extra.append(line)

    def add_limits(self, bone: Bone, text: str, lineno: int) -> None:
        text = text.strip()
        pairs = text.replace(")", ") ").split(")")
        if not text or pairs[-1].strip():
            self.fail(f"limits need '(min max)' pairs, got {text[:40]!r}", lineno)
        for pair in pairs[:-1]:
            pair = pair.strip()
            if not pair.startswith("("):
                self.fail(f"limits need '(min max)' pairs, got {text[:40]!r}", lineno)
            lo_hi = pair[1:].split()
            if len(lo_hi) != 2:
                self.fail(f"limits need '(min max)' pairs, got {pair + ')'!r}", lineno)
            lo, hi = (self.limit(w, lineno) for w in lo_hi)
            if lo > hi:
                self.fail(f"limit minimum {lo_hi[0]} is above maximum {lo_hi[1]}", lineno)
            bone.limits.append((lo, hi))

    def limit(self, word: str, lineno: int) -> float:
        lowered = word.lower()
        if lowered in ("inf", "+inf", "infinity", "+infinity"):
            return math.inf
        if lowered in ("-inf", "-infinity"):
            return -math.inf
        return self.num(word, lineno, what="limit")

    def end_bone(self, lineno: int) -> None:
        bone = self.bone
        if not bone.name:
            self.fail(f"bone (begin at line {self.bone_line}) has no name", lineno)
        if bone.limits and len(bone.limits) != len(bone.dof):
            self.fail(f"bone '{bone.name}' has {len(bone.dof)} dof but {len(bone.limits)} limits", lineno)
        if len(self.skel.bones) == MAX_BONES_PER_SKELETON:
            self.fail(f"more than the {MAX_BONES_PER_SKELETON:,} bones a skeleton may have", lineno)
        self.skel.bones.append(bone)
        if self.length_line is not None:
            self.length_lines[bone.name] = self.length_line
        self.bone = None
        self.limits_open = False

    def line_hierarchy(self, words, line, lineno):
        key = words[0].lower()
        if key == "begin" and len(words) == 1:
            if self.hierarchy_state is not None:
                self.fail("second 'begin' in ':hierarchy'", lineno)
            self.hierarchy_state, self.hierarchy_line = "open", lineno
            return
        if key == "end" and len(words) == 1:
            if self.hierarchy_state != "open":
                self.fail("'end' without 'begin' in ':hierarchy'", lineno)
            self.hierarchy_state = "closed"
            return
        if self.hierarchy_state == "closed":
            self.fail(f"text after the hierarchy's 'end': {line[:40]!r}", lineno)
        self.skel.hierarchy.append((words[0], words[1:]))
        self.hierarchy_lines.append(lineno)

    def line_unknown(self, words, line, lineno):
        pass

    # ------------------------------------------------------------------ checks

    def finish(self, last_line: int) -> None:
        skel = self.skel
        if self.bone is not None:
            self.fail(f"file ends inside bone '{self.bone.name or '?'}' (begin at line {self.bone_line}; missing 'end')", last_line)
        if self.hierarchy_state == "open":
            self.fail(f"file ends inside ':hierarchy' (begin at line {self.hierarchy_line}; missing 'end')", last_line)
        for section in ("root", "bonedata", "hierarchy"):
            if section not in self.seen:
                self.fail(f"not a complete ASF file: no ':{section}' section", last_line)
        names = {b.name for b in skel.bones}
        parent_of: dict[str, tuple[str, int]] = {}
        for (parent, children), lineno in zip(skel.hierarchy, self.hierarchy_lines):
            if parent != ROOT and parent not in names:
                self.fail(f"hierarchy names unknown bone '{parent}'", lineno)
            for child in children:
                if child == ROOT:
                    self.fail(f"'root' cannot be a child (of '{parent}'): cycle in ':hierarchy'", lineno)
                if child not in names:
                    self.fail(f"hierarchy names unknown bone '{child}'", lineno)
                if child in parent_of:
                    first_parent, first_line = parent_of[child]
                    self.fail(
                        f"bone '{child}' has two parents in ':hierarchy', '{first_parent}' (line {first_line}) and '{parent}'",
                        lineno,
                    )
                parent_of[child] = (parent, lineno)
        for bone in skel.bones:
            if bone.name not in parent_of:
                self.fail(f"bone '{bone.name}' is not in ':hierarchy'", self.bone_lines.get(bone.name))
        # Every bone has one parent; a bone that does not lead back to root sits on a cycle.
        # A walk stops at the first bone known to reach root, so each bone is walked once.
        reaches_root = {ROOT}
        for bone in skel.bones:
            chain, on_chain = [], set()
            node = bone.name
            while node not in reaches_root:
                if node in on_chain:
                    loop = chain[chain.index(node) :] + [node]
                    self.fail(f"cycle in ':hierarchy': {' <- '.join(loop)}", parent_of[loop[0]][1])
                chain.append(node)
                on_chain.add(node)
                node = parent_of[node][0]
            reaches_root.update(chain)
        cm_per_unit = skel.cm_per_unit
        for bone in skel.bones:
            cm = float(np.linalg.norm(bone.direction)) * abs(bone.length) * cm_per_unit
            if not cm <= MAX_BONE_CM:
                self.fail(f"bone '{bone.name}' is {cm:.3g} cm long (direction x length x {cm_per_unit:.6g} cm "
                          f"per unit), longer than the {MAX_BONE_CM:g} cm a bone may be",
                          self.length_lines.get(bone.name, self.bone_lines[bone.name]))


# --------------------------------------------------------------------------- writing


def format_asf(skel: Skeleton) -> str:
    """ASF text for `skel`, in the source's order, LF line endings; numbers written exactly."""
    out: list[str] = list(skel.comments)
    if skel.version is not None:
        out.append(f":version {skel.version}".rstrip())
    if skel.name is not None:
        out.append(f":name {skel.name}".rstrip())
    out.append(":units")
    out += [f"  {k} {v}" for k, v in skel.units.items()]
    if skel.documentation:
        out.append(":documentation")
        out += [f"   {line}" for line in skel.documentation]
    out.append(":root")
    out.append("   order " + " ".join(skel.root_order))
    out.append(f"   axis {skel.root_axis}")
    out.append("   position " + _numbers(skel.root_position))
    out.append("   orientation " + _numbers(skel.root_orientation))
    out.append(":bonedata")
    for bone in skel.bones:
        out.append("  begin")
        if bone.id is not None:
            out.append(f"     id {bone.id}")
        out.append(f"     name {bone.name}")
        out.append("     direction " + _numbers(bone.direction))
        out.append(f"     length {_g(bone.length)}")
        out.append(f"     axis {_numbers(bone.axis)} {bone.axis_order}")
        if bone.dof:
            out.append("    dof " + " ".join(bone.dof))
        for i, (lo, hi) in enumerate(bone.limits):
            prefix = "    limits " if i == 0 else "           "
            out.append(f"{prefix}({_g(lo)} {_g(hi)})")
        out += [f"    {line}" for line in bone.extra]
        out.append("  end")
    out.append(":hierarchy")
    out.append("  begin")
    out += [f"    {parent} {' '.join(children)}".rstrip() for parent, children in skel.hierarchy]
    out.append("  end")
    return "\n".join(out) + "\n"


def write_asf(skel: Skeleton, path: str | os.PathLike) -> None:
    text = format_asf(skel)
    try:
        data = text.encode("latin-1")
    except UnicodeEncodeError:
        data = text.encode("utf-8")
    with open(path, "wb") as fh:
        fh.write(data)


def _g(value: float) -> str:
    """Shortest text that reads back as the same float ('inf' for limits)."""
    value = float(value)
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return str(int(value)) if value.is_integer() and abs(value) < 1e15 and not (value == 0 and math.copysign(1, value) < 0) else repr(value)


def _numbers(values) -> str:
    return " ".join(_g(float(v)) for v in values)
