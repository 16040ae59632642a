"""The .mcz container: named, checksummed byte streams in one HDF5 file (spec: docs/format.md).

The container knows nothing about motion capture; the codec decides what the streams mean.
All payloads live back to back in ONE uint8 dataset (an HDF5 object costs hundreds of bytes,
so one object per stream would dwarf small streams), described by a JSON index that stock HDF5
tools print (`h5dump -a index`): stream names, lengths and CRC32s, readable without mocapzip.
The index is a root attribute, or a deflated dataset when it is large. Formats 1 to 6 held it
zstd-compressed in a dataset: `ArchiveReader` reads that layout through `mocapzip.legacy.container`
(`legacy.format_of` says which layout an archive has), and nothing writes it.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import functools
import io
import itertools
import json
import os
import re
import secrets
import stat
import tempfile
import zlib
from collections.abc import Iterator, Mapping
from contextlib import contextmanager

import h5py
import numpy as np
from h5py import h5d, h5p, h5t, h5z

if os.name == "posix":
    import fcntl

from mocapzip.legacy import Format, container, format_of
from mocapzip.limits import MAX_DECODED_STREAM_BYTES
from mocapzip.formats.errors import ArchiveError
from mocapzip.formats.mcz_checks import MAGIC, dataset_problem, index_columns, parse_json, root_datasets, section
from mocapzip.formats.text import open_regular_file

__all__ = ["FORMAT_VERSION", "MAGIC", "ArchiveError", "ArchiveReader", "ArchiveWriter", "parse_json", "write_archive"]

FORMAT_VERSION = 13
# HDF5 object versions no newer than HDF5 1.10's (format 12 on). With "latest", h5py's own HDF5
# decides: HDF5 2.0 writes a chunked dataset's filter pipeline in a message version 1.10's tools
# cannot read (`h5ls -r`: "/index Dataset *ERROR*"), and the bytes of an archive depended on the
# HDF5 that wrote it. Measured with HDF5 2.0: attribute-index archives are byte-identical either way.
LIBVER = ("v110", "v110")
_WRITE_BATCH = 1 << 20  # one h5py write per small stream costs ~50 us; batch them instead
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_ATTRIBUTES = ("magic", "format_version", "index", "index_crc32")
# An index up to this size is a root attribute; a larger one a deflated dataset, which costs about
# 90 bytes more of HDF5 structure (`_without_attributes`; without its hint, 260) but compresses the
# index about 2.5x (measured crossover: about 360 bytes of JSON with a clips table).
INDEX_ATTRIBUTE_BYTES = 360
_INDEX_KEYS = ("tool", "names", "lengths", "crc32")
# The index obeys the limit of every decoded stream (a zstd-coded index, `legacy.container`: stored and unpacked).
MAX_INDEX_BYTES = MAX_DECODED_STREAM_BYTES


def write_archive(
    path: str | os.PathLike, streams: Mapping[str, bytes | SpooledStream], *, tool_version: str,
    overwrite: bool = False, contents: dict | None = None
) -> int:
    """Write `streams` (in iteration order) to `path` atomically; return the file size in bytes.
    `contents`, a JSON object, goes into the index for people and stock HDF5 tools to read
    (format 10 on; readers never rely on it).

    The file is built under a temporary name in the same directory, fsynced, then renamed over
    `path`, so readers never see half an archive and a failure leaves nothing behind. A writer
    killed outright leaves its temporary file: the next write to `path` deletes it
    (`_remove_stale_temporaries`).
    """
    path = os.fspath(path)
    _check_target(path, tool_version, overwrite)
    directory = os.path.dirname(os.path.abspath(path))
    _remove_stale_temporaries(path)
    tmp = os.path.join(directory, f"{_temporary_prefix(path)}{os.getpid()}-{secrets.token_hex(6)}")
    with _failures_naming(path):
        file = _HDF5Output(tmp, "x+")  # O_EXCL: never opens an existing name, nor follows a planted symlink
        try:
            with _held_until_renamed(file):
                with file:
                    _write_hdf5(file, streams, tool_version, contents)
                    if file.error:
                        raise file.error
                    os.fsync(file.fileno())
                _check_target(path, tool_version, overwrite)  # again: the target may have appeared meanwhile
                os.replace(tmp, path)
        except BaseException:  # also KeyboardInterrupt/SystemExit: never leave a temporary file
            os.unlink(tmp)
            raise
    if os.name == "posix":  # make the rename itself durable
        fd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    return os.path.getsize(path)


def _temporary_prefix(path: str) -> str:
    """`write_archive`'s temporary files for `path` are named this, then the writer's PID, "-" and 12 hex digits."""
    return f".{os.path.basename(path)}.tmp-"


@contextmanager
def _held_until_renamed(file: io.FileIO) -> Iterator[None]:
    """An exclusive lock on the temporary `file`, held on a descriptor of its own until the block
    ends (after the rename): while it is held, `_remove_stale_temporaries` leaves the file alone.
    The kernel drops it when the process dies, however it dies (POSIX; elsewhere no lock, no clean-up)."""
    if os.name != "posix":
        yield
        return
    held = os.dup(file.fileno())  # the same open file: the lock outlives `file`'s close
    try:
        fcntl.flock(held, fcntl.LOCK_EX)
        yield
    finally:
        os.close(held)


def _remove_stale_temporaries(path: str) -> None:
    """Delete the temporary files a write to `path` left when it was killed outright (SIGKILL: no
    clean-up ran, docs/format_notes.md), and only those: named as `write_archive` names them,
    regular files of this user, whose writer's PID is no process here, and whose writer's lock
    (`_held_until_renamed`) is free, which also guards a writer in another PID namespace or on
    another NFS client. Whatever cannot be checked is left."""
    if os.name != "posix":
        return
    directory, prefix = os.path.dirname(os.path.abspath(path)), _temporary_prefix(path)
    try:
        names = [name for name in os.listdir(directory) if name.startswith(prefix)]
    except OSError:
        return
    for name in names:
        owner = re.fullmatch(r"([1-9][0-9]{0,9})-[0-9a-f]{12}", name[len(prefix):])
        if owner is None or _alive(int(owner.group(1))):
            continue
        stale = os.path.join(directory, name)
        try:
            fd = os.open(stale, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
        except OSError:  # a symbolic link, gone meanwhile, not ours to read
            continue
        try:
            status = os.fstat(fd)
            if not stat.S_ISREG(status.st_mode) or status.st_uid != os.geteuid():
                continue
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            now = os.lstat(stale)
            if (now.st_dev, now.st_ino) == (status.st_dev, status.st_ino):  # the name still names this file
                os.unlink(stale)
        except OSError:  # locked by a live writer, or gone meanwhile
            continue
        finally:
            os.close(fd)


def _alive(pid: int) -> bool:
    """Whether a process `pid` exists here (one of another user counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):  # another user's; a PID too large to ask about is left alone
        pass
    return True


@contextmanager
def _failures_naming(path: str) -> Iterator[None]:
    """An I/O failure (e.g. a full disk) as one line naming the archive, not a temporary file.

    The OSError of a failed write names the temporary file, or no file at all (the unnamed spool).
    """
    try:
        yield
    except OSError as exc:
        if isinstance(exc, FileExistsError) or not exc.errno:
            raise
        raise OSError(exc.errno, f"cannot write the archive: {os.strerror(exc.errno)}", path) from exc


def _check_target(path: str, tool_version, overwrite: bool) -> None:
    """Refuse a bad tool_version, an existing `path` unless `overwrite`, and always a `path` that is a
    device, FIFO or directory: renaming over it would replace /dev/null with an archive.

    A symbolic link may be replaced: the rename replaces the link itself, never what it points to.
    """
    if not isinstance(tool_version, str) or not tool_version or "\0" in tool_version:
        raise ValueError(f"tool_version must be a non-empty string without NUL, got {tool_version!r}")
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    if not overwrite:
        raise FileExistsError(errno.EEXIST, "refusing to overwrite an existing file (pass overwrite=True)", path)
    if not (stat.S_ISREG(mode) or stat.S_ISLNK(mode)):
        raise OSError(None, "not a regular file; refusing to replace it", path)


class _HDF5Output(io.FileIO):
    """The temporary archive as HDF5 writes it (h5py's file-object driver): a failed write is kept, not raised.

    HDF5 does not survive a failed write: on a full disk its close failed half-way, left the file open
    inside the library and the interpreter crashed at exit (segmentation fault). Told that every write
    succeeded, HDF5 closes cleanly; `write_archive` then raises the first error as a plain OSError.
    """

    error: OSError | None = None

    def write(self, data) -> int:
        if self.error is None:
            try:
                view = memoryview(data).cast("B")
                while view:  # a short write (the disk filling up) is followed by the error
                    view = view[super().write(view) :]
            except OSError as exc:
                self.error = exc
        return len(data)

    def truncate(self, size: int | None = None) -> int:
        if self.error is None:
            try:
                return super().truncate(size)
            except OSError as exc:
                self.error = exc
        return size


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

    def read(self, name: str) -> bytes:
        """The bytes of stream `name`, added before (KeyError if not)."""
        with _failures_naming(self.path):
            return self._streams[name].read()

    @property
    def names(self) -> list[str]:
        """Names of the streams added so far, in the order they came."""
        return list(self._streams)

    def commit(self, order: list[str], contents: dict | None = None) -> int:
        """Write the archive with every added stream, in `order`, and `contents` in its index;
        return its size (see `write_archive`)."""
        if sorted(order) != sorted(self._streams):
            raise ValueError("the order must name every added stream once")
        return write_archive(self.path, {name: self._streams[name] for name in order},
                             tool_version=self._tool_version, overwrite=self._overwrite, contents=contents)

    def close(self) -> None:
        # The spool's bytes are thrown away: failing to flush them (a full disk) must not hide the
        # error that stopped the work. The file is closed even then.
        with contextlib.suppress(OSError):
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


def _write_hdf5(file: _HDF5Output, streams: Mapping[str, bytes | SpooledStream], tool_version: str,
                contents: dict | None) -> None:
    # meta_block_size=0 and "all metadata before any raw data" keep HDF5 from leaving 2 KB
    # half-empty aggregation blocks inside the file: the empty archive shrinks from ~2 KB to ~1 KB.
    with h5py.File(file, "x", libver=LIBVER, track_order=False, meta_block_size=0) as f:
        items = list(streams.items())
        for name, value in items:
            _check_stream(name, value)
        values = [value if isinstance(value, SpooledStream) else memoryview(value).cast("B") for _, value in items]
        lengths = [len(v) for v in values]
        index_doc = {
            "tool": tool_version,
            "names": [name for name, _ in items],
            "lengths": lengths,
            "crc32": [v.crc32 if isinstance(v, SpooledStream) else zlib.crc32(v) for v in values],
        }
        if contents is not None:
            index_doc["contents"] = contents
        # A file name read from disk may hold undecodable bytes as lone surrogates: written as
        # JSON escapes (\udcXX), the only text UTF-8 cannot hold, they read back as they were.
        index = json.dumps(index_doc, ensure_ascii=False, separators=(",", ":")).encode("utf-8", "backslashreplace")
        if len(index) > MAX_INDEX_BYTES:  # readers refuse it: never write it
            what = " and its contents" if contents is not None else ""
            raise ValueError(f"the index of {len(items)} streams{what} exceeds {MAX_INDEX_BYTES} bytes")

        f.attrs.create("magic", np.bytes_(MAGIC.encode()))
        f.attrs.create("format_version", np.uint32(FORMAT_VERSION))
        text = h5py.string_dtype("utf-8", len(index))
        if len(index) <= INDEX_ATTRIBUTE_BYTES:
            f.attrs.create("index", np.bytes_(index), dtype=text)
        else:  # one element, one chunk, deflated: h5dump still prints it as text
            f.create_dataset("index", shape=(1,), dtype=text, chunks=(1,), compression="gzip", compression_opts=9,
                             track_times=False, dcpl=_without_attributes())[0] = np.bytes_(index)
        f.attrs.create("index_crc32", np.uint32(zlib.crc32(index)))
        payload_ds = f.create_dataset("payload", shape=(sum(lengths),), dtype=np.uint8, track_times=False,
                                      dcpl=_without_attributes())
        _write_payload(payload_ds, values)


def _without_attributes() -> h5p.PropDCID:
    """A dataset creation list that tells HDF5 the dataset will never have attributes, so that its
    object header is made no bigger than its messages: by default HDF5 reserves room for attributes,
    188 of a `payload` header's 268 bytes, about a fifth of a one-clip archive's fixed cost.

    That is `H5Pset_dset_no_attrs_hint` (HDF5 1.10.5 on), which h5py does not wrap; it is called
    through ctypes in the HDF5 library h5py's own extension is linked to (found by `dlsym`, which
    searches a library's dependencies). Where that fails (Windows looks in the extension alone),
    the list is plain: the archive is the same but for those bytes, and reads the same."""
    hint = _no_attrs_hint()
    plist = h5p.create(h5p.DATASET_CREATE)
    if hint is not None and hint(plist.id, True) < 0:  # refused (it never is): the plain list after all
        plist = h5p.create(h5p.DATASET_CREATE)
    return plist


@functools.cache
def _no_attrs_hint():
    """HDF5's `herr_t H5Pset_dset_no_attrs_hint(hid_t dcpl, hbool_t minimize)`, or None."""
    try:
        function = ctypes.CDLL(h5p.__file__).H5Pset_dset_no_attrs_hint
    except (OSError, AttributeError):
        return None
    function.argtypes, function.restype = (ctypes.c_int64, ctypes.c_bool), ctypes.c_int
    return function


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


def _index_dataset_problem(ds: h5py.Dataset, file_size: int) -> str | None:
    """What, if anything, makes the index dataset other than one element in one chunk, deflated
    and stored within this file (the reader inflates it itself: `ArchiveReader._inflated`)."""
    plist = ds.id.get_create_plist()
    if plist.get_layout() != h5d.CHUNKED or ds.shape != (1,) or ds.chunks != (1,):
        return "is not one element in one chunk"
    if plist.get_nfilters() != 1 or plist.get_filter(0)[0] != h5z.FILTER_DEFLATE:
        return "is not compressed by deflate alone"
    if plist.get_external_count() or ds.attrs:
        return "has external storage or attributes"
    chunk = ds.id.get_chunk_info(0)
    if chunk.filter_mask or chunk.byte_offset is None or chunk.byte_offset + chunk.size > file_size:
        return "is not stored deflated within the file"
    return None


def _has_hdf5_signature(file, size: int) -> bool:
    """Whether HDF5's signature is where HDF5 looks for it (offset 0, 512, 1024, 2048, ...).

    Without it h5py only says "file signature not found": the file is something else
    (an AMC, a text file, an empty file), which deserves a plain message.
    """
    offset = 0
    while offset + len(_HDF5_SIGNATURE) <= size:
        file.seek(offset)
        if file.read(len(_HDF5_SIGNATURE)) == _HDF5_SIGNATURE:
            return True
        offset = offset * 2 or 512
    return False


class ArchiveReader:
    """Random access to the streams of an .mcz archive; checks header and index on open.

    Use as a context manager. `read` touches only the requested stream's bytes and checks its CRC32.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = os.fspath(path)
        self.contents: dict | None = None  # the index's `contents` (format 10 on): for people, never relied on
        # A missing file or no permission: the plain OSError, not "damaged". A FIFO or a device
        # (symbolic links followed) is refused without blocking: HDF5 would wait on it forever.
        with open_regular_file(self.path) as file:
            file_size = os.fstat(file.fileno()).st_size
            if not _has_hdf5_signature(file, file_size):
                raise self._error("header: not an mcz archive (not an HDF5 file)")
        with section(self.path, "header"):
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
        with section(self.path, "header"):
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
        self.format: Format = format_of(self.format_version)  # what it does differently from the newest
        if self.format.container == 1:
            payload_ds, self._names, lengths, crcs, self.tool_version = container.read_index(
                f, self.path, self.format_version, file_size, MAX_INDEX_BYTES)
        else:
            with section(self.path, "header"):
                in_attribute = "index" in f.attrs  # names only: nothing is read yet
            if in_attribute:
                payload_ds = root_datasets(f, self.path, file_size, _ATTRIBUTES,
                                           {"payload": dataset_problem})["payload"]
                with section(self.path, "index"):
                    stored = f.attrs.get_id("index")
                self._names, lengths, crcs = self._index(stored, (), lambda size: bytes(f.attrs["index"]))
            else:
                datasets = root_datasets(f, self.path, file_size, tuple(a for a in _ATTRIBUTES if a != "index"),
                                          {"index": _index_dataset_problem, "payload": dataset_problem})
                payload_ds, index_ds = datasets["payload"], datasets["index"]
                self._names, lengths, crcs = self._index(index_ds.id, (1,), lambda size: self._inflated(index_ds, size))
        starts = [0, *itertools.accumulate(lengths)]
        self._entries = dict(zip(self._names, zip(starts, lengths, crcs)))
        if starts[-1] != payload_ds.shape[0]:
            raise self._error(f"index: streams need {starts[-1]} bytes, payload has {payload_ds.shape[0]}")
        self._payload = payload_ds

    def _index(self, stored, shape: tuple, read) -> tuple[list[str], list[int], list[int]]:
        """Format 7: the index (UTF-8 JSON) from `read(size)`, once its HDF5 object `stored` (the
        attribute, or the dataset `_index_dataset_problem` passed) is found to hold one null-padded,
        fixed-length UTF-8 string of `size` bytes within the limit; checked against index_crc32.
        Sets `tool_version`."""
        f = self._file
        with section(self.path, "index"):
            kind = stored.get_type()
            if (kind.get_class() != h5t.STRING or kind.is_variable_str() or stored.shape != shape
                    or kind.get_cset() != h5t.CSET_UTF8 or kind.get_strpad() != h5t.STR_NULLPAD):
                raise self._error("index: not one fixed-length UTF-8 string")
            size = kind.get_size()
            if size > MAX_INDEX_BYTES:
                raise self._error(f"index: {size} bytes stored, more than the limit of {MAX_INDEX_BYTES}")
            crc_attr = f.attrs.get_id("index_crc32")
            crc_kind = crc_attr.get_type()
            if (crc_kind.get_class() != h5t.INTEGER or crc_kind.get_size() != 4 or crc_kind.get_sign() != h5t.SGN_NONE
                    or crc_attr.shape != ()):
                raise self._error("index: index_crc32 is not a scalar uint32")
            index = read(size)
            if len(index) != size or zlib.crc32(index) != f.attrs["index_crc32"]:
                raise self._error("index: CRC32 mismatch")
            doc = parse_json(index)
        contents = doc.pop("contents", {}) if isinstance(doc, dict) and self.format.index_contents else {}
        if not isinstance(doc, dict) or sorted(doc) != sorted(_INDEX_KEYS):
            raise self._error(f"index: not a JSON object with exactly the keys {', '.join(_INDEX_KEYS)}"
                              + (" (and contents)" if self.format.index_contents else ""))
        if not isinstance(contents, dict):
            raise self._error("index: contents is not a JSON object")
        self.contents = contents or None  # absent (or empty): nothing to show
        tool = doc["tool"]
        if not isinstance(tool, str) or not tool or "\0" in tool:
            raise self._error("index: tool must be a non-empty string without NUL")
        self.tool_version = tool
        return index_columns(doc, _INDEX_KEYS[1:], self.path)

    def _inflated(self, index_ds: h5py.Dataset, size: int) -> bytes:
        """The index dataset's one chunk (within the file: `_index_dataset_problem`), inflated here,
        never by HDF5: HDF5's deflate filter inflates whatever a chunk holds before dropping what
        exceeds the element, so a few kilobytes could make it allocate gigabytes. It must inflate
        to exactly `size` bytes (checked as it inflates, never past `size` + 1)."""
        raw = index_ds.id.read_direct_chunk((0,))[1]
        inflater = zlib.decompressobj()
        data = inflater.decompress(raw, size + 1)
        if len(data) != size or not inflater.eof or inflater.unused_data:
            raise self._error(f"index: its deflated chunk does not hold exactly its {size} bytes")
        return data

    def names(self) -> list[str]:
        """Stream names in stored order."""
        return list(self._names)

    def sizes(self) -> dict[str, int]:
        """Stored bytes per stream, in stored order (for `mcz info`; reads no payload)."""
        return {name: self._entries[name][1] for name in self._names}

    def read(self, name: str) -> bytes:
        """The bytes of stream `name` (KeyError if there is none), checked against its CRC32."""
        offset, length, crc32 = self._entries[name]
        with section(self.path, f"stream {name!r}"):
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
