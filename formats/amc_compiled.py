"""AMC's per-value loops, compiled with numba: `scan_frames` reads the usual layout of frame
lines (`amc._parse_fast`), converting its values in the same pass; `format_frames` writes them
(`amc.format_amc`). The numbers themselves are read and written by `numbers_compiled`, which
says why this is compiled and what to do after editing it (numba's cache does not see it here).
"""

from __future__ import annotations

import numba
import numpy as np

from mocapzip.formats.numbers_compiled import (CONVERTED, INVALID, LEFT, count_number, grown, is_space, new_stats,
                                               note_hard, put_bytes, put_fixed, put_general, put_int, scan_number)

# scan_frames' verdicts
LAYOUT_OK, LAYOUT_OTHER = 0, 1


@numba.njit(cache=True, nogil=True, inline="always")
def _line_end(body, pos, end):
    """Past the end of the line at `pos` (after blanks; `end` at the end of the body), or -1
    where something else than blanks comes first, or a CR that is not part of CRLF."""
    while pos < end and (body[pos] == 32 or body[pos] == 9 or body[pos] == 11 or body[pos] == 12):
        pos += 1
    if pos == end:
        return end
    if body[pos] == 10:
        return pos + 1
    if body[pos] == 13 and pos + 1 < end and body[pos + 1] == 10:
        return pos + 2
    return -1


@numba.njit(cache=True, nogil=True)
def scan_frames(body, names, name_ends, counts, allowed, max_frame_number, max_abs_value):
    """Read `body` (from the first frame number on) as the usual layout: a line holding only the
    frame number, then one line for each bone of `names` (concatenated, ending at `name_ends`),
    in that order, with `counts` values each; frame numbers consecutive digits up to
    `max_frame_number`, no blank lines, CR only in CRLF, blanks allowed at line ends and after
    the last line. (Limits are arguments: numba's cache would not see them change elsewhere.)

    Returns (verdict, first frame number, frames, values, faults, left, stats): LAYOUT_OTHER
    when the body is not that layout (then nothing else counts). Values are converted for the
    first `allowed` frames only: `faults` of them are not numbers or beyond `max_abs_value`,
    `left` are NaN, left to float().
    """
    end = body.size
    while end > 0 and is_space(body[end - 1]):
        end -= 1
    n_bones = counts.size
    n_values = 0
    for c in counts:
        n_values += c
    lines = 1
    for k in range(end):
        if body[k] == 10:
            lines += 1
    n_frames = lines // (1 + n_bones)
    values = np.empty((min(n_frames, allowed), n_values))
    stats = new_stats()
    if lines % (1 + n_bones):
        return LAYOUT_OTHER, 0, 0, values, 0, 0, stats
    flat = values.reshape(-1)
    first = 0
    faults = 0
    left = 0
    pos = 0
    for frame in range(n_frames):
        number = 0
        start = pos
        while pos < end and 48 <= body[pos] <= 57 and number <= max_frame_number:
            number = number * 10 + (body[pos] - 48)
            pos += 1
        if pos == start or number > max_frame_number or (pos < end and not is_space(body[pos])):
            return LAYOUT_OTHER, 0, 0, values, 0, 0, stats
        if frame == 0:
            first = number
        elif number != first + frame:
            return LAYOUT_OTHER, 0, 0, values, 0, 0, stats
        pos = _line_end(body, pos, end)
        if pos < 0:
            return LAYOUT_OTHER, 0, 0, values, 0, 0, stats
        column = frame * n_values
        name_start = 0
        for b in range(n_bones):
            length = name_ends[b] - name_start
            if pos + length > end or (pos + length < end and not is_space(body[pos + length])):
                return LAYOUT_OTHER, 0, 0, values, 0, 0, stats
            for j in range(length):
                if body[pos + j] != names[name_start + j]:
                    return LAYOUT_OTHER, 0, 0, values, 0, 0, stats
            pos += length
            name_start = name_ends[b]
            for _ in range(counts[b]):
                while pos < end and (body[pos] == 32 or body[pos] == 9 or body[pos] == 11 or body[pos] == 12):
                    pos += 1
                if pos == end or body[pos] == 10 or body[pos] == 13:
                    return LAYOUT_OTHER, 0, 0, values, 0, 0, stats  # too few values (or a lone CR)
                if frame < allowed:
                    pos, value, kind, sig, decimals, exp_digits, has_dot = scan_number(body, pos, end)
                    if kind == INVALID or (kind == CONVERTED and not abs(value) <= max_abs_value):
                        faults += 1
                    else:
                        if kind == LEFT:
                            left += 1
                        count_number(stats, sig, decimals, exp_digits, has_dot)
                    flat[column] = value
                    column += 1
                else:
                    while pos < end and not is_space(body[pos]):
                        pos += 1
            pos = _line_end(body, pos, end)
            if pos < 0:
                return LAYOUT_OTHER, 0, 0, values, 0, 0, stats  # too many values
    if pos != end:
        return LAYOUT_OTHER, 0, 0, values, 0, 0, stats
    return LAYOUT_OK, first, n_frames, values, faults, left, stats


@numba.njit(cache=True, nogil=True)
def format_frames(values, frames, names, name_ends, counts, separator, newline, frame_newline, fixed, digits, width):
    """The frame lines of an AMC file as bytes: each frame's number (`%d` of `frames`, float64),
    then one line for each bone (`names` concatenated, ending at `name_ends`; `counts` values
    each), values as '%.<digits>f' (`fixed`) or '%.<digits>g' with exponents of at least
    `width` digits.

    Returns (text, hard): `hard` lists (offset in text, item) of the numbers left to Python,
    which belong at that offset; item is row * (columns + 1), plus 1 + column for a value.
    """
    n_frames, n_columns = values.shape
    n_bones = counts.size
    frame_bytes = 24 + frame_newline.size + names.size + n_bones * (separator.size + newline.size)
    most = frame_bytes + n_columns * (40 + digits + width)  # what one frame can take
    out = np.empty(max(n_frames * (frame_bytes + 12 * n_columns), most), np.uint8)
    hard = np.empty((16, 2), np.int64)
    n_hard = 0
    pos = 0
    for row in range(n_frames):
        if pos + most > out.size:
            out = grown(out)
        item = row * (n_columns + 1)
        end = put_int(out, pos, frames[row])
        if end < 0:
            hard = note_hard(hard, n_hard, pos, item)
            n_hard += 1
        else:
            pos = end
        pos = put_bytes(out, pos, frame_newline, 0, frame_newline.size)
        column = 0
        name_start = 0
        for b in range(n_bones):
            pos = put_bytes(out, pos, names, name_start, name_ends[b])
            name_start = name_ends[b]
            if counts[b]:
                pos = put_bytes(out, pos, separator, 0, separator.size)
            for t in range(counts[b]):
                if t:
                    out[pos] = 32
                    pos += 1
                x = values[row, column]
                column += 1
                end = put_fixed(out, pos, x, digits) if fixed else put_general(out, pos, x, digits, width)
                if end < 0:
                    hard = note_hard(hard, n_hard, pos, item + column)
                    n_hard += 1
                else:
                    pos = end
            pos = put_bytes(out, pos, newline, 0, newline.size)
    return out[:pos], hard[:n_hard]
