"""Lossless coding of integer arrays and byte blobs with zstandard.

What the range coder and the rANS coder do not code ends here: the byte
streams (meta, the skeletons' text, priors, warping paths), the lossless
channel coder's integer sections, format 1's coefficient layouts (decoded
by `legacy.streams`) and the size estimates of `--classes auto`. Each
integer array becomes bytes as small as zstd can make them.

zstd alone does poorly on raw little-endian integers, so each array is first
rearranged into one of three layouts, and the smallest result is kept:

* dense: signed values are zigzag-mapped (0, -1, 1, -2, ... -> 0, 1, 2, 3,
  ...) so small magnitudes of either sign have zero high bytes, stored with
  the narrowest byte width that holds the largest value and split into byte
  planes (all lowest bytes, then all second bytes, ...).  A plane of high
  bytes is nearly constant and costs almost nothing; interleaved with the
  noisy low bytes zstd could not see that.
* bit length: for noisy data (prediction residuals) even the planes waste
  space, because zstd spends a Huffman code on every low byte although its
  bits are random.  This layout gives zstd only the bit length of each
  zigzag code (one byte per value, cheap to entropy-code) and stores the bits
  below the leading one verbatim after the zstd frame, protected by a CRC32.
  Measured on prediction residuals of motion capture data: 1.5-6 % smaller
  than the planes.
* bitmap (only tried by `encode_sparse`): a bitmap of the non-zero positions,
  then the non-zero values as planes.

Arrays with two or more dimensions are also tried in both C and Fortran
(transposed) order; which one wins depends on the data, by 3-12 % on the
matrices this project produces.

About `encode_sparse`: measured on DCT coefficients of random-walk curves
(T=500, K=20) quantised to 5-20 % non-zeros, the bitmap layout wins by at
most about 4 % (rough curves, 20 % non-zeros) and loses by up to 5 %
elsewhere, because zstd already codes the long zero runs of the dense
layout very cheaply.  So `encode_sparse` simply adds the bitmap to the
candidates; the first byte of the payload records which layout won.

Integrity: every blob is a zstd frame with a content checksum (plus a CRC32
over the verbatim bits of the bit-length layout).  A corrupted, truncated or
padded blob raises `ValueError`; decoding never returns wrong data silently.

Untrusted input: a blob may come from anyone, so every size it declares is
checked before it is allocated or looped over (`check_size`), and a zstd
frame is never unpacked past a limit its caller states (`decode_bytes`,
`decode_ints`): a few kilobytes of zstd can unpack to gigabytes.

The zstd contexts are created once per process and reused (creating a level
19 context per call costs more than compressing a small array).  They are
not thread safe, so each use holds a lock.
"""

import functools
import math
import threading
import zlib

import numpy as np
import zstandard

from mocapzip.limits import MAX_DECODED_STREAM_BYTES, MAX_VALUES_PER_CLIP

__all__ = [
    "encode_ints",
    "encode_sparse",
    "decode_ints",
    "encode_bytes",
    "decode_bytes",
    "pack_blobs",
    "unpack_blobs",
    "write_varint",
    "ByteReader",
    "check_size",
]

_COMPRESSOR = zstandard.ZstdCompressor(level=19, write_checksum=True)
_DECOMPRESSOR = zstandard.ZstdDecompressor()
_COMPRESSOR_LOCK = threading.Lock()
_DECOMPRESSOR_LOCK = threading.Lock()

# The integer dtypes that can be stored; the index is written to the header.
_DTYPES = tuple(
    np.dtype(name)
    for name in ("int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64")
)

# Layout codes, the first byte of every encoded array.
_DENSE = 0
_BITMAP = 1
_BIT_LENGTH = 2

_ORDERS = ("C", "F")
_POWERS_OF_TWO = np.uint64(1) << np.arange(64, dtype=np.uint64)
_MAX_HEADER = 4 + 255 * 10  # layout, dtype, order and dimension count, then up to 255 ten-byte varints
# Compressed bytes unpacked at a time: a 4-byte block that repeats one byte unpacks to up to
# 128 KiB, so a step yields at most about 32 MiB, and a frame is refused soon after its limit.
_UNPACK_STEP = 1 << 10


# --------------------------------------------------------------------- bytes


def encode_bytes(data: bytes, dictionary: bytes | None = None) -> bytes:
    """Compress a raw byte string into one checksummed zstd frame, with `dictionary` (raw content
    that the frame may refer back to, as if it came first: `mocapzip.archive.dictionaries`) if given."""
    if dictionary is None:
        with _COMPRESSOR_LOCK:
            return _COMPRESSOR.compress(bytes(data))
    compressor, lock = _with_dictionary(dictionary)[0]
    with lock:
        return compressor.compress(bytes(data))


def decode_bytes(blob: bytes, limit: int = MAX_DECODED_STREAM_BYTES, dictionary: bytes | None = None) -> bytes:
    """Inverse of `encode_bytes` (with the same `dictionary`); raises ValueError if `blob` is not
    exactly one intact frame or unpacks to more than `limit` bytes."""
    data, rest = _decompress_frame(blob, limit, dictionary)
    if rest:
        raise ValueError(f"{len(rest)} unexpected bytes after the zstd frame")
    return data


@functools.cache
def _with_dictionary(dictionary: bytes):
    """A compressor and a decompressor for one raw-content dictionary, each with its lock: built
    once per process (preparing the dictionary costs more than a small frame)."""
    prepared = zstandard.ZstdCompressionDict(dictionary, dict_type=zstandard.DICT_TYPE_RAWCONTENT)
    return ((zstandard.ZstdCompressor(level=19, write_checksum=True, dict_data=prepared), threading.Lock()),
            (zstandard.ZstdDecompressor(dict_data=prepared), threading.Lock()))


# --------------------------------------------------------------- framing


def pack_blobs(blobs) -> bytes:
    """Concatenate byte strings so that `unpack_blobs` can split them again.

    Layout: count, then each length (all as varints), then the blobs.
    """
    blobs = [bytes(blob) for blob in blobs]
    header = bytearray()
    write_varint(header, len(blobs))
    for blob in blobs:
        write_varint(header, len(blob))
    return bytes(header) + b"".join(blobs)


def unpack_blobs(data: bytes) -> list:
    """Inverse of `pack_blobs`; raises ValueError on inconsistent lengths."""
    reader = ByteReader(bytes(data))
    count = check_size(reader.varint(), reader.remaining(), "blobs")  # a length takes at least a byte
    lengths = [reader.varint() for _ in range(count)]
    blobs = [reader.take(length) for length in lengths]
    if not reader.at_end():
        raise ValueError(f"{reader.remaining()} unexpected bytes after the last blob")
    return blobs


# -------------------------------------------------------------- integers


def encode_ints(array) -> bytes:
    """Losslessly encode an integer array of any shape (shape and dtype included)."""
    array = _as_int_array(array)
    candidates = []
    for order in _orders(array):
        codes = _to_codes(array.ravel(order=order))
        candidates.append(_dense(array, order, codes))
        candidates.append(_bit_length(array, order, codes))
    return min(candidates, key=len)


def encode_sparse(matrix) -> bytes:
    """Like `encode_ints`, but also tries the bitmap layout for mostly-zero data."""
    array = _as_int_array(matrix)
    candidates = [encode_ints(array)]
    for order in _orders(array):
        candidates.append(_bitmap(array, order, _to_codes(array.ravel(order=order))))
    return min(candidates, key=len)


_ESTIMATOR = zstandard.ZstdCompressor(level=9)


def estimated_size(ints) -> int:
    """About the bytes `encode_sparse` takes for an integer array, at a faster zstd level (the
    dense and bit-length layouts of C order only): for size estimates (`ratecontrol.class_bytes`)."""
    codes = _to_codes(_as_int_array(ints).ravel(order="C"))
    lengths, verbatim = split_leading_bits(codes)
    return 8 + min(len(_ESTIMATOR.compress(_planes(codes))), len(_ESTIMATOR.compress(lengths.tobytes())) + len(verbatim))


def decode_ints(blob: bytes, max_values: int = MAX_VALUES_PER_CLIP) -> np.ndarray:
    """Decode the output of `encode_ints` or `encode_sparse`; an array declaring more than
    `max_values` values is refused before it is unpacked or allocated."""
    # The largest layout (bitmap) takes a bit, eight bytes per value and a plane width byte.
    payload, rest = _decompress_frame(blob, _MAX_HEADER + 1 + (max_values + 7) // 8 + 8 * max_values)
    reader = ByteReader(payload)
    layout = reader.byte()
    dtype_index = reader.byte()
    if dtype_index >= len(_DTYPES):
        raise ValueError(f"unknown dtype code {dtype_index}")
    order_index = reader.byte()
    if order_index >= len(_ORDERS):
        raise ValueError(f"unknown array order code {order_index}")
    n_dims = reader.byte()
    shape = tuple(check_size(reader.varint(), max_values, "array values along one axis") for _ in range(n_dims))
    count = check_size(math.prod(shape), max_values, "array values")

    if layout == _DENSE:
        codes = _read_planes(reader, count)
    elif layout == _BITMAP:
        nonzero = _read_bits(reader.take((count + 7) // 8), count).astype(bool)
        codes = np.zeros(count, np.uint64)
        codes[nonzero] = _read_planes(reader, int(nonzero.sum()))
        if np.any(codes[nonzero] == 0):
            raise ValueError("bitmap marks a zero value as non-zero")
    elif layout == _BIT_LENGTH:
        crc = int.from_bytes(reader.take(4), "little")
        lengths = np.frombuffer(reader.take(count), np.uint8).astype(np.int64)
        if np.any(lengths > 64):
            raise ValueError("bit length above 64")
        if zlib.crc32(rest) != crc:
            raise ValueError("CRC mismatch in the verbatim bits after the zstd frame")
        codes = join_leading_bits(lengths, rest)
        rest = b""
    else:
        raise ValueError(f"unknown layout code {layout}")
    if not reader.at_end():
        raise ValueError(f"{reader.remaining()} unexpected bytes after the array data")
    if rest:
        raise ValueError(f"{len(rest)} unexpected bytes after the zstd frame")

    values = _from_codes(codes, _DTYPES[dtype_index])
    return values.reshape(shape, order=_ORDERS[order_index])


# ------------------------------------------------------------- layouts


def _dense(array, order, codes) -> bytes:
    return encode_bytes(_header(_DENSE, array, order) + _planes(codes))


def _bitmap(array, order, codes) -> bytes:
    nonzero = codes != 0
    body = np.packbits(nonzero).tobytes() + _planes(codes[nonzero])
    return encode_bytes(_header(_BITMAP, array, order) + body)


def _bit_length(array, order, codes) -> bytes:
    lengths, verbatim = split_leading_bits(codes)
    crc = zlib.crc32(verbatim).to_bytes(4, "little")
    return encode_bytes(_header(_BIT_LENGTH, array, order) + crc + lengths.tobytes()) + verbatim


def split_leading_bits(codes):
    """Bit length of each code (uint8) and the bits below each leading one, packed.

    The verbatim bits are written bit position by bit position (bit 0 of
    every code that has one, then bit 1, ...), which keeps both directions a
    short loop over at most 63 positions instead of a loop over values.
    """
    lengths = np.searchsorted(_POWERS_OF_TWO, codes, side="right")
    n_verbatim = np.maximum(lengths - 1, 0)
    bits = [
        ((codes[n_verbatim > position] >> np.uint64(position)) & np.uint64(1)).astype(np.uint8)
        for position in range(int(n_verbatim.max(initial=0)))
    ]
    packed = np.packbits(np.concatenate(bits)) if bits else np.zeros(0, np.uint8)
    return lengths.astype(np.uint8), packed.tobytes()


def join_leading_bits(lengths: np.ndarray, verbatim: bytes) -> np.ndarray:
    n_verbatim = np.maximum(lengths - 1, 0)
    bits = _read_bits(verbatim, int(n_verbatim.sum())).astype(np.uint64)
    codes = np.where(lengths > 0, _POWERS_OF_TWO[n_verbatim], 0).astype(np.uint64)
    start = 0
    for position in range(int(n_verbatim.max(initial=0))):
        has_bit = n_verbatim > position
        end = start + int(has_bit.sum())
        codes[has_bit] |= bits[start:end] << np.uint64(position)
        start = end
    return codes


# ------------------------------------------------------------- internals


def _decompress_frame(blob: bytes, limit: int = MAX_DECODED_STREAM_BYTES, dictionary: bytes | None = None):
    """Decompress the zstd frame at the start of `blob`; return (data, bytes after the frame).

    A few kilobytes of zstd can unpack to gigabytes: the size the frame header declares is
    checked against `limit` first. A frame that states its size (every one this project writes;
    zstd refuses a frame that outgrows it) is unpacked in one call; one that does not is unpacked
    a step at a time and refused as soon as its output passes `limit`, so it never holds much more.
    """
    blob = bytes(blob)
    view = memoryview(blob)
    parts, size, position = [], 0, 0
    try:
        declared = zstandard.frame_content_size(blob)  # -1: not declared
        if declared > limit:
            raise ValueError(f"zstd stream unpacks to {declared} bytes, more than the limit of {limit}")
        step = len(blob) if declared >= 0 else _UNPACK_STEP
        decompressor, lock = (_DECOMPRESSOR, _DECOMPRESSOR_LOCK) if dictionary is None else _with_dictionary(dictionary)[1]
        with lock:
            stream = decompressor.decompressobj()
            while not stream.eof and position < len(blob):
                parts.append(stream.decompress(view[position : position + step]))
                position += step
                size += len(parts[-1])
                if size > limit:
                    raise ValueError(f"zstd stream unpacks to more than the limit of {limit} bytes")
    except zstandard.ZstdError as error:
        raise ValueError(f"corrupt zstd data: {error}") from None
    if not stream.eof:
        raise ValueError("truncated zstd data: the frame ends early")
    return b"".join(parts), stream.unused_data + blob[position:]


def _as_int_array(array) -> np.ndarray:
    array = np.asarray(array)
    if array.dtype.kind not in "iu":
        raise TypeError(f"expected an integer array, got dtype {array.dtype}")
    return array


def _orders(array: np.ndarray):
    return _ORDERS if array.ndim >= 2 else _ORDERS[:1]


def _to_codes(flat: np.ndarray) -> np.ndarray:
    """Map integers to uint64 so that small magnitudes give small codes (zigzag for signed)."""
    if flat.dtype.kind == "u":
        return flat.astype(np.uint64)
    signed = flat.astype(np.int64)
    return ((signed << 1) ^ (signed >> 63)).view(np.uint64)


def _from_codes(codes: np.ndarray, dtype: np.dtype) -> np.ndarray:
    if dtype.kind == "u":
        values = codes
    else:
        sign = np.uint64(0) - (codes & np.uint64(1))
        values = ((codes >> np.uint64(1)) ^ sign).view(np.int64)
    info = np.iinfo(dtype)
    if values.size and (values.min() < info.min or values.max() > info.max):
        raise ValueError(f"decoded values do not fit the stored dtype {dtype}")
    return values.astype(dtype)


def _header(layout: int, array: np.ndarray, order: str) -> bytes:
    dtype_index = _DTYPES.index(array.dtype.newbyteorder("="))
    header = bytearray([layout, dtype_index, _ORDERS.index(order), array.ndim])
    for size in array.shape:
        write_varint(header, size)
    return bytes(header)


def _planes(codes: np.ndarray) -> bytes:
    """Width byte, then the codes split into that many byte planes (lowest byte first)."""
    width = (int(codes.max(initial=0)).bit_length() + 7) // 8
    as_bytes = codes.astype("<u8").view(np.uint8).reshape(-1, 8)
    return bytes([width]) + as_bytes[:, :width].T.tobytes()


def _read_planes(reader: "ByteReader", count: int) -> np.ndarray:
    width = reader.byte()
    if width > 8:
        raise ValueError(f"invalid byte width {width}")
    planes = np.frombuffer(reader.take(width * count), np.uint8).reshape(width, count)
    as_bytes = np.zeros((count, 8), np.uint8)
    as_bytes[:, :width] = planes.T
    return as_bytes.view("<u8").reshape(count).astype(np.uint64)


def _read_bits(data: bytes, count: int) -> np.ndarray:
    """Unpack exactly `count` bits; the byte count and the zero padding must match."""
    if len(data) != (count + 7) // 8:
        raise ValueError(f"expected {(count + 7) // 8} bytes of bits, got {len(data)}")
    bits = np.unpackbits(np.frombuffer(data, np.uint8))
    if np.any(bits[count:]):
        raise ValueError("padding bits are not zero")
    return bits[:count]


def check_size(size: int, limit: int, what: str) -> int:
    """`size` if 0 <= size <= limit: a size read from a stream is checked against what the stream
    or the limits allow before anything is allocated or looped over for it."""
    if not 0 <= size <= limit:
        raise ValueError(f"stream declares {size} {what} (at most {limit})")
    return size


def write_varint(out: bytearray, value: int) -> None:
    """Unsigned LEB128: 7 bits per byte, high bit set on all but the last byte."""
    if value < 0:
        raise ValueError("varints are unsigned")
    while value >= 0x80:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)


class ByteReader:
    """Sequential reader over bytes that reports short or malformed data as ValueError."""

    def __init__(self, data: bytes):
        self._data = data
        self._pos = 0

    def byte(self) -> int:
        return self.take(1)[0]

    def varint(self) -> int:
        value = 0
        for shift in range(0, 64, 7):
            byte = self.byte()
            value |= (byte & 0x7F) << shift
            if byte < 0x80:
                return value
        raise ValueError("varint longer than 64 bits")

    def take(self, count: int) -> bytes:
        end = self._pos + count
        if end > len(self._data):
            raise ValueError(
                f"data too short: needed {count} bytes at offset {self._pos}, "
                f"only {len(self._data) - self._pos} left"
            )
        chunk = self._data[self._pos : end]
        self._pos = end
        return chunk

    def remaining(self) -> int:
        return len(self._data) - self._pos

    def at_end(self) -> bool:
        return self._pos == len(self._data)
