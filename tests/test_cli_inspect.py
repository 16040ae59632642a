"""`mcz inspect` and input discovery on the real shared data."""

from __future__ import annotations

import json
import shutil

import pytest
from click.testing import CliRunner

from mocapzip.cli.main import main
from mocapzip.formats.errors import MocapFormatError
from mocapzip.inputs.discover import find_clips


def run(*args):
    return CliRunner().invoke(main, list(args))


def test_version_and_help():
    assert run("--version").output.startswith("mcz, version ")
    result = run("--help")
    assert result.exit_code == 0 and "mcz compress" in result.output


def test_inspect_cmu_subject_json(shared_data):
    result = run("inspect", "--json", str(shared_data / "cmu" / "07"))
    assert result.exit_code == 0, result.output
    report = json.loads(result.output)
    frames = {r["path"]: r["frames"] for r in report["clips"]}
    assert frames["07_01.amc"] == 316  # MANIFEST.tsv
    assert report["total"]["clips"] == 10 and report["total"]["skeletons"] == 1
    assert all(r["dof"] == 62 for r in report["clips"])
    assert abs(report["clips"][0]["seconds"] - 316 / 120) < 1e-9


def test_inspect_fps_and_table(shared_data):
    result = run("inspect", "--fps", "200", str(shared_data / "other-vicon-blade"))
    assert result.exit_code == 0, result.output
    assert "walkMoCapVideo.amc" in result.output and "total: 3 clips" in result.output


def test_inspect_missing_path_is_exit_1(tmp_path):
    result = run("inspect", str(tmp_path / "nope"))
    assert result.exit_code == 1
    assert "no such file or directory" in result.output


def test_inspect_reports_bad_amc_with_file_and_line(shared_data, tmp_path):
    src = shared_data / "cmu" / "07"
    shutil.copy(src / "07.asf", tmp_path / "07.asf")
    lines = (src / "07_01.amc").read_text().splitlines()
    lines[10] = lines[10].split()[0] + " abc 1 2"
    (tmp_path / "bad.amc").write_text("\n".join(lines))
    result = run("inspect", str(tmp_path))
    assert result.exit_code == 1
    assert "bad.amc:11:" in result.output and "not a number" in result.output
    assert "Traceback" not in result.output


def test_find_clips_pairs_skeletons(shared_data, tmp_path):
    clips = find_clips([shared_data / "hdm05"])
    assert len(clips) == 34
    assert all(c.skeleton.parent == c.motion.parent for c in clips)
    assert any(c.relpath.endswith(".AMC") for c in clips)  # upper-case extension found
    # No skeleton in the folder: a clear error naming the clip.
    shutil.copy(shared_data / "cmu" / "07" / "07_01.amc", tmp_path / "a.amc")
    with pytest.raises(MocapFormatError, match=r"a\.amc: no skeleton"):
        find_clips([tmp_path])
