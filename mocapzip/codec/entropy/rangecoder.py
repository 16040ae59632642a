"""A binary adaptive range coder (the LZMA design) for context-modelled bits.

Why binary: the lossy coefficients are few (about ten thousand decisions per
clip) but their statistics depend strongly on context (frequency, neighbours).
Adaptive binary models handle any number of contexts with no stored tables
and learn within a few dozen bits, which matters when every clip is coded on
its own for random access.

Each model is an 11-bit probability that the next bit is 0, moved 1/2**shift
of the way towards each coded bit: shift 4 (fast) for models that start at
1/2, 5 for models that start from trained priors (`coefficients.Priors`).
`encode_bit` and `decode_bit` take the model array and an index into it, so
callers keep one array per kind of decision.  Bits known to be near 50/50
(signs, low bits of magnitudes) go through `encode_direct`/`decode_direct`,
which cost exactly one bit.

Integer arithmetic only: encoder and decoder agree bit for bit everywhere.
The encoder's first output byte is always 0 and is not stored.

Why numba: the coder runs for every clip, class basis and priors table, a
few million decisions per archive, several times over while the encoder
searches for its steps.  In pure Python a decision took about half a
microsecond and profiles showed the coder as a hot spot; compiled with numba
(`numba.njit`), it is 25-40x faster.  So the coder's state lives in small
int64 arrays (the slots below) rather than in Python objects, models are
int64 arrays, and the encoder writes into a byte array that callers grow
with `reserve` before coding.  `encode_bit` and `encode_direct` are inlined
into their compiled callers (`inline="always"`): left to LLVM they were not,
and the encoder was 20 % slower.  Compiled code is cached on disk
(`cache=True`, next to the sources in __pycache__), so only the first run
after an install or an edit compiles (a few seconds).  numba's cache does
not notice an edit of this file in the compiled code of `coefficients`,
which holds its own copy of these functions: after changing them, delete
the cache files (`find mocapzip -name '*.nb[ic]' -delete`).

`Encoder` and `Decoder` hold that state for callers in Python: `coefficients`
passes it on to its compiled loops; `bit` and `direct` code one decision, `Decoder.exp_golomb` one
integer of `archive.skeletons`.
"""

import numba
import numpy as np

__all__ = ["Encoder", "Decoder", "new_models", "reserve", "encode_bit", "encode_direct", "decode_bit", "decode_direct",
           "decode_exp_golomb", "exhausted"]

_PROB_BITS = 11
_ONE = 1 << _PROB_BITS
FAST_SHIFT = 4  # adaptation rate of models that start at 1/2: fast, because a clip's streams are short
_TOP = 1 << 24
_MASK32 = 0xFFFFFFFF
# A modelled bit leaves the range at least 2**24 >> 11 (models stay within 1..2047), so at most two
# bytes move out before it is back above 2**24; a direct bit halves it, so at most one.
_MOST_BYTES_PER_DECISION = 2

# Encoder state slots: low can exceed 32 bits by one carry, which int64 holds.
_LOW, _RANGE, _CACHE, _PENDING, _SIZE, _ENCODER_SHIFT = range(6)
# Decoder state slots; `_EXHAUSTED` is set when a byte is needed past the end of the stream.
_CODE, _DECODER_RANGE, _POSITION, _DECODER_SHIFT, _EXHAUSTED = range(5)


def new_models(count: int) -> np.ndarray:
    """`count` fresh models, each at probability 1/2."""
    return np.full(count, _ONE >> 1, np.int64)


# --------------------------------------------------------------------------- encoding


@numba.njit(cache=True, nogil=True)
def reserve(state, out, decisions):
    """`out`, or a larger copy of it, with room for all that `decisions` more decisions can write
    (the held-back bytes plus `_MOST_BYTES_PER_DECISION` each).  Callers reserve before coding."""
    needed = state[_SIZE] + state[_PENDING] + _MOST_BYTES_PER_DECISION * decisions
    if needed <= out.size:
        return out
    grown = np.empty(max(needed, 2 * out.size), np.uint8)
    grown[: state[_SIZE]] = out[: state[_SIZE]]
    return grown


@numba.njit(cache=True, nogil=True, inline="always")
def encode_bit(state, out, models, index, bit):
    p = models[index]
    bound = (state[_RANGE] >> _PROB_BITS) * p
    if bit:
        state[_LOW] += bound
        state[_RANGE] -= bound
        models[index] = p - (p >> state[_ENCODER_SHIFT])
    else:
        state[_RANGE] = bound
        models[index] = p + ((_ONE - p) >> state[_ENCODER_SHIFT])
    while state[_RANGE] < _TOP:
        state[_RANGE] <<= 8
        _shift_low(state, out)


@numba.njit(cache=True, nogil=True, inline="always")
def encode_direct(state, out, value, n_bits):
    """The low `n_bits` of `value`, most significant first, at one bit each."""
    for shift in range(n_bits - 1, -1, -1):
        state[_RANGE] >>= 1
        if (value >> shift) & 1:
            state[_LOW] += state[_RANGE]
        while state[_RANGE] < _TOP:
            state[_RANGE] <<= 8
            _shift_low(state, out)


@numba.njit(cache=True, nogil=True)
def _shift_low(state, out):
    low = state[_LOW]
    if low < 0xFF000000 or low > _MASK32:
        carry = low >> 32
        byte = state[_CACHE]
        while state[_PENDING]:
            out[state[_SIZE]] = (byte + carry) & 0xFF
            state[_SIZE] += 1
            byte = 0xFF
            state[_PENDING] -= 1
        state[_CACHE] = (low >> 24) & 0xFF
    state[_PENDING] += 1
    state[_LOW] = (low & 0x00FFFFFF) << 8


@numba.njit(cache=True, nogil=True)
def _finish_encoding(state, out):
    """Flush the encoder; returns the buffer (maybe grown), whose bytes 1..state[_SIZE] are the stream."""
    out = reserve(state, out, 5)  # five decisions' room: more than five flushed bytes need
    for _ in range(5):
        _shift_low(state, out)
    return out


class Encoder:
    """The encoder's state slots and output buffer (`out`, replaced when it grows).  Compiled
    callers take both and return the buffer they ended with; `bit` and `direct` code one decision."""

    def __init__(self, shift: int = FAST_SHIFT):
        self.state = np.zeros(6, np.int64)
        self.state[_RANGE] = _MASK32
        self.state[_PENDING] = 1  # bytes held back until a carry can no longer change them (the first: 0)
        self.state[_ENCODER_SHIFT] = shift
        self.out = np.empty(1024, np.uint8)

    def bit(self, models: np.ndarray, index: int, bit: int) -> None:
        self.out = reserve(self.state, self.out, 1)
        encode_bit(self.state, self.out, models, index, bit)

    def direct(self, value: int, n_bits: int) -> None:
        """The low `n_bits` of `value`, most significant first, at one bit each."""
        self.out = reserve(self.state, self.out, n_bits)
        encode_direct(self.state, self.out, value, n_bits)

    def finish(self) -> bytes:
        self.out = _finish_encoding(self.state, self.out)
        return self.out[1 : self.state[_SIZE]].tobytes()  # the first byte is always 0


# --------------------------------------------------------------------------- decoding


@numba.njit(cache=True, nogil=True)
def _normalise(state, data):
    while state[_DECODER_RANGE] < _TOP:
        state[_DECODER_RANGE] <<= 8
        if state[_POSITION] < data.size:
            byte = data[state[_POSITION]]
            state[_POSITION] += 1
        else:  # the caller checks `_EXHAUSTED` before acting on what was decoded
            state[_EXHAUSTED] = 1
            byte = 0
        # Only a stream starting FF FF FF FF has code >= range; every bit then decodes as 1 up to
        # an error.  The min keeps its code within int64 (and still >= range) while that lasts.
        state[_CODE] = min((state[_CODE] << 8) | byte, state[_DECODER_RANGE])


@numba.njit(cache=True, nogil=True)
def decode_bit(state, data, models, index):
    p = models[index]
    bound = (state[_DECODER_RANGE] >> _PROB_BITS) * p
    if state[_CODE] < bound:
        state[_DECODER_RANGE] = bound
        models[index] = p + ((_ONE - p) >> state[_DECODER_SHIFT])
        bit = 0
    else:
        state[_CODE] -= bound
        state[_DECODER_RANGE] -= bound
        models[index] = p - (p >> state[_DECODER_SHIFT])
        bit = 1
    _normalise(state, data)
    return bit


@numba.njit(cache=True, nogil=True)
def decode_direct(state, data, n_bits):
    value = 0
    for _ in range(n_bits):
        state[_DECODER_RANGE] >>= 1
        bit = 0
        if state[_CODE] >= state[_DECODER_RANGE]:
            state[_CODE] -= state[_DECODER_RANGE]
            bit = 1
        value = (value << 1) | bit
        _normalise(state, data)
    return value


@numba.njit(cache=True, nogil=True)
def decode_exp_golomb(state, data, models, max_length, chunks):
    """An integer in the adaptive Exp-Golomb code of `archive.skeletons` (models[0]: is it 0,
    [1]: its sign, [2:]: its bit length in unary up to `max_length`; then its bits below the
    leading one direct, 32 at most at a time): its bit length, negated if it is negative (0 for
    0), and those bits in `chunks` as they came.  Why compiled: a skeletons stream holds some
    thousands of them, and a decision at a time from Python cost a call each."""
    if not decode_bit(state, data, models, 0):
        return 0
    negative = decode_bit(state, data, models, 1)
    length = 1
    while length < max_length and decode_bit(state, data, models, 1 + length):
        length += 1
    bits = length - 1
    i = 0
    while bits > 0:
        take = min(bits, 32)
        bits -= take
        chunks[i] = decode_direct(state, data, take)
        i += 1
    return -length if negative else length


@numba.njit(cache=True, nogil=True)
def exhausted(state):
    """Whether the decoder needed a byte past the end of its stream (what it decoded since is void)."""
    return state[_EXHAUSTED] != 0


class Decoder:
    """Reads what `Encoder` wrote.  Compiled callers take the state slots and `data` and stop at
    `exhausted`; their caller then raises through `check_not_exhausted`.  `finish` checks that
    exactly all bytes were used."""

    def __init__(self, data: bytes, shift: int = FAST_SHIFT):
        if len(data) < 4:
            raise ValueError("range-coded stream shorter than its 4-byte minimum")
        self.data = np.frombuffer(bytes(data), np.uint8)
        self.state = np.zeros(5, np.int64)
        self.state[_CODE] = int.from_bytes(data[:4], "big")
        self.state[_DECODER_RANGE] = _MASK32
        self.state[_POSITION] = 4
        self.state[_DECODER_SHIFT] = shift
        self._chunks = np.zeros(0, np.int64)  # exp_golomb's direct bits

    def bit(self, models: np.ndarray, index: int) -> int:
        bit = decode_bit(self.state, self.data, models, index)
        self.check_not_exhausted()
        return bit

    def direct(self, n_bits: int) -> int:
        value = decode_direct(self.state, self.data, n_bits)
        self.check_not_exhausted()
        return value

    def exp_golomb(self, models: np.ndarray, max_length: int) -> int:
        """An integer as `decode_exp_golomb` reads it, of at most `max_length` bits."""
        if self._chunks.size < (max_length + 30) // 32:
            self._chunks = np.zeros((max_length + 30) // 32, np.int64)
        length = decode_exp_golomb(self.state, self.data, models, max_length, self._chunks)
        self.check_not_exhausted()
        bits, rest = abs(length) - 1, 0
        for chunk in self._chunks.tolist():
            if bits <= 0:
                break
            take = min(bits, 32)
            bits -= take
            rest = (rest << take) | chunk
        magnitude = (1 << (abs(length) - 1)) + rest if length else 0
        return -magnitude if length < 0 else magnitude

    def check_not_exhausted(self) -> None:
        if self.state[_EXHAUSTED]:
            raise ValueError("range-coded stream ends early")

    def finish(self) -> None:
        self.check_not_exhausted()
        if self.state[_POSITION] != self.data.size:
            raise ValueError(f"{self.data.size - self.state[_POSITION]} unexpected bytes after the range-coded stream")
        if self.state[_CODE] >= self.state[_DECODER_RANGE]:
            raise ValueError("range-coded stream is inconsistent at its end")
