"""Hostile archives (issue 13): a stranger's .mcz, every checksum valid, must never write outside
the output folder, hang, exhaust memory or crash. Each case (tests/hostile_archives.py) runs
`mcz test`, `mcz info` and `mcz decompress` in a child limited to 1 GiB of address space and
60 seconds: each must exit 1 with one line naming the archive and the part at fault, and
nothing may appear anywhere in the temporary tree the case runs in.
"""

from __future__ import annotations

from pathlib import Path

import pytest

import hostile_archives

CASES = hostile_archives.cases(Path("/placeholder"))  # names only; each test builds its case in its own tree


@pytest.mark.parametrize("name", [case.name for case in CASES])
def test_hostile_archive_is_refused_in_one_line(name, tmp_path):
    case = next(c for c in hostile_archives.cases(tmp_path) if c.name == name)
    assert hostile_archives.check(case, tmp_path) == []


def test_every_golden_archive_passes_the_same_checks(tmp_path):
    """The checks refuse what is hostile, not what is valid: each base archive decompresses."""
    for base, path in hostile_archives.BASES.items():
        out = tmp_path / base
        for command in (("test", "-q", path), ("info", "--json", path), ("decompress", "-q", path, "-o", out)):
            result = hostile_archives.run_mcz(*map(str, command))
            assert result.returncode == 0, result.stderr
        assert sorted(p.name for p in out.iterdir()) == ["09.asf", "09_01.amc", "64.asf", "64_01.amc"]
