"""`mcz bench` end to end on two short real clips: report structure and consistency of its numbers."""

from __future__ import annotations

import csv
import io
import json
import lzma
import os

import pytest
from click.testing import CliRunner

from mocapzip.cli.bench import bench

TARGET = 1.0


@pytest.fixture(scope="module")
def clips(shared_data):
    folder = shared_data / "cmu" / "07"
    return [folder / "07_01.amc", folder / "07_02.amc"]  # two walks, 316 and 329 frames


@pytest.fixture(scope="module")
def report(clips, tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    args = [*map(str, clips), "--error", str(TARGET), "--codec", "mcz,hou,hou-shared,xz", "-j", "1",
            "--json", str(out / "report.json"), "--csv", str(out / "report.csv")]
    result = CliRunner().invoke(bench, args)
    assert result.exit_code == 0, result.output
    data = json.loads((out / "report.json").read_text())
    data["_csv"] = (out / "report.csv").read_text()
    data["_stdout"] = result.output
    return data


def run_of(report, codec):
    return next(r for r in report["runs"] if r["codec"] == codec)


def test_structure(report, clips):
    assert [c["path"] for c in report["clips"]] == ["07_01.amc", "07_02.amc"]
    assert {c["group"] for c in report["clips"]} == {"walk"}  # MANIFEST.tsv's class column, found above the inputs
    assert [r["codec"] for r in report["runs"]] == ["mcz", "xz", "hou", "hou-shared"]
    for run in report["runs"]:
        assert set(run) >= {"label", "target_error_cm", "overall", "classes", "clips", "error_measured_on"}
        assert list(run["classes"]) == ["walk"]
        assert [c["path"] for c in run["clips"]] == ["07_01.amc", "07_02.amc"]
        for row in [run["overall"], *run["clips"]]:
            for key in ("frames", "bytes", "payload_bytes", "bytes_per_frame", "ratio_amc", "ratio_f32_channels",
                        "ratio_f32_positions", "mean_error_cm", "p99_error_cm", "max_error_cm"):
                assert row[key] >= 0, key
            assert row["bytes"] > 0 and row["payload_bytes"] > 0
    assert report["git"] is None or len(report["git"]["commit"]) == 40
    assert "measured" in report["rules"]


def test_mcz_sizes_add_up_to_the_archive(report, clips):
    run = run_of(report, "mcz")
    assert sum(c["bytes"] for c in run["clips"]) == pytest.approx(run["archive_bytes"])
    assert run["overall"]["bytes"] == pytest.approx(run["archive_bytes"])
    for row, path in zip(run["clips"], clips):
        amc = os.path.getsize(path)
        assert row["ratio_amc"] == pytest.approx(amc / row["bytes"])
        assert row["bytes_per_frame"] == pytest.approx(row["bytes"] / row["frames"])
        assert row["ratio_f32_positions"] == pytest.approx(row["frames"] * 31 * 3 * 4 / row["bytes"])
        assert row["ratio_f32_channels"] == pytest.approx(row["frames"] * 62 * 4 / row["bytes"])
        assert row["payload_bytes"] < row["bytes"]  # plus its share of meta, skeleton and class basis
        assert row["pose_bytes"] + row["root_bytes"] == row["payload_bytes"]
    assert run["overall"]["ratio_amc"] == pytest.approx(sum(map(os.path.getsize, clips)) / run["archive_bytes"])


def test_mcz_fixed_costs_are_the_archive_less_its_clips(report):
    """The fixed costs (skeletons, bases, meta, priors, container) and the clip streams make the whole file."""
    run = run_of(report, "mcz")
    fixed = run["fixed_bytes"]
    assert set(fixed) == {"skeletons", "bases", "meta", "priors", "container"}
    assert fixed["skeletons"] > 0 and fixed["meta"] > 0 and fixed["container"] > 0
    assert fixed["bases"] == run["class_bytes"]
    patches = run["shared_bytes"] - sum(fixed.values()) + fixed["bases"]  # shared: all but clips and bases
    assert patches >= 0
    assert sum(fixed.values()) + sum(c["payload_bytes"] for c in run["clips"]) + patches == run["archive_bytes"]
    assert "fixed costs: skeletons" in report["_stdout"]


def test_mcz_keeps_its_error_promise_end_to_end(report):
    run = run_of(report, "mcz")
    assert "read back" in run["error_measured_on"]
    for row in run["clips"]:
        assert 0 < row["mean_error_cm"] <= TARGET
        assert row["mean_error_cm"] <= row["p99_error_cm"] <= row["max_error_cm"]
        assert row["skin_error"] > 0
        assert row["mean_error_cm"] == pytest.approx(row["codec_reported_error_cm"], rel=1e-3)
        assert row["max_error_cm"] <= 5 * TARGET  # compress's default bound on every joint, 5 x -e
        assert row["contact_frames"] > 0 and row["foot_skate_cm_s"] > 0  # walks: planted feet slide a little
    o = run["overall"]
    assert o["encode_fps"] > 0 and o["decode_fps"] > 0 and o["encode_peak_rss_mb"] > 10
    frames = [r["frames"] for r in run["clips"]]
    expected = sum(r["mean_error_cm"] * f for r, f in zip(run["clips"], frames)) / sum(frames)
    assert o["mean_error_cm"] == pytest.approx(expected)
    contact = [r["contact_frames"] for r in run["clips"]]  # foot skate: weighed by each clip's planted frames
    skate = sum(r["foot_skate_cm_s"] * c for r, c in zip(run["clips"], contact)) / sum(contact)
    assert o["foot_skate_cm_s"] == pytest.approx(skate)
    assert "every joint <= 5 cm" in run["label"]


def test_mcz_reports_the_worst_vertex_by_acls_metric(report):
    assert report["shell_cm"] == 3.0
    run = run_of(report, "mcz")
    for row in run["clips"]:
        # vertices 3 cm off every bone: a turn of the bone moves them, so the worst is above 0, and no
        # vertex moves more than its frame's origin (a joint) plus the 6 cm a half turn carries it
        assert 0 < row["shell_error_cm"] <= row["max_error_cm"] + 6
        assert isinstance(row["shell_worst_bone"], str)
    assert run["overall"]["shell_error_cm"] == max(r["shell_error_cm"] for r in run["clips"])
    assert run["classes"]["walk"]["shell_error_cm"] == run["overall"]["shell_error_cm"]
    assert run_of(report, "xz")["overall"]["shell_error_cm"] == 0
    assert run_of(report, "hou")["overall"]["shell_error_cm"] is None  # positions only: no bone turns to see
    assert "vertex: worst vertex, cm (ACL's metric, 3 cm shell)" in report["_stdout"]
    rows = list(csv.DictReader(io.StringIO(report["_csv"])))
    assert float(next(r for r in rows if r["codec"] == "mcz")["shell_error_cm"]) > 0


def test_xz_is_lossless_and_its_bytes_are_xz_minus_9(report, clips, shared_data):
    run = run_of(report, "xz")
    skeleton = lzma.compress((shared_data / "cmu" / "07" / "07.asf").read_bytes(), preset=9)
    frames = sum(r["frames"] for r in run["clips"])
    for row, path in zip(run["clips"], clips):
        assert row["payload_bytes"] == len(lzma.compress(path.read_bytes(), preset=9))
        assert row["bytes"] == pytest.approx(row["payload_bytes"] + len(skeleton) * row["frames"] / frames)
        assert row["mean_error_cm"] == 0 and row["max_error_cm"] == 0 and row["foot_skate_cm_s"] == 0


@pytest.mark.parametrize("codec", ["hou", "hou-shared"])
def test_hou_meets_the_target_on_positions(report, codec):
    run = run_of(report, codec)
    assert run["target_error_cm"] == TARGET
    assert "positions" in run["error_measured_on"]
    for row in run["clips"]:
        assert row["mean_error_cm"] <= TARGET
        assert row["skin_error"] is None and row["foot_skate_cm_s"] > 0
        assert set(row["hou"]) == {"L", "k", "Q"}
    if codec == "hou-shared":  # one basis for the subject: same L and k, bytes = own stream + basis share
        assert len({(r["hou"]["L"], r["hou"]["k"]) for r in run["clips"]}) == 1
        for row in run["clips"]:
            assert row["bytes"] == pytest.approx(row["payload_bytes"] + row["basis_bytes"])


def test_comparisons(report):
    (entry,) = report["comparisons"]
    mcz, hou = run_of(report, "mcz"), run_of(report, "hou")
    ratios = sorted(m["bytes"] / h["bytes"] for m, h in zip(mcz["clips"], hou["clips"]))
    assert entry["mcz_over_hou_bytes"]["median"] == pytest.approx(sum(ratios) / 2)
    assert entry["mcz_over_hou_bytes"]["worst"] == pytest.approx(ratios[-1])
    assert entry["mcz_over_hou_shared_bytes"]["clips"] == 2
    xz = run_of(report, "xz")
    assert entry["vs_xz"]["bytes"] == pytest.approx(mcz["overall"]["bytes"] / xz["overall"]["bytes"])
    assert entry["vs_xz"]["encode_speed"] == pytest.approx(mcz["overall"]["encode_fps"] / xz["overall"]["encode_fps"])


def test_csv_and_text(report):
    rows = list(csv.DictReader(io.StringIO(report["_csv"])))
    assert {r["level"] for r in rows} == {"overall", "class", "clip"}
    assert len(rows) == 4 * (1 + 1 + 2)  # four runs: overall, one class, two clips
    assert "overall" in report["_stdout"] and "mcz bytes / Hou bytes" in report["_stdout"]


def test_no_pca_emulation_and_split(clips, tmp_path):
    out = tmp_path / "r.json"
    result = CliRunner().invoke(bench, [str(clips[0]), "-e", "1", "-r", "channels", "-c", "none", "--split", "0,0,1",
                                        "--codec", "mcz", "--shell-cm", "0", "--json", str(out), "-q"])
    assert result.exit_code == 0, result.output
    (run,) = json.loads(out.read_text())["runs"]
    assert run["settings"]["classes"] == "none" and run["settings"]["split"] == [0, 0, 1]
    assert run["archive_bytes"] is None
    (row,) = run["clips"]
    assert 0 < row["mean_error_cm"] <= 1.0
    assert row["bytes"] == row["payload_bytes"] == row["pose_bytes"]  # channels: no separate root track
    # at no shell distance the vertices are the bones' origins, and every joint is one: the worst joint
    assert row["shell_error_cm"] == pytest.approx(row["max_error_cm"], rel=1e-12)


def test_bad_options(clips):
    runner = CliRunner()
    result = runner.invoke(bench, [str(clips[0]), "--codec", "gzip"])
    assert result.exit_code == 2 and "gzip" in result.output
    result = runner.invoke(bench, [str(clips[0]), "--split", "1,2"])
    assert result.exit_code == 2
    result = runner.invoke(bench, ["/nonexistent/clip.amc", "--codec", "xz"])
    assert result.exit_code == 1
