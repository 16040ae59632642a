"""Hostile archives (issue 13): a stranger's .mcz, every checksum valid, must never write outside
the output folder, hang, exhaust memory or crash. Each case (tests/hostile_archives.py) runs
`mcz test`, `mcz info` and `mcz decompress` in a child limited to 1 GiB of address space and
60 seconds: each must exit 1 with one line naming the archive and the part at fault, and
nothing may appear anywhere in the temporary tree the case runs in.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import hostile_archives
from mocapzip.archive import Archive
from mocapzip.cli.main import main
from mocapzip.formats.amc import read_amc, write_amc
from mocapzip.formats.asf import read_asf
from mocapzip.formats.bvh import read_bvh, write_bvh
from test_bvh_pipeline import rescaled

CASES = hostile_archives.cases(Path("/placeholder"))  # names only; each test builds its case in its own tree


@pytest.mark.slow
@pytest.mark.parametrize("name", [case.name for case in CASES])
def test_hostile_archive_is_refused_in_one_line(name, tmp_path):
    case = next(c for c in hostile_archives.cases(tmp_path) if c.name == name)
    assert hostile_archives.check(case, tmp_path) == []


def test_every_golden_archive_passes_the_same_checks(tmp_path):
    """The checks refuse what is hostile, not what is valid: each base archive decompresses. (In
    this process, not in a limited child as the hostile cases: a valid archive needs no limit, and
    a child's start-up cost 11 s of the fast tier.)"""
    for base, path in hostile_archives.BASES.items():
        out = tmp_path / base
        for command in (("test", "-q", path), ("info", "--json", path), ("decompress", "-q", path, "-o", out)):
            result = CliRunner().invoke(main, list(map(str, command)))
            assert result.exit_code == 0, result.output
        bvh = ["dataset-1_walk-back_normal_001.bvh"] if base.endswith(("_bvh", "_plant", "_tensor")) else []
        assert sorted(p.name for p in out.iterdir()) == ["09.asf", "09_01.amc", "64.asf", "64_01.amc", *bvh]


def test_compress_refuses_what_readers_would_refuse(shared_data, tmp_path):
    """Two input folders whose skeletons share a file name, clips stored side by side: the
    archive would write both ASFs to one path, which every reader refuses; so compress does."""
    for folder, subject, clip in (("a", "09", "09_01.amc"), ("b", "07", "07_01.amc")):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "actor.asf").write_bytes((shared_data / "cmu" / subject / f"{subject}.asf").read_bytes())
        (tmp_path / folder / clip).write_bytes((shared_data / "cmu" / subject / clip).read_bytes())
    archive = tmp_path / "db.mcz"
    result = hostile_archives.run_mcz("compress", str(tmp_path / "a"), str(tmp_path / "b"), "-o", str(archive),
                                      "--lossless", "-q")
    assert result.returncode == 1 and result.stderr.splitlines() == [
        f"mcz: error: {archive}: meta: clips[1].skeleton: 'actor.asf' is written twice (already skeleton 1's file)"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b"]


def test_file_names_that_are_not_utf8_round_trip(shared_data, tmp_path):
    """A name read from disk keeps its non-UTF-8 bytes (surrogate escapes) and is written back as it was."""
    folder, out = tmp_path / "in", tmp_path / "out"
    folder.mkdir()
    name = b"T\xe4nzer.amc"
    (folder / "09.asf").write_bytes((shared_data / "cmu" / "09" / "09.asf").read_bytes())
    (folder / os.fsdecode(name)).write_bytes((shared_data / "cmu" / "09" / "09_01.amc").read_bytes())
    archive = tmp_path / "db.mcz"
    for command in (("compress", folder, "-o", archive, "--lossless", "-q"), ("test", "-q", archive),
                    ("decompress", archive, "-o", out, "-q")):
        result = hostile_archives.run_mcz(*map(str, command))
        assert result.returncode == 0, result.stderr
    assert sorted(os.listdir(os.fsencode(out))) == [b"09.asf", name]


def test_what_compress_writes_at_the_edges_of_the_meta_rules_passes(shared_data, tmp_path):
    """The meta rules refuse what no compress writes, not what it does: a lossless BVH archive whose
    unit compress could not tell (`units` null: 10_03 in inches, which reads as a child in cm) and a
    class of one still pose (0 components: the mean alone meets the target) pass `mcz test`."""
    inches = tmp_path / "inches" / "10_03.bvh"
    inches.parent.mkdir()
    write_bvh(rescaled(read_bvh(shared_data / "cmu-bvh" / "10" / "10_03.bvh"), 1 / 2.54), inches)
    still = tmp_path / "still"
    still.mkdir()
    (still / "09.asf").write_bytes((shared_data / "cmu" / "09" / "09.asf").read_bytes())
    source = read_amc(shared_data / "cmu" / "09" / "09_01.amc", read_asf(still / "09.asf"))
    write_amc(dataclasses.replace(source, values=np.repeat(source.values[:1], 100, axis=0),
                                  frame_numbers=np.arange(1, 101)), still / "still.amc")
    for folder, options, field, value in ((inches.parent, ["--lossless"], ("skeletons", "units"), None),
                                          (still, [], ("classes", "components"), 0)):
        archive = tmp_path / f"{folder.name}.mcz"
        for command in (("compress", folder, "-o", archive, "-q", *options), ("test", "-q", archive)):
            result = CliRunner().invoke(main, list(map(str, command)))
            assert result.exit_code == 0, result.output
        with Archive(archive) as opened:
            assert opened.meta[field[0]][0][field[1]] == value
