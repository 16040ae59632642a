"""Biovision Hierarchy (BVH): read and write, exactly.

A BVH file is a HIERARCHY of joints (each an OFFSET from its parent, the CHANNELS the motion
gives it, and an optional End Site) and a MOTION section: `Frames:`, `Frame Time:`, then one
line of channel values per frame. Exporters differ in layout: 3 rotation channels per joint and
position channels on the root (CMU's conversion, mixed CRLF/LF line ends), or 6 channels on every
joint and an extra root above the hips (Bandai Namco's game-studio export), any rotation order.

Strict: every fault raises MocapFormatError naming file and line (a brace missing, a channel name
that is no channel, CHANNELS after a child joint, no CHANNELS at all, a frame line with too few
values, `Frames:` 0 or disagreeing with the lines, a number that is no finite number, a CR CR LF
among the MOTION lines and frames). Keywords, channel names and MOTION are ASCII words in any case.
Exact: a file read and written back is the same bytes. A Bvh read from a file keeps its text as
read (`header`, `frames_text`) and its values read-only; to write other values, make a new one
(`dataclasses.replace(bvh, values=..., frames_text=None)`): they are written in the number style
the file used (`BvhStyle`, found on a sample of its frames).
"""

from __future__ import annotations

import itertools
import os
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from mocapzip.formats.bvh_compiled import format_rows, scan_lines
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.numbers_compiled import with_numbers
from mocapzip.formats.text import (MAX_ABS_VALUE, MAX_FRAME_RATE, MIN_FRAME_RATE, VALUES_PER_BLOCK, check_size,
                                   check_text, detect_encoding, number, open_regular_file, read_regular_file,
                                   split_lines, whole_number)
from mocapzip.limits import MAX_BONES_PER_SKELETON, MAX_FRAMES_PER_CLIP, MAX_VALUES_PER_CLIP

CHANNELS = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
_CHANNEL_NAMES = {name.lower(): name for name in CHANNELS}
MAX_HIERARCHY_CHARS = 1 << 20  # the text before MOTION: a 1,024-joint skeleton takes about 200 KB
MAX_HIERARCHY_DEPTH = 200  # joints within joints (a human: about 10; each level is a Python call)
MAX_MOTION_CHARS = 4096  # the lines MOTION, Frames: and Frame Time: together, as an archive keeps them (a clip's)
# Larger files are refused unread (and so are such bytes, which convert reads back): a hierarchy (4
# bytes a character at most), the MOTION lines, and frames of 25 bytes a value, the longest number a
# style writes (`repr`: -1.2345678901234567e-05) and a blank, with room to spare (shared files: 9.7).
MAX_BVH_BYTES = 4 * (MAX_HIERARCHY_CHARS + MAX_MOTION_CHARS) + 25 * MAX_VALUES_PER_CLIP
_WHAT = "a text BVH file"  # what `check_text` says the file should have been
# tried in this order (`_style_of`)
NUMBER_STYLES = ("repr", "g6", "g7", "g8", "g9", "g10", "g15", "g17", "f6", "f3", "f4", "f5", "f7", "f8", "f9")


@dataclass(frozen=True, eq=False)
class BvhJoint:
    """One joint: its parent (an index into `Bvh.joints`, -1 for a root), offset from that
    parent in the file's units, channels in file order, and its End Site's offset, if any.
    Channel names are spelt as CHANNELS, whatever case the file used (its text keeps that case),
    so every reader of them agrees."""

    name: str
    parent: int
    offset: np.ndarray  # (3,)
    channels: tuple[str, ...]  # e.g. ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
    end_site: np.ndarray | None = None  # (3,)


@dataclass(frozen=True)
class BvhStyle:
    """How a file writes its frames: numbers ("repr": Python's shortest repr, as CMU's conversion;
    "g<p>": C's %.<p>g, as most exporters; "f<p>": %.<p>f, as Blender), the separator between
    values, what ends a frame's last value (a trailing blank, or nothing), the line end, whether
    the last frame has one, and the blank lines after it."""

    number: str = "g6"
    separator: str = " "
    trailing: str = ""
    line_end: str = "\n"
    final_line_end: bool = True
    after: str = ""  # blank lines (or blanks) after the last frame's line end

    def format(self, values: np.ndarray) -> str:
        """The frame lines of `values` (frames, channels), in this style: "g" and "f" numbers in
        compiled code (`bvh_compiled.format_rows`, the numbers it leaves and "repr" in Python)."""
        return "".join(self.blocks(values))

    def blocks(self, values: np.ndarray) -> Iterator[str]:
        """`format`'s text in blocks of whole frames of at most `VALUES_PER_BLOCK` values: a writer
        that writes each, or drops it, never holds a long clip's text whole."""
        width = values.shape[1] if values.ndim == 2 else 0
        ending = self.trailing + self.line_end
        per_block = max(1, VALUES_PER_BLOCK // max(width, 1))
        for first in range(0, values.shape[0], per_block):
            text = self._rows(values[first : first + per_block], ending)
            if first + per_block >= values.shape[0] and not self.final_line_end:  # the last frame has no line end
                text = text[: len(text) - len(self.line_end)]
            yield text
        yield self.after

    def _rows(self, values: np.ndarray, ending: str) -> str:
        width = values.shape[1] if values.ndim == 2 else 0
        if width == 0:
            return ending * values.shape[0]
        if self.number == "repr":
            texts = [repr(v) for v in values.ravel().tolist()]
            return "".join(self.separator.join(texts[i : i + width]) + ending for i in range(0, len(texts), width))
        return self._compiled_rows(np.ascontiguousarray(values, dtype=np.float64), ending)

    def _compiled_rows(self, values: np.ndarray, ending: str) -> str:
        spec, flat = f".{int(self.number[1:])}{self.number[0]}", values.ravel()
        text, hard = format_rows(values, np.frombuffer(self.separator.encode(), np.uint8),
                                 np.frombuffer(ending.encode(), np.uint8), self.number[0] == "f",
                                 int(self.number[1:]))
        return with_numbers(text.tobytes(), hard, lambda item: format(float(flat[item]), spec)).decode("ascii")


@dataclass
class Bvh:
    """A BVH clip: the skeleton (`joints`), the frame time, and the values (frames, channels) in
    the order of the joints' CHANNELS. Read from a file, `header` and `frames_text` are its text,
    which `format_bvh` gives back; a Bvh built in code leaves them None (written out, in `style`)."""

    joints: list[BvhJoint]
    frame_time: float
    values: np.ndarray
    header: str | None = None  # the text before the first frame, verbatim
    style: BvhStyle = BvhStyle()
    frames_text: str | None = None  # the frame lines as read (None: written from `values` in `style`)
    encoding: str = "utf-8"
    path: str | None = None

    @property
    def fps(self) -> float:
        """Frames per second: 1 / `frame_time`, or the whole rate whose frame time it is, as
        exporters print it: to 6 significant digits (0.00833333: 120, not 120.00005) or 6 decimals
        (0.008333, Blender's)."""
        rate = 1.0 / self.frame_time
        whole = round(rate)
        printed = max(5e-6 * self.frame_time, 5e-7)  # how far a printed frame time is from its rate's
        return float(whole) if whole and abs(1.0 / whole - self.frame_time) <= printed else rate

    @property
    def n_frames(self) -> int:
        return int(self.values.shape[0])

    def columns(self) -> list[tuple[int, str]]:
        """(joint index, channel name) of each column of `values`."""
        return joint_columns(self.joints)


def joint_columns(joints: list[BvhJoint]) -> list[tuple[int, str]]:
    """(joint index, channel name) of each column of the frame lines of a hierarchy's clips."""
    return [(j, channel) for j, joint in enumerate(joints) for channel in joint.channels]


def read_bvh(path: str | os.PathLike) -> Bvh:
    """Read and check the BVH file at `path` (MocapFormatError with file and line on any fault)."""
    return parse_bvh(read_regular_file(path, MAX_BVH_BYTES, "a BVH file"), os.fspath(path))


def parse_bvh(data: bytes, path: str | None = None) -> Bvh:
    """A BVH file's bytes -> Bvh; see the module doc for what is checked."""
    check_size(len(data), MAX_BVH_BYTES, "a BVH file", path)
    data = check_text(data, path, _WHAT)
    encoding = detect_encoding(data)
    text = data.decode(encoding)
    parser = _Parser(text, path)
    joints = parser.hierarchy()
    n_frames, frame_time, header_end, first_line = parser.motion_header()
    if not n_frames:  # as an AMC with header lines only: a clip is motion, and every reader's shapes need a frame
        raise MocapFormatError("no frames: Frames: 0", path, first_line - 2)
    width = sum(len(joint.channels) for joint in joints)
    if n_frames * max(width, 1) > MAX_VALUES_PER_CLIP:
        raise MocapFormatError(f"{n_frames} frames of {width} values are more than the {MAX_VALUES_PER_CLIP:,} "
                               "a clip may hold", path, first_line - 2)
    parser.check_line_ends(first_line + n_frames - 2)  # after the last frame's line, blank lines may follow
    frames_text = text[header_end:]
    frames = data[len(text[:header_end].encode(encoding)) :]
    values, lines = _frame_values(frames, frames_text, n_frames, width, path, first_line)
    values.flags.writeable = False  # the text kept beside them must stay what they say
    line = lines if callable(lines) else lines.__getitem__
    return Bvh(joints, frame_time, values, text[:header_end], _style_of(frames_text, n_frames, line, values),
               frames_text, encoding, path)


def read_hierarchy(path: str | os.PathLike) -> tuple[str, str]:
    """(hierarchy text, encoding) of the BVH file at `path` (see `split_header`), reading no
    further than its MOTION line, nor past what a hierarchy may take (MAX_HIERARCHY_CHARS);
    MocapFormatError if it has none. Only a header can hold letters, so its encoding is the file's."""
    head = bytearray()
    line_start, motion = 0, None  # where the last line read starts: the next chunk may go on with it
    with open_regular_file(path) as file:
        while motion is None and len(head) <= 4 * MAX_HIERARCHY_CHARS:  # 4: the most bytes of a UTF-8 character
            chunk = file.read(1 << 16)
            head += chunk
            motion = _MOTION_BYTES.search(head, line_start)
            if motion and chunk and motion.end() == len(head) and head[-1:] not in b"\r\n":
                motion = None  # `MOTION` at the end of what was read: its line may go on
            if not chunk:
                break
            line_start = max(line_start, head.rfind(b"\n", line_start) + 1, head.rfind(b"\r", line_start) + 1)
    head = bytes(head)
    if motion is None:
        check_text(head, os.fspath(path), _WHAT)  # empty, UTF-16 or binary: say so rather than "no MOTION"
        where = f" in its first {len(head):,} bytes" if chunk else ""  # stopped short of the end
        raise MocapFormatError(f"no MOTION line{where}: not a BVH file", os.fspath(path))
    hierarchy = check_text(head[: motion.start()], os.fspath(path), _WHAT) if motion.start() else b""
    encoding = detect_encoding(hierarchy)
    return hierarchy.decode(encoding), encoding


# The one rule for the MOTION line, on text and on bytes: the ASCII word in any case, blanks (spaces
# and tabs) around it, alone on its line (`str.upper` would take `MOTıON`, `str.strip` a no-break space).
_BLANKS = " \t"
_MOTION_LINE = rf"[{_BLANKS}]*MOTION[{_BLANKS}]*"
_MOTION_WORD = re.compile(_MOTION_LINE, re.IGNORECASE | re.ASCII)
_MOTION_TEXT = re.compile(rf"(?:\A|(?<=[\r\n])){_MOTION_LINE}(?:\r|\n|\Z)", re.IGNORECASE | re.ASCII)
# (on a file's bytes: after a UTF-8 byte-order mark too, which `check_text` takes off the text)
_MOTION_BYTES = re.compile(rb"(?:\A(?:\xef\xbb\xbf)?|(?<=[\r\n]))" + _MOTION_LINE.encode() + rb"(?:\r|\n|\Z)",
                           re.IGNORECASE)


def split_header(header: str) -> tuple[str, str]:
    """(hierarchy, motion lines) of a BVH header: the text before its MOTION line, and the rest.
    An archive keeps the first once per skeleton and the second per clip."""
    motion = _MOTION_TEXT.search(header)  # as `_Parser` finds it
    if motion is None:
        raise ValueError("no MOTION line in the header")
    return header[: motion.start()], header[motion.start() :]


def motion_lines_problem(text: str, frames: int) -> str | None:
    """What is wrong with `text` as a clip's MOTION lines (`split_header`'s second part) for
    `frames` frames, as `parse_bvh` reads them; None if nothing (archives check what they keep)."""
    if len(text) > MAX_MOTION_CHARS:
        return f"longer than {MAX_MOTION_CHARS:,} characters"
    lines = _lines_with_ends(text, 4)
    if len(lines) != 3 or not all(line.endswith(("\n", "\r")) for line in lines):
        return "not three lines, each with its line end"
    if not _MOTION_WORD.fullmatch(lines[0].rstrip("\r\n")):
        return "not the lines MOTION, Frames: and Frame Time:"
    try:
        count, _ = _motion_numbers(lines[1:], 2, None)
    except MocapFormatError as exc:
        return exc.message
    return None if count == frames else f"Frames: is not {frames}"


def _motion_numbers(lines: list[str], first_line: int, path: str | None) -> tuple[int, float]:
    """(frames, frame time) of the lines `Frames:` and `Frame Time:` that follow MOTION (`lines`,
    the first of them line `first_line`); MocapFormatError naming the line at fault."""
    words = []
    for offset, key in enumerate(("frames:", "frame time:")):
        if offset >= len(lines):
            raise MocapFormatError(f"MOTION needs a '{key.capitalize()}' line", path, first_line + offset - 1)
        line = lines[offset].rstrip("\r\n").strip(_BLANKS)
        if not line.lower().startswith(key):
            raise MocapFormatError(f"expected '{key.capitalize()} ...', got {line[:40]!r}", path, first_line + offset)
        words.append(line[len(key):].strip(_BLANKS))
    count, seconds = words
    frames = whole_number(count, MAX_FRAMES_PER_CLIP)
    if frames is None:
        raise MocapFormatError(f"Frames: must be a count up to {MAX_FRAMES_PER_CLIP:,}, got {count[:30]!r}", path,
                               first_line)
    frame_time = number(seconds, path, first_line + 1, what="Frame Time")
    if not 1 / MAX_FRAME_RATE <= frame_time <= 1 / MIN_FRAME_RATE:
        raise MocapFormatError(f"Frame Time must be from {1 / MAX_FRAME_RATE:g} to {1 / MIN_FRAME_RATE:g} seconds "
                               f"(a rate of {MIN_FRAME_RATE:g} to {MAX_FRAME_RATE:,.0f} fps), got {seconds[:30]!r}",
                               path, first_line + 1)
    return frames, frame_time


def parse_hierarchy(text: str, path: str | None = None) -> list[BvhJoint]:
    """The joints of a hierarchy's text (`split_header`'s first part), checked as `parse_bvh` does."""
    parser = _Parser(text + "\nMOTION\n", path)
    if parser.motion_line <= len(_lines_with_ends(text, len(text) + 1)):
        raise MocapFormatError("a hierarchy holds no MOTION line", path, parser.motion_line)
    return parser.hierarchy()


def format_bvh(bvh: Bvh) -> str:
    """The text of `bvh`: as read, when it was read and its frames are unchanged; else its frames
    written from the values, in `style`, after its header (as read, with `Frames:` and
    `Frame Time:` saying what the values are) or a header written out."""
    if bvh.header is None:
        return _canonical_header(bvh) + bvh.style.format(bvh.values)
    if bvh.frames_text is not None:
        return bvh.header + bvh.frames_text
    hierarchy, motion = split_header(bvh.header)
    motion = _FRAMES.sub(lambda m: f"{m.group(1)}{bvh.n_frames}", motion, count=1)
    motion = _FRAME_TIME.sub(lambda m: m.group(0) if float(m.group(2)) == bvh.frame_time
                             else f"{m.group(1)}{bvh.frame_time!r}", motion, count=1)
    return hierarchy + motion + bvh.style.format(bvh.values)


# at a line's start, after any line end (`^` with re.MULTILINE is after LF only: a CR-only file's count stayed)
_FRAMES = re.compile(r"(?:\A|(?<=[\r\n]))([ \t]*Frames:[ \t]*)([0-9]+)", re.IGNORECASE | re.ASCII)
_FRAME_TIME = re.compile(r"(?:\A|(?<=[\r\n]))([ \t]*Frame Time:[ \t]*)([^ \t\r\n]+)", re.IGNORECASE | re.ASCII)


def _lines_with_ends(text: str, limit: int) -> list[str]:
    """The first `limit` lines of `text` with their ends; CRLF, LF and CR end a line, nothing else
    (as the hierarchy's words are read, so line numbers agree)."""
    lines, start = [], 0
    for end in _LINE_END.finditer(text):
        if len(lines) == limit:
            return lines
        lines.append(text[start : end.end()])
        start = end.end()
    if start < len(text) and len(lines) < limit:
        lines.append(text[start:])
    return lines


_LINE_END = re.compile(r"\r\n|\r|\n")


def write_bvh(bvh: Bvh, path: str | os.PathLike) -> None:
    """Write `bvh` to `path` (see `format_bvh`), in the encoding it was read in."""
    with open(path, "wb") as file:
        file.write(format_bvh(bvh).encode(bvh.encoding))


# ----------------------------------------------------------------------------- reading


class _Parser:
    """The hierarchy, read word by word (any line layout: `{` on its own line or not), and
    the three lines that open MOTION."""

    def __init__(self, text: str, path: str | None):
        self.text, self.path = text, path
        self.words: list[tuple[str, int]] = []  # (word, line) of the hierarchy
        self.position = 0
        motion = _MOTION_TEXT.search(text)  # the lines up to it, not the frames, are split
        if motion is None:
            raise self.fail("no MOTION line: not a BVH file", None)  # as `read_hierarchy` says
        if motion.end() > MAX_HIERARCHY_CHARS:
            raise self.fail(f"the hierarchy is longer than {MAX_HIERARCHY_CHARS:,} characters "
                            f"({MAX_BONES_PER_SKELETON:,} joints at most)", 1)
        lines = split_lines(text[: motion.start()])  # the last: what comes before MOTION on its line, nothing
        for line_number, line in enumerate(lines, start=1):
            self.words += [(word, line_number) for word in line.split()]
        self.motion_line = len(lines)
        doubled = text.find("\r\r\n", motion.start())
        self.doubled_line_end = None if doubled < 0 else self.motion_line + (  # the line that ends so, from MOTION on
            text.count("\n", motion.start(), doubled) + text.count("\r", motion.start(), doubled)
            - text.count("\r\n", motion.start(), doubled))

    def fail(self, message: str, line: int | None) -> MocapFormatError:
        return MocapFormatError(message, self.path, line)

    def next(self, expected: str | None = None) -> tuple[str, int]:
        if self.position >= len(self.words):
            last = self.words[-1][1] if self.words else 1
            raise self.fail(f"the hierarchy ends early{f', expected {expected!r}' if expected else ''}", last)
        word, line = self.words[self.position]
        self.position += 1
        if expected is not None and _keyword(word) != expected.upper():
            raise self.fail(f"expected {expected!r}, got {word[:40]!r}", line)
        return word, line

    def check_line_ends(self, last_line: int) -> None:
        """MocapFormatError if a line from MOTION to `last_line` ends in CR CR LF: every reader (and
        editor) takes that for a line end and then a blank line, which MOTION's lines cannot hold."""
        if self.doubled_line_end is not None and self.doubled_line_end <= last_line:
            raise self.fail("the line ends in CR CR LF (a line end, then a blank line): the MOTION lines and "
                            "frame lines each end in one CRLF, LF or CR", self.doubled_line_end)

    def hierarchy(self) -> list[BvhJoint]:
        self.next("HIERARCHY")
        joints: list[BvhJoint] = []
        roots = []
        while self.position < len(self.words):
            roots.append(self.next("ROOT")[1])
            self.joint(joints, -1)
        if not joints:
            raise self.fail("no ROOT joint", self.words[-1][1] if self.words else 1)
        if not any(joint.channels for joint in joints):  # frames of no values: blank lines, or none
            raise self.fail("no joint has a CHANNELS line: its frames would hold no values", roots[0])
        return joints

    def joint(self, joints: list[BvhJoint], parent: int, depth: int = 1) -> None:
        name, line = self.next()
        if depth > MAX_HIERARCHY_DEPTH:
            raise self.fail(f"joints nested more than {MAX_HIERARCHY_DEPTH} deep", line)
        if name in ("{", "}"):
            raise self.fail("a joint needs a name", line)
        if any(j.name == name for j in joints):
            raise self.fail(f"joint {name!r} appears twice", line)
        if len(joints) >= MAX_BONES_PER_SKELETON:
            raise self.fail(f"more than {MAX_BONES_PER_SKELETON} joints", line)
        self.next("{")
        self.next("OFFSET")
        offset = self.numbers(3, "OFFSET")
        channels: tuple[str, ...] = ()
        index = len(joints)
        joints.append(BvhJoint(name, parent, offset, channels))
        end_site = None
        while True:
            word, line = self.next()
            key = _keyword(word)
            if key == "CHANNELS":
                if channels:
                    raise self.fail(f"joint {name!r} has a second CHANNELS line", line)
                if len(joints) > index + 1:  # its columns would come before those of joints written before it
                    raise self.fail(f"joint {name!r} has its CHANNELS after its child joint "
                                    f"{joints[index + 1].name!r}: they must come before", line)
                count_word, count_line = self.next()
                count = whole_number(count_word, 6)
                if not count:
                    raise self.fail(f"CHANNELS count must be 1 to 6, got {count_word[:20]!r}", count_line)
                names = [self.next() for _ in range(count)]
                bad = [(w, n) for w, n in names if w.lower() not in _CHANNEL_NAMES]
                if bad:
                    raise self.fail(f"unknown channel {bad[0][0][:30]!r} (expected {', '.join(CHANNELS)})", bad[0][1])
                channels = tuple(_CHANNEL_NAMES[w.lower()] for w, _ in names)
                if len(set(channels)) != len(channels):
                    raise self.fail(f"joint {name!r} names a channel twice", line)
                joints[index] = BvhJoint(name, parent, offset, channels)
            elif key == "JOINT":
                self.joint(joints, index, depth + 1)
            elif key == "END":
                self.next("Site")
                self.next("{")
                self.next("OFFSET")
                if end_site is not None:
                    raise self.fail(f"joint {name!r} has a second End Site", line)
                end_site = self.numbers(3, "End Site OFFSET")
                self.next("}")
            elif key == "}":
                joints[index] = BvhJoint(name, parent, offset, channels, end_site)
                return
            else:
                raise self.fail(f"unexpected {word[:40]!r} in joint {name!r} (expected CHANNELS, JOINT, "
                                "End Site or '}')", line)

    def numbers(self, count: int, what: str) -> np.ndarray:
        values = []
        for _ in range(count):
            word, line = self.next()
            values.append(number(word, self.path, line, what=what))
        return np.array(values)

    def motion_header(self) -> tuple[int, float, int, int]:
        """(frames, frame time, offset of the first frame in the text, its line)."""
        self.check_line_ends(self.motion_line + 2)
        lines = _lines_with_ends(self.text, self.motion_line + 2)
        ends = list(itertools.accumulate(len(line) for line in lines[self.motion_line - 1 :]))
        if ends[-1] > MAX_MOTION_CHARS:
            raise self.fail(f"the lines MOTION, Frames: and Frame Time: take more than the {MAX_MOTION_CHARS:,} "
                            "characters they may", self.motion_line + next(k for k, end in enumerate(ends)
                                                                           if end > MAX_MOTION_CHARS))
        frames, frame_time = _motion_numbers(lines[self.motion_line :], self.motion_line + 1, self.path)
        return frames, frame_time, sum(len(line) for line in lines), self.motion_line + 3


def _keyword(word: str) -> str:
    """`word` as a keyword is compared: in upper case if ASCII (`str.upper` makes `JOıNT` JOINT)."""
    return word.upper() if word.isascii() else word


def _frame_values(frames: bytes, frames_text: str, n_frames: int, width: int, path: str | None,
                  first_line: int) -> tuple[np.ndarray, list[str] | Callable[[int], str]]:
    """The (frames, width) values of the frame lines, each line checked to hold `width` numbers
    (MocapFormatError naming the first line that does not), and line f's text (without its end)
    as `lines[f]` or `lines(f)`.

    The usual file is read in one compiled pass over its bytes (`bvh_compiled.scan_lines`); any
    other, word by word, which names the word or line at fault."""
    body = np.frombuffer(frames, dtype=np.uint8)
    ok, values, starts = scan_lines(body, n_frames, width, MAX_ABS_VALUE)
    if ok:
        def line(f: int) -> str:
            if f + 1 < n_frames:
                return frames[starts[f] : starts[f + 1]].rstrip(b"\r\n").decode("ascii")
            rest = frames[starts[f] :]
            return rest[: min((i for i in (rest.find(b"\n"), rest.find(b"\r")) if i >= 0), default=len(rest))].decode(
                "ascii")

        left = np.argwhere(np.isnan(values))  # (frame, column) of the numbers the compiled pass left to float()
        for f in np.unique(left[:, 0]).tolist():
            words = line(f).split()
            for k in np.flatnonzero(np.isnan(values[f])).tolist():
                values[f, k] = number(words[k], path, first_line + f)
        return values, line
    lines = frames_text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    while lines and not lines[-1].strip():  # blank lines after the last frame (and the final line end)
        lines.pop()
    if len(lines) != n_frames:
        raise MocapFormatError(f"Frames: says {n_frames}, but {len(lines)} frame lines follow", path, first_line - 2)
    words = [line.split() for line in lines]
    short = next((f for f, line in enumerate(words) if len(line) != width), None)
    if short is not None:
        raise MocapFormatError(f"frame {short + 1} has {len(words[short])} values, the hierarchy's channels need "
                               f"{width}", path, first_line + short)
    for f, line in enumerate(words):  # the words at fault, or those the compiled pass leaves to float()
        for k, word in enumerate(line):
            values[f, k] = number(word, path, first_line + f)
    return values, lines


def _style_of(frames_text: str, n_lines: int, line: Callable[[int], str], values: np.ndarray) -> BvhStyle:
    """The style that writes a sample of the frame lines (up to 16, spread over the clip; `line(f)`
    is line f's text) back from their values, tried in NUMBER_STYLES order; where none does,
    Python's repr, which keeps every value exactly. It is how values changed in code are written."""
    if not n_lines:
        return BvhStyle()
    body = line(0)
    after = frames_text[len(body) : len(body) + 2]
    line_end = "\r\n" if after.startswith("\r\n") else after[:1] if after[:1] in ("\r", "\n") else "\n"
    trailing = body[len(body.rstrip(" \t")):]
    separator = "\t" if "\t" in body.strip() and " " not in body.strip() else " "
    last = line(n_lines - 1)
    tail = frames_text[frames_text.rfind(last) + len(last) :] if last else ""  # the last line's end, and after
    final = tail.startswith(line_end)
    ends = {"final_line_end": final, "after": tail[len(line_end) :] if final else tail}
    sample = sorted({round(k * (n_lines - 1) / 15) for k in range(16)})
    for style in NUMBER_STYLES:
        candidate = BvhStyle(style, separator, trailing, line_end)
        if all(candidate.format(values[f : f + 1]).rstrip("\r\n") == line(f) for f in sample):
            return BvhStyle(style, separator, trailing, line_end, **ends)
    return BvhStyle("repr", separator, trailing, line_end, **ends)


def _canonical_header(bvh: Bvh) -> str:
    """HIERARCHY and the MOTION lines of a Bvh built in code: tabs, LF, numbers as `repr`."""
    out = ["HIERARCHY"]
    children: dict[int, list[int]] = {}
    for j, joint in enumerate(bvh.joints):
        children.setdefault(joint.parent, []).append(j)

    def numbers(values) -> str:
        return " ".join(repr(float(v)) for v in values)

    def write(j: int, depth: int) -> None:
        joint, pad = bvh.joints[j], "\t" * depth
        out.append(f"{pad}{'ROOT' if joint.parent < 0 else 'JOINT'} {joint.name}")
        out.append(f"{pad}{{")
        out.append(f"{pad}\tOFFSET {numbers(joint.offset)}")
        if joint.channels:
            out.append(f"{pad}\tCHANNELS {len(joint.channels)} {' '.join(joint.channels)}")
        for child in children.get(j, []):
            write(child, depth + 1)
        if joint.end_site is not None:
            out.extend([f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET {numbers(joint.end_site)}", f"{pad}\t}}"])
        out.append(f"{pad}}}")

    for root in children.get(-1, []):
        write(root, 0)
    out.extend(["MOTION", f"Frames: {bvh.n_frames}", f"Frame Time: {bvh.frame_time!r}"])
    return "\n".join(out) + "\n"
