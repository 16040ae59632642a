"""The per-value loops of AMC reading, compiled with numba.

Why: reading spends its time on each of the file's numbers (a CMU file holds a million in
9 MB), and NumPy's many passes capped it at about 55 MB/s; compiled, one pass over the bytes
reads at 250-300 MB/s.

Reading: `scan_frames` checks the usual layout (`amc._parse_fast`) and converts its values in
the same pass; `scan_tokens` converts space-separated words (`amc._parse_exact`). A value is
converted here where that is exact (Clinger's fast path: its digits below 2**53, then one
correctly rounded multiplication or division by a power of ten up to 1e22, which is
float()'s result); the caller converts the rest (NaN here) with float(). Which words those are
is the rule the former NumPy parser had (at most 22 bytes, the bytes read as digits below
2**53, the exponent within +-22), so a damaged file is reported at the same word as before.

Every kernel and helper lives in this module: numba's cache (`cache=True`) does not notice an
edit of a helper in another module, nor a changed constant of one (limits are arguments). The
first use after an install or an edit compiles: about 3 s for reading, 1 s for the exact
path; later runs load the cache from __pycache__ in a fraction of a second.
The small helpers that take an array and run for every value are inlined (`inline="always"`):
a compiled call that passes an array pays for reference counting, which cost reading 15 % of
its time.
"""

from __future__ import annotations

import numba
import numpy as np

_P10 = np.array([10.0**k for k in range(23)])  # exact doubles
_TWO53 = 1 << 53
_MAX_WIDTH = 22  # longest token converted here

# scan_frames' verdicts
LAYOUT_OK, LAYOUT_OTHER = 0, 1

# Slots of the number statistics that `amc._number_style` reads.
STAT_COUNT, STAT_ALL_DOT, STAT_ANY_EXP, STAT_FIRST_DECIMALS, STAT_SAME_DECIMALS, STAT_MAX_SIG, STAT_MIN_EXP_DIGITS = range(7)
_N_STATS = 7

_INVALID, _LEFT, _CONVERTED = 0, 1, 2  # what _number made of a token


# --------------------------------------------------------------------------- reading


@numba.njit(cache=True, inline="always")
def _is_space(byte):
    """What bytes.split() splits on: space, tab, LF, VT, FF, CR."""
    return byte == 32 or 9 <= byte <= 13


@numba.njit(cache=True, inline="always")
def _number(buf, start, end):
    """The token at buf[start] (it ends at white space or `end`): (its end, value, kind,
    significant digits, decimals, exponent digits, has a dot).

    kind: _INVALID (not the grammar of `text.NUMBER`), _LEFT (valid, for float() to convert)
    or _CONVERTED (value is float()'s).
    """
    i = start
    negative = False
    if buf[i] == 43 or buf[i] == 45:
        negative = buf[i] == 45
        i += 1
    mantissa = 0  # wraps beyond 18 digits: used only below 2**53 (see the end)
    sig = 0
    digits = 0
    decimals = 0
    has_dot = False
    while i < end:
        if 48 <= buf[i] <= 57:
            d = buf[i] - 48
            mantissa = mantissa * 10 + d
            if sig or d:
                sig += 1
            digits += 1
            decimals += has_dot
        elif buf[i] == 46 and not has_dot:
            has_dot = True
        else:
            break
        i += 1
    valid = digits > 0
    exp_digits = 0
    exponent = 0
    if valid and i < end and (buf[i] == 101 or buf[i] == 69):
        i += 1
        exp_negative = False
        if i < end and (buf[i] == 43 or buf[i] == 45):
            exp_negative = buf[i] == 45
            i += 1
        while i < end and 48 <= buf[i] <= 57:
            exponent = exponent * 10 + (buf[i] - 48)
            exp_digits += 1
            i += 1
        valid = exp_digits > 0
        if exp_negative:
            exponent = -exponent
    if i < end and not _is_space(buf[i]):
        valid = False
        while i < end and not _is_space(buf[i]):
            i += 1
    if not valid:
        return i, 0.0, _INVALID, 0, 0, 0, False
    exponent -= decimals
    length = i - start
    if abs(exponent) > 22 or (length > 15 and (length > _MAX_WIDTH or not _below_two53(buf, start, i))):
        return i, np.nan, _LEFT, sig, decimals, exp_digits, has_dot
    value = float(mantissa) * _P10[exponent] if exponent >= 0 else float(mantissa) / _P10[-exponent]
    return i, (-value if negative else value), _CONVERTED, sig, decimals, exp_digits, has_dot


@numba.njit(cache=True)
def _below_two53(buf, start, end):
    """Whether buf[start:end], every byte read as a digit (sign, dot and e as 0), is below
    2**53: then so are its mantissa and exponent (15 bytes or fewer always are)."""
    raw = 0
    for i in range(start, end):
        raw = raw * 10 + (buf[i] - 48 if 48 <= buf[i] <= 57 else 0)
        if raw >= _TWO53:
            return False
    return True


@numba.njit(cache=True)
def _new_stats():
    stats = np.zeros(_N_STATS, np.int64)
    stats[STAT_ALL_DOT] = 1
    stats[STAT_SAME_DECIMALS] = 1
    stats[STAT_MIN_EXP_DIGITS] = 1 << 30
    return stats


@numba.njit(cache=True, inline="always")
def _count(stats, sig, decimals, exp_digits, has_dot):
    """Add a valid token to `stats`: what `amc._number_style` needs of all of them."""
    if stats[STAT_COUNT] == 0:
        stats[STAT_FIRST_DECIMALS] = decimals
    elif decimals != stats[STAT_FIRST_DECIMALS]:
        stats[STAT_SAME_DECIMALS] = 0
    stats[STAT_COUNT] += 1
    if not has_dot:
        stats[STAT_ALL_DOT] = 0
    if exp_digits:
        stats[STAT_ANY_EXP] = 1
        stats[STAT_MIN_EXP_DIGITS] = min(stats[STAT_MIN_EXP_DIGITS], exp_digits)
    stats[STAT_MAX_SIG] = max(stats[STAT_MAX_SIG], sig)


@numba.njit(cache=True)
def scan_tokens(buf, n_tokens):
    """Values and statistics of the `n_tokens` tokens of `buf`, joined by single spaces.

    A value is NaN where the token is invalid or left to float(); statistics count valid tokens.
    """
    values = np.empty(n_tokens)
    stats = _new_stats()
    pos = 0
    for k in range(n_tokens):
        pos, value, kind, sig, decimals, exp_digits, has_dot = _number(buf, pos, buf.size)
        values[k] = value if kind == _CONVERTED else np.nan
        if kind != _INVALID:
            _count(stats, sig, decimals, exp_digits, has_dot)
        pos += 1
    return values, stats


@numba.njit(cache=True, inline="always")
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


@numba.njit(cache=True)
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
    while end > 0 and _is_space(body[end - 1]):
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
    stats = _new_stats()
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
        if pos == start or number > max_frame_number or (pos < end and not _is_space(body[pos])):
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
            if pos + length > end or (pos + length < end and not _is_space(body[pos + length])):
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
                    pos, value, kind, sig, decimals, exp_digits, has_dot = _number(body, pos, end)
                    if kind == _INVALID or (kind == _CONVERTED and not abs(value) <= max_abs_value):
                        faults += 1
                    else:
                        if kind == _LEFT:
                            left += 1
                        _count(stats, sig, decimals, exp_digits, has_dot)
                    flat[column] = value
                    column += 1
                else:
                    while pos < end and not _is_space(body[pos]):
                        pos += 1
            pos = _line_end(body, pos, end)
            if pos < 0:
                return LAYOUT_OTHER, 0, 0, values, 0, 0, stats  # too many values
    if pos != end:
        return LAYOUT_OTHER, 0, 0, values, 0, 0, stats
    return LAYOUT_OK, first, n_frames, values, faults, left, stats

