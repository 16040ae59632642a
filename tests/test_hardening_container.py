"""Untrusted containers and hostile places (issue 13).

Readers: every HDF5 feature the format does not define (external storage, virtual datasets,
links, extra objects, chunks and filters, other types, fill values) is refused when the archive
is opened, before any data is read, and so is an index that is malformed or unpacks to more than
the limit; a FIFO or device given as the archive is refused without blocking. Each hostile file is
built here with h5py from a valid archive; a case that could hang runs in a child with a timeout.

Writers: a full disk (a real small tmpfs where `mount` is permitted, else a file size limit) ends
in one line naming the archive, never a traceback or a crash, and leaves no file behind; a
device, FIFO or directory is never replaced, and the temporary file is never opened through a
planted symbolic link.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import resource
import signal
import stat
import subprocess
import sys
import zlib
from pathlib import Path

import h5py
import numpy as np
import pytest
import zstandard
from click.testing import CliRunner

from mocapzip.cli.main import main
from mocapzip.formats import MocapFormatError, mcz
from mocapzip.formats.mcz import ArchiveError, ArchiveReader, write_archive
from mocapzip.legacy.container import header_crc

MCZ = Path(sys.executable).with_name("mcz")
TIMEOUT = 30  # seconds; a child that blocks fails the test instead of hanging the suite
STREAMS = {"meta": b"m" * 100, "clip/00000": bytes(range(256)) * 4}
PAYLOAD = np.frombuffer(b"".join(STREAMS.values()), np.uint8)


def run(*args):
    return CliRunner().invoke(main, [os.fspath(a) for a in args])


def run_child(*args, preexec_fn=None) -> subprocess.CompletedProcess:
    return subprocess.run([MCZ, *map(os.fspath, args)], capture_output=True, text=True, timeout=TIMEOUT,
                          preexec_fn=preexec_fn)


def assert_one_line(result, expected_start: str) -> None:
    """Exit 1 and exactly one line on stderr, for CliRunner results and finished children alike."""
    code = result.exit_code if hasattr(result, "exit_code") else result.returncode
    lines = result.stderr.splitlines()
    assert code == 1 and len(lines) == 1 and lines[0].startswith(expected_start), (code, result.stderr)


def valid_archive(tmp_path: Path) -> Path:
    path = tmp_path / "a.mcz"
    write_archive(path, STREAMS, tool_version="1")
    return path


# ----------------------------------------------------------------------------- hostile containers


def replace_payload(data=PAYLOAD, **create):
    """An edit that stores the payload bytes again as `data`, created with `create` (h5py keywords)."""

    def edit(f, tmp_path):
        del f["payload"]
        f.create_dataset("payload", data=data, **create)

    return edit


def external_storage(name):
    def edit(f, tmp_path):
        data = f[name][:]
        del f[name]
        external = tmp_path / f"{name}.bin"
        external.write_bytes(data.tobytes())
        f.create_dataset(name, shape=data.shape, dtype=np.uint8, external=[(os.fspath(external), 0, data.size)])

    return edit


def virtual_payload(f, tmp_path):
    with h5py.File(tmp_path / "source.h5", "w") as source:
        source["data"] = PAYLOAD
    layout = h5py.VirtualLayout(shape=PAYLOAD.shape, dtype=np.uint8)
    layout[:] = h5py.VirtualSource(tmp_path / "source.h5", "data", shape=PAYLOAD.shape)
    del f["payload"]
    f.create_virtual_dataset("payload", layout)


def external_link(f, tmp_path):
    with h5py.File(tmp_path / "other.h5", "w") as other:
        other["payload"] = PAYLOAD
    del f["payload"]
    f["payload"] = h5py.ExternalLink("other.h5", "/payload")


def soft_link(f, tmp_path):
    del f["payload"]
    f["payload"] = h5py.SoftLink("/index")


def compact_payload(f, tmp_path):
    del f["payload"]
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_layout(h5py.h5d.COMPACT)
    space = h5py.h5s.create_simple(PAYLOAD.shape)
    h5py.h5d.create(f.id, b"payload", h5py.h5t.STD_U8LE, space, dcpl=dcpl).write(h5py.h5s.ALL, h5py.h5s.ALL, PAYLOAD)


def unwritten_payload(f, tmp_path):
    del f["payload"]
    f.create_dataset("payload", shape=PAYLOAD.shape, dtype=np.uint8)  # no storage until written


def group_payload(f, tmp_path):
    del f["payload"]
    f.create_group("payload")


def set_attr(obj, name, value):
    def edit(f, tmp_path):
        (f if obj == "/" else f[obj]).attrs[name] = value

    return edit


def delete_attr(f, tmp_path):
    del f.attrs["index_crc32"]


HEADER_CASES = {
    "external storage": (external_storage("payload"), "payload is stored in external files"),
    "virtual dataset": (virtual_payload, "payload is a virtual dataset"),
    "external link": (external_link, "payload is not a dataset but a link (ExternalLink)"),
    "soft link": (soft_link, "payload is not a dataset but a link (SoftLink)"),
    "group": (group_payload, "payload is not a dataset"),
    "extra group": (lambda f, tmp_path: f.create_group("extra"), "root item 'extra' is not in the format"),
    "extra dataset": (lambda f, tmp_path: f.create_dataset("more", data=PAYLOAD),
                      "root item 'more' is not in the format"),
    "extra attribute": (set_attr("/", "comment", b"hi"), "root attribute 'comment' is not in the format"),
    "missing attribute": (delete_attr, "root attribute 'index_crc32' is missing"),
    "index dataset of format 6": (lambda f, tmp_path: f.create_dataset("index", data=PAYLOAD),
                                  "root item 'index' is not in the format"),
    "gzip": (replace_payload(compression="gzip"), "payload is chunked, not contiguous"),
    "shuffle and fletcher32": (replace_payload(shuffle=True, fletcher32=True), "payload is chunked"),
    "chunks": (replace_payload(chunks=(64,)), "payload is chunked"),
    "compact": (compact_payload, "payload is compact, not contiguous"),
    "int8": (replace_payload(PAYLOAD.astype(np.int8)), "payload has type int8, not uint8"),
    "uint16": (replace_payload(PAYLOAD.astype(np.uint16)), "payload has type uint16, not uint8"),
    "enum of uint8": (replace_payload(dtype=h5py.enum_dtype({"a": 0}, basetype="u1")), "payload has type"),
    "2-D": (replace_payload(PAYLOAD.reshape(2, -1)), "payload has shape (2, 562), not 1-D"),
    "fill value": (replace_payload(fillvalue=7), "payload has a fill value"),
    "dataset attribute": (set_attr("payload", "note", 1), "payload has attributes"),
    "no storage": (unwritten_payload, "payload has 1124 bytes, not stored within the file"),
    # the sixth hostile pass
    "a terabyte declared": (lambda f, tmp_path: (f.__delitem__("payload"),
                                                 f.create_dataset("payload", shape=(1 << 40,), dtype=np.uint8)),
                            "payload has 1099511627776 bytes, not stored within the file"),
    "scalar": (replace_payload(np.uint8(7)), "payload has shape (), not 1-D"),
    "dangling soft link": (lambda f, tmp_path: (f.__delitem__("payload"), f.__setitem__("payload", h5py.SoftLink("/no"))),
                           "payload is not a dataset but a link (SoftLink)"),
    "format_version of one element": (set_attr("/", "format_version", np.array([12], np.uint32)),
                                      "invalid format_version array([12], dtype=uint32)"),
}
# Formats 1 to 6, read from a copy of the golden container: what their layout adds to check.
LEGACY_HEADER_CASES = {
    "external index": (external_storage("index"), "index is stored in external files"),
    "tool_version not a string": (set_attr("/", "tool_version", np.int64(1 << 40)), "tool_version is int64"),
    "missing attribute": (lambda f, tmp_path: f.attrs.__delitem__("header_crc32"),
                          "root attribute 'header_crc32' is missing"),
    "format 7's index attribute": (set_attr("/", "index", b"{}"), "root attribute 'index' is not in the format"),
}


def index_dataset(**create):
    """An edit that stores the index of the many-stream golden container again, created with `create`."""

    def edit(f, tmp_path):
        text = f["index"][0]
        del f["index"]
        options = {"shape": (1,), "dtype": h5py.string_dtype("utf-8", len(text)), **create}
        f.create_dataset("index", **options)[0] = text

    return edit


def index_two_elements(f, tmp_path):
    text = f["index"][0]
    del f["index"]
    f.create_dataset("index", data=[text, text], chunks=(1,), compression="gzip")


# Format 7 with the index in a dataset (an index over INDEX_ATTRIBUTE_BYTES), from the golden container.
INDEX_DATASET_CASES = {
    "contiguous": (index_dataset(), "index is not one element in one chunk"),
    "two elements": (index_two_elements, "index is not one element in one chunk"),
    "shuffle too": (index_dataset(chunks=(1,), compression="gzip", shuffle=True), "index is not compressed by deflate alone"),
    "lzf": (index_dataset(chunks=(1,), compression="lzf"), "index is not compressed by deflate alone"),
    "fletcher32": (index_dataset(chunks=(1,), fletcher32=True), "index is not compressed by deflate alone"),
    "attribute too": (set_attr("/", "index", b"{}"), "root item 'index' is not in the format"),
    "dataset attribute": (set_attr("index", "note", 1), "index has external storage or attributes"),
    "soft link": (lambda f, tmp_path: (f.__delitem__("index"), f.__setitem__("index", h5py.SoftLink("/payload"))),
                  "index is not a dataset but a link (SoftLink)"),
}


def hostile(tmp_path: Path, edit, legacy: bool = False) -> Path:
    path = valid_archive(tmp_path) if not legacy else legacy_archive(tmp_path)
    with h5py.File(path, "r+") as f:
        edit(f, tmp_path)
    return path


def legacy_archive(tmp_path: Path) -> Path:
    path = tmp_path / "v6.mcz"
    path.write_bytes((Path(__file__).parent / "golden" / "container_v6.mcz").read_bytes())
    return path


@pytest.mark.parametrize("case", [*HEADER_CASES, *(f"format 6: {case}" for case in LEGACY_HEADER_CASES),
                                  *(f"index dataset: {case}" for case in INDEX_DATASET_CASES)])
def test_hdf5_features_outside_the_format_are_refused_on_open(tmp_path, case):
    legacy = case.startswith("format 6: ")
    if case.startswith("index dataset: "):
        edit, message = INDEX_DATASET_CASES[case.removeprefix("index dataset: ")]
        path = tmp_path / "many.mcz"
        path.write_bytes((Path(__file__).parent / "golden" / "container_v7_index_dataset.mcz").read_bytes())
        with h5py.File(path, "r+") as f:
            edit(f, tmp_path)
    else:
        edit, message = LEGACY_HEADER_CASES[case.removeprefix("format 6: ")] if legacy else HEADER_CASES[case]
        path = hostile(tmp_path, edit, legacy)
    with pytest.raises(ArchiveError) as caught:
        ArchiveReader(path)
    assert caught.value.message.startswith(f"header: {message}"), caught.value.message
    for command in ("test", "info"):
        assert_one_line(run(command, path), f"mcz: error: {path}: header: {message}")


def test_external_storage_in_a_fifo_is_refused_without_blocking(tmp_path):
    path = hostile(tmp_path, external_storage("payload"))
    os.unlink(tmp_path / "payload.bin")
    os.mkfifo(tmp_path / "payload.bin")
    for command in ("test", "info"):
        assert_one_line(run_child(command, path), f"mcz: error: {path}: header: payload is stored in external files")


def test_the_golden_files_pass_every_check():
    for path in sorted((Path(__file__).parent / "golden").glob("*.mcz")):
        with ArchiveReader(path) as reader:
            reader.verify()


# ----------------------------------------------------------------------------- hostile indexes


def with_index(tmp_path: Path, index: bytes) -> Path:
    """A format-6 archive (the layout whose index is zstd-coded) whose index is `index`, with every
    checksum made to match."""
    path = legacy_archive(tmp_path)
    with h5py.File(path, "r+") as f:
        del f["index"]
        f["index"] = np.frombuffer(index, np.uint8)
        f.attrs["index_crc32"] = np.uint32(zlib.crc32(index))
        tool = f.attrs["tool_version"].decode()
        f.attrs["header_crc32"] = np.uint32(header_crc(6, tool, zlib.crc32(index)))
    return path


def assert_index_refused(path: Path, message: str) -> None:
    with pytest.raises(ArchiveError) as caught:
        ArchiveReader(path)
    assert caught.value.message.startswith(f"index: {message}"), caught.value.message
    assert_one_line(run("test", path), f"mcz: error: {path}: index: {message}")


def zeros_frame(size: int) -> bytes:
    """One zstd frame stating its content size, of `size` zero bytes, compressed a MiB at a time."""
    compressor = zstandard.ZstdCompressor(level=1).compressobj(size=size)
    chunk = bytes(1 << 20)
    parts = [compressor.compress(chunk[: min(len(chunk), size - done)]) for done in range(0, size, len(chunk))]
    return b"".join([*parts, compressor.flush()])


def test_index_that_unpacks_beyond_the_limit_is_refused_before_unpacking(tmp_path):
    size = mcz.MAX_INDEX_BYTES + (1 << 20)
    index = zeros_frame(size)
    assert len(index) < 100_000  # a bomb: kilobytes stored
    path = with_index(tmp_path, index)
    assert_index_refused(path, f"unpacks to {size} bytes, more than the limit of {mcz.MAX_INDEX_BYTES}")


def test_index_without_its_size_is_refused(tmp_path):
    index = zstandard.ZstdCompressor(write_content_size=False).compress(b"{}")
    assert_index_refused(with_index(tmp_path, index), "the zstd frame does not state its size")


def test_index_with_bytes_after_its_frame_is_refused(tmp_path):
    doc = {"names": ["a"], "offsets": [0], "lengths": [1124], "crc32": [0]}
    index = zstandard.ZstdCompressor().compress(json.dumps(doc).encode()) + b"junk"
    assert_index_refused(with_index(tmp_path, index), "damaged or unreadable (ZstdError")


@pytest.mark.parametrize("legacy", [False, True])
def test_stored_index_beyond_the_limit_is_refused_before_it_is_read(tmp_path, monkeypatch, legacy):
    path = legacy_archive(tmp_path) if legacy else valid_archive(tmp_path)
    with h5py.File(path, "r") as f:
        stored = f["index"].shape[0] if legacy else f.attrs.get_id("index").get_type().get_size()
    monkeypatch.setattr(mcz, "MAX_INDEX_BYTES", stored - 1)
    assert_index_refused(path, f"{stored} bytes stored, more than the limit of {stored - 1}")


def test_writer_never_writes_an_index_beyond_the_limit(tmp_path, monkeypatch):
    monkeypatch.setattr(mcz, "MAX_INDEX_BYTES", 50)
    with pytest.raises(ValueError, match="the index of 2 streams exceeds 50 bytes"):
        write_archive(tmp_path / "x.mcz", STREAMS, tool_version="1")
    assert os.listdir(tmp_path) == []


# ----------------------------------------------------------------------------- the archive itself


def test_archive_that_is_not_a_regular_file_is_refused_without_blocking(tmp_path):
    os.mkfifo(tmp_path / "fifo.mcz")
    os.symlink("/dev/zero", tmp_path / "zero.mcz")
    for name, kind in {"fifo.mcz": "a named pipe (FIFO)", "zero.mcz": "a character device (/dev/zero)"}.items():
        for command in ("test", "info"):
            result = run_child(command, tmp_path / name)
            assert_one_line(result, f"mcz: error: {tmp_path / name}: not a regular file: {kind}")
    with pytest.raises(MocapFormatError, match=": not a regular file: a directory"):
        ArchiveReader(tmp_path)  # the CLI refuses a folder itself (click), the reader too


def test_symbolic_link_to_an_archive_opens(tmp_path):
    os.symlink(valid_archive(tmp_path), tmp_path / "link.mcz")
    with ArchiveReader(tmp_path / "link.mcz") as reader:
        assert {name: reader.read(name) for name in reader.names()} == STREAMS


# ----------------------------------------------------------------------------- writing


@pytest.fixture(scope="module")
def small_disk(tmp_path_factory):
    """A fresh 1 MiB tmpfs, or None where mounting is not permitted (then a file size limit stands in)."""
    where = tmp_path_factory.mktemp("disk")
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", where], capture_output=True).returncode:
        yield None
        return
    try:
        yield where
    finally:
        subprocess.run(["umount", where], check=True)


def file_size_limit(limit: int):
    """For a child: writes beyond `limit` bytes of a file fail (EFBIG) instead of raising SIGXFSZ."""

    def apply():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return apply


@pytest.mark.slow
def test_full_disk_fails_in_one_line_and_leaves_nothing(small_disk, shared_data, tmp_path):
    """Room swept across the spool, the HDF5 writes and HDF5's final flush: each run either writes
    the whole archive or fails in one line (before: a traceback, then a segmentation fault)."""
    clip = shared_data / "cmu" / "09" / "09_01.amc"
    assert run_child("compress", clip, "--lossless", "-q", "-o", tmp_path / "ref.mcz").returncode == 0
    size = os.path.getsize(tmp_path / "ref.mcz")
    if small_disk:  # the spool (as big as the streams) and the archive share the free space
        out, reason = small_disk / "x.mcz", errno.ENOSPC
        rooms = [0, size // 2, *range(size, 2 * size + 12288, 4096)]
    else:  # each file on its own must fit: the spool a little before the archive
        out, reason = tmp_path / "out" / "x.mcz", errno.EFBIG
        rooms = [0, size // 2, size - 2048, size - 512, size - 1, size]
        out.parent.mkdir()
    outcomes = []
    for room in rooms:
        if small_disk:
            st = os.statvfs(small_disk)
            (small_disk / "filler").write_bytes(bytes(st.f_bavail * st.f_frsize - room))
        result = run_child("compress", clip, "--lossless", "-q", "-o", out,
                           preexec_fn=None if small_disk else file_size_limit(room))
        if small_disk:
            (small_disk / "filler").unlink()
        outcomes.append(result.returncode)
        if result.returncode == 0:
            assert out.read_bytes() == (tmp_path / "ref.mcz").read_bytes(), room
            out.unlink()
        else:
            assert_one_line(result, f"mcz: error: {out}: cannot write the archive: {os.strerror(reason)}")
        assert os.listdir(out.parent) == [], (room, os.listdir(out.parent))
    assert outcomes.count(1) >= 4 and outcomes[-1] == 0, outcomes


@pytest.mark.parametrize("call", ["fsync", "replace"])
def test_failed_fsync_or_rename_fails_in_one_line(shared_data, tmp_path, monkeypatch, call):
    def no_space(*args):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, call, no_space)
    out = tmp_path / "x.mcz"
    result = run("compress", shared_data / "cmu" / "09" / "09_01.amc", "--lossless", "-q", "-o", out)
    assert_one_line(result, f"mcz: error: {out}: cannot write the archive: No space left on device")
    assert os.listdir(tmp_path) == []


def make_special(tmp_path: Path, kind: str) -> Path:
    target = tmp_path / kind
    if kind == "fifo":
        os.mkfifo(target)
    elif kind == "directory":
        target.mkdir()
    else:
        os.mknod(target, stat.S_IFCHR | 0o666, os.makedev(1, 3))  # what /dev/null is
    return target


@pytest.mark.parametrize("kind", ["fifo", "directory", "character device"])
def test_forced_output_never_replaces_a_device_fifo_or_directory(shared_data, tmp_path, kind):
    try:
        target = make_special(tmp_path, kind)
    except PermissionError:  # no mknod here: check /dev/null itself, without ever writing an archive
        with pytest.raises(OSError, match="not a regular file; refusing to replace it"):
            mcz._check_target("/dev/null", "1", True)
        assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
        return
    mode = os.lstat(target).st_mode
    for write in (lambda: write_archive(target, STREAMS, tool_version="1", overwrite=True),
                  lambda: mcz.ArchiveWriter(target, tool_version="1", overwrite=True)):
        with pytest.raises(OSError, match="not a regular file; refusing to replace it"):
            write()
    if kind != "directory":  # the CLI refuses a folder itself (click)
        result = run("compress", shared_data / "cmu" / "09" / "09_01.amc", "--lossless", "-q", "-o", target, "-f")
        assert_one_line(result, f"mcz: error: {target}: not a regular file; refusing to replace it")
    assert os.lstat(target).st_mode == mode and os.listdir(tmp_path) == [kind]


def test_forced_output_replaces_a_symbolic_link_not_its_target(tmp_path):
    (tmp_path / "victim.txt").write_bytes(b"precious")
    os.symlink("victim.txt", tmp_path / "x.mcz")
    write_archive(tmp_path / "x.mcz", STREAMS, tool_version="1", overwrite=True)
    assert (tmp_path / "victim.txt").read_bytes() == b"precious"
    assert stat.S_ISREG(os.lstat(tmp_path / "x.mcz").st_mode)
    with ArchiveReader(tmp_path / "x.mcz") as reader:
        assert reader.read("meta") == STREAMS["meta"]


def test_temporary_file_is_never_opened_through_a_planted_link(tmp_path, monkeypatch):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.setattr(mcz.secrets, "token_hex", lambda n: "planted")
    planted = f".x.mcz.tmp-{os.getpid()}-planted"
    os.symlink(elsewhere / "created", tmp_path / planted)
    with pytest.raises(FileExistsError):
        write_archive(tmp_path / "x.mcz", STREAMS, tool_version="1")
    assert os.listdir(elsewhere) == [] and sorted(os.listdir(tmp_path)) == [planted, "elsewhere"]


def test_a_dead_writers_temporary_file_is_removed_by_the_next_write_and_nothing_else(tmp_path):
    """A writer killed outright (SIGKILL; tests/test_edit.py kills one for real) leaves its temporary
    file: the next write to that archive deletes it. Only a regular file named as the writer names
    them, whose PID is no process and whose lock is free: not a live writer's (its PID, or its lock
    where the PID says nothing, as from another PID namespace), not a link, not another archive's."""
    dead = int(Path("/proc/sys/kernel/pid_max").read_text()) + 1  # a PID no process can have
    victim = tmp_path / "victim"
    victim.write_bytes(b"precious")
    names = {"stale": f".x.mcz.tmp-{dead}-0123456789ab", "live": f".x.mcz.tmp-{os.getpid()}-0123456789ab",
             "locked": f".x.mcz.tmp-{dead}-ba9876543210", "link": f".x.mcz.tmp-{dead}-aaaaaaaaaaaa",
             "other": f".y.mcz.tmp-{dead}-0123456789ab", "unlike": f".x.mcz.tmp-{dead}-planted",
             "older": ".x.mcz.tmp-0123456789ab"}
    for kind, name in names.items():
        if kind == "link":
            os.symlink(victim, tmp_path / name)
        else:
            (tmp_path / name).write_bytes(b"\x89HDF")
    with open(tmp_path / names["locked"], "rb") as held:  # a live writer whose PID means nothing here
        fcntl.flock(held, fcntl.LOCK_EX)
        write_archive(tmp_path / "x.mcz", STREAMS, tool_version="1")
    assert sorted(os.listdir(tmp_path)) == sorted({"x.mcz", "victim", *names.values()} - {names["stale"]})
    assert victim.read_bytes() == b"precious"
