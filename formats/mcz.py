"""The .mcz container: named, checksummed byte streams in one HDF5 file (spec: docs/format.md).

The container knows nothing about motion capture; the codec decides what the streams mean.
All payloads live back to back in ONE uint8 dataset (an HDF5 object costs ~650 bytes, so one
object per stream would dwarf small streams), described by one zstd-compressed JSON index.
"""

from __future__ import annotations

import itertools
import json
import os
import secrets
import tempfile
import zlib
from collections.abc import Iterator, Mapping
from contextlib import contextmanager

import h5py
import numpy as np
import zstandard

from .errors import MocapFormatError

__all__ = ["FORMAT_VERSION", "MAGIC", "ArchiveError", "ArchiveReader", "ArchiveWriter", "write_archive"]

FORMAT_VERSION = 4
MAGIC = "MCZ mocapzip archive"
_WRITE_BATCH = 1 << 20  # one h5py write per small stream costs ~50 us; batch them instead


class ArchiveError(MocapFormatError):
    """A damaged or invalid archive; the message starts with the section: header, index or stream."""


def _header_crc(format_version: int, tool_version: str, index_crc32: int) -> int:
    """CRC32 over the header attributes, so a flipped byte in tool_version is not silently returned."""
    return zlib.crc32(f"{MAGIC}\n{format_version}\n{tool_version}\n{index_crc32}".encode())


def write_archive(
    path: str | os.PathLike, streams: Mapping[str, bytes | SpooledStream], *, tool_version: str,
    overwrite: bool = False
) -> int:
    """Write `streams` (in iteration order) to `path` atomically; return the file size in bytes.

    The file is built under a temporary name in the same directory, fsynced, then renamed over
    `path`, so readers never see half an archive and a failure leaves nothing behind.
    """
    path = os.fspath(path)
    _check_target(path, tool_version, overwrite)
    directory = os.path.dirname(os.path.abspath(path))
    tmp = os.path.join(directory, f".{os.path.basename(path)}.tmp-{secrets.token_hex(6)}")
    with _failures_naming(path):
        try:
            _write_hdf5(tmp, streams, tool_version)
            fd = os.open(tmp, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
            if not overwrite and os.path.lexists(path):  # appeared while we were writing
                raise FileExistsError(f"refusing to overwrite existing file {path} (pass overwrite=True)")
            os.replace(tmp, path)
        except BaseException:  # also KeyboardInterrupt/SystemExit: never leave a temporary file
            if os.path.lexists(tmp):
                os.unlink(tmp)
            raise
    if os.name == "posix":  # make the rename itself durable
        fd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    return os.path.getsize(path)


@contextmanager
def _failures_naming(path: str) -> Iterator[None]:
    """An I/O failure (e.g. a full disk) as one line naming the archive, not a temporary file.

    HDF5 reports such failures in several lines naming the temporary file; a spool write names none.
    """
    try:
        yield
    except OSError as exc:
        if isinstance(exc, FileExistsError) or not exc.errno:
            raise
        raise OSError(exc.errno, f"cannot write the archive: {os.strerror(exc.errno)}", path) from exc


def _check_target(path: str, tool_version, overwrite: bool) -> None:
    if not isinstance(tool_version, str) or not tool_version or "\0" in tool_version:
        raise ValueError(f"tool_version must be a non-empty string without NUL, got {tool_version!r}")
    if not overwrite and os.path.lexists(path):
        raise FileExistsError(f"refusing to overwrite existing file {path} (pass overwrite=True)")


class SpooledStream:
    """A stream's bytes parked in an `ArchiveWriter`'s spool file, read back when their turn comes."""

    def __init__(self, spool, offset: int, length: int, crc32: int):
        self._spool, self._offset, self._length, self.crc32 = spool, offset, length, crc32

    def __len__(self) -> int:
        return self._length

    def read(self) -> bytes:
        self._spool.seek(self._offset)
        return self._spool.read(self._length)


class ArchiveWriter:
    """An archive built from streams added one at a time, in any order, then written by `commit`.

    The index (names, lengths, CRC32s) comes before the payload in the file, and a codec knows
    its metadata stream last, so streams cannot be written to their place as they come. They wait
    in an unnamed temporary file beside the archive instead of in memory: a database larger than
    memory compresses with flat memory use. The archive is byte for byte what `write_archive`
    writes for the same streams in the same order. Use as a context manager (it frees the spool).
    """

    def __init__(self, path: str | os.PathLike, *, tool_version: str, overwrite: bool = False):
        self.path, self._tool_version, self._overwrite = os.fspath(path), tool_version, overwrite
        _check_target(self.path, tool_version, overwrite)  # refuse before any work is done
        # Unnamed where the OS allows: nothing left after a crash, nothing seen beside the archive.
        with _failures_naming(self.path):
            self._spool = tempfile.TemporaryFile(dir=os.path.dirname(os.path.abspath(self.path)))
        self._streams: dict[str, SpooledStream] = {}

    def add(self, name: str, data: bytes) -> None:
        """Park stream `name`; names are unique."""
        _check_stream(name, data)
        if name in self._streams:
            raise ValueError(f"stream {name!r} added twice")
        data = memoryview(data).cast("B")
        with _failures_naming(self.path):
            offset = self._spool.seek(0, os.SEEK_END)
            self._spool.write(data)
        self._streams[name] = SpooledStream(self._spool, offset, len(data), zlib.crc32(data))

    @property
    def names(self) -> list[str]:
        """Names of the streams added so far, in the order they came."""
        return list(self._streams)

    def commit(self, order: list[str]) -> int:
        """Write the archive with every added stream, in `order`; return its size (see `write_archive`)."""
        if sorted(order) != sorted(self._streams):
            raise ValueError("the order must name every added stream once")
        return write_archive(self.path, {name: self._streams[name] for name in order},
                             tool_version=self._tool_version, overwrite=self._overwrite)

    def close(self) -> None:
        self._spool.close()

    def __enter__(self) -> ArchiveWriter:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def _check_stream(name, value) -> None:
    if not isinstance(name, str) or not name:
        raise TypeError(f"stream names must be non-empty str, got {name!r}")
    if not isinstance(value, (bytes, bytearray, memoryview, SpooledStream)):
        raise TypeError(f"stream {name!r} must be bytes, got {type(value).__name__}")


def _write_hdf5(tmp: str, streams: Mapping[str, bytes | SpooledStream], tool_version: str) -> None:
    # meta_block_size=0 and "all metadata before any raw data" keep HDF5 from leaving 2 KB
    # half-empty aggregation blocks inside the file: the empty archive shrinks from ~2 KB to ~1 KB.
    with h5py.File(tmp, "x", libver="latest", track_order=False, meta_block_size=0) as f:
        items = list(streams.items())
        for name, value in items:
            _check_stream(name, value)
        values = [value if isinstance(value, SpooledStream) else memoryview(value).cast("B") for _, value in items]
        lengths = [len(v) for v in values]
        offsets = [0, *itertools.accumulate(lengths)]
        index_doc = {
            "names": [name for name, _ in items],
            "offsets": offsets[:-1],
            "lengths": lengths,
            "crc32": [v.crc32 if isinstance(v, SpooledStream) else zlib.crc32(v) for v in values],
        }
        index = zstandard.ZstdCompressor(level=19).compress(
            json.dumps(index_doc, ensure_ascii=False, separators=(",", ":")).encode()
        )
        index_crc32 = zlib.crc32(index)
        tool_bytes = tool_version.encode()

        f.attrs.create("magic", np.bytes_(MAGIC.encode()))
        f.attrs.create("format_version", np.uint32(FORMAT_VERSION))
        f.attrs.create("tool_version", np.bytes_(tool_bytes), dtype=h5py.string_dtype("utf-8", len(tool_bytes)))
        f.attrs.create("index_crc32", np.uint32(index_crc32))
        f.attrs.create("header_crc32", np.uint32(_header_crc(FORMAT_VERSION, tool_version, index_crc32)))
        index_ds = f.create_dataset("index", shape=(len(index),), dtype=np.uint8, track_times=False)
        payload_ds = f.create_dataset("payload", shape=(offsets[-1],), dtype=np.uint8, track_times=False)
        index_ds[:] = np.frombuffer(index, np.uint8)
        _write_payload(payload_ds, values)


def _write_payload(dataset: h5py.Dataset, values: list[memoryview | SpooledStream]) -> None:
    """Copy the streams back to back into `dataset`, about 1 MiB per HDF5 write."""
    start, batch, batch_len = 0, [], 0

    def flush() -> None:
        nonlocal start, batch, batch_len
        batch = [v.read() if isinstance(v, SpooledStream) else v for v in batch]
        data = batch[0] if len(batch) == 1 else b"".join(batch)  # no copy of a lone big stream
        dataset[start : start + batch_len] = np.frombuffer(data, np.uint8)
        start, batch, batch_len = start + batch_len, [], 0

    for value in values:
        batch.append(value)
        batch_len += len(value)
        if batch_len >= _WRITE_BATCH:
            flush()
    if batch_len:
        flush()


@contextmanager
def _section(path: str, section: str) -> Iterator[None]:
    """Turn whatever h5py/HDF5 raises on a damaged file (OSError, KeyError, ValueError, ...) into ArchiveError."""
    try:
        yield
    except ArchiveError:
        raise
    except Exception as exc:
        raise ArchiveError(f"{section}: damaged or unreadable ({type(exc).__name__}: {exc})", path) from exc


class ArchiveReader:
    """Random access to the streams of an .mcz archive; checks header and index on open.

    Use as a context manager. `read` touches only the requested stream's bytes and checks its CRC32.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = os.fspath(path)
        with open(self.path, "rb"):  # missing file / permissions: the plain OSError, not "damaged"
            pass
        file_size = os.path.getsize(self.path)
        with _section(self.path, "header"):
            self._file = h5py.File(self.path, "r")
        try:
            self._open(file_size)
        except BaseException:
            self._file.close()
            raise

    def _error(self, message: str) -> ArchiveError:
        return ArchiveError(message, self.path)

    def _open(self, file_size: int) -> None:
        f = self._file
        with _section(self.path, "header"):
            attrs = {key: f.attrs[key] for key in ("magic", "format_version")}
            if attrs["magic"] != MAGIC.encode():
                raise self._error(f"header: not a mocapzip archive (magic {attrs['magic']!r}, expected {MAGIC!r})")
            if not isinstance(attrs["format_version"], np.integer) or attrs["format_version"] < 1:
                raise self._error(f"header: invalid format_version {attrs['format_version']!r}")
            self.format_version = int(attrs["format_version"])
            if self.format_version > FORMAT_VERSION:
                raise self._error(
                    f"header: archive format_version {self.format_version} is newer than this mocapzip "
                    f"supports (up to {FORMAT_VERSION}); upgrade mocapzip to read it"
                )
            self.tool_version = bytes(f.attrs["tool_version"]).decode()
            index_crc32, header_crc32 = (f.attrs[key] for key in ("index_crc32", "header_crc32"))
            if _header_crc(self.format_version, self.tool_version, index_crc32) != header_crc32:
                raise self._error("header: CRC32 mismatch in the root attributes")
            index_ds, payload_ds = f["index"], f["payload"]
            for ds in (index_ds, payload_ds):  # bounds first: a damaged shape must not allocate gigabytes
                if ds.dtype != np.uint8 or ds.ndim != 1 or ds.shape[0] > file_size:
                    raise self._error(f"header: dataset {ds.name} has dtype {ds.dtype}, shape {ds.shape}")
        with _section(self.path, "index"):
            index = index_ds[:].tobytes()
            if zlib.crc32(index) != index_crc32:
                raise self._error("index: CRC32 mismatch")
            doc = json.loads(zstandard.ZstdDecompressor().decompress(index))
            names, offsets, lengths = doc["names"], doc["offsets"], doc["lengths"]
            self._names = names
            self._entries = dict(zip(names, zip(offsets, lengths, doc["crc32"], strict=True), strict=True))
            if len(self._entries) != len(names) or not all(isinstance(name, str) and name for name in names):
                raise self._error("index: stream names must be unique non-empty strings")
            starts = [0, *itertools.accumulate(lengths)]
            if starts[:-1] != offsets or min(lengths, default=0) < 0:
                raise self._error("index: streams are not stored back to back")
            if starts[-1] != payload_ds.shape[0]:
                raise self._error(f"index: streams need {starts[-1]} bytes, payload has {payload_ds.shape[0]}")
        self._payload = payload_ds

    def names(self) -> list[str]:
        """Stream names in stored order."""
        return list(self._names)

    def sizes(self) -> dict[str, int]:
        """Stored bytes per stream, in stored order (for `mcz info`; reads no payload)."""
        return {name: self._entries[name][1] for name in self._names}

    def read(self, name: str) -> bytes:
        """The bytes of stream `name` (KeyError if there is none), checked against its CRC32."""
        offset, length, crc32 = self._entries[name]
        with _section(self.path, f"stream {name!r}"):
            data = self._payload[offset : offset + length].tobytes()
        if zlib.crc32(data) != crc32:
            raise self._error(f"stream {name!r}: CRC32 mismatch")
        return data

    def verify(self) -> None:
        """Read and check every stream (for `mcz test`); raises ArchiveError naming the first bad one."""
        for name in self._names:
            self.read(name)

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> ArchiveReader:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
