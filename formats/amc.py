"""Acclaim Motion Capture (AMC): read and write.

A `Motion` holds one clip as a float64 matrix (frames x channels). Columns follow the bone
order of the file's first frame, each bone contributing its values in the order its line
carries them, so a written file keeps the source's layout.

Reading has two paths that accept exactly the same files and give the same numbers:

* a fast path for the usual layout (every frame lists the first frame's bones in the same
  order, one bone per line): one compiled pass over the frames checks the layout and
  converts every value (`amc_compiled.scan_frames`), no Python loop per value or per line;
* an exact line-by-line path for everything else (bones in varying order, comments or blank
  lines between frames, a truncated last frame) and for damaged files, where it names the
  file, line and fault in a `MocapFormatError`.

Rules (both paths): header lines before the first frame are `#` comments, `:KEYWORDS` or
blank; a frame is a line holding only its number, then one line per bone (name, values);
frame numbers may start anywhere but must go up by one; every frame lists the same bones
with the same number of values; values follow the grammar in `text` and lie within
+-`text.MAX_ABS_VALUE` (1e9). A truncated LAST frame (a copy cut short, e.g. cmu/64/golf_01.amc)
is dropped with a warning and counted in `Motion.dropped_frames` (or, with
`partial_last_frame="error"`, refused: lossless compression cannot keep it); a truncated frame
anywhere else is an error.

Size limits (`mocapzip.limits`) are checked before the work they bound: a file larger than
`MAX_AMC_BYTES` is refused before it is read, values per frame when the first frame is read,
and frames and frames x values before more values than they allow are converted. With a
skeleton, the angles of a clip in radians must lie within `MAX_RADIANS` (see `_check_angles`).

Writing remembers how the source wrote its numbers and lines (`AmcStyle`): CMU files are
written back with 6 significant digits and 3-digit exponents, Vicon Blade files with 6 fixed
decimals, so values come back without loss; every file of the shared data set except the
truncated golf_01.amc comes back byte for byte (line ends, header and spacing included).
Numbers are written in compiled code (`amc_compiled.format_frames`), exactly as Python's `%`
operator writes them, a block of frames at a time (`amc_blocks`).
"""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from mocapzip.limits import MAX_FRAMES_PER_CLIP, MAX_VALUES_PER_CLIP, MAX_VALUES_PER_FRAME
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.text import (
    MAX_ABS_VALUE,
    NUMBER,
    VALUES_PER_BLOCK,
    WHITESPACE,
    check_text,
    detect_encoding,
    number,
    open_regular_file,
    stated_frame_rate,
    whole_number,
)
from mocapzip.formats.amc_compiled import LAYOUT_OK, format_frames, scan_frames
from mocapzip.formats.numbers_compiled import (
    STAT_ALL_DOT,
    STAT_ANY_EXP,
    STAT_COUNT,
    STAT_FIRST_DECIMALS,
    STAT_MAX_SIG,
    STAT_MIN_EXP_DIGITS,
    STAT_SAME_DECIMALS,
    scan_tokens,
    with_numbers,
)

__all__ = ["AmcStyle", "Motion", "read_amc", "parse_amc", "format_amc", "amc_blocks", "write_amc"]

_MAX_FAST_BONES = 255  # first frames with more bones take the exact path
MAX_FRAME_NUMBER = 10**9  # larger frame numbers are refused (a day at 10 kHz is below 1e9)
BYTES_PER_VALUE = 16  # shared files take at most 13.7 (Vicon Blade's 6 decimals; CMU 9), names and frame lines included
MAX_AMC_BYTES = BYTES_PER_VALUE * MAX_VALUES_PER_CLIP  # 128 MiB: larger files are refused unread
MAX_RADIANS = 100 * np.pi  # 50 turns; the largest angle of the shared (degree) files is 2,070 deg, 36 rad


@dataclass(frozen=True)
class AmcStyle:
    """How an AMC file writes its numbers and lines; `read_amc` detects it, `format_amc` uses it.

    The defaults are CMU's conventions with portable line ends: 6 significant digits, LF.
    """

    notation: str = "g"  # 'g': significant digits (CMU, HDM05); 'f': fixed decimals (Vicon Blade)
    digits: int = 6  # significant digits ('g') or decimals ('f')
    exponent_digits: int = 2  # minimum exponent width; CMU (Windows printf) writes e-015: 3
    name_separator: str = " "  # between a bone name and its first value (Blade: two spaces)
    newline: str = "\n"  # line end of the bone lines ('\r\n' for CRLF files), default for all lines
    header_newline: str | None = None  # line end of the header lines, when it differs
    frame_newline: str | None = None  # line end of the frame-number lines, when it differs (HDM05: LF)
    final_newline: bool = True  # whether the last line ends with a newline
    encoding: str = "utf-8"  # of header comments: 'latin-1' when the source was not UTF-8

    def __post_init__(self):
        if self.notation not in ("g", "f"):
            raise ValueError(f"AmcStyle.notation must be 'g' or 'f', got {self.notation!r}")
        if not (1 if self.notation == "g" else 0) <= int(self.digits) <= 40:
            raise ValueError(f"AmcStyle.digits out of range: {self.digits!r}")
        if self.exponent_digits < 1:
            raise ValueError(f"AmcStyle.exponent_digits must be >= 1, got {self.exponent_digits!r}")
        if not self.name_separator or self.name_separator.strip(" \t"):
            raise ValueError(f"AmcStyle.name_separator must be spaces or tabs, got {self.name_separator!r}")
        for nl in (self.newline, self.header_newline, self.frame_newline):
            if nl is not None and nl not in ("\n", "\r\n", "\r"):
                raise ValueError(f"AmcStyle newline must be LF, CRLF or CR, got {nl!r}")

    @property
    def number_format(self) -> str:
        """The printf format of one value, e.g. '%.6g' or '%.6f'."""
        return f"%.{int(self.digits)}{self.notation}"

    def to_dict(self) -> dict:
        """JSON-ready form (for archives that want byte-identical AMC files back)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "AmcStyle":
        known = {k: data[k] for k in cls.__dataclass_fields__ if k in data}
        return cls(**known)


@dataclass
class Motion:
    """One AMC clip."""

    bones: list[str]  # bone order of the file's frames
    counts: list[int]  # values per bone, same order
    values: np.ndarray  # (frames, sum(counts)) float64
    frame_numbers: np.ndarray  # (frames,) int64, as numbered in the file (consecutive)
    header: list[str] = field(default_factory=list)  # lines before the first frame, verbatim (no line ends)
    path: str | None = None
    style: AmcStyle = field(default_factory=AmcStyle)  # number and line style of the source file
    dropped_frames: int = 0  # incomplete frames left out at the end of the file (a copy cut short)

    @property
    def n_frames(self) -> int:
        return int(self.values.shape[0])

    @property
    def frame_rate(self) -> float | None:
        """The frame rate the header states (Vicon Blade: `# Frame Rate: 200.000 fps`), else None."""
        return stated_frame_rate(self.header)

    @property
    def angle_unit(self) -> str:
        """'rad' when the header says :RADIANS, else 'deg' (the Acclaim default)."""
        return "rad" if any(h.strip().upper() == ":RADIANS" for h in self.header) else "deg"

    def columns(self) -> dict[str, slice]:
        """Bone name -> slice of its columns in `values`."""
        starts = np.concatenate([[0], np.cumsum(self.counts)]).astype(int)
        return {b: slice(int(starts[i]), int(starts[i + 1])) for i, b in enumerate(self.bones)}


# --------------------------------------------------------------------------- reading


def read_amc(path: str | os.PathLike, skeleton=None, *, partial_last_frame: str = "drop") -> Motion:
    """Parse an AMC file; with `skeleton` (a Skeleton), also check bone names, value counts and
    angles. `partial_last_frame`: "drop" an incomplete last frame with a warning (counted in
    `Motion.dropped_frames`) or refuse the file ("error"), for callers that must keep every byte."""
    path = os.fspath(path)
    with open_regular_file(path) as fh:
        _check_size(os.fstat(fh.fileno()).st_size, path)
        data = fh.read(MAX_AMC_BYTES + 1)  # the file may have grown since
    return _parse(data, path, skeleton, partial_last_frame, stacklevel=4)


def parse_amc(data: bytes, path: str | None = None, skeleton=None, *, partial_last_frame: str = "drop") -> Motion:
    """Parse AMC bytes (`path` only names the source in messages and in `Motion.path`); see `read_amc`."""
    return _parse(data, path, skeleton, partial_last_frame, stacklevel=4)


def _parse(data, path, skeleton, partial_last_frame: str, stacklevel: int) -> Motion:
    if partial_last_frame not in ("drop", "error"):
        raise ValueError(f"partial_last_frame must be 'drop' or 'error', got {partial_last_frame!r}")
    if isinstance(data, str):
        data = data.encode("utf-8")
    _check_size(len(data), path)
    data = check_text(data, path)
    encoding = "utf-8" if data.isascii() else detect_encoding(data)
    parsed = _parse_fast(data, path, encoding)
    if parsed is None:
        motion, first_lines = _parse_exact(data, path, encoding, skeleton, partial_last_frame, stacklevel)
    else:
        motion, first_lines = parsed
        if skeleton is not None:
            _check_against_skeleton(motion.bones, motion.counts, first_lines, skeleton, path)
    if skeleton is not None:
        _check_angles(motion, skeleton, path)
    return motion


def _check_size(n_bytes: int, path) -> None:
    """Refuse a file too large to hold a clip within the limits, before reading or parsing it."""
    if n_bytes > MAX_AMC_BYTES:
        raise MocapFormatError(
            f"file of {n_bytes:,} bytes is larger than the {MAX_AMC_BYTES:,} bytes an AMC file may have "
            f"({BYTES_PER_VALUE} bytes for each of the {MAX_VALUES_PER_CLIP:,} values a clip may hold)", path
        )


def _frames_allowed(n_values: int) -> int:
    """How many frames of `n_values` values a clip may have (MAX_FRAMES_PER_CLIP, MAX_VALUES_PER_CLIP)."""
    return min(MAX_FRAMES_PER_CLIP, MAX_VALUES_PER_CLIP // n_values) if n_values else MAX_FRAMES_PER_CLIP


def _too_many_frames(n_values: int, frame_number: int, path, line: int) -> MocapFormatError:
    """The error for frame `frame_number`, the first beyond `_frames_allowed(n_values)`."""
    if _frames_allowed(n_values) == MAX_FRAMES_PER_CLIP:
        limit = f"more than the {MAX_FRAMES_PER_CLIP:,} frames a clip may have"
    else:
        limit = f"more than the {MAX_VALUES_PER_CLIP:,} values a clip may have ({n_values} per frame)"
    return MocapFormatError(f"frame {frame_number} makes the clip too long: {limit}", path, line)


def _is_frame_line(stripped: bytes) -> bool:
    return stripped.isdigit()


def _parse_fast(data: bytes, path, encoding):
    """The usual layout, vectorised; None when the file needs the exact path (or is damaged)."""
    # Header: '#', ':' and blank lines up to the first frame number.
    header: list[str] = []
    header_newline = None
    pos = 0
    while True:
        end = data.find(b"\n", pos)
        raw = data[pos:] if end < 0 else data[pos:end]
        if raw.endswith(b"\r"):
            raw = raw[:-1]
        stripped = raw.strip(WHITESPACE)
        if _is_frame_line(stripped):
            break
        if (stripped and stripped[:1] not in (b"#", b":")) or b"\r" in raw or end < 0:
            return None
        header.append(raw.decode(encoding))
        if header_newline is None:
            header_newline = "\r\n" if data[end - 1 : end] == b"\r" else "\n"
        pos = end + 1
    if not raw[:1].isdigit():
        return None  # indented frame number
    body = data[pos:]
    final_newline = body.endswith(b"\n")
    body = body.rstrip(WHITESPACE)

    # First frame, in Python: bone names, value counts, line style.
    lines = body.split(b"\n", _MAX_FAST_BONES + 1)
    frame_newline = "\r\n" if lines[0].endswith(b"\r") else "\n"
    newline = "\r\n" if len(lines) > 1 and lines[1].endswith(b"\r") else frame_newline
    bones: list[str] = []
    counts: list[int] = []
    name_bytes: list[bytes] = []
    separator = None
    for raw in lines[1 : _MAX_FAST_BONES + 1]:
        words = raw.split()
        if len(words) == 1 and _is_frame_line(words[0]):
            break
        if not words or raw[:1] in WHITESPACE or NUMBER.match(words[0]) or words[0][:1] == b"#":
            return None
        if words[0] in name_bytes:
            return None
        name_bytes.append(words[0])
        bones.append(words[0].decode(encoding))
        counts.append(len(words) - 1)
        if separator is None and len(words) > 1:
            separator = raw[len(words[0]) : raw.index(words[1], len(words[0]))].decode("ascii", "replace")
    else:
        if len(lines) > _MAX_FAST_BONES + 1:
            return None  # a first frame of more than _MAX_FAST_BONES bones: exact path
    n_bones = len(bones)
    n_values = sum(counts)
    if n_bones == 0 or n_values > MAX_VALUES_PER_FRAME:
        return None  # the exact path names the fault

    # The rest of the body, compiled: layout, frame numbers, bone names and values.
    allowed = _frames_allowed(n_values)
    verdict, first, n_frames, values, faults, left, stats = scan_frames(
        np.frombuffer(body, np.uint8),
        np.frombuffer(b"".join(name_bytes), np.uint8),
        np.cumsum([len(name) for name in name_bytes], dtype=np.int64),
        np.array(counts, np.int64),
        allowed,
        MAX_FRAME_NUMBER,
        MAX_ABS_VALUE,
    )
    if verdict != LAYOUT_OK:
        return None
    if n_frames > allowed:
        raise _too_many_frames(n_values, first + allowed, path, len(header) + 1 + allowed * (1 + n_bones))
    if faults:
        return None
    if left:  # long numbers, left to float()
        words = body.split()
        width = 1 + n_bones + n_values
        value_words = np.setdiff1d(np.arange(1, width), np.cumsum([1] + [c + 1 for c in counts[:-1]]))
        for i in np.flatnonzero(np.isnan(values)):
            frame, column = divmod(int(i), n_values)
            try:
                values.flat[i] = number(words[frame * width + value_words[column]], path, None)
            except MocapFormatError:
                return None
    frame_numbers = np.arange(first, first + n_frames, dtype=np.int64)

    style = AmcStyle(
        **_number_style(stats),
        name_separator=_separator(separator),
        newline=newline,
        header_newline=header_newline if header_newline not in (None, newline) else None,
        frame_newline=frame_newline if frame_newline != newline else None,
        final_newline=final_newline,
        encoding=encoding,
    )
    first_lines = {b: len(header) + 2 + i for i, b in enumerate(bones)}
    return Motion(bones, counts, values, frame_numbers, header, path, style), first_lines


def _separator(text: str | None) -> str:
    return text if text and not text.strip(" \t") else " "


def _number_style(stats) -> dict:
    """notation, digits and exponent width that write every value counted in `stats` (from
    `numbers_compiled`) back unchanged."""
    if stats[STAT_COUNT] == 0:
        return {}
    max_sig = int(stats[STAT_MAX_SIG])
    decimals = int(stats[STAT_FIRST_DECIMALS])
    if stats[STAT_ALL_DOT] and not stats[STAT_ANY_EXP] and stats[STAT_SAME_DECIMALS] and max_sig <= 15 and decimals <= 17:
        return {"notation": "f", "digits": decimals}
    digits = max(6, max_sig) if max_sig <= 15 else 17
    exponent_digits = 3 if stats[STAT_ANY_EXP] and stats[STAT_MIN_EXP_DIGITS] >= 3 else 2
    return {"notation": "g", "digits": digits, "exponent_digits": exponent_digits}


def _parse_exact(data: bytes, path, encoding, skeleton=None, partial_last_frame: str = "drop", stacklevel: int = 2):
    """Line by line: any valid layout, and the first fault of a damaged file with its line."""
    parts = re.split(rb"(\r\n|\r|\n)", data)
    lines = parts[0::2]
    endings = parts[1::2]
    n_lines = len(lines)
    last_content = n_lines - 1
    while last_content >= 0 and not lines[last_content].strip(WHITESPACE):
        last_content -= 1

    header: list[str] = []
    i = 0
    while i < n_lines:
        stripped = lines[i].strip(WHITESPACE)
        if _is_frame_line(stripped):
            break
        if stripped and stripped[:1] not in (b"#", b":"):
            raise MocapFormatError(
                f"expected a frame number, got {_show(stripped)}"
                + (" (a bone line before the first frame number)" if not NUMBER.match(stripped.split()[0]) else ""),
                path,
                i + 1,
            )
        header.append(lines[i].decode(encoding))
        i += 1
    if i >= n_lines:
        raise MocapFormatError("no frames: the file has header lines only", path, last_content + 1)
    first_frame_line = i
    header_newline = endings[0].decode() if header and endings else None
    frame_newline = endings[i].decode() if i < len(endings) else "\n"
    newline = next((endings[k].decode() for k in range(i + 1, len(endings)) if lines[k].strip(WHITESPACE)), frame_newline)

    bones: list[str] | None = None
    column: dict[bytes, int] = {}
    counts: list[int] = []
    first_lines: dict[str, int] = {}
    separator = None
    frame_numbers: list[int] = []
    frame_rows: list[list] = []  # per frame: per bone (in column order) its value words
    frame_linenos: list[list] = []
    current: dict[bytes, tuple[int, list[bytes]]] = {}
    current_number = current_line = None
    truncated_at = None
    allowed = 0  # frames the clip may have, once the first frame gives the values per frame

    def close_frame(next_line: int | None) -> None:
        nonlocal bones, counts, allowed
        if current_number is None:
            return
        if bones is None:
            if not current:
                raise MocapFormatError(f"frame {current_number} has no bone lines", path, current_line)
            order = list(current)
            bones = [b.decode(encoding) for b in order]
            counts = [len(current[b][1]) for b in order]
            column.update({b: k for k, b in enumerate(order)})
            first_lines.update({bones[k]: current[b][0] for k, b in enumerate(order)})
            if skeleton is not None:
                _check_against_skeleton(bones, counts, first_lines, skeleton, path)
            if sum(counts) > MAX_VALUES_PER_FRAME:
                raise MocapFormatError(f"frame {current_number} has {sum(counts):,} values, more than the "
                                       f"{MAX_VALUES_PER_FRAME:,} a frame may have", path, current_line)
            allowed = _frames_allowed(sum(counts))
        elif len(current) != len(column):
            missing = [b.decode(encoding) for b in column if b not in current]
            shown = ", ".join(repr(m) for m in missing[:5]) + (", ..." if len(missing) > 5 else "")
            if next_line is None:
                return  # the caller decides about a truncated last frame
            raise MocapFormatError(
                f"truncated frame {current_number}: {len(current)} of {len(column)} bones, "
                f"missing {shown} (frame starts at line {current_line})",
                path,
                next_line,
            )
        rows, linenos = [], []
        for b in column:
            lineno, words = current[b]
            rows.append(words)
            linenos.append(lineno)
        if len(frame_numbers) == allowed:
            raise _too_many_frames(sum(counts), current_number, path, current_line)
        frame_rows.append(rows)
        frame_linenos.append(linenos)
        frame_numbers.append(current_number)

    for i in range(first_frame_line, n_lines):
        words = lines[i].split()
        lineno = i + 1
        if not words or words[0][:1] == b"#":
            continue
        if len(words) == 1 and _is_frame_line(words[0]):
            close_frame(lineno)
            number_ = whole_number(words[0], MAX_FRAME_NUMBER)
            if number_ is None:
                raise MocapFormatError(
                    f"frame number {_show(words[0])[1:-1]} is out of range (> {MAX_FRAME_NUMBER})", path, lineno
                )
            if frame_numbers:
                previous = frame_numbers[-1]
                if number_ == previous:
                    raise MocapFormatError(f"duplicate frame number {number_}", path, lineno)
                if number_ < previous:
                    raise MocapFormatError(f"frame number {number_} out of order (after {previous})", path, lineno)
                if number_ != previous + 1:
                    raise MocapFormatError(
                        f"frame numbers jump from {previous} to {number_} (frames must be consecutive)",
                        path,
                        lineno,
                    )
            current, current_number, current_line = {}, number_, lineno
            continue
        name = words[0]
        if NUMBER.match(name):
            raise MocapFormatError(f"expected a bone name or a frame number, got {_show(lines[i].strip())}", path, lineno)
        if name in current:
            raise MocapFormatError(
                f"bone '{name.decode(encoding)}' appears twice in frame {current_number} "
                f"(first at line {current[name][0]})",
                path,
                lineno,
            )
        values = words[1:]
        if bones is not None:
            k = column.get(name)
            if k is None:
                raise MocapFormatError(
                    f"bone '{name.decode(encoding)}' is not among the first frame's bones", path, lineno
                )
            if len(values) != counts[k]:
                if i == last_content and frame_numbers:
                    truncated_at = lineno  # the file was cut inside this line
                    break
                raise MocapFormatError(
                    f"bone '{name.decode(encoding)}' has {len(values)} values, expected {counts[k]}", path, lineno
                )
        elif separator is None and values:
            raw = lines[i]
            separator = raw[len(name) : raw.index(values[0], len(name))].decode("ascii", "replace")
        current[name] = (lineno, values)

    dropped = 0
    if bones is not None and current_number is not None and (truncated_at is not None or len(current) != len(column)):
        incomplete = (f"last frame {current_number} is incomplete ({len(current)} of {len(column)} bones, "
                      f"the file ends at line {truncated_at or last_content + 1})")
        if partial_last_frame == "error":
            raise MocapFormatError(f"{incomplete}: --lossless cannot keep a partial frame", path, current_line)
        warnings.warn(f"{path}:{current_line}: {incomplete}; dropped", stacklevel=stacklevel)
        current_number, dropped = None, 1
    close_frame(None)
    if bones is None:  # only possible when the single frame had no bones
        raise MocapFormatError(f"frame {current_number} has no bone lines", path, current_line)

    n_frames = len(frame_rows)
    counts_arr = np.array(counts, dtype=np.int64)
    tokens = [w for rows in frame_rows for words in rows for w in words]
    token_lines = np.repeat(np.array(frame_linenos, dtype=np.int64).reshape(-1), np.tile(counts_arr, n_frames))
    values, stats = scan_tokens(np.frombuffer(b" ".join(tokens), np.uint8), len(tokens))
    for k in np.flatnonzero(np.isnan(values)):  # invalid, or left to float()
        values[k] = number(tokens[k], path, int(token_lines[k]))
    bad = np.flatnonzero(~(np.abs(values) <= MAX_ABS_VALUE))
    if bad.size:
        k = int(bad[0])
        number(tokens[k], path, int(token_lines[k]))  # raises with the reason

    last_ending = data[-1:]
    style = AmcStyle(
        **_number_style(stats),
        name_separator=_separator(separator),
        newline=newline,
        header_newline=header_newline if header_newline not in (None, newline) else None,
        frame_newline=frame_newline if frame_newline != newline else None,
        final_newline=last_ending in (b"\n", b"\r"),
        encoding=encoding,
    )
    values = values.reshape(n_frames, int(counts_arr.sum()))
    motion = Motion(bones, counts, values, np.array(frame_numbers, dtype=np.int64), header, path, style, dropped)
    return motion, first_lines


def _show(raw: bytes) -> str:
    text = raw[:40].decode("latin-1")
    return repr(text + ("..." if len(raw) > 40 else ""))


def _check_against_skeleton(bones, counts, first_lines: dict, skeleton, path) -> None:
    where = f" {skeleton.path}" if getattr(skeleton, "path", None) else ""
    dofs = skeleton.dof_map()
    for name, count in zip(bones, counts):
        dof = dofs.get(name)
        if dof is None:
            raise MocapFormatError(f"bone '{name}' is not in the skeleton{where}", path, first_lines.get(name))
        if count != len(dof):
            raise MocapFormatError(
                f"bone '{name}' has {count} values, the skeleton{where} gives it {len(dof)} dof ({' '.join(dof) or 'none'})",
                path,
                first_lines.get(name),
            )


def _check_angles(motion: Motion, skeleton, path) -> None:
    """Refuse a clip in radians holding an angle beyond MAX_RADIANS.

    No joint turns 50 times: such values are degrees under a wrong ':RADIANS' header (or ASF
    'angle rad'), and read as radians they make a random pose of each frame. The unit is
    decided as `SkeletonModel.layout` decides it: the AMC header first, then the skeleton.
    """
    header = [line.strip().upper() for line in motion.header]
    if ":RADIANS" in header:
        line, declared = header.index(":RADIANS") + 1, "this ':RADIANS' line declares"
    elif ":DEGREES" not in header and skeleton.angle_unit == "rad":
        where = f" {skeleton.path}" if skeleton.path else ""
        line, declared = None, f"the skeleton{where} declares ('angle rad')"
    else:
        return
    dofs = skeleton.dof_map()
    rotations = np.array([d.startswith("r") for bone in motion.bones for d in dofs[bone]], dtype=bool)
    beyond = (np.abs(motion.values) > MAX_RADIANS) & rotations
    if beyond.any():
        frame, column = divmod(int(np.argmax(beyond)), beyond.shape[1])
        bone = motion.bones[int(np.searchsorted(np.cumsum(motion.counts), column, side="right"))]
        raise MocapFormatError(
            f"angle {motion.values[frame, column]:g} of bone '{bone}' in frame {motion.frame_numbers[frame]} is beyond "
            f"{MAX_RADIANS:.4g} rad (50 turns): the values look like degrees, not the radians {declared}",
            path,
            line,
        )


# --------------------------------------------------------------------------- writing

def format_amc(motion: Motion, digits: int | None = None, *, style: AmcStyle | None = None) -> str:
    """AMC text of `motion`: header lines, then every frame in the source's bone order.

    Numbers and line ends follow `style` (default: `motion.style`, what `read_amc` detected, so a
    file read and written again keeps its precision). `digits` overrides with that many
    significant digits (`%.<digits>g`). The text is exactly what Python's `%` operator gives
    (`amc_compiled.format_frames` writes it; the numbers it leaves are formatted here).
    """
    return "".join(amc_blocks(motion, digits, style=style))


def amc_blocks(motion: Motion, digits: int | None = None, *, style: AmcStyle | None = None) -> Iterator[str]:
    """`format_amc`'s text in pieces: the header, then blocks of whole frames of at most
    `VALUES_PER_BLOCK` values. A writer that writes each piece, or drops it, never holds a long
    clip's text whole: at the size limits made at once, it took 330 MB more than the values."""
    style = style or getattr(motion, "style", None) or AmcStyle()
    if digits is not None:
        style = replace(style, notation="g", digits=int(digits))
    values = np.ascontiguousarray(motion.values, dtype=np.float64)
    frames = np.asarray(motion.frame_numbers)
    n_frames = values.shape[0] if values.ndim == 2 else -1
    if values.ndim != 2 or values.shape[1] != sum(motion.counts) or frames.shape != (n_frames,):
        raise ValueError(
            f"inconsistent Motion: values {values.shape}, counts sum {sum(motion.counts)}, "
            f"frame_numbers {frames.shape}"
        )
    if len(motion.bones) != len(motion.counts):
        raise ValueError(f"inconsistent Motion: {len(motion.bones)} bones but {len(motion.counts)} counts")
    if not np.all(np.isfinite(values)):
        raise ValueError("cannot write non-finite values to an AMC file")

    nl = style.newline
    names = [_widen_exponents(bone, style).encode("utf-8", "surrogatepass") for bone in motion.bones]
    tables = (np.frombuffer(b"".join(names), np.uint8), np.cumsum([len(name) for name in names], dtype=np.int64),
              np.array(motion.counts, dtype=np.int64), np.frombuffer(style.name_separator.encode(), np.uint8),
              np.frombuffer(nl.encode(), np.uint8), np.frombuffer((style.frame_newline or nl).encode(), np.uint8),
              style.notation == "f", int(style.digits), max(2, style.exponent_digits))
    frames = frames.astype(np.float64)  # '%d' of a float64, as frame numbers were always written
    per_block = max(1, VALUES_PER_BLOCK // max(values.shape[1], 1))
    text = "".join(line + (style.header_newline or nl) for line in motion.header)
    for first in range(0, n_frames, per_block):
        yield text
        text = _frame_lines(values[first : first + per_block], frames[first : first + per_block], tables, style)
    yield text if style.final_newline else text.removesuffix(nl)


def _frame_lines(values: np.ndarray, frames: np.ndarray, tables: tuple, style: AmcStyle) -> str:
    """The lines of these frames (`amc_blocks`' `tables`: the bone names and the style as arrays)."""
    text, hard = format_frames(values, frames, *tables)
    per_row = values.shape[1] + 1

    def number(item: int) -> str:  # a number format_frames left, as Python's % writes it
        row, column = divmod(item, per_row)
        text = "%d" % float(frames[row]) if column == 0 else style.number_format % float(values[row, column - 1])
        return _widen_exponents(text, style)

    return with_numbers(text.tobytes(), hard, number).decode("utf-8", "surrogatepass")


_EXPONENT = re.compile(r"(?<=[0-9.])e([+-])([0-9]+)(?![0-9])")


def _widen_exponents(text: str, style: AmcStyle) -> str:
    """'1e-05' -> '1e-005' (exponent_digits 3), as the Windows C library writes them. Bone
    names that look like exponents are widened too, as they always were."""
    if style.notation != "g" or style.exponent_digits == 2:
        return text
    return _EXPONENT.sub(lambda m: f"e{m[1]}{m[2].zfill(style.exponent_digits)}", text)


def write_amc(motion: Motion, path: str | os.PathLike, digits: int | None = None, *, style: AmcStyle | None = None) -> None:
    """Write `motion` as an AMC file (see `format_amc`)."""
    chosen = style or getattr(motion, "style", None) or AmcStyle()
    text = format_amc(motion, digits, style=chosen)
    try:
        data = text.encode(chosen.encoding)
    except (UnicodeEncodeError, LookupError):
        data = text.encode("utf-8")
    with open(path, "wb") as fh:
        fh.write(data)
