"""BVH's per-value loops, compiled with numba: `scan_lines` reads a file's frame lines
(`bvh.parse_bvh`), `format_rows` writes them (`bvh.BvhStyle.format`). The numbers themselves
are read and written by `numbers_compiled`, which says why this is compiled and what to do after
editing it (numba's cache does not see it here).
"""

from __future__ import annotations

import numba
import numpy as np

from mocapzip.formats.numbers_compiled import (CONVERTED, INVALID, grown, note_hard, put_bytes, put_fixed, put_general,
                                               scan_number)


@numba.njit(cache=True, nogil=True)
def scan_lines(body, n_lines, width, max_abs_value):
    """Read `body` as `n_lines` lines of `width` numbers each (a BVH file's frames, `bvh.parse_bvh`):
    numbers separated by blanks, lines ending in LF, CRLF or CR, blank lines and blanks allowed
    after the last one only.

    Returns (ok, values, starts): ok is False where the body is not that, or a value is not a
    number or beyond `max_abs_value` (the caller then reads it word by word, which names the
    fault); values left to float() are NaN; starts[f] is where line f begins.
    """
    end = body.size
    values = np.empty((n_lines, width))
    flat = values.reshape(-1)
    starts = np.zeros(n_lines, dtype=np.int64)
    line = 0
    blank_lines = 0
    pos = 0
    while pos < end:
        start = pos
        count = 0
        while True:
            while pos < end and (body[pos] == 32 or body[pos] == 9 or body[pos] == 11 or body[pos] == 12):
                pos += 1
            if pos == end or body[pos] == 10 or body[pos] == 13:
                break
            if line >= n_lines or count >= width:
                return False, values, starts
            pos, value, kind, sig, decimals, exp_digits, has_dot = scan_number(body, pos, end)
            if kind == INVALID or (kind == CONVERTED and not abs(value) <= max_abs_value):
                return False, values, starts
            flat[line * width + count] = value
            count += 1
        if pos < end:
            pos += 2 if body[pos] == 13 and pos + 1 < end and body[pos + 1] == 10 else 1
        if count == 0:
            blank_lines += 1
            continue
        if blank_lines or count != width:
            return False, values, starts
        starts[line] = start
        line += 1
    return line == n_lines, values, starts


@numba.njit(cache=True, nogil=True)
def format_rows(values, separator, ending, fixed, digits):
    """BVH frame lines: each row of `values` as '%.<digits>f' (`fixed`) or '%.<digits>g' numbers
    joined by `separator`, then `ending`.

    Returns (text, hard) as `format_frames` does; here item is row * columns + column.
    """
    n_rows, n_columns = values.shape
    most = ending.size + n_columns * (40 + digits + separator.size)  # what one row can take
    out = np.empty(max(n_rows * (ending.size + n_columns * (12 + separator.size)), most), np.uint8)
    hard = np.empty((16, 2), np.int64)
    n_hard = 0
    pos = 0
    for row in range(n_rows):
        if pos + most > out.size:
            out = grown(out)
        for column in range(n_columns):
            if column:
                pos = put_bytes(out, pos, separator, 0, separator.size)
            x = values[row, column]
            end = put_fixed(out, pos, x, digits) if fixed else put_general(out, pos, x, digits, 2)
            if end < 0:
                hard = note_hard(hard, n_hard, pos, row * n_columns + column)
                n_hard += 1
            else:
                pos = end
        pos = put_bytes(out, pos, ending, 0, ending.size)
    return out[:pos], hard[:n_hard]
