"""A binary adaptive range coder (the LZMA design) for context-modelled bits.

Why binary: the lossy coefficients are few (about ten thousand decisions per
clip) but their statistics depend strongly on context (frequency, neighbours).
Adaptive binary models handle any number of contexts with no stored tables
and learn within a few dozen bits, which matters when every clip is coded on
its own for random access.

Each model is an 11-bit probability that the next bit is 0, moved 1/2**shift
of the way towards each coded bit: shift 4 (fast) for models that start at
1/2, 5 for models that start from trained priors (`coefficients.Priors`).  `Encoder.bit` and `Decoder.bit` take the
model array and an index into it, so callers keep one array per kind of
decision.  Bits known to be near 50/50 (signs, low bits of magnitudes) go
through `direct`, which costs exactly one bit.

Integer arithmetic only: encoder and decoder agree bit for bit everywhere.
The encoder's first output byte is always 0 and is not stored.
"""

__all__ = ["Encoder", "Decoder", "new_models"]

_PROB_BITS = 11
_ONE = 1 << _PROB_BITS
FAST_SHIFT = 4  # adaptation rate of models that start at 1/2: fast, because a clip's streams are short
_TOP = 1 << 24
_MASK32 = 0xFFFFFFFF


def new_models(count: int) -> list[int]:
    """`count` fresh models, each at probability 1/2."""
    return [_ONE >> 1] * count


class Encoder:
    def __init__(self, shift: int = FAST_SHIFT):
        self._adaptation = shift
        self._low = 0
        self._range = _MASK32
        self._cache = 0
        self._pending = 1  # bytes held back until a carry can no longer change them
        self._out = bytearray()

    def bit(self, models: list[int], index: int, bit: int) -> None:
        p = models[index]
        bound = (self._range >> _PROB_BITS) * p
        if bit:
            self._low += bound
            self._range -= bound
            models[index] = p - (p >> self._adaptation)
        else:
            self._range = bound
            models[index] = p + ((_ONE - p) >> self._adaptation)
        while self._range < _TOP:
            self._range <<= 8
            self._shift_low()

    def direct(self, value: int, n_bits: int) -> None:
        """The low `n_bits` of `value`, most significant first, at one bit each."""
        for shift in range(n_bits - 1, -1, -1):
            self._range >>= 1
            if (value >> shift) & 1:
                self._low += self._range
            while self._range < _TOP:
                self._range <<= 8
                self._shift_low()

    def _shift_low(self) -> None:
        if self._low < 0xFF000000 or self._low > _MASK32:
            carry = self._low >> 32
            byte = self._cache
            while self._pending:
                self._out.append((byte + carry) & 0xFF)
                byte = 0xFF
                self._pending -= 1
            self._cache = (self._low >> 24) & 0xFF
        self._pending += 1
        self._low = (self._low & 0x00FFFFFF) << 8

    def finish(self) -> bytes:
        for _ in range(5):
            self._shift_low()
        return bytes(self._out[1:])  # the first byte is always 0


class Decoder:
    """Reads what `Encoder` wrote; `finish` checks that exactly all bytes were used."""

    def __init__(self, data: bytes, shift: int = FAST_SHIFT):
        self._adaptation = shift
        self._data = b"\x00" + bytes(data)
        if len(self._data) < 5:
            raise ValueError("range-coded stream shorter than its 4-byte minimum")
        self._code = int.from_bytes(self._data[1:5], "big")
        self._pos = 5
        self._range = _MASK32

    def _next_byte(self) -> int:
        if self._pos >= len(self._data):
            raise ValueError("range-coded stream ends early")
        byte = self._data[self._pos]
        self._pos += 1
        return byte

    def bit(self, models: list[int], index: int) -> int:
        p = models[index]
        bound = (self._range >> _PROB_BITS) * p
        if self._code < bound:
            self._range = bound
            models[index] = p + ((_ONE - p) >> self._adaptation)
            bit = 0
        else:
            self._code -= bound
            self._range -= bound
            models[index] = p - (p >> self._adaptation)
            bit = 1
        while self._range < _TOP:
            self._range <<= 8
            self._code = (self._code << 8) | self._next_byte()
        return bit

    def direct(self, n_bits: int) -> int:
        value = 0
        for _ in range(n_bits):
            self._range >>= 1
            bit = self._code >= self._range
            if bit:
                self._code -= self._range
            value = (value << 1) | bit
            while self._range < _TOP:
                self._range <<= 8
                self._code = (self._code << 8) | self._next_byte()
        return value

    def finish(self) -> None:
        if self._pos != len(self._data):
            raise ValueError(f"{len(self._data) - self._pos} unexpected bytes after the range-coded stream")
        if self._code >= self._range:
            raise ValueError("range-coded stream is inconsistent at its end")
