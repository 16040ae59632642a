"""Numbers in text files, read and written in compiled code (numba): what every format's
compiled loops share (AMC's in `amc_compiled`, BVH's in `bvh_compiled`).

Why: reading and writing spend their time on each of the file's numbers (a CMU file holds a
million in 9 MB), and NumPy's many passes or Python's `%` operator capped them at about 55 MB/s
and 70,000 frames/s; compiled, one pass over the bytes reads at 250-300 MB/s and writes
300,000-400,000 CMU frames/s.

Reading: `scan_number` reads one word. A value is converted here where that is exact
(Clinger's fast path: its digits below 2**53, then one correctly rounded multiplication or
division by a power of ten up to 1e22, which is float()'s result); the caller converts the rest
(NaN here) with float(). Which words those are is the rule the former NumPy parser had (at most
22 bytes, the bytes read as digits below 2**53, the exponent within +-22), so a damaged file is
reported at the same word as before. `count_number` adds a word to the statistics an AMC's
number style is found from (`amc._number_style`); `scan_tokens` converts space-separated words
(`amc._parse_exact`).

Writing: `put_int`, `put_fixed` and `put_general` write numbers as Python's `%d`, `%.<p>f` and
`%.<p>g` do. Those round the exact binary value half to even; here the value is scaled by one
correctly rounded operation and rounded from there, which decides every rounding but where the
scaled value is exactly a half, or outside the ranges where that holds (more than 15 digits,
scales beyond 1e22): those numbers are left to Python (noted with `note_hard`, written in by
`with_numbers`), so the text is always Python's.

numba's cache (`cache=True`, next to the sources in __pycache__) does not notice an edit of
this module in the compiled code of `amc_compiled` and `bvh_compiled`, which hold their own
copies of these functions (nor a changed constant: limits are arguments): after changing them,
delete the cache files (`find formats -name '*.nb[ic]' -delete`). The first use after an install
or an edit compiles: about 3 s for reading, 1 s for the exact path, 4 s for writing; later runs
load the cache in a fraction of a second. The small helpers that take an array and run for
every value are inlined (`inline="always"`): a compiled call that passes an array pays for
reference counting, which cost reading 15 % and writing a quarter of its time. So is
`put_general`, which writes the usual "g" numbers (CMU's and Bandai's): 10 % less time writing
the shared CMU set, for about a second more of compiling each of the writing loops, once. The
rarer `put_fixed` and `put_int` are not.
"""

from __future__ import annotations

import math

import numba
import numpy as np

_P10 = np.array([10.0**k for k in range(23)])  # exact doubles
_I10 = np.array([10**k for k in range(19)], dtype=np.int64)
_PAIRS = np.frombuffer(b"".join(b"%02d" % i for i in range(100)), np.uint8)  # '00' .. '99'
_TWO52 = 2.0**52
_TWO53 = 1 << 53
_MAX_WIDTH = 22  # longest token converted here

# Slots of the number statistics that `amc._number_style` reads.
STAT_COUNT, STAT_ALL_DOT, STAT_ANY_EXP, STAT_FIRST_DECIMALS, STAT_SAME_DECIMALS, STAT_MAX_SIG, STAT_MIN_EXP_DIGITS = range(7)
_N_STATS = 7

INVALID, LEFT, CONVERTED = 0, 1, 2  # what scan_number made of a token


# --------------------------------------------------------------------------- reading


@numba.njit(cache=True, nogil=True, inline="always")
def is_space(byte):
    """What bytes.split() splits on: space, tab, LF, VT, FF, CR."""
    return byte == 32 or 9 <= byte <= 13


@numba.njit(cache=True, nogil=True, inline="always")
def scan_number(buf, start, end):
    """The token at buf[start] (it ends at white space or `end`): (its end, value, kind,
    significant digits, decimals, exponent digits, has a dot).

    kind: INVALID (not the grammar of `text.NUMBER`), LEFT (valid, for float() to convert)
    or CONVERTED (value is float()'s).
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
    if i < end and not is_space(buf[i]):
        valid = False
        while i < end and not is_space(buf[i]):
            i += 1
    if not valid:
        return i, 0.0, INVALID, 0, 0, 0, False
    exponent -= decimals
    length = i - start
    if abs(exponent) > 22 or (length > 15 and (length > _MAX_WIDTH or not _below_two53(buf, start, i))):
        return i, np.nan, LEFT, sig, decimals, exp_digits, has_dot
    value = float(mantissa) * _P10[exponent] if exponent >= 0 else float(mantissa) / _P10[-exponent]
    return i, (-value if negative else value), CONVERTED, sig, decimals, exp_digits, has_dot


@numba.njit(cache=True, nogil=True)
def _below_two53(buf, start, end):
    """Whether buf[start:end], every byte read as a digit (sign, dot and e as 0), is below
    2**53: then so are its mantissa and exponent (15 bytes or fewer always are)."""
    raw = 0
    for i in range(start, end):
        raw = raw * 10 + (buf[i] - 48 if 48 <= buf[i] <= 57 else 0)
        if raw >= _TWO53:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def new_stats():
    stats = np.zeros(_N_STATS, np.int64)
    stats[STAT_ALL_DOT] = 1
    stats[STAT_SAME_DECIMALS] = 1
    stats[STAT_MIN_EXP_DIGITS] = 1 << 30
    return stats


@numba.njit(cache=True, nogil=True, inline="always")
def count_number(stats, sig, decimals, exp_digits, has_dot):
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


@numba.njit(cache=True, nogil=True)
def scan_tokens(buf, n_tokens):
    """Values and statistics of the `n_tokens` tokens of `buf`, joined by single spaces.

    A value is NaN where the token is invalid or left to float(); statistics count valid tokens.
    """
    values = np.empty(n_tokens)
    stats = new_stats()
    pos = 0
    for k in range(n_tokens):
        pos, value, kind, sig, decimals, exp_digits, has_dot = scan_number(buf, pos, buf.size)
        values[k] = value if kind == CONVERTED else np.nan
        if kind != INVALID:
            count_number(stats, sig, decimals, exp_digits, has_dot)
        pos += 1
    return values, stats


# --------------------------------------------------------------------------- writing


@numba.njit(cache=True, nogil=True, inline="always")
def _put_digits(out, end, n, count):
    """The last `count` <= `end` digits of 0 <= `n` < 2**63 (zero-padded) into
    out[end - count:end]; returns n // 10**count. Two digits a step: each division costs more
    than the table look-up. In unsigned integers: for signed ones numba adds Python's
    floor-division and negative-index corrections to every step (writing the shared CMU set took
    8 % longer)."""
    u = np.uint64(n)
    at = np.uint64(end)
    while count >= 2:
        pair = np.uint64(2) * (u % np.uint64(100))
        u //= np.uint64(100)
        at -= np.uint64(2)
        out[at] = _PAIRS[pair]
        out[at + np.uint64(1)] = _PAIRS[pair + np.uint64(1)]
        count -= 2
    if count:
        out[at - np.uint64(1)] = np.uint64(48) + u % np.uint64(10)
        u //= np.uint64(10)
    return np.int64(u)


@numba.njit(cache=True, nogil=True)
def _n_digits(n):
    count = 1
    while n >= 10:
        n //= 10
        count += 1
    return count


@numba.njit(cache=True, nogil=True)
def _round_half_even(s):
    """round(s) for 0 <= s < 2**52, or -1 where s is exactly a half (the exact value it stands
    for may lie on either side)."""
    whole = math.floor(s)
    fraction = s - whole  # exact below 2**52
    if fraction == 0.5:
        return -1
    return int(whole) + (1 if fraction > 0.5 else 0)


@numba.njit(cache=True, nogil=True, inline="always")
def _put_point(out, pos, n, int_digits, zeros, fraction):
    """At out[pos:]: the digits of `n` but its last `fraction` (`int_digits` of them,
    zero-padded), `zeros` zeros, then a point and those last digits (no point without them).
    Returns the end."""
    end = pos + int_digits + zeros + (fraction + 1 if fraction else 0)
    if fraction:
        n = _put_digits(out, end, n, fraction)
        out[end - fraction - 1] = 46
    start_zeros = pos + int_digits
    _put_digits(out, start_zeros + zeros, 0, zeros)
    _put_digits(out, start_zeros, n, int_digits)
    return end


@numba.njit(cache=True, nogil=True)
def put_int(out, pos, x):
    """'%d' % x at out[pos:]; returns the end, or -1 to leave it to Python."""
    if not abs(x) < 2.0**62:
        return -1
    n = int(x)
    if n < 0:
        out[pos] = 45
        pos += 1
        n = -n
    count = _n_digits(n)
    _put_digits(out, pos + count, n, count)
    return pos + count


@numba.njit(cache=True, nogil=True)
def put_fixed(out, pos, x, decimals):
    """'%.<decimals>f' % x at out[pos:]; returns the end, or -1 to leave it to Python.

    s = |x| * 10**decimals is one correctly rounded product, so it is within half an ulp of
    the exact product; an ulp is at most 1/2 below 2**52, so unless s is exactly a half, the
    exact product lies on the same side of the half as s and rounds to the same integer."""
    if decimals > 22:
        return -1
    s = abs(x) * _P10[decimals]
    if not s < _TWO52:
        return -1
    n = _round_half_even(s)
    if n < 0:
        return -1
    if math.copysign(1.0, x) < 0:
        out[pos] = 45
        pos += 1
    return _put_point(out, pos, n, _n_digits(n // _I10[decimals]) if decimals < 19 else 1, 0, decimals)


@numba.njit(cache=True, nogil=True, inline="always")
def _general_scale(a, p):
    """(s, k): s = a * 10**k (one correctly rounded operation) with p digits before the point,
    for 0 < a and p <= 15; k = 99 where no k within +-22 gives that (`put_general`)."""
    k = p - 1 - ((math.frexp(a)[1] * 78913) >> 18)  # floor(log10(a)), or one less
    s = 0.0
    for _ in range(3):  # log10 can be one off next to a power of ten
        if abs(k) > 22:
            return s, 99
        s = a * _P10[k] if k >= 0 else a / _P10[-k]
        if s < _P10[p - 1]:
            k += 1
        elif s >= _P10[p]:
            k -= 1
        else:
            break
    if not _P10[p - 1] <= s < _P10[p]:
        return s, 99
    return s, k


@numba.njit(cache=True, nogil=True, inline="always")
def put_general(out, pos, x, p, width):
    """'%.<p>g' % x at out[pos:] with at least `width` exponent digits; returns the end, or -1
    to leave it to Python.

    k is chosen so that s = |x| * 10**k (one correctly rounded operation) has p digits before
    the point; then round(s) is the exact rounding of |x| to p digits (see `put_fixed`). Where
    the exact product is just outside [10**(p-1), 10**p) and s is not, the result is the same:
    below, s is 10**(p-1) itself and the true rounding carries to it; above, s rounds up to
    10**p, which carries like the true rounding does (p <= 15 keeps both margins below 1/2).
    """
    negative = math.copysign(1.0, x) < 0
    a = abs(x)
    if a == 0.0:
        if negative:
            out[pos] = 45
            pos += 1
        out[pos] = 48
        return pos + 1
    if p > 15:
        return -1
    s, k = _general_scale(a, p)
    if k > 22:
        return -1
    n = _round_half_even(s)
    if n < 0:
        return -1
    exponent = p - 1 - k
    if n == _I10[p]:
        n = _I10[p - 1]
        exponent += 1
    kept = p  # significant digits written: trailing zeros go (unsigned: `_put_digits`)
    u = np.uint64(n)
    while kept > 1 and u % np.uint64(10) == np.uint64(0):
        u //= np.uint64(10)
        kept -= 1
    n = np.int64(u)
    if negative:
        out[pos] = 45
        pos += 1
    if exponent < -4 or exponent >= p:  # d.ddde+XX
        shown = abs(exponent)
        exp_len = max(width, _n_digits(shown))
        end = pos + kept + (1 if kept > 1 else 0) + 2 + exp_len
        _put_digits(out, end, shown, exp_len)
        j = end - exp_len - 2
        out[j] = 101
        out[j + 1] = 45 if exponent < 0 else 43
        if kept > 1:
            n = _put_digits(out, j, n, kept - 1)
            out[j - kept] = 46
        out[pos] = 48 + n
        return end
    if exponent >= 0:  # ddd.ddd, or ddd000
        fraction = max(kept - exponent - 1, 0)
        return _put_point(out, pos, n, kept - fraction, exponent + 1 - (kept - fraction), fraction)
    return _put_point(out, pos, n, 1, 0, kept - exponent - 1)  # 0.000ddd


@numba.njit(cache=True, nogil=True)
def grown(array):
    """A copy of 1-d `array` twice as long (a loop: a slice assignment compiles string
    formatting for its error message, seconds of cold start)."""
    larger = np.empty(2 * array.size, array.dtype)
    for j in range(array.size):
        larger[j] = array[j]
    return larger


@numba.njit(cache=True, nogil=True)
def note_hard(hard, n_hard, at, item):
    """hard[n_hard] = (at, item), in a larger copy of `hard` when it is full: a number a writing
    loop leaves to Python (`with_numbers`), which belongs at offset `at` of its text."""
    if n_hard == hard.shape[0]:
        hard = grown(hard.reshape(-1)).reshape(-1, 2)
    hard[n_hard, 0] = at
    hard[n_hard, 1] = item
    return hard


@numba.njit(cache=True, nogil=True, inline="always")
def put_bytes(out, pos, text, start, end):
    """text[start:end] at out[pos:] (a loop: slicing costs more for so few bytes)."""
    for j in range(start, end):
        out[pos] = text[j]
        pos += 1
    return pos


def with_numbers(text: bytes, hard: np.ndarray, number) -> bytes:
    """`text` from a writing loop (`amc_compiled.format_frames`, `bvh_compiled.format_rows`) with
    the numbers it left to Python (`note_hard`) written in at their offsets; `number(item)` is an
    item's text."""
    if not hard.size:
        return text
    pieces, done = [], 0
    for at, item in hard.tolist():
        pieces += [text[done:at], number(item).encode()]
        done = at
    pieces.append(text[done:])
    return b"".join(pieces)


@numba.njit(cache=True, nogil=True)
def printed_values(values, fixed, p, out):
    """out[i] = float('%.<p>f' % values[i]) ('f' if `fixed`) or float('%.<p>g' % ...), without the
    text: the integer n the printed digits make, as `put_fixed` and `put_general` find it, times
    or over an exact power of ten (one correctly rounded operation: what reading the text gives).
    Returns how many were left (NaN in `out`) for Python to print and read."""
    left = 0
    for i in range(values.size):
        x = values[i]
        a = abs(x)
        out[i] = np.nan
        if a == 0.0 or not a < 1e300:
            if a == 0.0:
                out[i] = x
            else:
                left += 1
            continue
        if fixed:
            if p > 22:
                left += 1
                continue
            k = p
            s = a * _P10[k]
            if not s < _TWO52:
                left += 1
                continue
        else:
            if p > 15:
                left += 1
                continue
            s, k = _general_scale(a, p)
            if k > 22:
                left += 1
                continue
        n = _round_half_even(s)
        if n < 0:
            left += 1
            continue
        v = n / _P10[k] if k >= 0 else n * _P10[-k]
        out[i] = -v if math.copysign(1.0, x) < 0 else v
    return left
