"""What real exporters and folders do that a strict reader must still take (issue 18, items 2-3):

- frame rates the files state: ASF/AMC have no field for one, but exporters write it (Vicon
  Blade's AMC header, `fps:30` in an ASF's documentation). A clip takes its files' rate, `--fps`
  overrides every clip, and the archive, `info`, `inspect` and the API report it;
- units named instead of given as factors (`mass kg`, `length m`);
- folders holding several ASFs: copies of one skeleton, or different ones named like their clips."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

import mocapzip
from mocapzip.cli.main import main
from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import parse_asf, read_asf
from mocapzip.formats.text import stated_frame_rate


@pytest.mark.parametrize("line, rate", [
    ("# Frame Rate: 200.000 fps", 200.0), ("#frame rate:59.94", 59.94), ("# FRAME RATE = 30 Hz", 30.0),
    ("fps:30", 30.0), ("# fps = 60", 60.0), ("captured with fps = 60 on stage 2", None),
    ("120 fps = 0.00833 s", None), ("fps: 0.5", None),
    ("# Frame Rate: 0 fps", None), ("fps:1e9", None), ("myfps:30", None), ("# Frame Rate: fast", None),
    ("# Frame Rate: 200000 fps", None), (":FULLY-SPECIFIED", None),
])
def test_a_stated_rate_is_read_where_exporters_write_it(line, rate):
    assert stated_frame_rate(["# File created by Blade", line]) == rate


def test_real_files_state_their_rates_or_none(shared_data):
    blade = sorted((shared_data / "other-vicon-blade").glob("*/*.amc"))
    assert len(blade) == 3
    for amc in blade:
        assert read_amc(amc).frame_rate == 200.0
    assert read_amc(shared_data / "cmu" / "09" / "09_01.amc").frame_rate is None
    cmu = (shared_data / "cmu" / "09" / "09.asf").read_bytes()
    assert read_asf(shared_data / "cmu" / "09" / "09.asf").frame_rate is None
    documented = cmu.replace(b":documentation", b":documentation\r\n   fps:30", 1)
    assert parse_asf(documented, "09.asf").frame_rate == 30.0


def test_each_clip_keeps_its_files_rate_and_fps_overrides_them_all(shared_data, tmp_path):
    blade, cmu = shared_data / "other-vicon-blade", shared_data / "cmu" / "09"
    inputs = [str(blade), str(cmu / "09.asf"), str(cmu / "09_01.amc")]
    runner = CliRunner()
    assert runner.invoke(main, ["compress", *inputs, "-o", str(tmp_path / "a.mcz"), "-q"]).exit_code == 0
    report = json.loads(runner.invoke(main, ["info", "--json", str(tmp_path / "a.mcz")]).output)
    rates = {clip["path"]: clip["fps"] for clip in report["clips"]}
    assert rates == {"09_01.amc": 120.0, "trial1_200fps/trial1.amc": 200.0,
                     "walk_200fps/walkMoCap2.amc": 200.0, "walk_200fps/walkMoCapVideo.amc": 200.0}
    assert "fps_from_files" not in report["settings"] and report["settings"]["fps"] == 120.0
    assert "3 clips at 200 fps (from their files)" in runner.invoke(main, ["info", str(tmp_path / "a.mcz")]).output
    with mocapzip.open(tmp_path / "a.mcz") as archive:
        assert {clip.path: clip.fps for clip in archive} == rates
        stored = [row.get("fps") for row in archive._archive.clips]  # a row says so only where it differs
        assert stored == [None if rate == 120.0 else rate for rate in rates.values()]

    assert runner.invoke(main, ["compress", *inputs, "-o", str(tmp_path / "b.mcz"), "-q", "--fps", "100"]).exit_code == 0
    report = json.loads(runner.invoke(main, ["info", "--json", str(tmp_path / "b.mcz")]).output)
    assert {clip["fps"] for clip in report["clips"]} == {100.0}
    assert report["settings"]["fps_from_files"] is False and report["settings"]["fps"] == 100.0


def test_inspect_gives_each_clip_its_rate_and_duration(shared_data):
    runner = CliRunner()
    report = json.loads(runner.invoke(main, ["inspect", "--json", str(shared_data / "other-vicon-blade")]).output)
    assert [(r["fps"], r["seconds"]) for r in report["clips"]] == [(200.0, r["frames"] / 200) for r in report["clips"]]
    report = json.loads(runner.invoke(main, ["inspect", "--json", "--fps", "50",
                                             str(shared_data / "other-vicon-blade")]).output)
    assert {r["fps"] for r in report["clips"]} == {50.0} and report["fps"] == 50.0


def test_units_given_by_name_are_read_as_other_readers_read_them(shared_data):
    """An exporter writing `mass kg` and `length m` (tab-separated) was refused at :units."""
    text = (shared_data / "cmu" / "09" / "09.asf").read_bytes()
    named = text.replace(b"  mass 1.0", b"  mass\tkg", 1).replace(b"  length 0.45", b"  length\tm", 1)
    assert named != text
    metres, inches = parse_asf(named, "09.asf"), parse_asf(text, "09.asf")
    assert metres.units == {"mass": "kg", "length": "m", "angle": "deg"}
    assert metres.cm_per_unit == 100.0 and inches.cm_per_unit == pytest.approx(2.54 / 0.45)
    clip = read_amc(shared_data / "cmu" / "09" / "09_01.amc", inches)
    scale = 100.0 / (2.54 / 0.45)  # the same numbers, read as metres instead of 1/0.45 inch
    assert np.allclose(mocapzip.joint_positions(metres, clip), scale * mocapzip.joint_positions(inches, clip))


def test_a_folder_of_several_skeletons_pairs_without_asking_where_nothing_is_ambiguous(shared_data, tmp_path):
    """CMU ships folders with `07.asf` and `07-walk.asf`, alike but for line ends: one skeleton.
    Different skeletons pair each AMC with the ASF whose name begins its own, and say so."""
    cmu07, cmu09 = shared_data / "cmu" / "07", shared_data / "cmu" / "09"
    copies = tmp_path / "copies"
    copies.mkdir()
    (copies / "07.asf").symlink_to(cmu07 / "07.asf")
    (copies / "07-walk.asf").write_bytes((cmu07 / "07.asf").read_bytes().replace(b"\r\n", b"\n"))
    (copies / "07_01.amc").symlink_to(cmu07 / "07_01.amc")
    runner = CliRunner()
    result = runner.invoke(main, ["compress", str(copies), "-o", str(tmp_path / "a.mcz"), "-q"])
    assert result.exit_code == 0, result.output
    assert json.loads(runner.invoke(main, ["info", "--json", str(tmp_path / "a.mcz")]).output)["skeletons"] == 1
    (copies / "09.asf").symlink_to(cmu09 / "09.asf")  # and a different one: 07_01 still takes a copy of 07
    with pytest.warns(UserWarning, match="2 different skeletons"):
        mocapzip.compress(copies, tmp_path / "a2.mcz")
    with mocapzip.open(tmp_path / "a2.mcz") as archive:
        assert archive["07_01.amc"].skeleton.path == "07.asf"

    mixed = tmp_path / "mixed"
    mixed.mkdir()
    for source in (cmu07 / "07.asf", cmu07 / "07_01.amc", cmu09 / "09.asf", cmu09 / "09_01.amc"):
        (mixed / source.name).symlink_to(source)
    with pytest.warns(UserWarning, match=r"2 different skeletons; each AMC paired with the .asf whose name begins "
                                         r"its own: 07.asf \(1 clip\), 09.asf \(1 clip\)"):
        summary = mocapzip.compress(mixed, tmp_path / "b.mcz")
    assert summary["clips"] == 2
    with mocapzip.open(tmp_path / "b.mcz") as archive:
        assert {clip.path: clip.skeleton.path for clip in archive} == {"07_01.amc": "07.asf", "09_01.amc": "09.asf"}

    for name in ("walk.amc", "070_01.amc"):  # no skeleton's name begins it (up to a boundary)
        (mixed / name).symlink_to(cmu07 / "07_02.amc")
        result = runner.invoke(main, ["compress", str(mixed), "-o", str(tmp_path / "c.mcz"), "-q"])
        assert result.exit_code == 1 and f"{name}: ambiguous skeleton: 2 different skeletons" in result.output
        (mixed / name).unlink()
