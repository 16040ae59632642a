"""Acclaim Motion Capture (AMC): read and write.

A `Motion` holds one clip as a float64 matrix (frames x channels). Columns follow
the bone order of the file's first frame, each bone contributing its values in
the order its line carries them, so a written file keeps the source's layout.
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass, field

import numpy as np

from .errors import MocapFormatError
from .text import decode_text

_FRAME_NUMBER = re.compile(r"^\s*(\d+)\s*$")


@dataclass
class Motion:
    """One AMC clip."""

    bones: list[str]  # bone order of the file's frames
    counts: list[int]  # values per bone, same order
    values: np.ndarray  # (frames, sum(counts)) float64
    frame_numbers: np.ndarray  # (frames,) int64, as numbered in the file
    header: list[str] = field(default_factory=list)  # lines before the first frame, verbatim
    path: str | None = None

    @property
    def n_frames(self) -> int:
        return int(self.values.shape[0])

    @property
    def angle_unit(self) -> str:
        """'rad' when the header says :RADIANS, else 'deg' (the Acclaim default)."""
        return "rad" if any(h.strip().upper() == ":RADIANS" for h in self.header) else "deg"

    def columns(self) -> dict[str, slice]:
        """Bone name -> slice of its columns in `values`."""
        starts = np.concatenate([[0], np.cumsum(self.counts)])
        return {b: slice(int(starts[i]), int(starts[i + 1])) for i, b in enumerate(self.bones)}


def read_amc(path: str | os.PathLike, skeleton=None) -> Motion:
    """Parse an AMC file; with `skeleton`, also check bone names and value counts against it."""
    path = os.fspath(path)
    with open(path, "rb") as fh:
        data = fh.read()
    return parse_amc(data, path, skeleton)


def parse_amc(data: bytes, path: str | None = None, skeleton=None) -> Motion:
    lines = decode_text(data, path).splitlines()
    first = _first_frame_line(lines, path)
    header = [line.rstrip() for line in lines[:first] if line.strip()]
    body = lines[first:]
    # Drop blank lines but keep file line numbers for messages.
    numbered = [(first + 1 + i, line) for i, line in enumerate(body) if line.strip()]
    linenos = np.fromiter((n for n, _ in numbered), dtype=np.int64, count=len(numbered))
    texts = [line for _, line in numbered]
    is_frame = np.fromiter((bool(_FRAME_NUMBER.match(t)) for t in texts), dtype=bool, count=len(texts))
    frame_rows = np.flatnonzero(is_frame)
    starts = np.append(frame_rows, len(texts))
    per_frame = np.diff(starts) - 1

    first_frame = texts[frame_rows[0] + 1 : starts[1]]
    bones = [t.split(None, 1)[0] for t in first_frame]
    if len(set(bones)) != len(bones):
        dup = next(b for b in bones if bones.count(b) > 1)
        raise MocapFormatError(f"bone '{dup}' appears twice in one frame", path, int(linenos[frame_rows[0] + 1 + bones.index(dup) + 1]))
    counts = [len(t.split()) - 1 for t in first_frame]
    if skeleton is not None:
        _check_against_skeleton(bones, counts, first_frame, linenos[frame_rows[0] + 1 :], skeleton, path)

    frame_numbers = np.array([int(texts[r]) for r in frame_rows], dtype=np.int64)
    _check_frame_numbers(frame_numbers, linenos[frame_rows], path)

    n_frames, n_bones = len(frame_rows), len(bones)
    if n_frames > 1 and per_frame[-1] < n_bones:
        # Real files end mid-frame when a copy was cut short (cmu/64/golf_01.amc): keep the
        # complete frames and say so; a short frame anywhere else is an error.
        warnings.warn(
            f"{path}:{int(linenos[frame_rows[-1]])}: last frame {frame_numbers[-1]} is incomplete "
            f"({per_frame[-1]} of {n_bones} bones); dropped",
            stacklevel=2,
        )
        texts, is_frame, linenos = texts[: frame_rows[-1]], is_frame[: frame_rows[-1]], linenos[: frame_rows[-1]]
        frame_rows, per_frame, frame_numbers = frame_rows[:-1], per_frame[:-1], frame_numbers[:-1]
        n_frames -= 1
    if np.any(per_frame != n_bones) or not _same_bone_order(texts, is_frame, bones):
        return _parse_irregular(texts, linenos, frame_rows, bones, counts, frame_numbers, header, path)

    bone_lines = [t for t, f in zip(texts, is_frame) if not f]
    tokens = " ".join(bone_lines).split()
    expected_tokens = n_frames * (n_bones + sum(counts))
    if len(tokens) != expected_tokens:
        return _parse_irregular(texts, linenos, frame_rows, bones, counts, frame_numbers, header, path)
    table = np.array(tokens, dtype=object).reshape(n_frames, n_bones + sum(counts))
    value_cols = np.ones(table.shape[1], dtype=bool)
    value_cols[np.concatenate([[0], np.cumsum(np.array(counts) + 1)[:-1]])] = False
    values = _to_float(table[:, value_cols], path, texts, linenos, is_frame)
    return Motion(bones, counts, values, frame_numbers, header, path)


def _first_frame_line(lines: list[str], path) -> int:
    for i, line in enumerate(lines):
        stripped = line.strip()
        if not stripped or stripped.startswith("#") or stripped.startswith(":"):
            continue
        if _FRAME_NUMBER.match(line):
            return i
        raise MocapFormatError(f"expected a frame number, got {stripped[:40]!r}", path, i + 1)
    raise MocapFormatError("no frames (empty AMC file)", path)


def _check_frame_numbers(numbers: np.ndarray, linenos: np.ndarray, path) -> None:
    steps = np.diff(numbers)
    bad = np.flatnonzero(steps != 1)
    if bad.size:
        i = int(bad[0]) + 1
        kind = "duplicate" if steps[bad[0]] == 0 else "out-of-order" if steps[bad[0]] < 0 else "skipped"
        raise MocapFormatError(
            f"{kind} frame number {numbers[i]} after {numbers[i - 1]}", path, int(linenos[i])
        )


def _same_bone_order(texts, is_frame, bones) -> bool:
    names = [t.split(None, 1)[0] for t, f in zip(texts, is_frame) if not f]
    n = len(bones)
    return all(names[i::n] == [b] * len(names[i::n]) for i, b in enumerate(bones)) if names else True


def _parse_irregular(texts, linenos, frame_rows, bones, counts, frame_numbers, header, path) -> Motion:
    """Slow path for files whose frames list bones in varying order or are damaged: find the fault."""
    column = {b: i for i, b in enumerate(bones)}
    offsets = np.concatenate([[0], np.cumsum(counts)])
    values = np.empty((len(frame_rows), int(offsets[-1])))
    ends = list(frame_rows[1:]) + [len(texts)]
    for f, (start, end) in enumerate(zip(frame_rows, ends)):
        seen = set()
        for row in range(start + 1, end):
            words = texts[row].split()
            name, line = words[0], int(linenos[row])
            if name not in column:
                raise MocapFormatError(f"bone '{name}' is not in the first frame's bones", path, line)
            if name in seen:
                raise MocapFormatError(f"bone '{name}' appears twice in frame {frame_numbers[f]}", path, line)
            seen.add(name)
            i = column[name]
            if len(words) - 1 != counts[i]:
                raise MocapFormatError(
                    f"bone '{name}' has {len(words) - 1} values, expected {counts[i]}", path, line
                )
            values[f, offsets[i] : offsets[i + 1]] = _to_float(np.array(words[1:], dtype=object), path, texts, linenos, None, row)
        if len(seen) != len(bones):
            missing = next(b for b in bones if b not in seen)
            raise MocapFormatError(
                f"truncated frame {frame_numbers[f]}: bone '{missing}' missing", path, int(linenos[end - 1])
            )
    return Motion(bones, counts, values, frame_numbers, header, path)


def _to_float(tokens: np.ndarray, path, texts, linenos, is_frame, row=None) -> np.ndarray:
    """Vectorised float conversion; on failure find the offending token's line."""
    try:
        values = tokens.astype(np.float64)
    except ValueError:
        values = None
    if values is not None and np.all(np.isfinite(values)):
        return values
    rows = [row] if row is not None else [i for i, f in enumerate(is_frame) if not f]
    for r in rows:
        for word in texts[r].split()[1:]:
            try:
                v = float(word)
            except ValueError:
                raise MocapFormatError(f"not a number: {word[:40]!r}", path, int(linenos[r])) from None
            if not np.isfinite(v):
                raise MocapFormatError(f"value is not finite: {word!r}", path, int(linenos[r]))
    raise MocapFormatError("unparseable values", path)


def _check_against_skeleton(bones, counts, lines, linenos, skeleton, path) -> None:
    for name, count, line, lineno in zip(bones, counts, lines, linenos):
        try:
            dof = skeleton.dof_of(name)
        except KeyError:
            raise MocapFormatError(f"bone '{name}' is not in the skeleton", path, int(lineno)) from None
        if count != len(dof):
            raise MocapFormatError(
                f"bone '{name}' has {count} values, the skeleton gives it {len(dof)} dof", path, int(lineno)
            )


def format_amc(motion: Motion, digits: int = 6) -> str:
    """AMC text with `digits` significant digits (CMU writes 6), LF line endings."""
    out = list(motion.header)
    columns = motion.columns()
    fmt = f"%.{digits}g"
    for f in range(motion.n_frames):
        out.append(str(int(motion.frame_numbers[f])))
        row = motion.values[f]
        for bone in motion.bones:
            out.append(bone + " " + " ".join(fmt % v for v in row[columns[bone]]))
    return "\n".join(out) + "\n"


def write_amc(motion: Motion, path: str | os.PathLike, digits: int = 6) -> None:
    with open(path, "w", encoding="latin-1", newline="\n") as fh:
        fh.write(format_amc(motion, digits))
