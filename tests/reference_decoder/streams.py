"""The lossy codec streams: `class/NNNN`, `clip/NNNNN[/SSS]` and `priors`.

Implements docs/format.md §8, "Lossy codec streams" (section names below are its headings),
with the "Range decoder" (§1.10) and "Integer arrays (`ints`)" (§1.11) it uses. Format 1 stores
integer matrices as zstd "ints" blobs; formats 2-4 as
"matrices streams" of an LZMA-style binary range coder. Every function raises ValueError
on a stream that breaks a *must* rule it checks, in particular on a matrices stream that
does not end exactly where the end-of-stream rule says.
"""

import math
import struct
import zlib

import numpy as np

from .container import Reader, zstd_frame, zstd_stream

# "Matrices streams": limits on every declared shape.
MAX_ROWS = 1 << 20
MAX_COLUMNS = 1 << 14
MAX_VALUES = 1 << 25

MEAN_FACTOR = 0.001  # "class/NNNN": mean = float64(mean_int) * 0.001 (a multiplication)


# --------------------------------------------------------------------------- helpers

def bitlen(x: int) -> int:
    return x.bit_length()


# --------------------------------------------------------------------------- range decoder

class RangeDecoder:
    """"Range decoder": LZMA's binary decoder with 11-bit probabilities, 4-byte start."""

    def __init__(self, payload: bytes, shift: int):
        if len(payload) < 4:
            raise ValueError("range coder payload shorter than 4 bytes")
        self.payload = payload
        self.code = int.from_bytes(payload[:4], "big")
        self.range = 0xFFFFFFFF
        self.pos = 4
        self.shift = shift
        if self.code >= self.range:  # FF FF FF FF can never pass the end rule
            raise ValueError("range coder payload starts with FF FF FF FF")

    def normalise(self):
        while self.range < (1 << 24):
            if self.pos >= len(self.payload):
                raise ValueError("range coder stream ends early")
            self.range = (self.range << 8) & 0xFFFFFFFF
            self.code = ((self.code << 8) | self.payload[self.pos]) & 0xFFFFFFFF
            self.pos += 1

    def bit(self, probs: list, i: int) -> int:
        """One modelled bit; probs[i] is the probability of a 0 in 1/2048 units."""
        p = probs[i]
        bound = (self.range >> 11) * p
        if self.code < bound:
            self.range = bound
            probs[i] = p + ((2048 - p) >> self.shift)
            b = 0
        else:
            self.code -= bound
            self.range -= bound
            probs[i] = p - (p >> self.shift)
            b = 1
        self.normalise()
        return b

    def direct(self, n: int) -> int:
        """n equiprobable bits, most significant first."""
        v = 0
        for _ in range(n):
            self.range >>= 1
            b = 1 if self.code >= self.range else 0
            if b:
                self.code -= self.range
            v = (v << 1) | b
            self.normalise()
        return v

    def finish(self):
        """End-of-stream rule: every payload byte read, and code < range."""
        if self.pos != len(self.payload):
            raise ValueError(f"matrices stream does not end where the decoder stops "
                             f"({len(self.payload) - self.pos} payload bytes left)")
        if not self.code < self.range:
            raise ValueError("matrices stream ends with code >= range")


# --------------------------------------------------------------------------- models

# "Models": five arrays per matrix, in this order (also the `priors` slot layout).
MODEL_SIZES = (("zero", 54), ("length", 144), ("below", 63), ("end_length", 64), ("end_below", 64))
MODELS_PER_SLOT = sum(size for _, size in MODEL_SIZES)  # 389


def split_models(probabilities: list) -> dict:
    """A flat list of 389 probabilities -> {array name: list}, fresh copies."""
    models, k = {}, 0
    for name, size in MODEL_SIZES:
        models[name] = list(probabilities[k:k + size])
        k += size
    return models


def read_priors(data: bytes) -> list:
    """`priors`: a zstd stream of u8 version (1), u8 slots, slots x 389 bytes.

    Returns one list of 389 starting probabilities per slot, byte b -> (b << 3) | 4.
    """
    content = zstd_stream(data)
    if len(content) < 2 or content[0] != 1:
        raise ValueError("priors: version must be 1")
    slots = content[1]
    if len(content) != 2 + MODELS_PER_SLOT * slots:
        raise ValueError("priors: content must be exactly 2 + 389 * slots bytes")
    return [[(b << 3) | 4 for b in content[2 + MODELS_PER_SLOT * i:2 + MODELS_PER_SLOT * (i + 1)]]
            for i in range(slots)]


# --------------------------------------------------------------------------- matrices stream

def magnitude(rc: RangeDecoder, probs: list, length: int) -> int:
    """"Matrix syntax": the bits below the leading one; the first modelled, the rest direct."""
    if length < 2:
        return 1
    v = (2 | rc.bit(probs, length)) << (length - 2)
    return v | rc.direct(length - 2)


def decode_matrix(rc: RangeDecoder, m: dict, rows: int, cols: int) -> np.ndarray:
    """One matrix, column by column ("Matrix syntax", "Neighbour context")."""
    out = np.zeros((rows, cols), dtype=np.int64)
    prev = [0] * rows  # magnitudes of column c-1
    bef = [0] * rows   # magnitudes of column c-2

    def at(column, r):
        return column[r] if 0 <= r < rows else 0

    for c in range(cols):
        node = 1
        for _ in range(6):
            node = (node << 1) | rc.bit(m["end_length"], node)
        end_length = node - 64
        end = magnitude(rc, m["end_below"], end_length) if end_length else 0
        if end > rows:
            raise ValueError("column end past the matrix's rows")
        cur = [0] * rows
        for r in range(end):
            near = (2 * at(cur, r - 1) + at(cur, r - 2) + at(prev, r - 1) + at(prev, r)
                    + at(prev, r + 1) + at(bef, r))
            ctx = min(bitlen(near), 8)
            dist = min(bitlen(end - 1 - r), 5)
            if dist and rc.bit(m["zero"], ctx * 6 + dist) == 0:
                continue
            length = 1
            while length < 62 and rc.bit(m["length"], ctx * 16 + min(length, 15)):
                length += 1
            cur[r] = magnitude(rc, m["below"], length)
            out[r, c] = -cur[r] if rc.direct(1) else cur[r]
        bef, prev = prev, cur
    return out


def decode_matrices(data: bytes, expected_shapes: list, version: int, priors=None) -> list:
    """"Matrices streams": u8 version, u8 count, count x (varint rows, varint columns), payload.

    `version` is the one the enclosing stream requires (1, or 2 with `priors`). The declared
    shapes must equal `expected_shapes`; returns the int64 matrices in header order.
    """
    reader = Reader(data)
    stored_version, count = reader.u8(), reader.u8()
    if stored_version not in (1, 2):
        raise ValueError(f"matrices stream: unknown version {stored_version}")
    if stored_version != version:
        raise ValueError(f"matrices stream: version {stored_version}, expected {version}")
    shapes = [(reader.varint(), reader.varint()) for _ in range(count)]
    for rows, cols in shapes:
        if rows > MAX_ROWS or cols > MAX_COLUMNS or rows * cols > MAX_VALUES:
            raise ValueError(f"matrices stream: shape {(rows, cols)} over the limits")
    if shapes != [tuple(s) for s in expected_shapes]:
        raise ValueError(f"matrices stream: shapes {shapes}, expected {list(expected_shapes)}")

    rc = RangeDecoder(reader.rest(), shift=4 if version == 1 else 5)
    out = []
    for i, (rows, cols) in enumerate(shapes):
        if version == 1:
            models = split_models([1024] * MODELS_PER_SLOT)
        else:
            if priors is None or i >= len(priors):
                raise ValueError(f"matrices stream: no priors slot for matrix {i}")
            models = split_models(priors[i])
        out.append(decode_matrix(rc, models, rows, cols))
    rc.finish()
    return out


# --------------------------------------------------------------------------- format 1 ints blobs

SIGNED = {0: 8, 1: 16, 2: 32, 3: 64}
UNSIGNED = {4: 8, 5: 16, 6: 32, 7: 64}


def _plane_block(reader: Reader, n: int) -> list:
    """u8 width (<= 8), then `width` planes of n bytes, least significant byte first."""
    width = reader.u8()
    if width > 8:
        raise ValueError("ints: plane width over 8")
    codes = [0] * n
    for k in range(width):
        plane = reader.take(n)
        for i in range(n):
            codes[i] |= plane[i] << (8 * k)
    return codes


def decode_ints(blob: bytes, max_values: int) -> np.ndarray:
    """"Integer arrays (`ints`)": zstd_frame(body) [verbatim] -> array of the stored shape.

    `max_values` is N, the number of values the matrix should hold (size checks).
    """
    content, verbatim = zstd_frame(blob, limit=2554 + 1 + math.ceil(max_values / 8) + 8 * max_values)
    body = Reader(content)
    layout, dtype, order, ndim = body.u8(), body.u8(), body.u8(), body.u8()
    if layout not in (0, 1, 2):
        raise ValueError(f"ints: unknown layout {layout}")
    if dtype > 7:
        raise ValueError(f"ints: unknown dtype {dtype}")
    if order not in (0, 1):
        raise ValueError(f"ints: unknown order {order}")
    shape = [body.varint() for _ in range(ndim)]
    count = math.prod(shape)
    if any(s > max_values for s in shape) or count > max_values:
        raise ValueError("ints: more values than the matrix holds")

    if layout == 0:
        codes = _plane_block(body, count)
    elif layout == 1:
        bitmap = body.take(math.ceil(count / 8))
        marked = [i for i in range(count) if bitmap[i >> 3] >> (7 - (i & 7)) & 1]
        if any(bitmap[i >> 3] >> (7 - (i & 7)) & 1 for i in range(count, 8 * len(bitmap))):
            raise ValueError("ints: bitmap padding bits must be 0")
        packed = _plane_block(body, len(marked))
        if 0 in packed:
            raise ValueError("ints: a marked code is zero")
        codes = [0] * count
        for i, code in zip(marked, packed):
            codes[i] = code
    else:
        (crc,) = body.unpack("I")
        lengths = body.take(count)
        if any(length > 64 for length in lengths):
            raise ValueError("ints: bit length over 64")
        if zlib.crc32(verbatim) != crc:
            raise ValueError("ints: CRC mismatch of the verbatim bits")
        nv = [max(length - 1, 0) for length in lengths]
        if len(verbatim) != math.ceil(sum(nv) / 8):
            raise ValueError("ints: verbatim bits of the wrong length")
        bits = int.from_bytes(verbatim, "big")
        total = 8 * len(verbatim)
        codes = [1 << (length - 1) if length else 0 for length in lengths]
        p_bit = 0  # index of the next verbatim bit, most significant first
        for p in range(max(nv, default=0)):
            for i in range(count):
                if nv[i] > p:
                    codes[i] |= (bits >> (total - 1 - p_bit) & 1) << p
                    p_bit += 1
        if bits & ((1 << (total - p_bit)) - 1):
            raise ValueError("ints: verbatim padding bits must be 0")
    if body.pos != len(content):
        raise ValueError("ints: frame content does not end where the data ends")
    if layout != 2 and verbatim:
        raise ValueError("ints: bytes after the zstd frame")

    if dtype in SIGNED:
        bits_ = SIGNED[dtype]
        values = [(code >> 1) ^ -(code & 1) for code in codes]
        lo, hi = -(1 << (bits_ - 1)), (1 << (bits_ - 1)) - 1
        np_dtype = np.dtype(f"int{bits_}")
    else:
        bits_ = UNSIGNED[dtype]
        values = codes
        lo, hi = 0, (1 << bits_) - 1
        np_dtype = np.dtype(f"uint{bits_}")
    if any(not lo <= v <= hi for v in values):
        raise ValueError("ints: value outside its dtype's range")
    return np.array(values, dtype=np_dtype).reshape(shape, order="C" if order == 0 else "F")


def _blobs(reader: Reader, limits: list) -> list:
    """Format 1: `u32 size, ints blob` pairs, one per entry of `limits` (values each may hold)."""
    return [decode_ints(reader.take(reader.u32()), limit) for limit in limits]


# --------------------------------------------------------------------------- class streams

def class_basis(data: bytes, format_version: int) -> tuple[np.ndarray, np.ndarray]:
    """`class/NNNN` (lossy) -> (mean float64 (M,), basis float64 (M, Q)), dequantised."""
    reader = Reader(data)
    m_width, q = reader.u32(), reader.u32()
    if m_width > MAX_ROWS or q > MAX_COLUMNS or m_width * q > MAX_VALUES:
        raise ValueError(f"class: M={m_width}, Q={q} over the limits")
    steps = np.array(reader.unpack(f"{q}f"), dtype=np.float64)  # f32 widened exactly

    if format_version == 1:
        mean_arr, basis_arr = _blobs(reader, [m_width, m_width * q])
        if reader.pos != len(data):
            raise ValueError("class: bytes after the second blob")
        if mean_arr.size != m_width or basis_arr.size != m_width * q:
            raise ValueError("class: blobs do not hold M and M*Q values")
        mean_int = mean_arr.reshape(-1)               # row-major order of its own shape
        big_b = basis_arr.reshape(-1).reshape(m_width, q)
    elif format_version == 2:
        mean_col, big_b = decode_matrices(reader.rest(), [(m_width, 1), (m_width, q)], version=1)
        mean_int = mean_col[:, 0]
    elif format_version >= 3:
        mean_col, off, resid = decode_matrices(
            reader.rest(), [(m_width, 1), (m_width, 1), (m_width, q)], version=1)
        mean_int = mean_col[:, 0]
        big_b = np.zeros((m_width, q), dtype=np.int64)
        for r in range(m_width):  # each row coded against an earlier one
            o = int(off[r, 0])
            if not 0 <= o <= r:
                raise ValueError(f"class: reference offset {o} of row {r} out of range")
            big_b[r] = resid[r] + (big_b[r - o] if o > 0 else 0)
    else:
        raise ValueError(f"class: unknown format {format_version}")

    mean = mean_int.astype(np.float64) * MEAN_FACTOR
    basis = big_b.astype(np.float64) * steps[np.newaxis, :]
    return mean, basis


# --------------------------------------------------------------------------- clip streams

def _step(value: float, what: str) -> float:
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"clip: {what} must be finite and > 0, got {value!r}")
    return value


def clip_coefficients(data: bytes, format_version: int, coder: str, rows: int, components: int,
                      root_track: bool, priors) -> tuple[np.ndarray, np.ndarray | None]:
    """`clip/NNNNN` or `clip/NNNNN/SSS` (lossy) -> (P (T, Q), S (T, 4) or None).

    P and S are the dequantised transform coefficients (integer * step, in float64). S is
    the *scaled* root track's: column 3 is still the heading times 50 (the division by 50.0
    comes after the inverse temporal transform, outside this module).
    `rows` is T, `components` is Q (from the class header); `root_track` follows the
    representation (aligned, scaled, normalised: True; channels, positions: False).
    """
    expected = [(rows, components)] + ([(rows, 4)] if root_track else [])
    reader = Reader(data)
    if format_version == 1:
        if coder != "zstd":
            raise ValueError(f"clip: format 1 has coder 'zstd', not {coder!r}")
        pose_step, root_step = reader.unpack("dd")
        n = reader.u8()
        if n != len(expected):
            raise ValueError(f"clip: {n} blobs, expected {len(expected)}")
        mats = _blobs(reader, [r * c for r, c in expected])
        if reader.pos != len(data):
            raise ValueError("clip: bytes after the last blob")
        for mat, shape in zip(mats, expected):
            if mat.shape != shape:
                raise ValueError(f"clip: blob shape {mat.shape}, expected {shape}")
    elif format_version >= 2:
        allowed = ("context",) if format_version == 2 else ("context", "primed")
        if coder not in allowed:
            raise ValueError(f"clip: coder {coder!r} not allowed in format {format_version}")
        pose_step, root_step = reader.unpack("ff")  # widened exactly to float64
        version = 1 if coder == "context" else 2
        mats = decode_matrices(reader.rest(), expected, version, priors)
    else:
        raise ValueError(f"clip: unknown format {format_version}")

    pose = mats[0].astype(np.float64) * _step(float(pose_step), "pose_step")
    root = None
    if root_track:
        root = mats[1].astype(np.float64) * _step(float(root_step), "root_step")
    return pose, root


# --------------------------------------------------------------------------- patch/NNNNN (format 5)

def frame_patches(data: bytes, row: dict) -> tuple[float, list]:
    """`patch/NNNNN`: (step_cm, [(frame, level, ints), ...]) for the row's `patched_frames`."""
    count, width = row["patched_frames"], sum(row["counts"])
    step_cm = _step(struct.unpack_from("<f", data, 0)[0], "patch step_cm")
    head, stored = decode_matrices(data[4:], [(count, 2), (count, width)], 1)
    patches, frame = [], -1
    for i in range(count):
        gap, level = int(head[i, 0]), int(head[i, 1])
        if gap < 0 or not 0 <= level <= 40:
            raise ValueError(f"patch row {i}: gap {gap}, level {level}")
        ints = stored[i].copy()
        if i and gap == 0 and level == patches[-1][1]:
            ints += patches[-1][2]
        frame += 1 + gap
        if frame >= row["frames"]:
            raise ValueError(f"patched frame {frame} is past the clip's {row['frames']} frames")
        patches.append((frame, level, ints))
    return step_cm, patches


# --------------------------------------------------------------------------- plant/NNNNN (format 9)

def planted_stances(data: bytes, row: dict, n_feet: int) -> list:
    """`plant/NNNNN`: [(foot, first frame, frames), ...] for the row's `planted_stances`."""
    count = row["planted_stances"]
    (stored,) = decode_matrices(data, [(count, 3)], 1)
    stances = []
    for i in range(count):
        foot, gap, frames = (int(x) for x in stored[i])
        if not 0 <= foot < n_feet or (stances and foot < stances[-1][0]):
            raise ValueError(f"stance {i}: foot {foot}")
        if gap < 0 or frames < 1:
            raise ValueError(f"stance {i}: gap {gap}, frames {frames}")
        same = stances and stances[-1][0] == foot
        first = (stances[-1][1] + stances[-1][2] if same else 0) + gap
        if first + frames > row["frames"]:
            raise ValueError(f"stance {i} ends past the clip's {row['frames']} frames")
        stances.append((foot, first, frames))
    return stances


# --------------------------------------------------------------------------- tensor models (format 11)

FACTOR_FACTOR = 2.0 ** -9  # "tensor/NNNN": each factor = ints * 2^-9


def tensor_model(data: bytes) -> tuple:
    """`tensor/NNNN` -> (mean (M,), core (r_0, ..., r_(K+1)), [U_frames, U_values, U_1 .. U_K])."""
    reader = Reader(data)
    k = reader.u8()
    if not 1 <= k <= 8:
        raise ValueError(f"tensor: {k} natural modes")
    sizes = [reader.varint() for _ in range(k + 2)]
    ranks = [reader.varint() for _ in range(k + 2)]
    (core_step,) = reader.unpack("f")
    if any(not 1 <= r <= n for r, n in zip(ranks, sizes)) or not (math.isfinite(core_step) and core_step > 0):
        raise ValueError(f"tensor: ranks {ranks} for sizes {sizes}, core step {core_step}")
    shapes = [(sizes[1], 1), (ranks[0], math.prod(ranks[1:]))] + list(zip(sizes, ranks))
    for rows, columns in [(sizes[0], sizes[1]), *shapes]:  # the prediction L x M too
        if rows > MAX_ROWS or columns > MAX_COLUMNS or rows * columns > MAX_VALUES:
            raise ValueError(f"tensor: a {rows} x {columns} matrix, over the limits")
    mean, core, *factors = decode_matrices(reader.rest(), shapes, version=1)
    return (mean[:, 0].astype(np.float64) * MEAN_FACTOR,
            core.reshape(ranks).astype(np.float64) * float(core_step),
            [f.astype(np.float64) * FACTOR_FACTOR for f in factors])


def tensor_prediction(model: tuple, at: list, moves_frame: bytes, frames: int) -> np.ndarray:
    """A tensor class's prediction of a clip (n x M): the model at levels `at` on the warped
    timeline, each clip frame the mean of the rows its `warp/NNNNN` path matches to it."""
    mean, core, factors = model
    if len(at) != len(factors) - 2 or any(not 0 <= a < len(f) for a, f in zip(at, factors[2:])):
        raise ValueError(f"tensor_at {at}: not a place of the model's grid")
    g = core
    for k in range(len(at), 0, -1):
        g = g @ factors[1 + k][at[k - 1]]
    warped = factors[0] @ g @ factors[1].T + mean
    length = warped.shape[0]
    moves, rest = zstd_frame(moves_frame, length + frames)
    if rest:
        raise ValueError("warp: bytes after its zstd frame")
    i = j = 0
    sums, counts = np.zeros((frames, warped.shape[1])), np.zeros(frames)
    sums[0] += warped[0]
    counts[0] += 1
    for move in moves:
        if move > 2:
            raise ValueError(f"warp: move {move}")
        i, j = i + (move != 1), j + (move != 0)
        if i >= length or j >= frames:
            raise ValueError("warp: the path leaves the grid")
        sums[j] += warped[i]
        counts[j] += 1
    if (i, j) != (length - 1, frames - 1):
        raise ValueError(f"warp: the path ends at {(i, j)}")
    return sums / counts[:, None]
