"""Damaged archives and determinism (issue 5, items 2 and 5).

Every sampled single-byte change and truncation of the golden lossy archive must make
`mcz test`, `mcz info` and `mcz decompress` fail in one line naming the section or clip,
quickly, writing nothing; or, if the change is harmless, give exactly the undamaged output.
"""

from __future__ import annotations

import faulthandler
import os
import re
import shutil
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mocapzip.archive import Archive
from mocapzip.cli.main import main
from mocapzip.formats.mcz import FORMAT_VERSION, ArchiveReader, write_archive

GOLDEN_LOSSY = Path(__file__).parent / "golden" / f"lossy_v{FORMAT_VERSION}.mcz"  # the newest codec
SECTION = re.compile(r"(header|index): |stream '(meta|skeletons|priors|(class|tensor)/\d{4}|"
                     r"(clip|patch|extra_root|plant|warp)/\d{5})': .*|"
                     r"(clip|patch|extra_root|plant|warp)/\d{5} \(\S+\): damaged")


def run(*args):
    return CliRunner().invoke(main, [os.fspath(a) for a in args])


def tree(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


class Sweep:
    """Runs the three commands on damaged copies written to one path and sorts the outcomes."""

    def __init__(self, work: Path):
        self.work, self.archive = work, work / "damaged.mcz"
        self.archive.write_bytes(GOLDEN_LOSSY.read_bytes())
        self.reference_info = run("info", "--json", self.archive).stdout
        assert run("decompress", self.archive, "-o", work / "reference", "-q").exit_code == 0
        self.reference = tree(work / "reference")
        self.outcomes: Counter = Counter()
        self.failures: list[str] = []

    def check(self, label: str, data: bytes) -> None:
        self.archive.write_bytes(data)
        out = self.work / "out"
        results = {}
        for command in (("test", "-q", self.archive), ("info", "--json", self.archive),
                        ("decompress", self.archive, "-o", out, "-q")):
            shutil.rmtree(out, ignore_errors=True)
            result = run(*command)
            results[command[0]] = result
            if result.exit_code == 1:
                lines = result.stderr.splitlines()
                if not (isinstance(result.exception, SystemExit) and len(lines) == 1 and result.stdout == ""
                        and lines[0].startswith(f"mcz: error: {self.archive}: ") and SECTION.search(lines[0])):
                    self.failures.append(f"{label}: {command[0]} refused badly: {result.output!r}")
                if out.exists() and tree(out):
                    self.failures.append(f"{label}: decompress wrote {sorted(tree(out))} from a damaged archive")
            elif result.exit_code != 0:
                self.failures.append(f"{label}: {command[0]} exit {result.exit_code}: {result.exception!r}")
        codes = {name: r.exit_code for name, r in results.items()}
        if set(codes.values()) == {1}:
            self.outcomes["detected"] += 1
        elif set(codes.values()) == {0}:
            self.outcomes["harmless"] += 1
            if results["info"].stdout != self.reference_info or tree(out) != self.reference:
                self.failures.append(f"{label}: accepted but decodes differently (wrong output)")
        else:
            self.failures.append(f"{label}: commands disagree {codes}")


@pytest.fixture
def hang_guard():
    """Dump the stacks and abort if the whole sweep hangs inside C code (HDF5, zstd)."""
    faulthandler.dump_traceback_later(300, exit=True)
    yield
    faulthandler.cancel_dump_traceback_later()


def test_every_sampled_byte_change_is_detected_or_harmless(tmp_path, hang_guard):
    golden = GOLDEN_LOSSY.read_bytes()
    # the superblock and root object header byte by byte, then positions spread over the rest
    positions = sorted(set(range(96)) | set(np.linspace(96, len(golden) - 1, 304).astype(int).tolist()))
    assert len(positions) == 400
    sweep = Sweep(tmp_path)
    for k, position in enumerate(positions):
        data = bytearray(golden)
        data[position] ^= (0x01, 0x80, 0xFF)[k % 3]
        sweep.check(f"byte {position}", bytes(data))
    print(f"single-byte changes: {len(positions)} tried, {dict(sweep.outcomes)}")
    assert sweep.failures == []
    assert sweep.outcomes["detected"] >= 0.9 * len(positions)  # CRCs and HDF5 checksums cover nearly all


def test_every_sampled_truncation_is_detected(tmp_path, hang_guard):
    golden = GOLDEN_LOSSY.read_bytes()
    lengths = sorted(set(range(0, 64)) | set(np.linspace(64, len(golden) - 1, 136).astype(int).tolist()))
    sweep = Sweep(tmp_path)
    for length in lengths:
        sweep.check(f"truncated to {length}", golden[:length])
    print(f"truncations: {len(lengths)} tried, {dict(sweep.outcomes)}")
    assert sweep.failures == []
    assert sweep.outcomes == {"detected": len(lengths)}  # a cut archive is never complete


def test_damaged_clip_is_named_by_its_path(tmp_path):
    """A CRC failure in a clip stream names the clip's stored path, so the user knows what is lost."""
    data = bytearray(GOLDEN_LOSSY.read_bytes())
    with ArchiveReader(GOLDEN_LOSSY) as reader:
        stream = reader.read("clip/00001")  # the second clip
    with Archive(GOLDEN_LOSSY) as archive:
        path = archive.clips[1]["path"]
    start = data.find(stream)
    assert start > 0 and data.count(stream) == 1
    data[start + len(stream) // 2] ^= 0x55
    damaged = tmp_path / "d.mcz"
    damaged.write_bytes(bytes(data))
    for command in (("test", damaged), ("info", damaged), ("decompress", damaged, "-o", tmp_path / "out")):
        result = run(*command)
        assert result.exit_code == 1
        assert result.stderr == f"mcz: error: {damaged}: stream 'clip/00001': CRC32 mismatch (clip {path})\n"
    assert not (tmp_path / "out").exists()


@pytest.fixture(scope="module")
def two_clips(tmp_path_factory, shared_data) -> Path:
    folder = tmp_path_factory.mktemp("two")
    for name in ("09.asf", "09_01.amc", "09_03.amc"):
        shutil.copy(shared_data / "cmu" / "09" / name, folder / name)
    return folder


@pytest.mark.parametrize("mode", [["--lossless"], ["-e", "1.5"]])
def test_same_inputs_give_byte_identical_archives(two_clips, tmp_path, mode):
    """Same inputs and options, run twice, with 1 or 2 workers and the files named in another
    order: the same bytes (no timestamps in HDF5, sorted inputs, no unseeded randomness)."""
    clips = [two_clips / "09_01.amc", two_clips / "09_03.amc"]
    runs = {"-j 1": [*clips, "-j", "1"], "-j 1 again": [*clips, "-j", "1"], "-j 2, other order": [*clips[::-1], "-j", "2"]}
    archives = {}
    for label, args in runs.items():
        path = tmp_path / f"{len(archives)}.mcz"
        result = run("compress", *args, *mode, "-o", path, "-q")
        assert result.exit_code == 0, result.output
        archives[label] = path.read_bytes()
        if len(archives) == 1:
            time.sleep(1.1)  # any timestamp written would differ between the first two runs
    first = archives["-j 1"]
    assert all(data == first for data in archives.values()), {k: len(v) for k, v in archives.items()}


def test_a_clips_table_that_disagrees_with_meta_fails_the_test_only(tmp_path):
    """The index's `contents` (format 10) is for people: decoding never reads it, so `info` and
    `decompress` do as before, and `mcz test` says it does not match."""
    with ArchiveReader(GOLDEN_LOSSY) as reader:
        streams = {name: reader.read(name) for name in reader.names()}
        contents = reader.contents
    assert contents["clips"][0][:2] == ["09_01.amc", 148]
    contents["clips"][0][1] = 149
    damaged = tmp_path / "table.mcz"
    write_archive(damaged, streams, tool_version="x", contents=contents)
    result = run("test", damaged)
    assert result.exit_code == 1
    assert result.stderr == f"mcz: error: {damaged}: index: contents (the clips table) does not match meta\n"
    assert run("decompress", damaged, "-o", tmp_path / "out", "-q").exit_code == 0
    assert tree(tmp_path / "out") == tree_of_golden(tmp_path)


def tree_of_golden(tmp_path: Path) -> dict[str, bytes]:
    assert run("decompress", GOLDEN_LOSSY, "-o", tmp_path / "golden", "-q").exit_code == 0
    return tree(tmp_path / "golden")
