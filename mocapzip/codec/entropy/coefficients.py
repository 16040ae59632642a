"""Context-modelled coding of quantised transform coefficients (the lossy clip streams).

A clip's coefficients are matrices of small integers, one column per curve
(PCA component or root channel), one row per frequency (or wavelet band
position).  Almost all of them are zero, and the few that are not sit at low
frequencies and in the first components.  zstd sees only bytes; this coder
uses what is known about the layout:

* Each column first codes its end: one past its last non-zero row.  Nothing
  after it is coded, so the long tail of zero frequencies costs nothing.
* Every row before the end codes a zero flag, then (if non-zero) the bit
  length of its magnitude in unary, the bit after the leading one, the
  remaining bits and the sign.  The last row before the end is known to be
  non-zero and skips the flag.
* The context of the flag and of the bit length is (a) the magnitude of the
  neighbours already coded: the two previous rows of this column, the
  previous, same and next row of the previous column and the same row two
  columns back (neighbouring components have similar spectra), and (b) how
  far the row is from the column's end.

Measured on CMU clips at 1 cm (`python benchmarks/ratio_distortion.py` and
the notes in docs/benchmarks.md), this is 25-35 % smaller than the best zstd
layout of `entropy.zstd.encode_sparse`.

Models restart for every call, so a clip decodes without any other clip.
Several matrices can share one stream (`encode_matrices`), each with its own
models: the pose coefficients and the root track have different statistics.

Priors (stream version 2).  A clip of a few hundred frames codes only a few
thousand decisions, and models that start at 1/2 spend a good part of them
learning.  `Priors.train` runs the models over every clip of an archive and
keeps their final state; the archive stores it once (a few hundred bytes) and
every clip's models start from it, adapting more slowly (shift 5).  Clips
still decode on their own, given the archive's priors.  The gain is largest
for short clips; `python benchmarks/coder_priors.py` measures it on the shared
CMU set.

Speed.  The coder runs for every clip and class basis an archive writes or
reads (and several times per clip while the error search tries steps), and
Priors.train runs it over every clip once more.  In pure Python it made a
decision in about half a microsecond, 25-40x slower than now: the matrix loops
below and the range coder under them are compiled with numba (`numba.njit`),
so models are int64 arrays and the contexts come from arrays of neighbour
magnitudes.  The compiled code is cached on disk (`cache=True`), so only the
first run after an install or an edit compiles it (a few seconds).  What
compiled code does badly (formatted errors, input checks, stream headers)
stays in Python around it: `_decode_matrix` returns what went wrong and
`decode_matrices` raises it.
"""

import numba
import numpy as np

from mocapzip.codec.entropy.zstd import ByteReader, check_size, write_varint
from mocapzip.codec.entropy.rangecoder import (Decoder, Encoder, decode_bit, decode_direct, encode_bit, encode_direct,
                                              exhausted, new_models, reserve)
from mocapzip.limits import MAX_COEFFICIENTS_PER_MATRIX, MAX_FRAMES_PER_CLIP, MAX_VALUES_PER_FRAME
from mocapzip.stages import Stage, register

__all__ = ["ContextCoder", "PrimedCoder", "encode_matrices", "decode_matrices", "matrix_shapes",
           "check_matrix_shape", "Priors"]

_VERSION = 1  # models start at 1/2
_PRIMED_VERSION = 2  # models start from the archive's priors
_PRIMED_SHIFT = 5  # primed models adapt more slowly: they start close to right
_TRAINING_SHIFT = 6  # priors average over many clips (on CMU: 6 beat 4, 5, 7 and 8)
_PRIORS_VERSION = 1
_PRIOR_STEP_BITS = 3  # priors are stored to 8 bits: probability >> 3
_NEIGHBOUR_CONTEXTS = 9  # bit length of the weighted neighbour magnitude, capped
_DISTANCE_CONTEXTS = 6  # bit length of the distance to the column's end, capped
_LARGEST = 1 << 62  # magnitudes stay below this, as UniformQuantiser's do
_MAX_LENGTH = 62  # bit length of the largest magnitude
_LENGTH_CONTEXTS = 16  # unary steps of the bit length with a model of their own
_END_BITS = 6  # the bit length of a column's end is coded with a 6-bit tree (0..63)
_MOST_DECISIONS = 128  # more than one value (1 + 61 + 1 + 60 + 1) or one column end (6 + 1 + 61) codes
_ROWS_PER_RESERVE = 256  # the encoder's buffer is grown, if need be, before every so many rows
_CONTEXT_CAP = 1 << (_NEIGHBOUR_CONTEXTS - 1)  # neighbour magnitudes summing to this or more share the top context


class _Models:
    """The adaptive models of one matrix, one int64 array per kind of decision."""

    _KINDS = ("zero", "length", "below_leading", "end_length", "end_below")

    def __init__(self):
        self.zero = new_models(_NEIGHBOUR_CONTEXTS * _DISTANCE_CONTEXTS)
        self.length = new_models(_NEIGHBOUR_CONTEXTS * _LENGTH_CONTEXTS)
        self.below_leading = new_models(_MAX_LENGTH + 1)
        self.end_length = new_models(1 << _END_BITS)
        self.end_below = new_models(1 << _END_BITS)

    def arrays(self) -> tuple[np.ndarray, ...]:
        """The model arrays in `_KINDS` order, as the compiled coder unpacks them."""
        return tuple(getattr(self, kind) for kind in self._KINDS)

    def state(self) -> list[int]:
        return np.concatenate(self.arrays()).tolist()

    @classmethod
    def from_state(cls, state: list[int]) -> "_Models":
        models, position = cls(), 0
        for kind in cls._KINDS:
            size = len(getattr(models, kind))
            setattr(models, kind, np.array(state[position : position + size], np.int64))
            position += size
        return models


_MODEL_COUNT = len(_Models().state())


class Priors:
    """Starting states of the models, one per matrix slot of a stream (pose, root), as stored.

    `train` runs fresh models over matrices in order, carrying them from one stream to the
    next with slow adaptation (an average over many clips), and keeps their final state
    rounded to 8 bits as stored, so encoder and decoder start alike.
    """

    def __init__(self, states: list[list[int]]):
        self.states = states

    @classmethod
    def train(cls, streams) -> "Priors":
        """`streams`: lists of matrices as `encode_matrices` takes them (slot i trains models i)."""
        models: list[_Models] = []
        for matrices in streams:
            encoder = Encoder(_TRAINING_SHIFT)  # its output is thrown away: only the models' adaptation matters
            for slot, matrix in enumerate(matrices):
                if slot == len(models):
                    models.append(_Models())
                encoder.out = _encode_matrix(encoder.state, encoder.out, _int64_matrix(matrix), models[slot].arrays())
        return cls.decode(cls([m.state() for m in models]).encode())

    def encode(self) -> bytes:
        """Version, slot count, then every model's probability >> 3 as one byte."""
        body = bytes(p >> _PRIOR_STEP_BITS for state in self.states for p in state)
        return bytes([_PRIORS_VERSION, len(self.states)]) + body

    @classmethod
    def decode(cls, blob: bytes) -> "Priors":
        if len(blob) < 2 or blob[0] != _PRIORS_VERSION:
            raise ValueError("not a coefficient priors table of a known version")
        slots = blob[1]
        if len(blob) != 2 + slots * _MODEL_COUNT:
            raise ValueError(f"priors table of {len(blob)} bytes, expected {2 + slots * _MODEL_COUNT}")
        # The middle of each 8-unit step: never 0 or 1, which the coder cannot code against.
        probabilities = [(byte << _PRIOR_STEP_BITS) | (1 << (_PRIOR_STEP_BITS - 1)) for byte in blob[2:]]
        return cls([probabilities[i * _MODEL_COUNT : (i + 1) * _MODEL_COUNT] for i in range(slots)])

    def models(self, slot: int) -> "_Models":
        if slot >= len(self.states):
            raise ValueError(f"no priors for coefficient matrix {slot}")
        return _Models.from_state(self.states[slot])


@register
class ContextCoder(Stage):
    """Coefficient coder "context": matrices streams of version 1, models starting at 1/2 (format 2 on)."""

    kind = "coefficient coder"
    codec_id = "context"
    needs_priors = False

    def encode(self, matrices, priors: "Priors | None" = None) -> bytes:
        return encode_matrices(matrices)

    def decode(self, blob: bytes, shapes=None, priors: "Priors | None" = None) -> list[np.ndarray]:
        if matrix_stream_version(blob) != _VERSION:
            raise ValueError("coefficient stream is not of coder 'context' (version 1)")
        return decode_matrices(blob, shapes)


@register
class PrimedCoder(Stage):
    """Coefficient coder "primed": version-2 streams whose models start from the archive's
    `priors` stream (format 3 on). Class bases are too few to train on: they stay "context"."""

    kind = "coefficient coder"
    codec_id = "primed"
    needs_priors = True

    def encode(self, matrices, priors: "Priors | None" = None) -> bytes:
        if priors is None:
            raise ValueError("coefficient coder 'primed' needs the archive's priors")
        return encode_matrices(matrices, priors)

    def decode(self, blob: bytes, shapes=None, priors: "Priors | None" = None) -> list[np.ndarray]:
        if priors is None:
            raise ValueError("coefficient coder 'primed' needs the archive's priors")
        if matrix_stream_version(blob) != _PRIMED_VERSION:
            raise ValueError("coefficient stream is not of coder 'primed' (version 2)")
        return decode_matrices(blob, shapes, priors)


def encode_matrices(matrices, priors: Priors | None = None) -> bytes:
    """Code 2-D int64 matrices (rows x columns) into one stream, shapes included.

    With `priors` the models of matrix i start from `priors.models(i)` (stream version 2).
    """
    encoder = Encoder() if priors is None else Encoder(_PRIMED_SHIFT)
    header = bytearray([_VERSION if priors is None else _PRIMED_VERSION, len(matrices)])
    for slot, matrix in enumerate(matrices):
        matrix = _int64_matrix(matrix)
        for size in matrix.shape:
            write_varint(header, size)
        models = _Models() if priors is None else priors.models(slot)
        encoder.out = _encode_matrix(encoder.state, encoder.out, matrix, models.arrays())
    return bytes(header) + encoder.finish()


def decode_matrices(blob: bytes, shapes=None, priors: Priors | None = None) -> list[np.ndarray]:
    """Inverse of `encode_matrices`; raises ValueError on a damaged or padded stream.

    `shapes`, when the caller knows them, are checked against the stream's header before
    anything is decoded (a header may list fewer matrices than `shapes`, not more).
    A version-2 stream needs the `priors` it was coded with.
    """
    reader = ByteReader(bytes(blob))
    version, stored = _read_header(reader)
    if version == _PRIMED_VERSION and priors is None:
        raise ValueError("coefficient stream coded with priors, but none were given")
    if shapes is not None and stored != [tuple(shape) for shape in shapes][: len(stored)]:
        raise ValueError(f"coefficient matrices of shapes {stored}, expected {list(shapes)}")
    payload = reader.take(reader.remaining())
    decoder = Decoder(payload) if version == _VERSION else Decoder(payload, _PRIMED_SHIFT)
    matrices = []
    for slot, (rows, columns) in enumerate(stored):
        models = _Models() if version == _VERSION else priors.models(slot)
        matrix = np.zeros((rows, columns), np.int64)
        bad_column, bad_end = _decode_matrix(decoder.state, decoder.data, matrix, models.arrays())
        decoder.check_not_exhausted()
        if bad_column >= 0:
            raise ValueError(f"column {bad_column} ends at row {bad_end} of {rows}")
        matrices.append(matrix)
    decoder.finish()
    return matrices


def matrix_stream_version(blob: bytes) -> int:
    """A matrices stream's version byte (1: models start at 1/2, 2: from priors), checked."""
    return _read_header(ByteReader(bytes(blob)))[0]


def matrix_shapes(blob: bytes) -> list[tuple[int, int]]:
    """The shapes of the matrices a stream holds, from its header alone (nothing is decoded)."""
    return _read_header(ByteReader(bytes(blob)))[1]


def check_matrix_shape(rows: int, columns: int) -> None:
    """Refuse a declared matrix beyond the limits before anything is allocated or decoded for it.

    Rows are a clip's frames (or a basis's pose values), columns its curves; a stream of a few
    bytes can declare any shape, since all-zero columns cost almost nothing to code.
    """
    check_size(rows, MAX_FRAMES_PER_CLIP, "matrix rows")
    check_size(columns, MAX_VALUES_PER_FRAME, "matrix columns")
    check_size(rows * columns, MAX_COEFFICIENTS_PER_MATRIX, "matrix values")


def _read_header(reader: ByteReader) -> tuple[int, list[tuple[int, int]]]:
    version = reader.byte()
    if version not in (_VERSION, _PRIMED_VERSION):
        raise ValueError("not a coefficient stream of a known version")
    shapes = [(reader.varint(), reader.varint()) for _ in range(reader.byte())]
    for shape in shapes:
        check_matrix_shape(*shape)
    return version, shapes


def _int64_matrix(matrix) -> np.ndarray:
    """`matrix` as the C-ordered int64 array the compiled coder takes; refused if it cannot be coded
    (the compiled code does no bounds checks: magnitudes index models by their bit length)."""
    matrix = np.asarray(matrix)
    if matrix.ndim != 2 or matrix.dtype.kind not in "iu":
        raise ValueError("expected 2-D integer matrices")
    if not np.all((matrix > -_LARGEST) & (matrix < _LARGEST)):
        raise ValueError("coefficients must be below 2**62 in magnitude")
    return np.ascontiguousarray(matrix, np.int64)


# --------------------------------------------------------------------------- compiled coding (numba)
#
# Each column's magnitudes are kept for the contexts of the next two columns: `magnitudes` holds
# three rows (this column and the two before it, in turn by column % 3), one entry longer than the
# matrix so `row + 1` needs no check, zero past each column's end.  They are capped at
# `_CONTEXT_CAP`: the context only asks whether the weighted sum reaches it (2**62 magnitudes
# would overflow int64 when summed).


@numba.njit(cache=True, nogil=True)
def _bit_length(value):
    length = 0
    while value:
        value >>= 1
        length += 1
    return length


@numba.njit(cache=True, nogil=True)
def _neighbour_magnitudes(magnitudes, ends, column):
    """The rows of `magnitudes` for `column` and the two columns before it; the first cleared
    of what column - 3 left there (`ends`: the ends of the last three columns)."""
    current = magnitudes[column % 3]
    current[: ends[column % 3]] = 0
    return current, magnitudes[(column + 2) % 3], magnitudes[(column + 1) % 3]


@numba.njit(cache=True, nogil=True)
def _context(current, previous, before, row):
    """Bit length of the weighted magnitude of the already-coded neighbours, capped.

    `current` holds this column's magnitudes above `row`; `previous` and `before` the two
    columns to the left.
    """
    near = previous[row] + previous[row + 1] + before[row]
    if row >= 1:
        near += 2 * current[row - 1] + previous[row - 1]
    if row >= 2:
        near += current[row - 2]
    return min(_bit_length(near), _NEIGHBOUR_CONTEXTS - 1)


@numba.njit(cache=True, nogil=True)
def _encode_matrix(state, out, matrix, models):
    """Code `matrix` (int64, rows x columns); returns the encoder's buffer, grown if it had to be."""
    zero, length_models, below_leading, end_length, end_below = models
    rows, columns = matrix.shape
    magnitudes = np.zeros((3, rows + 1), np.int64)
    ends = np.zeros(3, np.int64)
    for column in range(columns):
        current, previous, before = _neighbour_magnitudes(magnitudes, ends, column)
        end = rows
        while end and matrix[end - 1, column] == 0:
            end -= 1
        ends[column % 3] = end
        out = reserve(state, out, _MOST_DECISIONS)
        _encode_end(state, out, end_length, end_below, end)
        for first_row in range(0, end, _ROWS_PER_RESERVE):
            out = reserve(state, out, _ROWS_PER_RESERVE * _MOST_DECISIONS)
            for row in range(first_row, min(first_row + _ROWS_PER_RESERVE, end)):
                value = matrix[row, column]
                magnitude = abs(value)
                current[row] = min(magnitude, _CONTEXT_CAP)
                context = _context(current, previous, before, row)
                distance = min(_bit_length(end - 1 - row), _DISTANCE_CONTEXTS - 1)
                if distance:  # the last row is known to be non-zero
                    encode_bit(state, out, zero, context * _DISTANCE_CONTEXTS + distance, value != 0)
                    if value == 0:
                        continue
                length = _bit_length(magnitude)
                lengths = context * _LENGTH_CONTEXTS  # the models of this context's unary steps
                for step in range(1, length):
                    encode_bit(state, out, length_models, lengths + min(step, _LENGTH_CONTEXTS - 1), 1)
                if length < _MAX_LENGTH:
                    encode_bit(state, out, length_models, lengths + min(length, _LENGTH_CONTEXTS - 1), 0)
                _encode_below_leading(state, out, below_leading, magnitude, length)
                encode_direct(state, out, 1 if value < 0 else 0, 1)
    return out


@numba.njit(cache=True, nogil=True)
def _decode_matrix(state, data, matrix, models):
    """Fill the zero `matrix` (rows x columns); returns (-1, 0), or (column, end) for the first
    column whose end lies past the last row.  Returns early when the stream is exhausted."""
    zero, length_models, below_leading, end_length, end_below = models
    rows, columns = matrix.shape
    magnitudes = np.zeros((3, rows + 1), np.int64)
    ends = np.zeros(3, np.int64)
    for column in range(columns):
        current, previous, before = _neighbour_magnitudes(magnitudes, ends, column)
        end = _decode_end(state, data, end_length, end_below)
        if exhausted(state):
            return -1, 0
        if end > rows:
            return column, end
        ends[column % 3] = end
        for row in range(end):
            context = _context(current, previous, before, row)
            distance = min(_bit_length(end - 1 - row), _DISTANCE_CONTEXTS - 1)
            if distance and not decode_bit(state, data, zero, context * _DISTANCE_CONTEXTS + distance):
                continue
            length = 1
            lengths = context * _LENGTH_CONTEXTS
            while length < _MAX_LENGTH and decode_bit(state, data, length_models,
                                                      lengths + min(length, _LENGTH_CONTEXTS - 1)):
                length += 1
            magnitude = _decode_below_leading(state, data, below_leading, length)
            current[row] = min(magnitude, _CONTEXT_CAP)
            matrix[row, column] = -magnitude if decode_direct(state, data, 1) else magnitude
    return -1, 0


@numba.njit(cache=True, nogil=True)
def _encode_end(state, out, end_length, end_below, end):
    """A column's end: its bit length through a binary tree, then the bits below the leading one."""
    length = _bit_length(end)
    node = 1
    for shift in range(_END_BITS - 1, -1, -1):
        bit = (length >> shift) & 1
        encode_bit(state, out, end_length, node, bit)
        node = (node << 1) | bit
    _encode_below_leading(state, out, end_below, end, length)


@numba.njit(cache=True, nogil=True)
def _decode_end(state, data, end_length, end_below):
    node = 1
    for _ in range(_END_BITS):
        node = (node << 1) | decode_bit(state, data, end_length, node)
    length = node - (1 << _END_BITS)
    return _decode_below_leading(state, data, end_below, length) if length else 0


@numba.njit(cache=True, nogil=True)
def _encode_below_leading(state, out, models, value, length):
    """The bits of `value` (bit length `length`) below its leading one: the first modelled
    per length (it is skewed for the decaying magnitudes coded here), the rest direct."""
    if length >= 2:
        encode_bit(state, out, models, length, (value >> (length - 2)) & 1)
        encode_direct(state, out, value, length - 2)


@numba.njit(cache=True, nogil=True)
def _decode_below_leading(state, data, models, length):
    """The value of bit length `length` >= 1 whose lower bits `_encode_below_leading` wrote."""
    if length < 2:
        return 1
    value = (2 | decode_bit(state, data, models, length)) << (length - 2)
    return value | decode_direct(state, data, length - 2)
