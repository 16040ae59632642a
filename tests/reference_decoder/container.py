"""The .mcz container: an HDF5 file holding named, CRC-checked byte streams.

Implements docs/format.md, sections "Layout", "The index", "Checksums" (§2) and "Versions" (§3),
plus the zstd-frame rules ("zstd frames", §1.8) and the "Dictionaries" (§4). A
trusted-input reader: it checks the magic, the index CRC (formats 1 to 6: also the header CRC),
that the lengths fill the payload, and every stream's CRC, and raises ValueError on any mismatch.
"""

import hashlib
import json
import struct
import zlib
from pathlib import Path

import h5py
import numpy as np
import zstandard

MAGIC = "MCZ mocapzip archive"
NEWEST_FORMAT = 13  # "Versions": formats 8 to 13 have format 7's container
MAX_ZSTD_OUTPUT = 1 << 28  # streams spec, "zstd frames": 2^28 bytes at most
# "Dictionaries": the files of the package source tree, by their SHA-256
DICTIONARY_FOLDER = Path(__file__).resolve().parents[2] / "mocapzip" / "archive" / "dictionaries"
DICTIONARY_SHA256 = {
    "asf.txt": "fc1669c1f3b42e1772cee8bfc43dd38ffa339970400e0fb6d09b25a74346f0ef",
    "meta.json": "4ce94dcc42a74062fd57a71db99d5c118ed2eb70fbe6a4a41f61a7e337a5cdf8",
    "asf_means.txt": "250c96c61d427606d0ca1014c01548e0cfc91fc3c016ccb8965dc660882b9432",
}


def dictionary(name: str) -> bytes:
    data = (DICTIONARY_FOLDER / name).read_bytes()
    if hashlib.sha256(data).hexdigest() != DICTIONARY_SHA256[name]:
        raise ValueError(f"dictionary {name}: SHA-256 mismatch")
    return data


class Reader:
    """A cursor over bytes: little-endian fixed-width fields and LEB128 varints (docs/format.md §1,
    "Conventions and building blocks"); `what` names the stream in errors."""

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


def zstd_frame(data: bytes, limit: int = MAX_ZSTD_OUTPUT, raw_dictionary: bytes | None = None) -> tuple[bytes, bytes]:
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
    kwargs = {}
    if raw_dictionary is not None:
        kwargs["dict_data"] = zstandard.ZstdCompressionDict(raw_dictionary, dict_type=zstandard.DICT_TYPE_RAWCONTENT)
    dobj = zstandard.ZstdDecompressor(**kwargs).decompressobj()
    try:
        content = dobj.decompress(data)
    except zstandard.ZstdError as exc:
        raise ValueError(f"bad zstd frame: {exc}") from None
    if not dobj.eof:
        raise ValueError("truncated zstd frame")
    if len(content) > limit:
        raise ValueError("zstd frame content too large")
    return content, dobj.unused_data


def zstd_stream(data: bytes, raw_dictionary: bytes | None = None) -> bytes:
    """A "zstd stream": exactly one zstd frame and nothing after it (streams spec)."""
    content, rest = zstd_frame(data, raw_dictionary=raw_dictionary)
    if rest:
        raise ValueError("bytes after the zstd frame")
    return content


def read_meta(data: bytes, version: int) -> dict:
    """Stream `meta`: zstd-coded UTF-8 JSON, with dictionary meta.json from format 7 on."""
    return json.loads(zstd_stream(data, dictionary("meta.json") if version >= 7 else None).decode("utf-8"))


def read_skeletons(data: bytes, version: int) -> list[str]:
    """Stream `skeletons`: the ASF texts (as Latin-1 str). Format 7 on: zstd with dictionary asf.txt
    of a varint count, the varint byte lengths, then the texts; before: zstd of a JSON list of str."""
    if version < 7:
        return json.loads(zstd_stream(data).decode("utf-8"))
    reader = Reader(zstd_stream(data, dictionary("asf.txt")), "skeletons")
    lengths = [reader.varint() for _ in range(reader.varint())]
    texts = [reader.take(n).decode("latin-1") for n in lengths]
    reader.end()
    return texts


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
        # "Versions": the version check comes before anything else is read.
        self.format_version = int(attrs["format_version"])
        if not 1 <= self.format_version <= NEWEST_FORMAT:
            raise ValueError(f"header: format_version {self.format_version} not supported "
                             f"(1 to {NEWEST_FORMAT})")
        names, lengths, crcs = self._index() if self.format_version >= 7 else self._legacy_index()
        if len(set(names)) != len(names) or not all(isinstance(n, str) and n for n in names):
            raise ValueError("index: names must be non-empty and unique")
        # Streams are back to back, from 0, and fill `payload` exactly.
        self._payload = self._file["payload"]
        offsets = [sum(lengths[:i]) for i in range(len(lengths))]
        if sum(lengths) != self._payload.shape[0]:
            raise ValueError("index: lengths do not add up to the payload's length")
        self.names = list(names)
        self._where = {n: (o, l, c) for n, o, l, c in zip(names, offsets, lengths, crcs)}

    def _index(self):
        """Format 7 on: UTF-8 JSON {tool, names, lengths, crc32} (format 10 on: and maybe contents),
        in attribute `index` or else as the one
        string of dataset `index` (deflated by HDF5); CRC in `index_crc32`."""
        attrs = self._file.attrs
        index_bytes = bytes(attrs["index"]) if "index" in attrs else bytes(self._file["index"][0])
        if zlib.crc32(index_bytes) != int(attrs["index_crc32"]):
            raise ValueError("index: CRC mismatch")
        index = json.loads(index_bytes.decode("utf-8"))
        if isinstance(index, dict) and self.format_version >= 10:  # "The index": contents, for people only
            self.contents = index.pop("contents", None)
        if not isinstance(index, dict) or sorted(index) != ["crc32", "lengths", "names", "tool"]:
            raise ValueError("index: not an object of tool and the three arrays")
        self.tool_version = index["tool"]
        names, lengths, crcs = (index[k] for k in ("names", "lengths", "crc32"))
        if not len(names) == len(lengths) == len(crcs) or min(lengths, default=0) < 0:
            raise ValueError("index: arrays of different lengths, or a negative length")
        return names, lengths, crcs

    def _legacy_index(self):
        """Formats 1 to 6: dataset `index`, zstd of JSON {names, offsets, lengths, crc32}; header CRC."""
        attrs = self._file.attrs
        self.tool_version = _text(attrs["tool_version"])
        index_crc = int(attrs["index_crc32"])
        # "Checksums": header_crc32 = CRC32 of "magic\nformat_version\ntool_version\nindex_crc32".
        header = f"{MAGIC}\n{self.format_version}\n{self.tool_version}\n{index_crc}"
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
        position = 0
        for offset, length in zip(offsets, lengths):
            if offset != position or length < 0:
                raise ValueError("index: streams are not stored back to back")
            position += length
        return names, lengths, crcs

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
