"""Context-modelled coding of integer residual matrices with interleaved rANS.

`encode_residuals` stores a (rows x steps) int64 matrix, typically the
prediction residuals of one motion channel per row, one frame per step.
Each value becomes its zigzag code (0, -1, 1, -2, ... -> 0, 1, 2, 3, ...),
which is split into its bit length (the "bucket", 0..64) and the bits below
the leading one.  The bits below are stored verbatim: for prediction
residuals they are close to uniform.  The buckets carry the distribution
and are entropy coded:

* Context: a per-row running level, an exponential moving average of the
  row's previous buckets (integer arithmetic, 4 fractional bits, each new
  bucket moves it by a quarter of the difference).  Scheme 1 also splits
  each level by whether the previous bucket was clearly below, near or
  clearly above the level (helps clips with alternating frame quality, such
  as data upsampled by interpolation); the encoder keeps the smaller scheme.
* Model: frequency counts per context, shared by all rows, starting flat
  and updated every `_BLOCK` steps with the buckets just coded, so the model
  learns the file without any stored table.  Counts are turned into
  frequencies summing to 2**15, every bucket keeping at least 1.
* Coder: rANS with one 32-bit state per row, all rows interleaved into one
  stream of 16-bit words, so every step is a handful of numpy operations on
  a vector of rows and there is no Python loop per value.

Everything is integer arithmetic, so encoder and decoder agree bit for bit
on every platform.  Integrity: a CRC32 covers the payload, every rANS state
must come back to its initial value after the last step, and all words and
bits must be consumed; otherwise decoding raises ValueError.
"""

import math
import zlib

import numpy as np

from mocapzip.codec.entropy import zstd
from mocapzip.limits import MAX_FRAMES_PER_CLIP, MAX_VALUES_PER_CLIP, MAX_VALUES_PER_FRAME

__all__ = ["encode_residuals", "decode_residuals"]

_VERSION = 1
_N_BUCKETS = 65  # bit lengths of uint64 zigzag codes: 0..64
_SCALE_BITS = 15
_TOTAL = 1 << _SCALE_BITS
_STATE_LOW = 1 << 16  # rANS states live in [2**16, 2**32)
_WORD_BITS = 16
_BLOCK = 8  # steps between model updates
_LEVEL_FRACTION = 16  # running level in 1/16 buckets
_LEVEL_SHIFT = 2  # the level moves by 1/4 of the difference per step
_LEVEL_QUANTUM = 8  # contexts: levels in half buckets
_N_LEVELS = _LEVEL_FRACTION * _N_BUCKETS // _LEVEL_QUANTUM + 1
_START_LEVEL = 8 * _LEVEL_FRACTION
_NEAR = 24  # scheme 1: previous bucket within 1.5 buckets of the level counts as near
_SCHEMES = (0, 1)
_INCREMENT = 32  # count added per coded bucket (initial count 1: a weak flat prior)
_HALVE_AT = 1 << 22  # a context's counts are halved when their total exceeds this
_SEGMENT_STEPS = 1024  # time segments coded side by side are at least this long ...
_MAX_SEGMENTS = 16  # ... and at most this many
# Decoding a bucket shrinks a lane's state x >= 2**16 by at least (_N_BUCKETS - 1) * (x >> 15)
# >= x * 2**-10 (no bucket has more than _TOTAL - 64 of the frequency), so from one refill to
# the next (or from the first state, or to the last) a lane decodes at most this many buckets,
# and a stream holds at most this many values per word and per lane (11,351).
_MAX_BUCKETS_PER_WORD = 1 + math.floor(
    _WORD_BITS * math.log(2) / -math.log1p(-(_N_BUCKETS - 1) / (2 * _TOTAL))
)


def encode_residuals(matrix) -> bytes:
    """Encode a (rows x steps) integer matrix; `decode_residuals` needs its shape."""
    matrix = np.asarray(matrix)
    if matrix.ndim != 2 or matrix.dtype.kind not in "iu":
        raise ValueError("expected a 2-D integer matrix")
    signed = matrix.astype(np.int64)
    codes = ((signed << 1) ^ (signed >> 63)).view(np.uint64)
    lengths, raw = zstd.split_leading_bits(codes)  # the verbatim bits as zstd.py stores them
    buckets = lengths.astype(np.int64)
    layout = _Layout(*matrix.shape)
    lanes = layout.to_lanes(buckets)
    best = None
    for scheme in _SCHEMES:
        starts, freqs = _model_pass(lanes, layout, scheme)
        states, words = _rans_encode(starts, freqs, layout)
        body = zstd.pack_blobs(
            [bytes([_VERSION, scheme]), states.astype("<u4").tobytes(),
             words.astype("<u2").tobytes(), raw]
        )
        if best is None or len(body) < len(best):
            best = body
    return zlib.crc32(best).to_bytes(4, "little") + best


def decode_residuals(blob: bytes, rows: int, steps: int) -> np.ndarray:
    """Inverse of `encode_residuals` for a matrix of the given shape.

    The shape is checked against the limits (rows are channels, steps frames) and against
    what the stream can hold before anything is allocated or decoded.
    """
    zstd.check_size(rows, MAX_VALUES_PER_FRAME, "residual rows")
    zstd.check_size(steps, MAX_FRAMES_PER_CLIP, "residual steps")
    zstd.check_size(rows * steps, MAX_VALUES_PER_CLIP, "residuals")
    blob = bytes(blob)
    if len(blob) < 4 or zlib.crc32(blob[4:]) != int.from_bytes(blob[:4], "little"):
        raise ValueError("CRC mismatch in the residual stream")
    parts = zstd.unpack_blobs(blob[4:])
    if len(parts) != 4 or len(parts[0]) != 2 or parts[0][0] != _VERSION:
        raise ValueError("not a residual stream of a known version")
    scheme = parts[0][1]
    if scheme not in _SCHEMES:
        raise ValueError(f"unknown context scheme {scheme}")
    layout = _Layout(rows, steps)
    if len(parts[1]) != 4 * layout.n_lanes or len(parts[2]) % 2:
        raise ValueError("residual stream does not match the matrix shape")
    if rows * steps > _MAX_BUCKETS_PER_WORD * (len(parts[2]) // 2 + layout.n_lanes):
        raise ValueError(f"a residual stream of {len(blob)} bytes cannot hold {rows} x {steps} values")
    states = np.frombuffer(parts[1], "<u4").astype(np.int64)
    words = np.frombuffer(parts[2], "<u2").astype(np.int64)
    buckets = layout.from_lanes(_rans_decode(states, words, layout, scheme))
    codes = zstd.join_leading_bits(buckets, parts[3])
    sign = np.uint64(0) - (codes & np.uint64(1))
    return ((codes >> np.uint64(1)) ^ sign).view(np.int64)


# ------------------------------------------------------------------ model


class _Model:
    """Adaptive bucket frequencies per context, shared by all rows."""

    def __init__(self, rows: int, scheme: int):
        self.scheme = scheme
        self.n_contexts = _N_LEVELS * (3 if scheme == 1 else 1)
        self.counts = np.ones((self.n_contexts, _N_BUCKETS), np.int64)
        self.freqs = np.empty((self.n_contexts, _N_BUCKETS), np.int64)
        # Cumulative frequencies of all contexts in one increasing array:
        # entry [context, j] is context * _TOTAL + (sum of freqs below bucket j),
        # so one searchsorted finds the bucket of every row at once.
        self.cumulative = np.empty((self.n_contexts, _N_BUCKETS + 1), np.int64)
        self.flat = self.cumulative.reshape(-1)
        self.level = np.full(rows, _START_LEVEL, np.int64)
        self.previous = np.full(rows, _START_LEVEL, np.int64)
        self._refresh(np.arange(self.n_contexts))
        self._pending_contexts = []
        self._pending_buckets = []

    def contexts(self, active: int) -> np.ndarray:
        """Context of each of the first `active` lanes."""
        self.active = active
        level = self.level[:active]
        quantised = np.minimum((level + _LEVEL_QUANTUM // 2) // _LEVEL_QUANTUM, _N_LEVELS - 1)
        if self.scheme == 0:
            return quantised
        difference = self.previous[:active] - level
        return quantised * 3 + (difference > _NEAR) - (difference < -_NEAR) + 1

    def update(self, contexts, buckets, end_of_block: bool) -> None:
        """Learn the buckets just coded by the lanes of the last `contexts` call."""
        scaled = buckets * _LEVEL_FRACTION
        level = self.level[: self.active]
        level += (scaled - level) >> _LEVEL_SHIFT
        self.previous[: self.active] = scaled
        self._pending_contexts.append(contexts)
        self._pending_buckets.append(buckets)
        if end_of_block:
            contexts = np.concatenate(self._pending_contexts)
            buckets = np.concatenate(self._pending_buckets)
            self._pending_contexts, self._pending_buckets = [], []
            np.add.at(self.counts, (contexts, buckets), _INCREMENT)
            touched = np.flatnonzero(np.bincount(contexts, minlength=self.n_contexts))
            full = touched[self.counts[touched].sum(axis=1) > _HALVE_AT]
            if full.size:
                self.counts[full] = (self.counts[full] + 1) >> 1
            self._refresh(touched)

    def _refresh(self, contexts) -> None:
        """Frequencies summing to _TOTAL (each at least 1) and their cumulative starts."""
        counts = self.counts[contexts]
        total = counts.sum(axis=1, keepdims=True)
        freqs = counts * (_TOTAL - _N_BUCKETS) // total + 1
        largest = np.argmax(freqs, axis=1)
        freqs[np.arange(len(contexts)), largest] += _TOTAL - freqs.sum(axis=1)
        self.freqs[contexts] = freqs
        cumulative = np.zeros((len(contexts), _N_BUCKETS + 1), np.int64)
        np.cumsum(freqs, axis=1, out=cumulative[:, 1:])
        self.cumulative[contexts] = cumulative + contexts[:, None] * _TOTAL


class _Layout:
    """Rows cut into up to _MAX_SEGMENTS time segments, coded side by side as lanes.

    Lane s * rows + r codes row r from step s * length on.  More lanes per
    step means fewer (vectorised) steps; only the last segment may be
    shorter, and its lanes are the last ones, so the active lanes of every
    step are a prefix.
    """

    def __init__(self, rows: int, steps: int):
        self.rows, self.steps = rows, steps
        segments = min(_MAX_SEGMENTS, max(1, steps // _SEGMENT_STEPS))
        self.length = -(-steps // segments) if steps else 0
        self.segments = -(-steps // self.length) if steps else 0
        self.n_lanes = rows * self.segments
        last = steps - (self.segments - 1) * self.length
        # Steps at or after `last` code only the lanes of the full segments.
        self.last = last
        self.short_lanes = rows * (self.segments - 1)

    def active(self, step: int) -> int:
        return self.n_lanes if step < self.last else self.short_lanes

    def to_lanes(self, matrix):
        """(rows, steps) -> (length, lanes), zero-padded after the end."""
        padded = np.zeros((self.rows, self.segments * self.length), matrix.dtype)
        padded[:, : self.steps] = matrix
        return padded.reshape(self.rows, self.segments, self.length).transpose(2, 1, 0).reshape(
            self.length, self.n_lanes
        )

    def from_lanes(self, lanes):
        matrix = lanes.reshape(self.length, self.segments, self.rows).transpose(2, 1, 0)
        return matrix.reshape(self.rows, self.segments * self.length)[:, : self.steps]


def _model_pass(lanes, layout, scheme):
    """(start, frequency) of every bucket, as the decoder's model will see them."""
    model = _Model(layout.n_lanes, scheme)
    starts = np.zeros(lanes.shape, np.int64)
    freqs = np.ones(lanes.shape, np.int64)
    for step in range(layout.length):
        active = layout.active(step)
        contexts = model.contexts(active)
        column = lanes[step, :active]
        starts[step, :active] = model.cumulative[contexts, column] - contexts * _TOTAL
        freqs[step, :active] = model.freqs[contexts, column]
        model.update(contexts, column, (step + 1) % _BLOCK == 0)
    return starts, freqs


# ------------------------------------------------------------------- rANS
#
# States are kept in int64 (they stay below 2**32, products below 2**47).


def _rans_encode(starts, freqs, layout):
    """Interleaved rANS over the lanes; returns (final states, 16-bit words in decoding order)."""
    state = np.full(layout.n_lanes, _STATE_LOW, np.int64)
    limits = freqs << (32 - _SCALE_BITS)  # renormalise while state >= limit
    emitted = []
    for step in range(layout.length - 1, -1, -1):
        active = layout.active(step)
        lanes = state[:active]
        out = lanes >= limits[step, :active]
        emitted.append(lanes[out] & 0xFFFF)
        lanes = np.where(out, lanes >> _WORD_BITS, lanes)
        quotient, remainder = np.divmod(lanes, freqs[step, :active])
        state[:active] = (quotient << _SCALE_BITS) + remainder + starts[step, :active]
    words = np.concatenate(emitted[::-1]) if emitted else np.zeros(0, np.int64)
    return state, words


def _rans_decode(state, words, layout, scheme):
    if state.size != layout.n_lanes or np.any(state < _STATE_LOW):
        raise ValueError("invalid rANS state")
    model = _Model(layout.n_lanes, scheme)
    buckets = np.zeros((layout.length, layout.n_lanes), np.int64)
    position = 0
    for step in range(layout.length if layout.n_lanes else 0):  # no lanes (no rows): nothing to decode
        active = layout.active(step)
        contexts = model.contexts(active)
        lanes = state[:active]
        key = (lanes & (_TOTAL - 1)) + contexts * _TOTAL
        index = np.searchsorted(model.flat, key, side="right") - 1
        bucket = index - contexts * (_N_BUCKETS + 1)
        lanes = model.freqs[contexts, bucket] * (lanes >> _SCALE_BITS) + key - model.flat[index]
        refill = lanes < _STATE_LOW
        count = int(np.count_nonzero(refill))
        if count:
            if position + count > words.size:
                raise ValueError("rANS stream ends early")
            lanes[refill] = (lanes[refill] << _WORD_BITS) | words[position : position + count]
            position += count
        state[:active] = lanes
        buckets[step, :active] = bucket
        model.update(contexts, bucket, (step + 1) % _BLOCK == 0)
    if position != words.size or np.any(state != _STATE_LOW):
        raise ValueError("rANS stream is inconsistent")
    return buckets
