"""The Python API (mocapzip/api.py, docs/api.md): its examples run, one clip is read alone, and
its defaults and errors are the command line's."""

from __future__ import annotations

import doctest
import subprocess
import sys
from pathlib import Path

import pytest

import mocapzip
from mocapzip.formats.mcz import ArchiveReader

DOCS = Path(__file__).resolve().parents[1] / "docs" / "api.md"
GOLDEN_LOSSY = Path(__file__).parent / "golden" / "lossy_v7.mcz"


def test_the_examples_in_docs_api_md_run(shared_data, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "data").symlink_to(shared_data)
    result = doctest.testfile(str(DOCS), module_relative=False, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0 and result.attempted >= 20, result


def test_import_mocapzip_stays_cheap():
    code = "import sys, mocapzip; assert 'numpy' not in sys.modules; mocapzip.open; assert 'numpy' in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)
    assert set(mocapzip.__all__) <= set(dir(mocapzip))
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        mocapzip.nothing


def test_reading_one_clip_reads_only_its_own_streams(monkeypatch):
    read = []
    original = ArchiveReader.read
    monkeypatch.setattr(ArchiveReader, "read", lambda self, name: read.append(name) or original(self, name))
    with mocapzip.open(GOLDEN_LOSSY) as archive:
        assert set(read) == {"meta", "skeletons"}
        read.clear()
        clip = archive["64_01.amc"]
        assert read == []  # nothing is decoded until asked for
        clip.channels
        assert set(read) == {"clip/00001", "patch/00001", "class/0000", "priors"}
        read.clear()
        clip.positions()
        assert read == []  # decoded once, then kept


def test_clips_by_path_and_position():
    with mocapzip.open(GOLDEN_LOSSY) as archive:
        assert [clip.path for clip in archive] == archive.paths == ["09_01.amc", "64_01.amc"]
        assert archive[-1].path == archive[1].path == "64_01.amc"
        assert archive["09_01.amc"].error == mocapzip.ClipError(*(archive._archive.clips[0][key] for key in (
            "error_cm", "p99_error_cm", "max_error_cm")))
        with pytest.raises(KeyError, match="no clip '10_01.amc'"):
            archive["10_01.amc"]
        with pytest.raises(IndexError):
            archive[2]
        with pytest.raises(TypeError, match="by path .* or position"):
            archive[1.0]


def test_compress_takes_the_command_line_defaults(shared_data, tmp_path):
    clip = shared_data / "cmu" / "09" / "09_01.amc"
    asf = clip.with_name("09.asf")
    summary = mocapzip.compress([asf, clip], tmp_path / "a.mcz", error=2.0)
    with mocapzip.open(tmp_path / "a.mcz") as archive:
        assert archive.settings.error_cm == 2.0 and archive.settings.max_error_cm == 20.0  # 10 x error
        assert archive[0].error.mean_cm == summary["largest_mean_error_cm"] <= 2.0
    mocapzip.compress([asf, clip], tmp_path / "a.mcz", error=2.0, max_error=None, representation="positions",
                      force=True)
    with mocapzip.open(tmp_path / "a.mcz") as archive:
        assert archive.settings.max_error_cm is None and archive.settings.representation == "positions"
    with pytest.raises(mocapzip.SettingsError, match="representation"):
        mocapzip.compress([asf, clip], tmp_path / "b.mcz", representation="quaternions")
    assert not (tmp_path / "b.mcz").exists()
