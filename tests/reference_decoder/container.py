"""The .mcz container: an HDF5 file holding named, CRC-checked byte streams.

Implements docs/format.md, sections "Layout", "The index", "Checksums" and "Versions",
plus the zstd-frame rules of the streams spec ("zstd frames"). A trusted-input reader:
it checks the magic, the header and index CRCs, the index's back-to-back layout and
every stream's CRC, and raises ValueError on any mismatch.
"""

import json
import struct
import zlib

import h5py
import numpy as np
import zstandard

MAGIC = "MCZ mocapzip archive"
NEWEST_FORMAT = 6
MAX_ZSTD_OUTPUT = 1 << 28  # streams spec, "zstd frames": 2^28 bytes at most


class Reader:
    """A cursor over bytes: little-endian fixed-width fields and LEB128 varints (both specs'
    "Conventions"/"Building blocks"); `what` names the stream in errors."""

    def __init__(self, data: bytes, what: str = "stream"):
        self.data = data
        self.pos = 0
        self.what = what

    def take(self, n: int) -> bytes:
        if n < 0 or self.pos + n > len(self.data):
            raise ValueError(f"{self.what}: ends early")
        chunk = self.data[self.pos:self.pos + n]
        self.pos += n
        return chunk

    def unpack(self, fmt: str):
        return struct.unpack("<" + fmt, self.take(struct.calcsize("<" + fmt)))

    def u8(self) -> int:
        return self.take(1)[0]

    def u32(self) -> int:
        return self.unpack("I")[0]

    def varint(self) -> int:
        """Unsigned LEB128, at most 10 bytes."""
        value = 0
        for k in range(10):
            byte = self.u8()
            value |= (byte & 0x7F) << (7 * k)
            if not byte & 0x80:
                return value
        raise ValueError(f"{self.what}: varint longer than 10 bytes")

    def rest(self) -> bytes:
        return self.take(len(self.data) - self.pos)

    def end(self):
        if self.pos != len(self.data):
            raise ValueError(f"{self.what}: {len(self.data) - self.pos} bytes too many")


def zstd_frame(data: bytes, limit: int = MAX_ZSTD_OUTPUT) -> tuple[bytes, bytes]:
    """Decode one zstd frame at the start of `data`; return (content, bytes after the frame).

    Streams spec, "zstd frames": the content checksum is verified when present (libzstd
    does so by default), the declared and actual content size must not exceed `limit`,
    and a truncated frame is an error. The caller decides what may follow the frame.
    """
    try:
        params = zstandard.get_frame_parameters(data)
    except zstandard.ZstdError as exc:
        raise ValueError(f"not a zstd frame: {exc}") from None
    if params.content_size != zstandard.CONTENTSIZE_UNKNOWN and params.content_size > limit:
        raise ValueError("zstd frame declares too large a content size")
    dobj = zstandard.ZstdDecompressor().decompressobj()
    try:
        content = dobj.decompress(data)
    except zstandard.ZstdError as exc:
        raise ValueError(f"bad zstd frame: {exc}") from None
    if not dobj.eof:
        raise ValueError("truncated zstd frame")
    if len(content) > limit:
        raise ValueError("zstd frame content too large")
    return content, dobj.unused_data


def zstd_stream(data: bytes) -> bytes:
    """A "zstd stream": exactly one zstd frame and nothing after it (streams spec)."""
    content, rest = zstd_frame(data)
    if rest:
        raise ValueError("bytes after the zstd frame")
    return content


def read_json(data: bytes):
    """A zstd-coded UTF-8 JSON stream (`meta`, `skeletons`) -> Python object."""
    return json.loads(zstd_stream(data).decode("utf-8"))


def _text(value) -> str:
    """A fixed-length, null-padded HDF5 string attribute as str."""
    if isinstance(value, (bytes, np.bytes_)):
        value = bytes(value).decode("utf-8")
    return str(value).rstrip("\0")


class Container:
    """Read the streams of an .mcz file (docs/format.md, "Layout" and "The index")."""

    def __init__(self, path):
        self._file = h5py.File(path, "r")
        try:
            self._open()
        except Exception:
            self._file.close()
            raise

    def _open(self):
        attrs = self._file.attrs
        magic = _text(attrs["magic"])
        if magic != MAGIC:
            raise ValueError(f"header: bad magic {magic!r}")
        # "Versions": the version check comes before the header CRC.
        self.format_version = int(attrs["format_version"])
        if not 1 <= self.format_version <= NEWEST_FORMAT:
            raise ValueError(f"header: format_version {self.format_version} not supported "
                             f"(1 to {NEWEST_FORMAT})")
        tool_version = _text(attrs["tool_version"])
        index_crc = int(attrs["index_crc32"])
        # "Checksums": header_crc32 = CRC32 of "magic\nformat_version\ntool_version\nindex_crc32".
        header = f"{magic}\n{self.format_version}\n{tool_version}\n{index_crc}"
        if zlib.crc32(header.encode("utf-8")) != int(attrs["header_crc32"]):
            raise ValueError("header: CRC mismatch")

        index_bytes = self._file["index"][:].tobytes()
        if zlib.crc32(index_bytes) != index_crc:
            raise ValueError("index: CRC mismatch")
        # "The index": one zstd frame that states its content size, nothing after it.
        if zstandard.get_frame_parameters(index_bytes).content_size == zstandard.CONTENTSIZE_UNKNOWN:
            raise ValueError("index: zstd frame does not state its content size")
        index = json.loads(zstd_stream(index_bytes).decode("utf-8"))
        if not isinstance(index, dict) or sorted(index) != ["crc32", "lengths", "names", "offsets"]:
            raise ValueError("index: not an object of the four arrays")
        names, offsets, lengths, crcs = (index[k] for k in ("names", "offsets", "lengths", "crc32"))
        if not len(names) == len(offsets) == len(lengths) == len(crcs):
            raise ValueError("index: arrays of different lengths")
        if len(set(names)) != len(names) or not all(isinstance(n, str) and n for n in names):
            raise ValueError("index: names must be non-empty and unique")

        # Streams are back to back, from 0, and fill `payload` exactly.
        self._payload = self._file["payload"]
        position = 0
        for offset, length in zip(offsets, lengths):
            if offset != position or length < 0:
                raise ValueError("index: streams are not stored back to back")
            position += length
        if position != self._payload.shape[0]:
            raise ValueError("index: lengths do not add up to the payload's length")

        self.names = list(names)
        self._where = {n: (o, l, c) for n, o, l, c in zip(names, offsets, lengths, crcs)}

    def read(self, name) -> bytes:
        """The bytes of stream `name`, CRC checked ("Checksums")."""
        offset, length, crc = self._where[name]
        data = self._payload[offset:offset + length].tobytes()
        if zlib.crc32(data) != crc:
            raise ValueError(f"stream {name!r}: CRC mismatch")
        return data

    def close(self):
        self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
