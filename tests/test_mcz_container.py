"""The .mcz container: round trip, random access, safe writing, determinism and damage detection."""

from __future__ import annotations

import json
import re
import os
import random
import time
import zlib
from collections.abc import Mapping
from pathlib import Path

import h5py
import numpy as np
import pytest
import zstandard

from mocapzip.formats import MocapFormatError
from mocapzip.formats import mcz
from mocapzip.formats.mcz import FORMAT_VERSION, ArchiveError, ArchiveReader, write_archive
from mocapzip.legacy.container import header_crc

GOLDEN = Path(__file__).parent / "golden"
GOLDEN_NEWEST = GOLDEN / f"container_v{FORMAT_VERSION}.mcz"
# Written once per format version by make_golden_container.py; repeated here literally so these
# bytes are checked forever.
GOLDEN_STREAMS = {
    "meta.json": b'{"codec":"golden","clips":["07_01"]}',
    "skeletons/07.asf": b":version 1.10\n:name VICON\n:units\n  mass 1.0\n",
    "clips/07_01/coefficients": bytes(range(256)) * 3,
    "clips/07_01/empty": b"",
    "names/\u00fcnic\u00f8de \u2713": "payload \u2713".encode(),
}
GOLDEN_CONTENTS = {"columns": ["path", "frames", "fps", "skeleton"], "clips": [["07_01.amc", 2, 120.0, "07.asf"]]}
# Format 12's clips table also lists each clip's achieved errors.
GOLDEN_CONTENTS_12 = {"columns": ["path", "frames", "fps", "skeleton", "mean_error_cm", "p99_error_cm", "max_error_cm"],
                      "clips": [["07_01.amc", 2, 120.0, "07.asf", 0.5, 1.25, 2.0]]}


# tests/golden/container_v7_index_dataset.mcz: enough streams for the index to be a dataset
MANY_STREAMS = {f"clips/{i:04d}": bytes([i]) * i for i in range(40)}


def read_all(path) -> tuple[str, dict[str, bytes]]:
    with ArchiveReader(path) as reader:
        return reader.tool_version, {name: reader.read(name) for name in reader.names()}


def assert_names_section(exc: ArchiveError) -> None:
    assert exc.message.startswith(("header:", "index:", "stream '")), exc.message


def test_round_trip_keeps_order_and_bytes(tmp_path):
    big = random.Random(0).randbytes(3 << 20)  # the writer batches ~1 MiB per HDF5 write
    streams = {"z": b"last", "a": bytearray(b"\x00\xff" * 10), "big": big, "empty": b"", "m": memoryview(b"view")}
    size = write_archive(tmp_path / "a.mcz", streams, tool_version="1.2.3")
    assert size == os.path.getsize(tmp_path / "a.mcz")
    with ArchiveReader(tmp_path / "a.mcz") as reader:
        assert (reader.format_version, reader.tool_version) == (FORMAT_VERSION, "1.2.3")
        assert reader.names() == ["z", "a", "big", "empty", "m"]
        assert {name: reader.read(name) for name in reader.names()} == {k: bytes(v) for k, v in streams.items()}
        reader.verify()
        with pytest.raises(KeyError):
            reader.read("missing")


def test_golden_container_with_its_index_in_a_dataset_still_decodes():
    path = GOLDEN / "container_v7_index_dataset.mcz"
    assert read_all(path) == ("golden-container-v7", MANY_STREAMS)
    with h5py.File(path, "r") as f:  # readable without mocapzip: the index is text, deflated by HDF5
        assert "index" not in f.attrs and json.loads(f["index"][0])["names"] == list(MANY_STREAMS)


@pytest.mark.parametrize("count", [0, 1, 5, 6, 40, 2000])
def test_the_index_is_an_attribute_while_small_and_a_deflated_dataset_beyond(tmp_path, count):
    streams = {f"clip/{i:05d}": bytes([i % 256]) * (i % 7) for i in range(count)}
    path = tmp_path / "a.mcz"
    write_archive(path, streams, tool_version="0.1.0")
    assert read_all(path) == ("0.1.0", streams)
    with h5py.File(path, "r") as f:
        in_attribute, in_dataset = "index" in f.attrs, "index" in f
        index = f.attrs["index"] if in_attribute else f["index"][0]
    assert in_attribute == (len(index) <= mcz.INDEX_ATTRIBUTE_BYTES) and in_attribute != in_dataset
    assert json.loads(index)["names"] == list(streams)


def test_empty_archive(tmp_path):
    write_archive(tmp_path / "e.mcz", {}, tool_version="1")
    assert read_all(tmp_path / "e.mcz") == ("1", {})


@pytest.mark.parametrize("version", range(1, FORMAT_VERSION + 1))
def test_golden_containers_still_decode(version):
    with ArchiveReader(GOLDEN / f"container_v{version}.mcz") as reader:
        assert (reader.format_version, reader.tool_version) == (version, f"golden-container-v{version}")
        assert reader.names() == list(GOLDEN_STREAMS)
        assert {name: reader.read(name) for name in reader.names()} == GOLDEN_STREAMS
        assert reader.contents == (GOLDEN_CONTENTS_12 if version >= 12 else GOLDEN_CONTENTS if version >= 10 else None)


def test_read_touches_only_its_own_stream(tmp_path):
    streams = {"a": b"A" * 50, "b": b"B" * 50, "c": b"C" * 50}
    path = tmp_path / "r.mcz"
    write_archive(path, streams, tool_version="1")
    data = bytearray(path.read_bytes())
    data[data.index(b"B" * 50) + 20] ^= 0xFF
    path.write_bytes(data)
    with ArchiveReader(path) as reader:
        assert reader.read("a") == streams["a"] and reader.read("c") == streams["c"]
        for check in (lambda: reader.read("b"), reader.verify):
            with pytest.raises(ArchiveError, match="stream 'b': CRC32 mismatch"):
                check()


def test_refuses_to_overwrite(tmp_path):
    path = tmp_path / "x.mcz"
    path.write_bytes(b"precious")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        write_archive(path, {"s": b"new"}, tool_version="1")
    assert path.read_bytes() == b"precious"
    write_archive(path, {"s": b"new"}, tool_version="1", overwrite=True)
    assert read_all(path)[1] == {"s": b"new"}


class ExplodingStreams(Mapping):
    """A mapping whose iteration fails after two streams, once the temporary file exists."""

    def __init__(self, exc: BaseException, directory: Path):
        self.exc, self.directory = exc, directory

    def __getitem__(self, name):
        return name.encode()

    def __iter__(self):
        yield "one"
        yield "two"
        assert any(name.startswith(".x.mcz.tmp-") for name in os.listdir(self.directory))
        raise self.exc

    def __len__(self):
        return 3


@pytest.mark.parametrize("exc", [RuntimeError("boom"), KeyboardInterrupt()])
@pytest.mark.parametrize("existing", [False, True])
def test_failed_write_leaves_no_file(tmp_path, exc, existing):
    path = tmp_path / "x.mcz"
    if existing:
        write_archive(path, {"old": b"old"}, tool_version="1")
    with pytest.raises(type(exc)):
        write_archive(path, ExplodingStreams(exc, tmp_path), tool_version="1", overwrite=True)
    assert os.listdir(tmp_path) == (["x.mcz"] if existing else [])
    if existing:
        assert read_all(path)[1] == {"old": b"old"}


def test_failed_rename_leaves_no_file(tmp_path, monkeypatch):
    def refuse(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(OSError, match="disk full"):
        write_archive(tmp_path / "x.mcz", {"s": b"x" * 1000}, tool_version="1")
    assert os.listdir(tmp_path) == []


def test_deterministic(tmp_path):
    streams = {f"clips/{i}": random.Random(i).randbytes(i * 10) for i in range(20)}
    write_archive(tmp_path / "1.mcz", streams, tool_version="1")
    time.sleep(1.1)  # HDF5 object timestamps have one-second resolution
    write_archive(tmp_path / "2.mcz", streams, tool_version="1")
    assert (tmp_path / "1.mcz").read_bytes() == (tmp_path / "2.mcz").read_bytes()



def test_streams_added_one_by_one_write_the_same_archive(tmp_path):
    """ArchiveWriter: streams come in any order, wait outside memory and the archive names no trace of
    them; the file is byte for byte write_archive's for the same streams in the same order."""
    big = random.Random(1).randbytes(3 << 20)
    streams = {"meta": b"known last", "b": big, "a": b"", "c": bytes(range(256))}
    write_archive(tmp_path / "whole.mcz", streams, tool_version="1")
    out = tmp_path / "out"
    out.mkdir()
    with mcz.ArchiveWriter(out / "streamed.mcz", tool_version="1") as writer:
        for name in ("c", "b", "a"):
            writer.add(name, streams[name])
        with pytest.raises(ValueError, match="added twice"):
            writer.add("a", b"again")
        writer.add("meta", streams["meta"])
        assert os.listdir(out) == []  # the spool has no name
        with pytest.raises(ValueError, match="every added stream"):
            writer.commit(["meta", "b", "a"])
        size = writer.commit(list(streams))
    assert os.listdir(out) == ["streamed.mcz"] and size == os.path.getsize(out / "streamed.mcz")
    assert (out / "streamed.mcz").read_bytes() == (tmp_path / "whole.mcz").read_bytes()


def test_writer_refuses_an_existing_file_before_any_stream(tmp_path):
    path = tmp_path / "x.mcz"
    path.write_bytes(b"precious")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        mcz.ArchiveWriter(path, tool_version="1")
    assert os.listdir(tmp_path) == ["x.mcz"]

def test_newer_format_version_refused(tmp_path):
    path = tmp_path / "future.mcz"
    write_archive(path, {"s": b"x"}, tool_version="9.9")
    with h5py.File(path, "r+") as f:
        f.attrs["format_version"] = f.attrs["format_version"] + 1
    with pytest.raises(ArchiveError, match=f"format_version {FORMAT_VERSION + 1} is newer .*up to {FORMAT_VERSION}"):
        ArchiveReader(path)


def test_not_an_archive(tmp_path):
    (tmp_path / "text.mcz").write_text("hello")
    with h5py.File(tmp_path / "plain.h5", "w") as f:
        f.attrs["magic"] = "HDF5 but something else"
    (tmp_path / "empty.mcz").write_bytes(b"")
    for name in ("text.mcz", "plain.h5", "empty.mcz"):
        with pytest.raises(MocapFormatError, match=f"{name}: header: "):
            ArchiveReader(tmp_path / name)
    for name in ("text.mcz", "empty.mcz"):  # no HDF5 signature: said plainly, not in HDF5's words
        with pytest.raises(MocapFormatError, match=r"header: not an mcz archive \(not an HDF5 file\)$"):
            ArchiveReader(tmp_path / name)
    with pytest.raises(FileNotFoundError):
        ArchiveReader(tmp_path / "missing.mcz")


def with_index(path: Path, index: bytes, crc: int | None = None) -> Path:
    """`path`, a format-7 archive, with its index attribute replaced by `index` (UTF-8 bytes) and
    the CRC made to match unless `crc` is given."""
    with h5py.File(path, "r+") as f:
        del f.attrs["index"]
        f.attrs.create("index", np.bytes_(index), dtype=h5py.string_dtype("utf-8", max(1, len(index))))
        f.attrs["index_crc32"] = np.uint32(zlib.crc32(index) if crc is None else crc)
    return path


def with_legacy_index(tmp_path: Path, doc) -> Path:
    """A copy of the format-6 golden container whose index dataset holds `doc`, every CRC made to match."""
    path = tmp_path / "bad_v6.mcz"
    path.write_bytes((GOLDEN / "container_v6.mcz").read_bytes())
    index = zstandard.ZstdCompressor().compress(json.dumps(doc).encode())
    with h5py.File(path, "r+") as f:
        del f["index"]
        f["index"] = np.frombuffer(index, np.uint8)
        f.attrs["index_crc32"] = np.uint32(zlib.crc32(index))
        f.attrs["header_crc32"] = np.uint32(header_crc(6, "golden-container-v6", zlib.crc32(index)))
    return path


def _index(names=("x",), lengths=(2,), crc32=(0,), tool="1", **changes) -> bytes:
    """A format-7 index as JSON bytes; a field given as ... is left out."""
    doc = {"tool": tool, "names": names, "lengths": lengths, "crc32": crc32, **changes}
    return json.dumps({k: list(v) if isinstance(v, tuple) else v for k, v in doc.items() if v is not ...}).encode()


@pytest.mark.parametrize(
    "index, problem",
    [
        (_index(names=["a", "a"], lengths=[1, 1], crc32=[0, 0]), "unique"),
        (_index(lengths=[1]), "need 1 bytes, payload has 2"),
        # wrong JSON types: an `index: ...` error, never a TypeError from deep inside the reader
        (b'[["x"], [2], [0]]', "not a JSON object with exactly the keys tool, names, lengths, crc32"),
        (_index(crc32=...), "not a JSON object with exactly the keys"),
        (_index(more=[]), "not a JSON object"),
        (_index(names="x"), "must be lists of equal length"),
        (_index(lengths={"0": 2}), "must be lists of equal length"),
        (_index(names=["x", "y"]), "must be lists of equal length"),
        (_index(names=[7]), "unique non-empty strings"),
        (_index(names=[["x"]]), "unique non-empty strings"),
        (_index(names=[""]), "unique non-empty strings"),
        (_index(lengths=[2.0]), "lengths must be non-negative integers"),
        (_index(lengths=[False]), "non-negative integers"),
        (_index(lengths=["2"]), "non-negative integers"),
        (_index(names=["x", "y"], lengths=[3, -1], crc32=[0, 0]), "non-negative integers"),
        (_index(crc32=[-1]), "crc32 values must be integers"),
        (_index(crc32=[1 << 32]), "crc32 values must be integers"),
        (_index(crc32=[None]), "crc32 values must be integers"),
        (_index(tool=""), "tool must be a non-empty string without NUL"),
        (_index(tool=7), "tool must be"),
        (_index(tool="a\0b"), "tool must be"),
        (b"\xff{", "damaged or unreadable"),
        (b'{"tool": NaN', "damaged or unreadable"),
    ],
)
def test_checksummed_but_inconsistent_index_refused(tmp_path, index, problem):
    """A writer bug or a hostile index must not turn into wrong reads, even when every CRC matches."""
    path = tmp_path / "bad.mcz"
    write_archive(path, {"x": b"12"}, tool_version="1")
    with pytest.raises(ArchiveError, match=f"index: .*{problem}"):
        ArchiveReader(with_index(path, index))


def test_index_that_is_not_a_fixed_length_string_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "bad.mcz"
    write_archive(path, {"x": b"12"}, tool_version="1")
    good = _index()
    for value, dtype in ((np.frombuffer(good, np.uint8), None), (good.decode(), h5py.string_dtype()),
                         (np.array([good, good]), h5py.string_dtype("utf-8", len(good))),
                         (np.bytes_(good), h5py.string_dtype("ascii", len(good)))):
        with h5py.File(path, "r+") as f:
            del f.attrs["index"]
            f.attrs.create("index", value, dtype=dtype)
            f.attrs["index_crc32"] = np.uint32(zlib.crc32(good))
        with pytest.raises(ArchiveError, match="index: not one fixed-length UTF-8 string"):
            ArchiveReader(path)


def test_index_crc_that_is_not_a_uint32_is_refused(tmp_path):
    path = tmp_path / "bad.mcz"
    write_archive(path, {"x": b"12"}, tool_version="1")
    with h5py.File(path, "r+") as f:
        f.attrs["index_crc32"] = np.int64(f.attrs["index_crc32"])
    with pytest.raises(ArchiveError, match="index: index_crc32 is not a scalar uint32"):
        ArchiveReader(path)


def many_streams_with_chunk(tmp_path: Path, chunk: bytes) -> Path:
    """The golden container whose index is a dataset, with its one chunk's stored bytes replaced."""
    path = tmp_path / "many.mcz"
    path.write_bytes((GOLDEN / "container_v7_index_dataset.mcz").read_bytes())
    with h5py.File(path, "r+") as f:
        f["index"].id.write_direct_chunk((0,), chunk)
    return path


def test_an_index_chunk_that_inflates_past_its_size_is_refused_before_it_is_inflated(tmp_path):
    """A deflate bomb: HDF5's own filter would inflate all of it; the reader stops one byte past the index."""
    with h5py.File(GOLDEN / "container_v7_index_dataset.mcz", "r") as f:
        text = bytes(f["index"][0])
    deflater = zlib.compressobj(9)
    bomb = b"".join([deflater.compress(text), *(deflater.compress(bytes(1 << 20)) for _ in range(64)), deflater.flush()])
    assert len(bomb) < 100_000  # 64 MiB stored in kilobytes
    with pytest.raises(ArchiveError, match=f"index: its deflated chunk does not hold exactly its {len(text)} bytes"):
        ArchiveReader(many_streams_with_chunk(tmp_path, bomb))
    with pytest.raises(ArchiveError, match="does not hold exactly"):  # and one that falls short
        ArchiveReader(many_streams_with_chunk(tmp_path, zlib.compress(text[:-1])))
    with ArchiveReader(many_streams_with_chunk(tmp_path, zlib.compress(text))) as reader:
        assert reader.names() == list(MANY_STREAMS)


def test_index_crc_mismatch_is_refused(tmp_path):
    path = tmp_path / "bad.mcz"
    write_archive(path, {"x": b"12"}, tool_version="1")
    good = _index(crc32=[zlib.crc32(b"12")])
    with ArchiveReader(with_index(path, good)) as reader:
        assert reader.read("x") == b"12"
    with pytest.raises(ArchiveError, match="index: CRC32 mismatch"):
        ArchiveReader(with_index(path, good, crc=zlib.crc32(good) ^ 1))


@pytest.mark.parametrize(
    "doc, problem",
    [
        ({"names": ["a", "a"], "offsets": [0, 1], "lengths": [1, 1], "crc32": [0, 0]}, "unique"),
        ({"names": ["a", "b"], "offsets": [0, 2], "lengths": [1, 1], "crc32": [0, 0]}, "back to back"),
        ({"names": ["a"], "offsets": [0], "lengths": [1], "crc32": [0]}, "need 1 bytes, payload has"),
        ([["x"], [0], [2], [0]], "not a JSON object with exactly the keys names, offsets, lengths, crc32"),
        ({"names": ["x"], "offsets": [0], "lengths": [2]}, "not a JSON object with exactly the keys"),
        ({"names": ["x"], "offsets": {"0": 0}, "lengths": [2], "crc32": [0]}, "must be lists of equal length"),
        ({"names": [""], "offsets": [0], "lengths": [2], "crc32": [0]}, "unique non-empty strings"),
        ({"names": ["x"], "offsets": [0.0], "lengths": [2], "crc32": [0]}, "offsets and lengths must be non-negative"),
        ({"names": ["x"], "offsets": [0], "lengths": [2], "crc32": [1 << 32]}, "crc32 values must be integers"),
    ],
)
def test_checksummed_but_inconsistent_legacy_index_refused(tmp_path, doc, problem):
    """Formats 1 to 6 keep the zstd-coded index dataset: its checks stay."""
    with pytest.raises(ArchiveError, match=f"index: .*{problem}"):
        ArchiveReader(with_legacy_index(tmp_path, doc))


def damage_outcomes(tmp_path, variants) -> dict[str, int]:
    """Open each damaged copy of the golden file: it must fail cleanly or give back the exact contents."""
    path = tmp_path / "damaged.mcz"
    outcomes = {"detected": 0, "harmless": 0}
    for data in variants:
        path.write_bytes(data)
        try:
            result = read_all(path)
        except ArchiveError as exc:
            assert_names_section(exc)
            outcomes["detected"] += 1
        else:
            assert result == (f"golden-container-v{FORMAT_VERSION}", GOLDEN_STREAMS)
            outcomes["harmless"] += 1
    return outcomes


@pytest.mark.slow
def test_single_byte_damage_is_detected_or_harmless(tmp_path):
    golden = GOLDEN_NEWEST.read_bytes()
    step = max(1, len(golden) // 2000)  # every byte of today's ~2 KB file; stays < 10 s if it grows

    def flipped():
        for position in range(0, len(golden), step):
            for mask in (0x01, 0xFF):
                data = bytearray(golden)
                data[position] ^= mask
                yield bytes(data)

    outcomes = damage_outcomes(tmp_path, flipped())
    print("single-byte damage:", outcomes)
    assert outcomes["detected"] > outcomes["harmless"]


def test_truncation_is_detected(tmp_path):
    golden = GOLDEN_NEWEST.read_bytes()
    outcomes = damage_outcomes(tmp_path, (golden[:size] for size in range(len(golden))))
    print("truncations:", outcomes)
    assert outcomes["harmless"] == 0


def test_overhead_is_small(tmp_path):
    empty = write_archive(tmp_path / "0.mcz", {}, tool_version="0.1.0")
    rng = random.Random(0)
    streams = {f"clips/{i:04d}/coefficients": rng.randbytes(100) for i in range(1000)}
    full = write_archive(tmp_path / "1000.mcz", streams, tool_version="0.1.0")
    per_stream = (full - empty - 100 * 1000) / 1000
    print(f"empty archive: {empty} bytes; index overhead: {per_stream:.1f} bytes/stream")
    assert empty < 800  # measured 487 with h5py 3.16 / HDF5 2.0; 656 without `_without_attributes` (format 6: 1032)
    assert per_stream < 15  # measured 8.8: readable JSON, deflated by HDF5 (format 6's zstd index: 6.9)


@pytest.mark.parametrize("count", [1, 2000])  # the index as an attribute, then as a dataset
def test_datasets_reserve_no_room_for_attributes(tmp_path, monkeypatch, count):
    """HDF5 gives each dataset's object header room for attributes mcz never writes, unless told
    (`_without_attributes`); told, the archive is 169 bytes smaller a dataset and reads the same."""
    if mcz._no_attrs_hint() is None:
        pytest.skip("this HDF5 library cannot be told (Windows: ctypes finds no HDF5 call in h5py's extension)")
    streams = {f"clip/{i:05d}": bytes([i % 256]) * 50 for i in range(count)}
    write_archive(tmp_path / "hinted.mcz", streams, tool_version="1")
    monkeypatch.setattr(mcz, "_no_attrs_hint", lambda: None)  # as where HDF5 cannot be reached (Windows)
    write_archive(tmp_path / "plain.mcz", streams, tool_version="1")
    sizes = {}
    for name in ("hinted", "plain"):
        path = tmp_path / f"{name}.mcz"
        assert read_all(path) == ("1", streams)
        with h5py.File(path, "r") as f:
            headers = [h5py.h5o.get_info(f[key].id).hdr.space for key in f]
            sizes[name] = os.path.getsize(path), sum(h.free for h in headers), len(headers)
    (hinted, hinted_free, datasets), (plain, plain_free, _) = sizes["hinted"], sizes["plain"]
    assert datasets == (1 if count == 1 else 2)
    assert plain_free >= 180 * datasets and hinted_free <= 24 * datasets
    assert plain - hinted >= 160 * datasets


def test_contents_are_written_into_the_index_and_read_back(tmp_path):
    """Format 10's `contents`: a JSON object in the index for people and `h5dump -a index`; the
    reader hands it back and relies on nothing in it; one that is no object is refused."""
    contents = {"columns": ["path"], "clips": [["a.amc"]]}
    write_archive(tmp_path / "c.mcz", {"s": b"x"}, tool_version="1", contents=contents)
    with ArchiveReader(tmp_path / "c.mcz") as reader:
        assert reader.contents == contents and reader.read("s") == b"x"
    with h5py.File(tmp_path / "c.mcz", "r") as f:
        assert json.loads(f.attrs["index"])["contents"] == contents  # plain text for stock tools
    write_archive(tmp_path / "d.mcz", {"s": b"x"}, tool_version="1", contents=[1])
    with pytest.raises(ArchiveError, match="index: contents is not a JSON object"):
        ArchiveReader(tmp_path / "d.mcz")


@pytest.mark.parametrize("index, problem", [
    (b'{"tool":"t","names":["a"],"names":["b"],"lengths":[0],"crc32":[0]}', "a key appears twice in an object: 'names'"),
    (b'\xef\xbb\xbf{"tool":"t","names":["a"],"lengths":[0],"crc32":[0]}', "Unexpected UTF-8 BOM"),
    (b'{"tool":"t","names":["a"],"lengths":[1e400],"crc32":[0]}', "1e400 is not a finite number"),
])
def test_an_index_python_would_read_loosely_is_refused(tmp_path, index, problem):
    """Python's json keeps the last of two keys, skips a byte-order mark and reads 1e400 as inf: the
    spec's index is strict JSON, so each is a damaged index (`parse_json`, shared with meta)."""
    path = tmp_path / "loose.mcz"
    path.write_bytes((GOLDEN / "container_v7.mcz").read_bytes())
    with pytest.raises(ArchiveError, match=re.escape(problem)):
        ArchiveReader(with_index(path, index)).close()
