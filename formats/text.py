"""Shared text handling for the Acclaim readers: decoding, line splitting and number parsing.

Numbers follow one grammar everywhere (ASF, AMC, fast and exact paths)::

    [+-]? ( digits [. digits?] | . digits ) ( [eE] [+-]? digits )?

so ``nan``, ``inf``, ``1_000`` or ``0x10`` are refused even though Python's ``float`` takes
some of them. Values must be finite and at most `MAX_ABS_VALUE` in magnitude: motion
capture angles and positions are far below 1e9, and a value like 1e308 is a corrupted file,
not a pose (it would also overflow every later computation).

`parse_number_tokens` converts many tokens of a byte buffer at once with NumPy: it rebuilds
each token's decimal mantissa and exponent exactly and does one correctly rounded
multiplication or division by an exact power of ten (Clinger's fast path), so its results are
bit-identical to ``float(token)``. Tokens outside that fast path (more than 15 significant
digits, exponents beyond 10**22, malformed text) are reported for the caller to handle.
"""

from __future__ import annotations

import io
import os
import re
import stat

import numpy as np

from mocapzip.formats.errors import MocapFormatError

MAX_ABS_VALUE = 1e9
"""Largest accepted magnitude of any number in an ASF or AMC file (limits may be +-inf)."""

NUMBER = re.compile(rb"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")
WHITESPACE = b" \t\r\n\x0b\x0c"  # what bytes.split() splits on
_UTF16_BOMS = (b"\xff\xfe", b"\xfe\xff")
_UTF8_BOM = b"\xef\xbb\xbf"


# --------------------------------------------------------------------------- opening

_KINDS = {stat.S_IFIFO: "a named pipe (FIFO)", stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device",
          stat.S_IFSOCK: "a socket", stat.S_IFDIR: "a directory"}


def check_regular_file(st: os.stat_result, path) -> None:
    """MocapFormatError unless `st` (of `path`) is a regular file: a pipe would block a reader
    and a device (/dev/zero) never ends, so input files must be plain files."""
    if not stat.S_ISREG(st.st_mode):
        kind = _KINDS.get(stat.S_IFMT(st.st_mode), "a special file")
        target = os.path.realpath(path)
        if target != os.path.abspath(path):
            kind += f" ({target})"
        raise MocapFormatError(f"not a regular file: {kind}", path)


def read_regular_file(path) -> bytes:
    """The bytes of `path`, opened by `open_regular_file`."""
    with open_regular_file(path) as file:
        return file.read()


def open_regular_file(path) -> io.BufferedReader:
    """`path` opened for binary reading; MocapFormatError if it is not a regular file (a symbolic
    link to one is fine), OSError if it cannot be opened.

    The type is checked before opening, so opening never blocks on a FIFO, and again on the
    open descriptor (opened with O_NONBLOCK), in case the path was replaced in between.
    """
    check_regular_file(os.stat(path), path)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    try:
        check_regular_file(os.fstat(fd), path)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


# --------------------------------------------------------------------------- decoding


def check_text(data: bytes, path: str | None) -> bytes:
    """`data` without a UTF-8 byte-order mark; MocapFormatError for empty, UTF-16 or binary input."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise TypeError(f"expected bytes, got {type(data).__name__}")
    data = bytes(data)
    if data.startswith(_UTF8_BOM):
        data = data[len(_UTF8_BOM):]
    if data[:2] in _UTF16_BOMS:
        raise MocapFormatError("UTF-16 text, not an ASCII Acclaim file", path, 1)
    head = data[:65536]
    if b"\x00" in head:
        # ASCII stored as UTF-16 without a byte-order mark: every other byte is NUL.
        utf16 = head[1::2].count(0) > len(head) // 4 or head[0::2].count(0) > len(head) // 4
        kind = "UTF-16 text" if utf16 else "binary data (NUL bytes)"
        raise MocapFormatError(f"{kind}, not an ASCII Acclaim file", path, line_of_offset(data, data.index(b"\x00")))
    if not data.strip():
        raise MocapFormatError("empty file", path, 1)
    return data


def detect_encoding(data: bytes) -> str:
    """'utf-8' when `data` is valid UTF-8 (ASCII included), else 'latin-1'.

    Acclaim files are ASCII in practice, but real ones carry Latin-1 bytes in comments
    (HDM05: 'f\\xfcr Bonn'); Latin-1 decodes any byte, so reading never fails on them.
    """
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return "latin-1"
    return "utf-8"


def decode_text(data: bytes, path: str | None) -> str:
    """Checked (see `check_text`) and decoded text of an Acclaim file."""
    data = check_text(data, path)
    return data.decode(detect_encoding(data))


def split_lines(text):
    """Lines of `text` (str or bytes) without their endings; CRLF, LF and CR all end a line.

    Unlike str.splitlines this never splits on form feeds, U+0085 or U+2028, so line
    numbers agree with every text editor.
    """
    if isinstance(text, str):
        return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    return text.replace(b"\r\n", b"\n").replace(b"\r", b"\n").split(b"\n")


def line_of_offset(data: bytes, offset: int) -> int:
    """1-based line number of byte `offset` (CRLF, LF and lone CR count as one line end each)."""
    head = data[:offset]
    return head.count(b"\n") + head.count(b"\r") - head.count(b"\r\n") + 1


# --------------------------------------------------------------------------- single numbers


def number(word, path: str | None, line: int | None, *, what: str = "value") -> float:
    """A finite float within MAX_ABS_VALUE, or MocapFormatError naming file and line."""
    raw = word.encode("latin-1", "replace") if isinstance(word, str) else bytes(word)
    if not NUMBER.match(raw):
        shown = raw[:40].decode("latin-1")
        lowered = shown.lower().lstrip("+-")
        if lowered in ("nan", "inf", "infinity"):
            raise MocapFormatError(f"{what} is not finite: {shown!r}", path, line)
        raise MocapFormatError(f"not a number: {shown!r}", path, line)
    value = float(raw)
    if not abs(value) <= MAX_ABS_VALUE:
        raise MocapFormatError(
            f"{what} {raw.decode('latin-1')} is out of range (|v| > {MAX_ABS_VALUE:g})", path, line
        )
    return value


def integer(word, path: str | None, line: int | None, *, what: str = "value") -> int:
    raw = word.encode("latin-1", "replace") if isinstance(word, str) else bytes(word)
    if not re.fullmatch(rb"[+-]?\d+", raw):
        raise MocapFormatError(f"{what} must be an integer, got {raw[:40].decode('latin-1')!r}", path, line)
    if len(raw.lstrip(b"+-0")) > 18:
        raise MocapFormatError(f"{what} {raw[:40].decode('latin-1')} is out of range", path, line)
    return int(raw)


def token_stats(raw: bytes) -> tuple[int, int, int, bool]:
    """(significant digits, decimals, exponent digits or 0, has a dot) of a valid number token."""
    mantissa, _, exponent = raw.lstrip(b"+-").lower().partition(b"e")
    whole, dot, frac = mantissa.partition(b".")
    digits = (whole + frac).lstrip(b"0")
    return len(digits), len(frac), len(exponent.lstrip(b"+-")), bool(dot)


# --------------------------------------------------------------------------- vectorised parsing

_P10 = 10.0 ** np.arange(23)  # 1e0 .. 1e22 are exact doubles
_TWO53 = 2.0**53
_MAX_WIDTH = 22  # longer tokens go to the caller's fallback
_PAD = 32  # spaces around the body in padded_buffer: room for a 24-byte window left of a token
_CHUNK = 1 << 13  # tokens per block: temporaries stay small enough for the CPU cache and malloc reuse

_U64 = np.dtype("<u8")
_ONES = np.uint64(0x0101010101010101)  # (w * _ONES) >> 56: sum of w's bytes (when it stays < 256)
# (w * _PLACES[k]) >> 56: sum over 0/1 bytes of (distance from the right end) for word k from the right
_PLACES = [np.uint64(sum((8 * k + t) << (8 * t) for t in range(8))) for k in range(3)]
_LOW_BITS = np.uint64(0x0101010101010101)
_S8, _S16, _S32, _S56 = (np.uint64(k) for k in (8, 16, 32, 56))
_M8 = np.uint64(0x00FF00FF00FF00FF)
_M16 = np.uint64(0x0000FFFF0000FFFF)
_K2, _K4, _K8 = np.uint64(2561), np.uint64(6553601), np.uint64(42949672960001)
_NIBBLE = np.uint64(15)
_FOUR = np.uint64(4)
_IS_SIGN = np.zeros(256, dtype=np.int64)
_IS_SIGN[[ord("+"), ord("-")]] = 1
_DIGIT_VALUE = np.zeros(256, dtype=np.uint8)
_DIGIT_VALUE[ord("0") : ord("9") + 1] = np.arange(10)
_CLASS_A = np.zeros(256, dtype=np.uint8)
_CLASS_A[ord("0") : ord("9") + 1] = 0x01
_CLASS_A[ord(".")] = 0x10
_CLASS_B = np.zeros(256, dtype=np.uint8)
_CLASS_B[[ord("e"), ord("E")]] = 0x01
_CLASS_B[[ord("+"), ord("-")]] = 0x10
# _MASKS[w][L]: keeps the last L of 8*w bytes
_MASKS = {w: np.tri(8 * w + 1, 8 * w, -1, dtype=np.uint8)[:, ::-1] * np.uint8(255) for w in (1, 2, 3)}


class NumberBlock:
    """Result of `parse_number_tokens`: values plus what the number style needs."""

    __slots__ = ("values", "ok", "has_dot", "decimals", "has_exp", "exp_digits", "mantissa", "fallback_sig")

    def __init__(self, n: int):
        self.values = np.empty(n)
        self.ok = np.zeros(n, dtype=bool)  # False: not converted (caller falls back to `number`)
        self.has_dot = np.zeros(n, dtype=bool)
        self.decimals = np.zeros(n, dtype=np.int64)  # digits after the dot
        self.has_exp = np.zeros(n, dtype=bool)
        self.exp_digits = np.zeros(n, dtype=np.int64)
        self.mantissa = np.zeros(n)  # the digits as an integer (leading zeros dropped)
        self.fallback_sig = 0  # most significant digits among tokens converted by the caller

    def store(self, i: int, value: float, raw: bytes) -> None:
        """Record a value the caller converted itself (a token with ok=False)."""
        sig, decimals, exp_digits, has_dot = token_stats(raw)
        self.values[i] = value
        self.ok[i] = True
        self.decimals[i] = decimals
        self.has_exp[i] = exp_digits > 0
        self.exp_digits[i] = exp_digits
        self.has_dot[i] = has_dot
        self.fallback_sig = max(self.fallback_sig, sig)

    def max_significant_digits(self) -> int:
        biggest = float(self.mantissa.max()) if self.mantissa.size else 0.0
        return max(int(np.searchsorted(_P10, biggest, side="right")), self.fallback_sig)


def padded_buffer(body: bytes) -> np.ndarray:
    """`body` as uint8 with _PAD spaces on both sides, as `parse_number_tokens` needs."""
    pad = b" " * _PAD
    return np.frombuffer(pad + body + pad, dtype=np.uint8)


def token_bounds(buf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end offsets (end exclusive) of the whitespace-separated tokens of `buf`.

    Whitespace is what bytes.split() uses: space, tab, CR, LF, VT, FF. Other control bytes
    belong to tokens (and then fail number parsing), as in the exact path.
    """
    ws = (buf == 32) | ((buf - np.uint8(9)) < 5)
    step = np.diff(ws.view(np.int8))
    starts = np.flatnonzero(step == -1) + 1
    ends = np.flatnonzero(step == 1) + 1
    return starts, ends


def parse_number_tokens(buf: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> NumberBlock:
    """Convert the tokens buf[starts[i]:ends[i]] to float64, exactly as float() would.

    `buf` must come from `padded_buffer`. Tokens that are malformed or outside the exact fast
    path get ok=False and are left for the caller (see NumberBlock.store).
    """
    out = NumberBlock(len(starts))
    for lo in range(0, len(starts), _CHUNK):
        hi = min(lo + _CHUNK, len(starts))
        _parse_block(buf, starts[lo:hi], ends[lo:hi], out, slice(lo, hi))
    return out


def _parse_block(buf, starts, ends, out: NumberBlock, sl: slice) -> None:
    n = len(starts)
    if n == 0:
        return
    length = ends - starts
    width = 8 * -(-min(int(length.max()), _MAX_WIDTH) // 8)  # 8, 16 or 24
    n_words = width // 8
    # Right-aligned rows: byte c of row i is buf[ends[i] - width + c]; bytes left of the token
    # are masked to 0, which no class below counts.
    windows = np.lib.stride_tricks.as_strided(buf, shape=(buf.size - width, width), strides=(1, 1))
    chars = windows[ends - width]
    chars &= _MASKS[n_words][np.minimum(length, width)]
    digits = np.take(_DIGIT_VALUE, chars).view(_U64)
    class_a = np.take(_CLASS_A, chars).view(_U64)  # digit 0x01, dot 0x10
    class_b = np.take(_CLASS_B, chars).view(_U64)  # e/E 0x01, sign 0x10

    # All digits as one integer, dot/sign/e columns counting as 0 (SWAR: 8 digits per word).
    v = (digits * _K2) >> _S8
    v = ((v & _M8) * _K4) >> _S16
    v = ((v & _M16) * _K8) >> _S32
    raw = v[:, 0].astype(np.float64)
    for m in range(1, n_words):
        raw = raw * 1e8 + v[:, m]

    n_digit, n_dot = _nibble_counts(class_a)
    n_exp, n_sign = _nibble_counts(class_b)
    j_dot = _position(class_a >> _FOUR)
    j_exp = _position(class_b)

    rows = np.arange(n)
    first = chars[rows, np.maximum(width - length, 0)]
    after_exp = chars[rows, np.clip(width - j_exp, 0, width - 1)]
    has_exp = n_exp == 1
    has_dot = n_dot == 1
    sign_first = _IS_SIGN[first]
    sign_exp = has_exp & _IS_SIGN[after_exp]
    exp_digits = np.where(has_exp, j_exp - sign_exp, 0)
    ok = (
        (length <= _MAX_WIDTH)
        & (n_digit + n_dot + n_exp + n_sign == length)
        & (n_dot <= 1)
        & (n_exp <= 1)
        & (n_sign == sign_first + sign_exp)
        & (~has_exp | (exp_digits >= 1))
        & (n_digit - exp_digits >= 1)
        & (~has_dot | ~has_exp | (j_dot > j_exp))
        & (raw < _TWO53)
        & (j_exp <= 21)
    )
    # raw < 2**53 is exact, so floor division by an exact power of ten is exact too.
    if has_exp.any():
        p_exp = _P10[np.where(ok, j_exp, 0)]
        exp_abs = np.where(has_exp, raw - np.floor(raw / p_exp) * p_exp, 0.0)
        dotted = np.where(has_exp, (raw - exp_abs) / (p_exp * 10.0), raw)
        decimals = np.where(has_dot & ok, j_dot - np.where(has_exp, j_exp + 1, 0), 0)
        exponent = np.where(after_exp == 45, -exp_abs, exp_abs).astype(np.int64) - decimals
    else:
        dotted = raw
        decimals = np.where(has_dot & ok, j_dot, 0)
        exponent = -decimals
    p_dec = _P10[np.clip(decimals, 0, 22)]
    low = dotted - np.floor(dotted / p_dec) * p_dec
    mantissa = np.where(has_dot, low + (dotted - low) / 10.0, dotted)
    ok &= np.abs(exponent) <= 22
    scale = _P10[np.minimum(np.abs(exponent), 22)]
    values = np.where(exponent >= 0, mantissa * scale, mantissa / scale)
    np.negative(values, out=values, where=first == 45)

    out.values[sl] = values
    out.ok[sl] = ok
    out.has_dot[sl] = has_dot
    out.decimals[sl] = decimals
    out.has_exp[sl] = has_exp
    out.exp_digits[sl] = exp_digits
    out.mantissa[sl] = np.where(ok, mantissa, 0.0)


def _byte_sum(words: np.ndarray) -> np.ndarray:
    """Sum of the bytes of each uint64 (correct while every partial sum stays below 256)."""
    return (words * _ONES) >> _S56


def _nibble_counts(words: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row of `words` (bytes 0x00, 0x01 or 0x10): the number of 0x01 and of 0x10 bytes.

    Two words are added before the byte sum (bytes then reach 0x22, sums 16 per nibble at
    most): a row of 16 equal classes overflows its nibble, which makes the counts disagree
    with the token length, so the token goes to the exact fallback and is never misread.
    """
    total = _byte_sum(words[:, 0] + words[:, 1] if words.shape[1] > 1 else words[:, 0]).astype(np.int64)
    low, high = total & 15, total >> 4
    if words.shape[1] > 2:
        more = _byte_sum(words[:, 2]).astype(np.int64)
        low = low + (more & 15)
        high = high + (more >> 4)
    return low, high


def _position(words: np.ndarray) -> np.ndarray:
    """Per row, sum of (distance from the row's right end) over bytes whose low bit is set."""
    n_words = words.shape[1]
    total = np.zeros(words.shape[0], dtype=np.uint64)
    for m in range(n_words):
        total += (words[:, m] & _LOW_BITS) * _PLACES[n_words - 1 - m]
    return (total >> _S56).astype(np.int64)
