"""Lossless coding of motion channel matrices parsed from decimal text (AMC).

An AMC file stores every channel value as decimal text, and a reader turns
each into the nearest float64.  `decode_channels(encode_channels(x))` gives
back exactly those float64 values, bit for bit (including -0.0 and, if they
ever occur, NaN or infinities), so any formatting of the decoded values
reproduces the text the file had.

Why not just compress the float64 bytes: the 52-bit mantissas of decimal
numbers look random.  The information really is a few decimal digits per
value, so each channel is turned into integers on a decimal grid, predicted
from the previous frames and only the small prediction residuals are stored.

Two kinds of decimal text occur:

* Fixed decimals (Vicon Blade: ``15.287990``, ``-0.000000``): every value is
  an integer multiple of 10**-6, so the channel is stored as those integers
  (the "grid" representation, ``sig_digits == 0``).
* Significant digits (CMU, HDM05 use ``%g`` with 6 digits: ``136.231``,
  ``9.37216``, ``3.64024e-015``): the quantum depends on the magnitude.  A
  single grid fine enough for the smallest values wastes bits on the large
  ones, and a channel that passes near zero would need 10**-20.  Instead each
  value is split around a per-channel *coarse unit* 10**coarse_exponent:

      value = sign * (coarse * 10**n + digits) * 10**(coarse_exponent - n)

  ``coarse`` (signed, truncated toward zero) is continuous in time, so it is
  predicted and its residuals are coded.  ``n`` is how many digits the value
  has below the coarse unit; the decoder derives it from ``coarse`` alone
  (a value has ``sig_digits`` digits, ``coarse`` shows how many are above
  the unit), so only the ``digits`` themselves are stored, grouped by ``n``.
  Values at or above the coarse decade need no extra digits at all.

Per channel the encoder tries the grid and a few coarse units, and for each
the predictors "none", "previous value", "linear extrapolation" and
"quadratic extrapolation" (integer differences of order 0-3), keeping the
cheapest by an estimate of the coded size.  Channels that never change are
stored once; channels identical to an earlier one are stored as a reference.

Every value is verified by running the decoder's arithmetic on it while
encoding; a value that would not come back bit for bit (too many digits,
outside the exactly representable range, NaN, ...) is stored raw as an
exception.  The decoder uses only integer arithmetic, table lookups of exact
powers of ten and single IEEE multiplications/divisions, so it gives the
same bits on every platform.

Measured on ../shared/data (bytes per frame, this codec vs ``xz -9`` of the
AMC text): CMU 01_01 113.0 vs 196.0, 07_01 119.8 vs 208.6, 135_02 103.4 vs
183.5; HDM05 bd squat 97.9 vs 181.0; Vicon Blade walkMoCapVideo 96.7 vs
191.6.  All 165 AMC files together: 0.57 of xz.  What is left is
measurement noise in the last printed digits (the prediction residuals are
nearly white); even optimistic in-sample models (16-tap linear prediction,
regression on every other channel of the same frame) leave about half of
xz on CMU data.
"""

import zlib
from dataclasses import dataclass

import numpy as np

from mocapzip.codec.entropy import ans
from mocapzip.codec.entropy import zstd
from mocapzip.limits import MAX_FRAMES_PER_CLIP, MAX_VALUES_PER_CLIP, MAX_VALUES_PER_FRAME
from mocapzip.stages import Stage, register

__all__ = ["DecimalChannelCoder", "encode_channels", "decode_channels"]


@register
class DecimalChannelCoder(Stage):
    """The lossless coder: AMC channel values back bit for bit (`--lossless`; the module doc says how)."""

    kind = "lossless coder"
    codec_id = "decimal"

    def encode(self, values) -> bytes:
        return encode_channels(values)

    def decode(self, blob: bytes) -> np.ndarray:
        return decode_channels(blob)

# The stream's own layout number, its first value (not the archive's format_version): 2 is
# written; 1, read only, was written by the first format-1 writers (docs/format.md).
_LAYOUT = 2
_KNOWN_LAYOUTS = (1, 2)

# Channel modes (first column of the channel table).
_CONSTANT = 0  # parameter: the float64 bits of the value
_DUPLICATE = 1  # parameter: index of the earlier, identical channel
_DECIMAL = 2  # parameters: sig_digits (0 = fixed grid), coarse_exponent, predictor order

_MAX_SIG_DIGITS = 15  # 10**15 < 2**53, so a significand converts to float64 exactly
_MAX_ORDER = 3
_MAX_COARSE = 2**50  # keeps order-3 differences (at most 8x larger) far inside int64
_MAX_COARSE_EXPONENT = 1 << 10  # far beyond any float64's decimal exponent (about -340 to 323)
_COARSE_CANDIDATES = 2  # coarse units tried: the top decade and one below (lower ones never won)
_EXACT_POWER = 22  # 10**k is exact in float64 for k <= 22
_POW10_INT = 10 ** np.arange(19, dtype=np.int64)
_POW10_FLOAT = np.array([float(10**k) for k in range(_EXACT_POWER + 1)])
_LOG2_10 = np.log2(10.0)
_EXCEPTION_BITS = 80  # rough coded cost of one raw exception (value + position)


def encode_channels(values) -> bytes:
    """Encode a (frames x channels) float64 matrix losslessly."""
    values = np.ascontiguousarray(values, dtype=np.float64)
    if values.ndim != 2:
        raise ValueError(f"expected a (frames x channels) matrix, got shape {values.shape}")
    n_frames, n_channels = values.shape
    bits = values.view(np.int64)

    table = np.zeros((n_channels, 4), np.int64)
    first_seen = {}
    decimal_columns = []
    for column in range(n_channels):
        column_bits = bits[:, column]
        if n_frames and np.all(column_bits == column_bits[0]):
            table[column] = (_CONSTANT, column_bits[0], 0, 0)
            continue
        key = column_bits.tobytes()
        if key in first_seen:
            table[column] = (_DUPLICATE, first_seen[key], 0, 0)
            continue
        first_seen[key] = column
        decimal_columns.append(column)

    needed, shortest_unit = _shortest_decimal(values[:, decimal_columns])
    channels = [
        _encode_decimal(values[:, column], needed[:, i], shortest_unit[:, i])
        for i, column in enumerate(decimal_columns)
    ]
    for column, channel in zip(decimal_columns, channels):
        table[column] = (_DECIMAL, channel.sig_digits, channel.coarse_exponent, 0)

    shape = (len(channels), n_frames)
    coarse = np.array([channel.coarse for channel in channels], np.int64).reshape(shape)
    orders, links, residuals = _choose_predictors(coarse)
    table[decimal_columns, 3] = orders
    n_below = np.array([channel.n_below for channel in channels], np.int64).reshape(shape)
    digits = np.array([channel.digits for channel in channels], np.int64).reshape(shape)
    exceptions = np.array([channel.exception for channel in channels], bool).reshape(shape)
    negative_zero = np.array([channel.negative_zero for channel in channels], bool).reshape(shape)
    decimal_bits = bits[:, decimal_columns].T

    exception_positions = np.flatnonzero(exceptions)
    meta = np.concatenate([[_LAYOUT, n_frames, n_channels], table.ravel()])
    sections = [
        zstd.encode_ints(meta),
        _encode_residuals(residuals),
        zstd.encode_ints(np.diff(exception_positions, prepend=0)),
        zstd.encode_ints(decimal_bits[exceptions]),
        zstd.encode_bytes(np.packbits(negative_zero[(coarse == 0) & ~exceptions]).tobytes()),
        zstd.encode_ints(_pack_links(links)),
    ]
    for n in range(1, n_below.max(initial=0) + 1):
        group = n_below == n
        if group.any():
            sections.append(_encode_digits(digits[group], n))
    return zstd.pack_blobs(sections)


def decode_channels(blob: bytes) -> np.ndarray:
    """Inverse of `encode_channels`; raises ValueError on corrupt input.

    The blob may come from anyone: its frame and channel counts are checked against the
    limits (mocapzip/limits.py), and every section against them, before anything is
    allocated or decoded.
    """
    sections = zstd.unpack_blobs(blob)
    if len(sections) < 5:
        raise ValueError(f"expected at least 5 sections, got {len(sections)}")
    meta = _int64s(sections[0], 3 + 4 * MAX_VALUES_PER_FRAME)
    if meta.ndim != 1 or meta.size < 3 or meta[0] not in _KNOWN_LAYOUTS:
        raise ValueError("not a lossless channel blob of a known version")
    layout = int(meta[0])
    n_frames = zstd.check_size(int(meta[1]), MAX_FRAMES_PER_CLIP, "frames")
    n_channels = zstd.check_size(int(meta[2]), MAX_VALUES_PER_FRAME, "channels")
    n_values = zstd.check_size(n_frames * n_channels, MAX_VALUES_PER_CLIP, "values")
    if meta.size != 3 + 4 * n_channels:
        raise ValueError("channel table does not match the channel count")
    table = meta[3:].reshape(n_channels, 4)
    modes = table[:, 0]
    if np.any((modes < _CONSTANT) | (modes > _DECIMAL)):
        raise ValueError("unknown channel mode in the channel table")
    decimal_columns = np.flatnonzero(modes == _DECIMAL)
    sig_digits, coarse_exponent, order = table[decimal_columns, 1:].T
    if (np.any((sig_digits < 0) | (sig_digits > _MAX_SIG_DIGITS)) or np.any((order < 0) | (order > _MAX_ORDER))
            or np.any((coarse_exponent < -_MAX_COARSE_EXPONENT) | (coarse_exponent > _MAX_COARSE_EXPONENT))):
        raise ValueError("invalid decimal channel parameters")
    shape = (len(decimal_columns), n_frames)

    first_digit_section = 5
    links = [None] * shape[0]
    if layout == 1:
        residuals = _int64s(sections[1], n_values)
        if residuals.shape != (shape[0] * shape[1],):
            raise ValueError(f"{residuals.size} residuals, expected {shape[0] * shape[1]}")
        residuals = residuals.reshape(shape)
    else:
        residuals = _decode_residuals(sections[1], shape)
        if len(sections) < 6:
            raise ValueError("missing predictor section")
        links = _unpack_links(_int64s(sections[5], shape[0] * (2 + 2 * _MAX_PARENTS)), shape[0])
        first_digit_section = 6
    coarse = _decode_coarse(residuals, order, links)

    exception_steps = _int64s(sections[2], n_values)
    exception_positions = np.cumsum(exception_steps)
    exception_bits = _int64s(sections[3], n_values)
    # Every position, not just the ends: huge steps could wrap around int64.
    in_range = np.all((exception_positions >= 0) & (exception_positions < coarse.size))
    increasing = np.all(exception_steps[1:] > 0)
    if exception_positions.size != exception_bits.size or not (in_range and increasing):
        raise ValueError("exception positions are inconsistent")
    exceptions = np.zeros(shape, bool)
    exceptions.flat[exception_positions] = True

    zero_slots = (coarse == 0) & ~exceptions
    sign_bits = np.unpackbits(np.frombuffer(zstd.decode_bytes(sections[4], (n_values + 7) // 8), np.uint8))
    n_zero_slots = int(zero_slots.sum())
    if sign_bits.size != (n_zero_slots + 7) // 8 * 8 or np.any(sign_bits[n_zero_slots:]):
        raise ValueError("zero sign bits do not match the zero values")
    negative_zero = np.zeros(shape, bool)
    negative_zero[zero_slots] = sign_bits[:n_zero_slots].astype(bool)

    n_below = np.where(exceptions, 0, _digits_below(coarse, sig_digits[:, None]))
    digits = np.zeros(shape, np.int64)
    next_section = first_digit_section
    for n in range(1, n_below.max(initial=0) + 1):
        group = n_below == n
        count = int(group.sum())
        if not count:
            continue
        if next_section >= len(sections):
            raise ValueError("missing digit section")
        if layout == 1:
            group_digits = zstd.decode_ints(sections[next_section], count)
        else:
            group_digits = _decode_digits(sections[next_section], n, count)
        next_section += 1
        if group_digits.shape != (count,):
            raise ValueError(f"digit section for n={n} has the wrong length")
        digits[group] = group_digits
    if next_section != len(sections):
        raise ValueError("unexpected extra sections")

    decimal_values = _assemble(coarse, digits, n_below, coarse_exponent[:, None], negative_zero)
    decimal_values.view(np.int64)[exceptions] = exception_bits

    out = np.empty((n_frames, n_channels), np.float64)
    out[:, decimal_columns] = decimal_values.T
    for column in range(n_channels):
        mode, parameter = table[column, :2]
        if mode == _CONSTANT:
            out[:, column] = np.array([parameter], np.int64).view(np.float64)[0]
        elif mode == _DUPLICATE:
            if not 0 <= parameter < column:
                raise ValueError(f"channel {column} duplicates invalid channel {parameter}")
            out[:, column] = out[:, parameter]
    return out


def _int64s(blob: bytes, max_values: int) -> np.ndarray:
    """A section the encoder writes as int64 (at most `max_values` of them); any other dtype is
    refused, so hostile values cannot overflow the decoder's arithmetic."""
    values = zstd.decode_ints(blob, max_values)
    if values.dtype != np.int64:
        raise ValueError(f"expected int64 values, got {values.dtype}")
    return values


# ------------------------------------------------------------ residual coding (layout 2)

_ANS = 1  # residuals: ans.encode_residuals (context-modelled bit lengths, rANS)
_ZSTD = 0  # digits: zstd.encode_ints
_PACKED = 2  # digits: groups packed in binary words (`_pack_decimal`)
_MAX_PACKED_DIGITS = 18
_ALWAYS_PACKED = 2  # digit groups of up to this many digits are uniform noise: no zstd try


def _encode_residuals(residuals) -> bytes:
    """Residuals with the rANS coder, behind a one-byte tag for the coder.

    On all AMC files of the shared data set it beats zstd.encode_ints by
    2-4 % (zstd never won), so zstd is not tried: it would double the time.
    """
    return bytes([_ANS]) + ans.encode_residuals(residuals)


def _decode_residuals(blob: bytes, shape) -> np.ndarray:
    if not blob or blob[0] != _ANS:
        raise ValueError("unknown residual coder")
    return ans.decode_residuals(blob[1:], *shape)


def _encode_digits(digits, n: int) -> bytes:
    """Digit groups below the coarse unit (each < 10**n): the smaller of zstd and packing.

    These digits are measurement noise, uniform for n = 1 and 2, where
    packing several groups into the fewest bits that hold them is within
    0.4 % of their entropy and about 5 % smaller than zstd.
    """
    candidates = [] if n <= _ALWAYS_PACKED else [bytes([_ZSTD]) + zstd.encode_ints(digits)]
    if n <= _MAX_PACKED_DIGITS:
        packed = _pack_decimal(digits, n)
        candidates.append(bytes([_PACKED]) + zlib.crc32(packed).to_bytes(4, "little") + packed)
    return min(candidates, key=len)


def _decode_digits(blob: bytes, n: int, count: int) -> np.ndarray:
    if not blob:
        raise ValueError("empty digit section")
    if blob[0] == _ZSTD:
        digits = zstd.decode_ints(blob[1:], count)
        if digits.shape != (count,):
            raise ValueError(f"digit section for n={n} has the wrong length")
    elif blob[0] == _PACKED and n <= _MAX_PACKED_DIGITS:
        crc, packed = blob[1:5], blob[5:]
        if len(crc) != 4 or zlib.crc32(packed) != int.from_bytes(crc, "little"):
            raise ValueError("CRC mismatch in packed digits")
        digits = _unpack_decimal(packed, n, count)
    else:
        raise ValueError(f"unknown digit coder {blob[0]}")
    if np.any((digits < 0) | (digits >= _POW10_INT[n])):
        raise ValueError(f"digit group out of range for n={n}")
    return digits.astype(np.int64)


def _decimal_word(n: int):
    """(groups per word, bits per word) with the fewest bits per group, words < 10**18."""
    options = [(g, (10 ** (g * n) - 1).bit_length()) for g in range(1, 18 // n + 1)]
    return min(options, key=lambda option: (option[1] / option[0], option[0]))


def _pack_decimal(digits, n: int) -> bytes:
    groups, width = _decimal_word(n)
    padded = np.zeros(-(-digits.size // groups) * groups, np.int64)
    padded[: digits.size] = digits
    words = padded.reshape(-1, groups) @ _POW10_INT[n * np.arange(groups)]
    bits = (words[:, None] >> np.arange(width - 1, -1, -1)) & 1
    return np.packbits(bits.astype(np.uint8)).tobytes()


def _unpack_decimal(packed: bytes, n: int, count: int) -> np.ndarray:
    groups, width = _decimal_word(n)
    n_words = -(-count // groups)
    if len(packed) != (n_words * width + 7) // 8:
        raise ValueError(f"packed digits for n={n} have the wrong length")
    bits = np.unpackbits(np.frombuffer(packed, np.uint8))
    if np.any(bits[n_words * width :]):
        raise ValueError("padding bits are not zero")
    bits = bits[: n_words * width].reshape(n_words, width).astype(np.int64)
    words = bits @ (np.int64(1) << np.arange(width - 1, -1, -1))
    if np.any(words >= _POW10_INT[n * groups]):
        raise ValueError("packed digit word out of range")
    digits = (words[:, None] // _POW10_INT[n * np.arange(groups)]) % _POW10_INT[n]
    digits = digits.ravel()
    if np.any(digits[count:]):
        raise ValueError("packed digits padding is not zero")
    return digits[:count]


# ------------------------------------------------------------ one channel


@dataclass
class _Channel:
    """One decimal channel as the container stores it (arrays have one entry per frame)."""

    sig_digits: int  # 0: fixed grid, no digits below the coarse unit
    coarse_exponent: int
    order: int  # predictor: differences of this order are stored
    coarse: np.ndarray
    n_below: np.ndarray  # digits stored below the coarse unit, 0 at exceptions
    digits: np.ndarray
    exception: np.ndarray  # stored raw instead
    negative_zero: np.ndarray
    cost: float  # estimated coded size in bits, to compare candidates


def _encode_decimal(column, needed, shortest_unit) -> _Channel:
    """Pick the cheapest (representation, coarse unit, predictor) for one channel.

    `needed` and `shortest_unit` come from `_shortest_decimal`.
    """
    decimal = needed > 0
    if not decimal.any():
        # Nothing decimal: every non-zero value becomes an exception.
        return _verified(column, 0, 0, *_grid_split(column, 0))

    # The finest fixed grid that holds every decimal value.
    grid_exponent = int(shortest_unit[decimal].min())
    candidates = [_verified(column, 0, grid_exponent, *_grid_split(column, grid_exponent))]

    # Significant digits, with the coarse unit at the top decade or a few below.
    sig_digits = int(needed.max())
    significand, unit = _significand(column, sig_digits)
    top_unit = int(unit[decimal].max())
    for coarse_exponent in range(top_unit, top_unit - _COARSE_CANDIDATES, -1):
        coarse, digits = _significant_split(significand, unit, coarse_exponent)
        candidates.append(_verified(column, sig_digits, coarse_exponent, coarse, digits))
    return min(candidates, key=lambda channel: channel.cost)


def _grid_split(column, grid_exponent):
    """coarse = value / 10**grid_exponent rounded; no digits below."""
    scaled = _scale(column, -grid_exponent)
    fits = np.isfinite(scaled) & (np.abs(scaled) < _MAX_COARSE)
    coarse = np.rint(np.where(fits, scaled, 0)).astype(np.int64)
    return coarse, np.zeros(column.shape, np.int64)


def _significant_split(significand, unit, coarse_exponent):
    """Split significand * 10**unit into coarse (units of 10**coarse_exponent) and digits below."""
    magnitude = np.abs(significand)
    shift = unit - coarse_exponent
    below = np.clip(-shift, 0, 18)
    above = np.clip(shift, 0, 18)
    fits = magnitude * _POW10_FLOAT[np.minimum(above, _EXACT_POWER)] < _MAX_COARSE
    coarse = np.where(fits, magnitude * _POW10_INT[above] // _POW10_INT[below], 0)
    return np.sign(significand) * coarse, magnitude % _POW10_INT[below]


def _verified(column, sig_digits, coarse_exponent, coarse, digits) -> _Channel:
    """Run the decoder on a candidate split, make failures exceptions, choose the predictor."""
    n_below = _digits_below(coarse, sig_digits)
    digits = np.where(n_below > 0, digits, 0)
    negative_zero = (coarse == 0) & np.signbit(column)
    decoded = _assemble(coarse, digits, n_below, coarse_exponent, negative_zero)
    exception = decoded.view(np.int64) != column.view(np.int64)

    # Exceptions are stored raw; hold the last good coarse value there so the
    # predictor does not see a jump.  The decoder ignores digits and signs there.
    coarse = np.where(exception, 0, coarse)
    coarse = coarse[np.maximum.accumulate(np.where(exception, 0, np.arange(column.size)))]
    n_below = np.where(exception, 0, n_below)
    digits = np.where(exception, 0, digits)
    negative_zero &= ~exception

    order = _best_order(coarse)
    cost = (
        np.log2(1.0 + np.abs(_difference(coarse, order))).sum()
        + _LOG2_10 * n_below.sum()
        + _EXCEPTION_BITS * exception.sum()
    )
    return _Channel(sig_digits, coarse_exponent, order, coarse, n_below, digits,
                    exception, negative_zero, cost)


def _best_order(coarse: np.ndarray) -> int:
    """Predictor order with the smallest sum of |residual| (ignoring the start-up values)."""
    sums = [np.abs(np.diff(coarse[_MAX_ORDER - k :], k)).sum() for k in range(_MAX_ORDER + 1)]
    return int(np.argmin(sums))


# ------------------------------------------------------------ decimal arithmetic


def _shortest_decimal(values: np.ndarray):
    """Shortest exact decimal form of each value: (significant digits, unit exponent).

    A value needing `needed` digits equals significand * 10**unit with
    |significand| < 10**needed.  needed == 0 marks zeros and values with no
    exact form of at most _MAX_SIG_DIGITS digits (binary fractions, NaN, ...).

    Any decimal of at most 15 digits survives the trip through float64, so
    rounding to 15 digits recovers it exactly, padded with trailing zeros;
    stripping those gives the shortest form, which is then verified.  Tiny
    values get fewer digits, so the power of ten used for scaling stays exact.
    """
    usable = np.isfinite(values) & (values != 0)
    decade = np.floor(np.log10(np.where(usable, np.abs(values), 1.0))).astype(np.int64)
    digits = np.clip(decade + _EXACT_POWER + 1, 1, _MAX_SIG_DIGITS)
    significand, unit = _significand(values, digits)
    magnitude = np.abs(significand)
    trailing_zeros = sum(
        magnitude % _POW10_INT[k] == 0 for k in range(1, _MAX_SIG_DIGITS)
    ).astype(np.int64)
    shortest_unit = unit + trailing_zeros
    shortest = (significand // _POW10_INT[trailing_zeros]).astype(np.float64)
    exact = (magnitude > 0) & (_scale(shortest, shortest_unit) == values)
    needed = np.where(exact, digits - trailing_zeros, 0)
    return needed, shortest_unit


def _significand(values, sig_digits):
    """Write each value as significand * 10**unit with |significand| having sig_digits digits.

    The significand is rounded, so it is exact only if the value really has
    that few digits; callers verify.  Zeros and non-finite values give 0.
    """
    usable = np.isfinite(values) & (values != 0)
    magnitude = np.where(usable, np.abs(values), 1.0)
    unit = np.floor(np.log10(magnitude)).astype(np.int64) - (sig_digits - 1)
    significand = np.rint(_scale(magnitude, -unit))
    # log10 can be off by one next to a power of ten; rounding can also carry
    # into a new digit (9.9999996 -> 10.00000).  Move the unit to fix both.
    unit = np.where(significand >= _POW10_FLOAT[sig_digits], unit + 1, unit)
    unit = np.where(significand < _POW10_FLOAT[sig_digits - 1], unit - 1, unit)
    significand = np.rint(_scale(magnitude, -unit))
    significand = np.where(usable & np.isfinite(significand), significand, 0)
    significand = np.where(significand < 2.0**62, significand, 0).astype(np.int64)
    return np.where(values < 0, -significand, significand), unit


def _scale(values, exponent):
    """values * 10**exponent, as a single IEEE operation with an exact power of ten.

    This is the decoder's conversion, so it must give the same bits on every
    platform: no pow() or log(), only table lookups and one multiply or divide.
    Exponents beyond the exact table are clipped; such values fail
    verification and become exceptions.
    """
    exponent = np.asarray(exponent)
    power = _POW10_FLOAT[np.minimum(np.abs(exponent), _EXACT_POWER)]
    with np.errstate(over="ignore", invalid="ignore"):
        return np.where(exponent >= 0, values * power, values / power)


def _digits_below(coarse, sig_digits):
    """Digits stored below the coarse unit: sig_digits minus the digits coarse already has."""
    magnitude = np.abs(coarse)
    digits_in_coarse = np.searchsorted(_POW10_INT, magnitude.ravel(), side="right").reshape(
        magnitude.shape
    )
    return np.where(coarse != 0, np.maximum(sig_digits - digits_in_coarse, 0), 0)


def _assemble(coarse, digits, n_below, coarse_exponent, negative_zero):
    """The decoder's formula: sign * (|coarse| * 10**n + digits) * 10**(coarse_exponent - n)."""
    n_below = np.clip(n_below, 0, 18)
    magnitude = (np.abs(coarse) * _POW10_INT[n_below] + digits).astype(np.float64)
    value = _scale(magnitude, coarse_exponent - n_below)
    value = np.where(coarse < 0, -value, value)
    return np.where(negative_zero, -0.0, value)


# ------------------------------------------------------------ prediction


def _difference(x: np.ndarray, order: int) -> np.ndarray:
    """Residuals of polynomial extrapolation of the given order along the last axis.

    The first `order` entries are the start-up values x[0], Δx[0], Δ²x[0], ...
    so the output has the same length as the input and `_integrate` inverts it.
    Order 1 predicts the previous value, 2 linear, 3 quadratic extrapolation.
    """
    r = np.array(x, copy=True)
    for j in range(order):
        r[..., j + 1 :] = np.diff(r[..., j:], axis=-1)
    return r


def _integrate(r: np.ndarray, order: int) -> np.ndarray:
    """Inverse of `_difference`."""
    x = np.array(r, np.int64, copy=True)
    for j in reversed(range(order)):
        x[..., j:] = np.cumsum(x[..., j:], axis=-1)
    return x


# ------------------------------------------------------------ links (layout 2)
#
# A channel may have a link: its residual row (differences of its order) is
# predicted as a weighted sum of the same differences of earlier channels'
# coarse values, and only what is left is stored.  Thumb angles follow the
# hand almost exactly, the angles of one joint move together, and channels
# of different bones share the solver's noise.

_MAX_PARENTS = 6
_MAX_MANTISSA = 2**31  # |weight mantissa| bound
_MAX_SHIFT = 62
_MAX_PREDICTION = 2.0**53  # predictions are clipped here, so residuals stay far inside int64
_LINK_BITS = 25  # rough coded cost of one stored parent (index and weight)
_STARTUP = _MAX_ORDER  # entries left out when fitting (they hold start-up values)
_WEIGHT_PRECISION = 0.1  # weight rounding error, relative to the residual it predicts
_SEARCH_MARGIN = 1.15  # link search only for orders this close to the best order alone


@dataclass
class _Link:
    """Prediction of a channel's differences from the same differences of earlier channels."""

    parents: np.ndarray  # indices of earlier decimal channels
    shift: int  # weights are mantissas / 2**shift
    mantissas: np.ndarray


def _link_prediction(coarse, link: _Link, order: int) -> np.ndarray:
    """The decoder's prediction: rint(sum(mantissa * feature) / 2**shift), clipped.

    Float64 arithmetic in a fixed order (one multiply and one add per parent,
    then an exact power-of-two scaling), so every platform gets the same bits.
    """
    total = np.zeros(coarse.shape[1], np.float64)
    for parent, mantissa in zip(link.parents, link.mantissas):
        total += float(mantissa) * _difference(coarse[parent].astype(np.float64), order)
    total = np.ldexp(total, -link.shift)
    prediction = np.rint(np.clip(total, -_MAX_PREDICTION, _MAX_PREDICTION)).astype(np.int64)
    prediction[:order] = 0  # start-up values are stored as they are
    return prediction


def _decode_coarse(residuals, orders, links) -> np.ndarray:
    """Coarse values from residuals: channels without links in bulk, the others in order."""
    coarse = np.empty(residuals.shape, np.int64)
    linked = np.array([link is not None for link in links], bool)
    for order in range(_MAX_ORDER + 1):
        rows = (orders == order) & ~linked
        if rows.any():
            coarse[rows] = _integrate(residuals[rows], order)
    for row in np.flatnonzero(linked):
        order = int(orders[row])
        predicted = residuals[row] + _link_prediction(coarse, links[row], order)
        coarse[row] = _integrate(predicted, order)
    return coarse


def _pack_links(links) -> np.ndarray:
    """[parent count per channel..., then per linked channel: shift, distances, mantissas]."""
    counts = [0 if link is None else len(link.parents) for link in links]
    parts = [np.array(counts, np.int64)]
    for row, link in enumerate(links):
        if link is not None:
            parts.append(np.array([link.shift], np.int64))
            parts.append(row - 1 - np.asarray(link.parents, np.int64))
            parts.append(np.asarray(link.mantissas, np.int64))
    return np.concatenate(parts)


def _unpack_links(flat: np.ndarray, n_rows: int) -> list:
    if flat.ndim != 1 or flat.size < n_rows:
        raise ValueError("predictor table is too short")
    counts = flat[:n_rows]
    if np.any((counts < 0) | (counts > _MAX_PARENTS)):
        raise ValueError("invalid parent count in the predictor table")
    links = [None] * n_rows
    position = n_rows
    for row in np.flatnonzero(counts):
        count = int(counts[row])
        end = position + 1 + 2 * count
        if end > flat.size:
            raise ValueError("predictor table is too short")
        shift = int(flat[position])
        parents = row - 1 - flat[position + 1 : position + 1 + count]
        mantissas = flat[position + 1 + count : end]
        if not 0 <= shift <= _MAX_SHIFT or np.any(parents < 0) or np.any(parents >= row):
            raise ValueError("invalid parent in the predictor table")
        if np.any(np.abs(mantissas) >= _MAX_MANTISSA) or len(set(parents.tolist())) != count:
            raise ValueError("invalid weight in the predictor table")
        links[row] = _Link(parents, shift, mantissas)
        position = end
    if position != flat.size:
        raise ValueError("unexpected extra entries in the predictor table")
    return links


def _residual_cost(residuals) -> np.ndarray:
    """Estimated coded bits of residual rows (last axis), without the start-up entries."""
    return np.log2(1.0 + np.abs(residuals[..., _STARTUP:])).sum(axis=-1)


def _choose_predictors(coarse):
    """Per channel, the cheapest predictor order and optional link to earlier channels.

    Links: parents are chosen greedily on the Gram matrix of the differences
    (each step takes the channel that explains most of what is left, as in
    orthogonal matching pursuit), weights by least squares, and a link is
    kept only if the residuals, rounded as the decoder rounds, are cheaper by
    more than the stored weights cost.  Returns (orders, links, residuals).
    """
    n_rows, n_frames = coarse.shape
    own = [_difference(coarse, order) for order in range(_MAX_ORDER + 1)]
    own_cost = np.array([_residual_cost(rows) for rows in own]).reshape(_MAX_ORDER + 1, n_rows)
    orders = np.argmin(own_cost, axis=0).astype(np.int64)
    links = [None] * n_rows
    residuals = np.array([own[order][row] for row, order in enumerate(orders)], np.int64)
    residuals = residuals.reshape(coarse.shape)
    usable = n_frames - _STARTUP
    if n_rows < 2 or usable < 8:
        return orders, links, residuals

    grams = {}
    for row in range(1, n_rows):
        best_cost = own_cost[orders[row], row]
        for order in range(_MAX_ORDER + 1):
            if own_cost[order, row] > _SEARCH_MARGIN * own_cost[orders[row], row] + 64:
                continue
            if order not in grams:
                tail = own[order][:, _STARTUP:].astype(np.float64)
                grams[order] = tail @ tail.T
            parents = _greedy_parents(grams[order], row, usable)
            link = _fit_link(grams[order], row, parents, usable) if parents else None
            if link is None:
                continue
            candidate = own[order][row] - _link_prediction(coarse, link, order)
            cost = _residual_cost(candidate) + _LINK_BITS * len(link.parents)
            if cost < best_cost:
                best_cost, orders[row], links[row], residuals[row] = cost, order, link, candidate
    return orders, links, residuals


def _greedy_parents(gram, row, usable) -> list:
    """Earlier channels that explain `row`, by forward selection on the Gram matrix."""
    matrix = gram[: row + 1, : row + 1].copy()
    diagonal = np.diag(matrix).copy()
    chosen = []
    while len(chosen) < _MAX_PARENTS:
        pivots = np.diag(matrix)[:row]
        valid = pivots > 1e-9 * np.maximum(diagonal[:row], 1e-300)
        valid[chosen] = False
        if not valid.any():
            break
        score = np.where(valid, matrix[:row, row] ** 2 / np.where(valid, pivots, 1.0), -1.0)
        best = int(np.argmax(score))
        left = matrix[row, row]
        after = max(left - score[best], 1e-12 * max(diagonal[row], 1e-300))
        if left <= 0 or 0.5 * usable * np.log2(left / after) < 2 * _LINK_BITS:
            break
        chosen.append(best)
        pivot_column = matrix[:, best].copy()
        matrix -= np.outer(pivot_column, matrix[best]) / matrix[best, best]
    return sorted(chosen)


def _fit_link(gram, row, parents, usable):
    """Least-squares weights for `parents`, quantised to mantissas / 2**shift."""
    normal = gram[np.ix_(parents, parents)]
    try:
        weights = np.linalg.solve(normal, gram[parents, row])
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(weights)) or not np.any(weights):
        return None
    explained = float(weights @ gram[parents, row])
    residual_rms = max(float(np.sqrt(max(gram[row, row] - explained, 0.0) / usable)), 0.5)
    feature_rms = float(np.sqrt(np.diag(normal).max() / usable))
    # Rounding each weight to 2**-shift moves the prediction by about
    # feature_rms * 2**-shift per parent: keep that well below the residual.
    wanted = np.ceil(np.log2(feature_rms * len(parents) / (_WEIGHT_PRECISION * residual_rms)))
    room = np.floor(np.log2((_MAX_MANTISSA - 1) / np.abs(weights).max()))
    shift = int(min(max(wanted, 0), room, _MAX_SHIFT))
    if shift < 0:
        return None
    mantissas = np.rint(np.ldexp(weights, shift)).astype(np.int64)
    keep = mantissas != 0
    if not keep.any():
        return None
    return _Link(np.asarray(parents, np.int64)[keep], shift, mantissas[keep])
