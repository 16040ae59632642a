"""Acclaim Skeleton File (ASF): read and write.

The parsed `Skeleton` keeps everything needed to write the file back (header
comments, units, documentation, bone order, hierarchy order), so a decoded
archive gives other ASF readers the file they expect.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from .errors import MocapFormatError
from .text import decode_text, number

ROOT = "root"
KNOWN_SECTIONS = {"version", "name", "units", "documentation", "root", "bonedata", "hierarchy"}


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
    def angle_unit(self) -> str:
        """'deg' or 'rad': the unit of axis, limits and AMC angles."""
        return "rad" if self.units.get("angle", "deg").lower().startswith("rad") else "deg"

    @property
    def length_scale(self) -> float:
        """The `:units length` factor: file lengths are (inches x this factor)."""
        return float(self.units.get("length", "1"))

    @property
    def cm_per_unit(self) -> float:
        """Centimetres per file length unit (CMU: 2.54 / 0.45)."""
        return 2.54 / self.length_scale

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


def read_asf(path: str | os.PathLike) -> Skeleton:
    """Parse an ASF file; raise MocapFormatError naming file and line on bad input."""
    path = os.fspath(path)
    with open(path, "rb") as fh:
        data = fh.read()
    return parse_asf(data, path)


def parse_asf(data: bytes, path: str | None = None) -> Skeleton:
    lines = decode_text(data, path).splitlines()
    skel = Skeleton(path=path)
    section = None
    bone: Bone | None = None
    bone_key = None  # last keyword inside a bone, for continuation lines of `limits`
    root_seen = bonedata_seen = False

    def fail(message: str, lineno: int):
        raise MocapFormatError(message, path, lineno)

    for lineno, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            if section is None:
                skel.comments.append(raw.rstrip())
            continue
        if line.startswith(":"):
            key, _, rest = line[1:].partition(" ")
            key = key.lower()
            rest = rest.strip()
            if bone is not None:
                fail(f"bone '{bone.name}' has no 'end' before section ':{key}'", lineno)
            section = key
            if key == "version":
                skel.version = rest
            elif key == "name":
                skel.name = rest
            elif key == "root":
                root_seen = True
            elif key == "bonedata":
                bonedata_seen = True
            elif key not in KNOWN_SECTIONS:
                warnings.warn(f"{path}:{lineno}: unknown ASF section ':{key}' skipped", stacklevel=2)
            continue
        if section is None:
            fail(f"text before the first ':section': {line[:40]!r}", lineno)
        words = line.split()
        if section == "units":
            if len(words) != 2:
                fail(f"units line needs 'name value', got {line!r}", lineno)
            skel.units[words[0].lower()] = words[1]
        elif section == "documentation":
            skel.documentation.append(line)
        elif section == "root":
            key = words[0].lower()
            if key == "order":
                skel.root_order = tuple(w.upper() for w in words[1:])
            elif key == "axis":
                skel.root_axis = words[1].upper() if len(words) > 1 else "XYZ"
            elif key in ("position", "orientation"):
                values = [number(w, path, lineno) for w in words[1:]]
                if len(values) != 3:
                    fail(f"root {key} needs 3 numbers, got {len(values)}", lineno)
                setattr(skel, f"root_{key}", np.array(values))
            else:
                fail(f"unknown root keyword {words[0]!r}", lineno)
        elif section == "bonedata":
            key = words[0].lower()
            if key == "begin":
                if bone is not None:
                    fail(f"'begin' inside bone '{bone.name}' (missing 'end')", lineno)
                bone, bone_key = Bone(name=""), None
            elif key == "end":
                if bone is None:
                    fail("'end' without 'begin'", lineno)
                if not bone.name:
                    fail("bone without a name", lineno)
                if bone.limits and len(bone.limits) != len(bone.dof):
                    fail(f"bone '{bone.name}' has {len(bone.dof)} dof but {len(bone.limits)} limits", lineno)
                skel.bones.append(bone)
                bone = None
            elif bone is None:
                fail(f"{words[0]!r} outside a begin/end block", lineno)
            else:
                _bone_line(bone, key, words, line, path, lineno)
                bone_key = key if key == "limits" else (bone_key if line.startswith("(") else key)
                if line.startswith("(") and bone_key != "limits":
                    fail("limits continuation without 'limits'", lineno)
        elif section == "hierarchy":
            key = words[0].lower()
            if key in ("begin", "end"):
                continue
            skel.hierarchy.append((words[0], words[1:]))
    if bone is not None:
        raise MocapFormatError(f"file ends inside bone '{bone.name}' (missing 'end')", path, len(lines))
    if not lines or not any(l.strip() for l in lines):
        raise MocapFormatError("empty file", path)
    if not (root_seen and bonedata_seen):
        raise MocapFormatError("not an ASF file: no ':root' and ':bonedata' sections", path)
    _check_hierarchy(skel, path)
    return skel


def _bone_line(bone: Bone, key: str, words: list[str], line: str, path, lineno: int) -> None:
    if key == "name":
        bone.name = words[1]
    elif key == "id":
        bone.id = int(number(words[1], path, lineno))
    elif key == "direction":
        bone.direction = np.array([number(w, path, lineno) for w in words[1:4]])
        if len(words) != 4:
            raise MocapFormatError(f"direction needs 3 numbers, got {len(words) - 1}", path, lineno)
    elif key == "length":
        bone.length = number(words[1], path, lineno)
    elif key == "axis":
        if len(words) not in (4, 5):
            raise MocapFormatError("axis needs 3 angles and an order", path, lineno)
        bone.axis = np.array([number(w, path, lineno) for w in words[1:4]])
        bone.axis_order = words[4].upper() if len(words) == 5 else "XYZ"
    elif key == "dof":
        bone.dof = tuple(w.lower() for w in words[1:])
        bad = [d for d in bone.dof if d not in ("rx", "ry", "rz", "tx", "ty", "tz", "l")]
        if bad:
            raise MocapFormatError(f"unknown dof {bad[0]!r} in bone '{bone.name}'", path, lineno)
    elif key == "limits" or line.startswith("("):
        text = line[len("limits"):] if key == "limits" else line
        for pair in text.replace(")", " ").split("("):
            if pair.strip():
                lo_hi = pair.split()
                if len(lo_hi) != 2:
                    raise MocapFormatError(f"limits need '(min max)', got {line!r}", path, lineno)
                bone.limits.append(tuple(_limit(w, path, lineno) for w in lo_hi))
    else:
        bone.extra.append(line)


def _limit(word: str, path, lineno: int) -> float:
    lowered = word.lower()
    if lowered in ("inf", "+inf"):
        return math.inf
    if lowered == "-inf":
        return -math.inf
    return number(word, path, lineno)


def _check_hierarchy(skel: Skeleton, path) -> None:
    names = {b.name for b in skel.bones}
    if len(names) != len(skel.bones):
        raise MocapFormatError("duplicate bone name in :bonedata", path)
    seen = {ROOT}
    for parent, children in skel.hierarchy:
        if parent not in names and parent != ROOT:
            raise MocapFormatError(f"hierarchy names unknown bone '{parent}'", path)
        for child in children:
            if child not in names:
                raise MocapFormatError(f"hierarchy names unknown bone '{child}'", path)
            if child in seen:
                raise MocapFormatError(f"bone '{child}' has two parents in :hierarchy", path)
            seen.add(child)
    orphans = names - seen
    if orphans:
        raise MocapFormatError(f"bone '{sorted(orphans)[0]}' is not in :hierarchy", path)


def format_asf(skel: Skeleton) -> str:
    """ASF text for `skel`, in the source's order, LF line endings."""
    out: list[str] = list(skel.comments)
    if skel.version is not None:
        out.append(f":version {skel.version}")
    if skel.name is not None:
        out.append(f":name {skel.name}")
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
    out += [f"    {parent} {' '.join(children)}" for parent, children in skel.hierarchy]
    out.append("  end")
    return "\n".join(out) + "\n"


def write_asf(skel: Skeleton, path: str | os.PathLike) -> None:
    with open(path, "w", encoding="latin-1", newline="\n") as fh:
        fh.write(format_asf(skel))


def _g(value: float) -> str:
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    value = float(value)
    return str(int(value)) if value.is_integer() and abs(value) < 1e15 else repr(value)


def _numbers(values) -> str:
    return " ".join(_g(float(v)) for v in values)
