"""Lossless clip streams (`clip/NNNNN` when `settings.lossless` is true).

Implements docs/format.md §9, "Lossless clip streams": the stream is a blob list of
sections (header, residuals, exceptions, negative zeros, links, digits) from which the
clip's AMC values are rebuilt as float64, bit for bit. Section names below are those of
that chapter ("Stream", "Residuals, layout 2", "Links", "Coarse values", "Exceptions",
"Negative zeros", "Digit sections", "Values", "Limits a reader checks"), with the building
blocks of §1 ("Conventions and building blocks"). The layout is the same in every container
format_version.

A reference decoder for trusted test files: it checks the CRCs, the exact lengths and the
limits the spec lists, and raises ValueError when one fails.
"""

import zlib

import numpy as np
import zstandard

from .container import Reader

MAX_FRAMES = 1 << 20
MAX_COLUMNS = 1 << 14
MAX_CELLS = 1 << 23
MAX_ZSTD_CONTENT = 1 << 28   # every zstd-coded stream is limited to 256 MiB (format.md)

INT64 = 3                    # "ints" dtype number of int64
DTYPES = [np.int8, np.int16, np.int32, np.int64, np.uint8, np.uint16, np.uint32, np.uint64]

# "Digit sections": digits per word `g` and word width `w` for n = 1 .. 18.
DIGIT_WORDS = {1: (3, 10), 2: (3, 20), 3: (1, 10), 4: (3, 40), 5: (3, 50), 6: (1, 20),
               7: (2, 47), 8: (1, 27), 9: (1, 30), 10: (1, 34), 11: (1, 37), 12: (1, 40),
               13: (1, 44), 14: (1, 47), 15: (1, 50), 16: (1, 54), 17: (1, 57), 18: (1, 60)}

# "Residuals, layout 2": the adaptive bucket model.
BUCKETS = 65
PROB_BITS = 15
PROB_TOTAL = 1 << PROB_BITS          # 32768
RANS_LOW = 1 << 16
COUNT_STEP = 32
COUNT_LIMIT = 1 << 22
UPDATE_PERIOD = 8
MAX_BUCKETS_PER_WORD = 11351


# --------------------------------------------------------------------------------------
# Building blocks (§1)
# --------------------------------------------------------------------------------------

def blob_list(data: bytes, what: str) -> list:
    """`varint n`, `n` varint lengths, the `n` byte strings; nothing after them."""
    reader = Reader(data, what)
    lengths = [reader.varint() for _ in range(reader.varint())]
    blobs = [reader.take(n) for n in lengths]
    reader.end()
    return blobs


def zstd_frame(data: bytes, what: str) -> tuple:
    """One zstd frame at the start of `data` -> (content, bytes after the frame).

    "zstd frame": the writer sets the content size and the content checksum; the
    checksum is verified (libzstd does so when the frame has one).
    """
    try:
        params = zstandard.get_frame_parameters(data)
    except zstandard.ZstdError as exc:
        raise ValueError(f"{what}: not a zstd frame ({exc})") from None
    if params.content_size == zstandard.CONTENTSIZE_UNKNOWN or not params.has_checksum:
        raise ValueError(f"{what}: zstd frame without content size or checksum")
    if params.content_size > MAX_ZSTD_CONTENT:
        raise ValueError(f"{what}: zstd frame too large")
    decoder = zstandard.ZstdDecompressor().decompressobj()
    try:
        content = decoder.decompress(data)
    except zstandard.ZstdError as exc:
        raise ValueError(f"{what}: bad zstd frame ({exc})") from None
    if not decoder.eof or len(content) != params.content_size:
        raise ValueError(f"{what}: truncated zstd frame")
    return content, decoder.unused_data


def zstd_only(data: bytes, what: str) -> bytes:
    """"zstd(x)": exactly one frame and nothing after it."""
    content, rest = zstd_frame(data, what)
    if rest:
        raise ValueError(f"{what}: bytes after the zstd frame")
    return content


def bit_string(data: bytes, bits: int, what: str) -> np.ndarray:
    """"bit string": `bits` bits, MSB first, exactly ceil(bits/8) bytes, zero padding."""
    if len(data) != (bits + 7) // 8:
        raise ValueError(f"{what}: bit string of {len(data)} bytes for {bits} bits")
    unpacked = np.unpackbits(np.frombuffer(data, dtype=np.uint8))
    if unpacked[bits:].any():
        raise ValueError(f"{what}: non-zero padding bits")
    return unpacked[:bits]


def unzigzag(codes: np.ndarray) -> np.ndarray:
    """zigzag back, in 64 bits: `v = (u >> 1) XOR -(u & 1)`."""
    codes = codes.astype(np.uint64)
    return ((codes >> np.uint64(1)) ^ (np.uint64(0) - (codes & np.uint64(1)))).view(np.int64)


def bits_below_leading_one(lengths: np.ndarray, data: bytes, what: str) -> np.ndarray:
    """Codes from their bit lengths and the bits below their leading ones (uint64).

    Shared by the ints "bit length" layout and the rANS "verbatim bits": one bit string
    written bit position by bit position: for p = 0, 1, ..., bit p (weight 2^p) of every
    code with `len - 1 > p`, codes in order. Code = 2^(len-1) + those bits, 0 for len 0.
    """
    lengths = np.asarray(lengths, dtype=np.int64)
    below = np.maximum(lengths - 1, 0)
    bits = bit_string(data, int(below.sum()), what)
    codes = np.zeros(len(lengths), dtype=np.uint64)
    nonzero = lengths > 0
    codes[nonzero] = np.uint64(1) << (lengths[nonzero] - 1).astype(np.uint64)
    pos = 0
    for p in range(int(below.max(initial=0))):
        which = np.nonzero(below > p)[0]
        chunk = bits[pos:pos + len(which)].astype(np.uint64)
        codes[which] |= chunk << np.uint64(p)
        pos += len(which)
    return codes


def dense_codes(reader: Reader, count: int) -> np.ndarray:
    """ints "dense" data: `u8 width`, then `width` byte planes of `count` bytes."""
    width = reader.u8()
    if width > 8:
        raise ValueError(f"{reader.what}: dense width {width} > 8")
    codes = np.zeros(count, dtype=np.uint64)
    for k in range(width):
        plane = np.frombuffer(reader.take(count), dtype=np.uint8).astype(np.uint64)
        codes |= plane << np.uint64(8 * k)
    return codes


def read_ints(section: bytes, what: str, max_count: int, dtype: int = None) -> np.ndarray:
    """An "ints" array (zstd frame; in layout 2 "bit length" followed by its tail bits).

    Returns the one-dimensional array in its declared dtype. `max_count` is the limit
    of "Limits a reader checks"; `dtype`, if given, is the required dtype number.
    """
    content, tail = zstd_frame(section, what)
    reader = Reader(content, what)
    layout, kind, order, ndim = reader.u8(), reader.u8(), reader.u8(), reader.u8()
    if layout > 2 or kind > 7 or order > 1:
        raise ValueError(f"{what}: bad ints header ({layout}, {kind}, {order})")
    if dtype is not None and kind != dtype:
        raise ValueError(f"{what}: dtype {kind}, expected {dtype}")
    if ndim != 1:
        raise ValueError(f"{what}: ints of {ndim} dimensions (must be 1)")
    count = reader.varint()
    if count > max_count:
        raise ValueError(f"{what}: {count} values, at most {max_count} allowed")

    if layout == 0:
        codes = dense_codes(reader, count)
    elif layout == 1:
        present = bit_string(reader.take((count + 7) // 8), count, what).astype(bool)
        codes = np.zeros(count, dtype=np.uint64)
        codes[present] = dense_codes(reader, int(present.sum()))
        if (codes[present] == 0).any():
            raise ValueError(f"{what}: bitmap lists a zero code")
    else:
        crc = reader.u32()
        lengths = np.frombuffer(reader.take(count), dtype=np.uint8)
        if (lengths > 64).any():
            raise ValueError(f"{what}: bit length above 64")
        if zlib.crc32(tail) != crc:
            raise ValueError(f"{what}: CRC mismatch of the bit-length tail")
        codes = bits_below_leading_one(lengths, tail, what)
        tail = b""
    reader.end()
    if tail:
        raise ValueError(f"{what}: bytes after the zstd frame")

    target = np.dtype(DTYPES[kind])
    if target.kind == "i":
        values = unzigzag(codes)
        info = np.iinfo(target)
        if ((values < info.min) | (values > info.max)).any():
            raise ValueError(f"{what}: value outside {target}")
    else:
        values = codes
        if ((values > np.iinfo(target).max)).any():
            raise ValueError(f"{what}: value outside {target}")
    return values.astype(target)


# --------------------------------------------------------------------------------------
# Residuals, layout 2: the rANS residual stream
# --------------------------------------------------------------------------------------

def refresh(counts: np.ndarray) -> tuple:
    """"refresh": frequencies (summing to 2^15) and cumulative starts from counts.

    `counts` is (contexts, 65); returns (f, cum) of the same shape.
    """
    total = counts.sum(axis=1, keepdims=True)
    freq = counts * (PROB_TOTAL - BUCKETS) // total + 1
    largest = np.argmax(freq, axis=1)            # first bucket with the largest f
    freq[np.arange(len(freq)), largest] += PROB_TOTAL - freq.sum(axis=1)
    cum = np.cumsum(freq, axis=1) - freq
    return freq, cum


def lane_layout(T: int) -> tuple:
    """"Lanes": (segment length `len`, segment count `G`); both 0 when T = 0."""
    if T == 0:
        return 0, 0
    seg_len = -(-T // min(16, max(1, T // 1024)))
    return seg_len, -(-T // seg_len)


def rans_buckets(scheme: int, states: list, words: np.ndarray, R: int, T: int) -> np.ndarray:
    """Decode the R x T bucket matrix ("Lanes", "Model", "Decoding").

    The lanes of one step are independent (all contexts are taken before any update and
    the tables change only every 8 steps), so each step is done for all lanes at once;
    the words are handed out in ascending lane order to the lanes that renormalise.
    """
    buckets = np.zeros((R, T), dtype=np.int64)
    seg_len, groups = lane_layout(T)
    lanes = R * groups
    if lanes == 0:
        return buckets
    last_len = T - (groups - 1) * seg_len        # steps of the last segment

    contexts = 131 if scheme == 0 else 393
    counts = np.ones((contexts, BUCKETS), dtype=np.int64)
    freq, cum = refresh(counts)
    level = np.full(lanes, 128, dtype=np.int64)
    prev = np.full(lanes, 128, dtype=np.int64)
    x = np.array(states, dtype=np.int64)
    lane_row = np.arange(lanes) % R
    lane_start = (np.arange(lanes) // R) * seg_len
    next_word = 0
    pending_ctx, pending_b = [], []

    for k in range(seg_len):
        active = lanes if k < last_len else R * (groups - 1)
        lvl = level[:active]
        q = np.minimum((lvl + 4) // 8, 130)
        if scheme == 0:
            ctx = q
        else:
            d = prev[:active] - lvl
            ctx = 3 * q + 1 + (d > 24).astype(np.int64) - (d < -24).astype(np.int64)

        xa = x[:active]
        y = xa & (PROB_TOTAL - 1)
        starts = cum[ctx]                                   # (active, 65)
        b = (starts <= y[:, None]).sum(axis=1) - 1          # starts strictly increase
        f_b = freq[ctx, b]
        xa = f_b * (xa >> PROB_BITS) + y - starts[np.arange(active), b]
        low = np.nonzero(xa < RANS_LOW)[0]                  # ascending lane order
        if next_word + len(low) > len(words):
            raise ValueError("rANS: word stream exhausted")
        xa[low] = (xa[low] << 16) | words[next_word:next_word + len(low)]
        next_word += len(low)
        x[:active] = xa
        buckets[lane_row[:active], lane_start[:active] + k] = b

        level[:active] = lvl + ((16 * b - lvl) >> 2)         # arithmetic shift: floor
        prev[:active] = 16 * b
        pending_ctx.append(ctx)
        pending_b.append(b)
        if (k + 1) % UPDATE_PERIOD == 0:
            ctx_all = np.concatenate(pending_ctx)
            np.add.at(counts, (ctx_all, np.concatenate(pending_b)), COUNT_STEP)
            touched = np.unique(ctx_all)
            sub = counts[touched]
            halve = sub.sum(axis=1) > COUNT_LIMIT
            sub[halve] = (sub[halve] + 1) >> 1
            counts[touched] = sub
            freq[touched], cum[touched] = refresh(sub)
            pending_ctx, pending_b = [], []

    if next_word != len(words):
        raise ValueError("rANS: words left over")
    if (x != RANS_LOW).any():
        raise ValueError("rANS: final state is not 2^16")
    return buckets


def rans_residuals(section: bytes, R: int, T: int) -> np.ndarray:
    """Section 1 of layout 2: `u8 1`, `u32 crc`, blob list body -> R x T int64 residuals."""
    reader = Reader(section, "residuals")
    if reader.u8() != 1:
        raise ValueError("residuals: unknown coder tag")
    crc = reader.u32()
    body = reader.rest()
    if zlib.crc32(body) != crc:
        raise ValueError("residuals: CRC mismatch")
    parts = blob_list(body, "residuals")
    if len(parts) != 4:
        raise ValueError("residuals: body must have 4 parts")
    head, state_bytes, word_bytes, verbatim = parts
    if len(head) != 2 or head[0] != 1 or head[1] > 1:
        raise ValueError("residuals: bad version or scheme")
    scheme = head[1]

    lanes = R * lane_layout(T)[1]
    if len(state_bytes) != 4 * lanes or len(word_bytes) % 2 or (lanes == 0 and word_bytes):
        raise ValueError("residuals: bad state or word stream length")
    states = [int.from_bytes(state_bytes[4 * i:4 * i + 4], "little") for i in range(lanes)]
    if any(s < RANS_LOW for s in states):
        raise ValueError("residuals: initial state below 2^16")
    words = np.frombuffer(word_bytes, dtype="<u2").astype(np.int64)
    if R * T > MAX_BUCKETS_PER_WORD * (len(words) + lanes):
        raise ValueError("residuals: more buckets than the words can hold")

    buckets = rans_buckets(scheme, states, words, R, T)
    codes = bits_below_leading_one(buckets.ravel(), verbatim, "residuals: verbatim bits")
    return unzigzag(codes).reshape(R, T)


# --------------------------------------------------------------------------------------
# Coarse values
# --------------------------------------------------------------------------------------

def diff(x: np.ndarray, order: int) -> np.ndarray:
    """The difference form of order `order` along the frames (works for int64 and float64)."""
    r = x.copy()
    for j in range(order):
        r[j + 1:] = r[j + 1:] - r[j:-1]
    return r


def integrate(r: np.ndarray, order: int) -> np.ndarray:
    """Inverse of `diff`, int64 (wrapping): running sums of x[j:] for j = o-1 .. 0."""
    x = r.astype(np.int64)
    for j in range(order - 1, -1, -1):
        x[j:] = np.cumsum(x[j:], dtype=np.int64)
    return x


def read_links(values: np.ndarray, R: int) -> list:
    """"Links": per row None or (shift, parents, mantissas)."""
    values = [int(v) for v in values]
    if len(values) < R:
        raise ValueError("links: fewer than R parent counts")
    counts, pos = values[:R], R
    links = []
    for r, m in enumerate(counts):
        if not 0 <= m <= 6:
            raise ValueError("links: parent count outside 0..6")
        if m == 0:
            links.append(None)
            continue
        if pos + 1 + 2 * m > len(values):
            raise ValueError("links: truncated")
        shift = values[pos]
        parents = [r - 1 - d for d in values[pos + 1:pos + 1 + m]]
        mantissas = values[pos + 1 + m:pos + 1 + 2 * m]
        pos += 1 + 2 * m
        if not 0 <= shift <= 62 or any(abs(mu) >= 1 << 31 for mu in mantissas):
            raise ValueError("links: shift or mantissa out of range")
        if len(set(parents)) != m or any(not 0 <= p < r for p in parents):
            raise ValueError("links: bad parents")
        links.append((shift, parents, mantissas))
    if pos != len(values):
        raise ValueError("links: values after the last link")
    return links


def coarse_values(residuals: np.ndarray, orders: list, links: list) -> np.ndarray:
    """"Coarse values": rows in ascending order, each from its residuals and links."""
    R, T = residuals.shape
    coarse = np.zeros((R, T), dtype=np.int64)
    for r in range(R):
        order = orders[r]
        e = residuals[r]
        if links[r] is not None:
            shift, parents, mantissas = links[r]
            acc = np.zeros(T)                          # +0.0
            for parent, mu in zip(parents, mantissas):
                g = diff(coarse[parent].astype(np.float64), order)
                acc = acc + float(mu) * g              # two roundings, no FMA
            acc = acc * 2.0 ** -shift                  # exact
            pred = np.rint(np.clip(acc, -2.0 ** 53, 2.0 ** 53)).astype(np.int64)
            pred[:order] = 0
            e = e + pred                               # int64, wraps
        coarse[r] = integrate(e, order)
    return coarse


# --------------------------------------------------------------------------------------
# Digits and values
# --------------------------------------------------------------------------------------

def nbelow(coarse: np.ndarray, sig: np.ndarray) -> np.ndarray:
    """Digits below `coarse`: max(S - D, 0), 0 where coarse = 0 or S = 0.

    D counts k = 0..18 with 10^k <= |coarse|; |INT64_MIN| stays negative and counts 0.
    """
    magnitude = np.abs(coarse)                          # wraps for INT64_MIN
    digits = np.zeros(coarse.shape, dtype=np.int64)
    for k in range(19):
        digits += magnitude >= 10 ** k
    n = np.maximum(sig[:, None] - digits, 0)
    n[(coarse == 0) | (sig[:, None] == 0)] = 0
    return n


def packed_digits(reader: Reader, n: int, count: int) -> np.ndarray:
    """Digit section tag 2: `u32 crc`, then `g` digits per `w`-bit word, MSB first."""
    if n not in DIGIT_WORDS:
        raise ValueError(f"digits: packed digits for n = {n} > 18")
    crc = reader.u32()
    rest = reader.rest()
    if zlib.crc32(rest) != crc:
        raise ValueError("digits: CRC mismatch")
    per_word, width = DIGIT_WORDS[n]
    n_words = -(-count // per_word)
    bits = bit_string(rest, n_words * width, "digits").reshape(n_words, width)
    words = np.zeros(n_words, dtype=np.uint64)
    for i in range(width):
        words = (words << np.uint64(1)) | bits[:, i].astype(np.uint64)
    unit = np.uint64(10 ** n)
    if (words >= np.uint64(10 ** (per_word * n))).any():
        raise ValueError("digits: word too large")
    digits = np.zeros((n_words, per_word), dtype=np.uint64)
    for j in range(per_word):
        digits[:, j] = words % unit
        words //= unit
    digits = digits.ravel()
    if digits[count:].any():
        raise ValueError("digits: non-zero filler digits")
    return digits[:count].astype(np.int64)


def digit_section(section: bytes, n: int, count: int, layout: int) -> np.ndarray:
    """One digit section: the `count` digits of the positions with nbelow = n."""
    if layout == 1:
        digits = read_ints(section, "digits", count)     # any dtype, taken as it is
    else:
        reader = Reader(section, "digits")
        tag = reader.u8()
        if tag == 0:
            digits = read_ints(reader.rest(), "digits", count)
        elif tag == 2:
            return packed_digits(reader, n, count)
        else:
            raise ValueError(f"digits: unknown tag {tag}")
        if ((digits < 0) | (digits >= 10 ** n)).any():
            raise ValueError("digits: digit outside [0, 10^n)")
    if len(digits) != count:
        raise ValueError(f"digits: {len(digits)} values, expected {count}")
    return digits.astype(np.int64)


def decimal_values(coarse, digits, n, exponent) -> np.ndarray:
    """"Values": v = ±(|coarse| * 10^n + digits) * 10^(E - n), one IEEE operation."""
    mantissa = (np.abs(coarse) * 10 ** n + digits).astype(np.float64)  # int64, then nearest
    e = exponent[:, None] - n
    power = 10.0 ** np.minimum(np.abs(e), 22)            # exact powers of ten only
    with np.errstate(over="ignore"):
        v = np.where(e >= 0, mantissa * power, mantissa / power)
    return np.where(coarse < 0, -v, v)


# --------------------------------------------------------------------------------------
# The stream
# --------------------------------------------------------------------------------------

def read_header(section: bytes, row: dict) -> tuple:
    """Section 0: `[L, T, C]` and 4 integers per column; checks "Limits a reader checks"."""
    head = read_ints(section, "header", 3 + 4 * MAX_COLUMNS, INT64)
    if len(head) < 3:
        raise ValueError("header: too short")
    layout, T, C = (int(v) for v in head[:3])
    if layout not in (1, 2):
        raise ValueError(f"header: layout {layout}")
    if not (0 <= T <= MAX_FRAMES and 0 <= C <= MAX_COLUMNS and T * C <= MAX_CELLS):
        raise ValueError("header: too many frames or columns")
    if T != row["frames"] or C != sum(row["counts"]):
        raise ValueError("header: frames or columns differ from meta")
    if len(head) != 3 + 4 * C:
        raise ValueError("header: wrong size")
    table = head[3:].reshape(C, 4)
    for column, (mode, a, b, c) in enumerate(table.tolist()):
        if mode == 1 and not 0 <= a < column:
            raise ValueError("header: duplicate of a later column")
        if mode == 2 and not (0 <= a <= 15 and -1024 <= b <= 1024 and 0 <= c <= 3):
            raise ValueError("header: decimal parameters out of range")
        if mode not in (0, 1, 2):
            raise ValueError(f"header: mode {mode}")
    return layout, T, C, table


def lossless_channels(data: bytes, row: dict, format_version: int) -> np.ndarray:
    """Decode a lossless `clip/NNNNN` stream to the clip's float64 (frames, channels) values.

    `format_version` is accepted for the common interface; the stream layout is the same
    in formats 1 to 6 and carries its own layout number (1 or 2).
    """
    sections = blob_list(data, "clip")
    if not sections:
        raise ValueError("clip: no sections")
    layout, T, C, table = read_header(sections[0], row)
    if len(sections) < (5 if layout == 1 else 6):
        raise ValueError("clip: too few sections")
    decimal = np.nonzero(table[:, 0] == 2)[0]
    R = len(decimal)
    sig = table[decimal, 1]
    exponent = table[decimal, 2]
    orders = table[decimal, 3].tolist()

    # Residuals (section 1) and links (section 5, layout 2 only).
    if layout == 1:
        residuals = read_ints(sections[1], "residuals", T * C, INT64)
        if len(residuals) != R * T:
            raise ValueError("residuals: wrong count")
        residuals = residuals.reshape(R, T)
        links = [None] * R
        next_section = 5
    else:
        residuals = rans_residuals(sections[1], R, T)
        links = read_links(read_ints(sections[5], "links", 14 * R, INT64), R)
        next_section = 6
    coarse = coarse_values(residuals, orders, links)

    # Exceptions (sections 2, 3).
    steps = read_ints(sections[2], "exception steps", T * C, INT64)
    patterns = read_ints(sections[3], "exception patterns", T * C, INT64)
    if len(steps) != len(patterns):
        raise ValueError("exceptions: steps and bit patterns differ in number")
    if len(steps) and (steps[0] < 0 or (steps[1:] <= 0).any()):
        raise ValueError("exceptions: steps not increasing")
    positions = np.cumsum(steps, dtype=np.int64)
    if len(positions) and positions[-1] >= R * T:
        raise ValueError("exceptions: position outside the matrix")
    is_exception = np.zeros(R * T, dtype=bool)
    is_exception[positions] = True
    is_exception = is_exception.reshape(R, T)

    # Negative zeros (section 4): one flag per non-exception zero slot.
    slots = (coarse == 0) & ~is_exception
    flags = bit_string(zstd_only(sections[4], "negative zeros"), int(slots.sum()),
                       "negative zeros")
    negative_zero = np.zeros((R, T), dtype=bool)
    negative_zero[slots] = flags.astype(bool)

    # Digit sections: one per n that occurs, ascending.
    n = nbelow(coarse, sig)
    n[is_exception] = 0
    digits = np.zeros((R, T), dtype=np.int64)
    for value in range(1, int(n.max(initial=0)) + 1):
        where = n == value
        count = int(where.sum())
        if count == 0:
            continue
        if next_section >= len(sections):
            raise ValueError("digits: missing digit section")
        digits[where] = digit_section(sections[next_section], value, count, layout)
        next_section += 1
    if next_section != len(sections):
        raise ValueError("clip: sections after the last digit section")

    # Values: decimal rows, exceptions, negative zeros; then constant and duplicate columns.
    values = decimal_values(coarse, digits, n, exponent)
    values[negative_zero] = -0.0
    flat = values.reshape(-1)                                          # a view
    flat[positions] = patterns.view(np.float64)

    out = np.zeros((T, C), dtype=np.float64)
    out[:, decimal] = values.T
    for column, (mode, a, _b, _c) in enumerate(table.tolist()):
        if mode == 0:
            out[:, column] = np.int64(a).view(np.float64)
        elif mode == 1:
            out[:, column] = out[:, a]
    return out
