"""`--model tensor` (seed 002's tensor model, mocapzip.ratecontrol.tensor) on real clips: Bandai walks,
two styles x two takes. The model pays on none of the shared data (docs/seed_methods.md), so the tests
that need a tensor class force it (`tensor._pays`); the others check that it falls back."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from mocapzip.archive import Archive
from mocapzip.cli.main import main
from mocapzip.formats.bvh import read_bvh
from mocapzip.formats.mcz import FORMAT_VERSION
from mocapzip.ratecontrol import tensor
from test_bvh_pipeline import errors_cm, linked
from test_reference_decoder import check_against_package

WALKS = [f"dataset-1_walk_{style}_{take}.bvh" for style in ("active", "angry") for take in ("001", "002")]
MODES = r"_(?P<style>[a-z]+)_(?P<take>[0-9]+)[.]bvh$"


def compress(inputs, out, *options):
    return CliRunner().invoke(main, ["compress", str(inputs), "-o", str(out), "-q", "-j", "1", *options])


@pytest.fixture(scope="module")
def forced(shared_data, tmp_path_factory):
    """(inputs, archive) of the four walks with their class forced to a tensor model."""
    root = tmp_path_factory.mktemp("tensor")
    inputs = linked(root / "in", *(shared_data / "bvh-bandai" / name for name in WALKS))
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(tensor, "_pays", lambda tensor_bytes, best_bytes: True)
        result = compress(inputs, root / "db.mcz", "--model", "tensor", "--modes", MODES, "-e", "1")
    assert result.exit_code == 0, result.output
    return inputs, root / "db.mcz"


def test_a_tensor_class_comes_back_within_its_bounds_end_to_end(forced, tmp_path):
    inputs, archive = forced
    with Archive(archive) as opened:
        (row,) = opened.meta["classes"]
        assert row["model"] == "tensor" and row["modes"] == ["style", "take"]
        assert row["levels"] == [["active", "angry"], ["001", "002"]]
        assert {tuple(clip["tensor_at"]) for clip in opened.clips} == {(0, 0), (0, 1), (1, 0), (1, 1)}
        assert {name.split("/")[0] for name in opened.stream_sizes()} >= {"tensor", "warp"}
        stored = {clip["path"]: (clip["error_cm"], clip["max_error_cm"]) for clip in opened.clips}
    assert CliRunner().invoke(main, ["decompress", str(archive), "-o", str(tmp_path / "out"), "-q"]).exit_code == 0
    for name in WALKS:
        distances = errors_cm(read_bvh(inputs / name), read_bvh(tmp_path / "out" / name))
        points = distances.shape[1] - 1  # the extra root, exact, is a point of the file but not of the body
        assert distances.sum() / (distances.shape[0] * points) <= stored[name][0] + 1e-3 <= 1.0 + 1e-3
        assert distances.max() <= stored[name][1] + 1e-3 <= 10.0 + 1e-3


def test_the_reference_decoder_decodes_a_tensor_class_as_mcz_does(forced, tmp_path):
    check_against_package(forced[1], tmp_path)


def test_the_prediction_is_what_the_clip_streams_leave_out(forced):
    """Decoded without its prediction, a clip is far off: the streams code only what the model misses."""
    with Archive(forced[1]) as opened:
        full = opened.decode(0).values
        opened._prediction = lambda row, moves, width: np.zeros((row["frames"], width))
        assert np.abs(opened.decode(0).values - full).max() > 5


def test_where_the_model_does_not_pay_or_no_grid_is_filled_the_class_is_pca(shared_data, tmp_path):
    inputs = linked(tmp_path / "in", *(shared_data / "bvh-bandai" / name for name in WALKS))
    runs = {"pays not": MODES, "no grid": r"_(?P<style>[a-z]+)_001[.]bvh$"}  # the takes 002 match nothing
    for label, modes in runs.items():
        assert compress(inputs, tmp_path / f"{label}.mcz", "--model", "tensor", "--modes", modes).exit_code == 0
        with Archive(tmp_path / f"{label}.mcz") as opened:
            assert [row["model"] for row in opened.meta["classes"]] == ["pca"], label
            assert not any(name.startswith(("tensor/", "warp/")) for name in opened.stream_sizes())
            assert not any("tensor_at" in clip for clip in opened.clips)
        shown = CliRunner().invoke(main, ["info", str(tmp_path / f"{label}.mcz")]).output
        assert "PCA (no tensor" in shown
    plain = compress(inputs, tmp_path / "plain.mcz")
    assert plain.exit_code == 0
    with Archive(tmp_path / "plain.mcz") as opened:  # without --model tensor, meta says nothing of models
        assert "model" not in opened.meta["settings"] and "model" not in opened.meta["classes"][0]
    info = json.loads(CliRunner().invoke(main, ["info", "--json", str(tmp_path / "plain.mcz")]).output)
    assert info["format_version"] == FORMAT_VERSION  # the newest: written as ever, a model or not


@pytest.mark.parametrize("options, problem", [
    (["--model", "tensor"], "--model tensor needs --modes"),
    (["--modes", MODES], "--modes is for --model tensor"),
    (["--model", "tensor", "--modes", "_([a-z]+)_"], "names 0 groups"),
    (["--model", "tensor", "--modes", "(?P<a>["], "not a regular expression"),
    (["--model", "tensor", "--modes", MODES, "--segment"], "does not combine with --segment"),
    (["--model", "tensor", "--modes", MODES, "--lossless"], "no meaning with --lossless"),
])
def test_tensor_options_that_make_no_sense_are_refused_in_one_line(shared_data, tmp_path, options, problem):
    result = compress(shared_data / "bvh-bandai" / WALKS[0], tmp_path / "db.mcz", *options)
    assert result.exit_code == 2 and problem in result.output
    assert not (tmp_path / "db.mcz").exists()


def test_the_python_api_takes_the_model_as_the_command_line_does(forced, tmp_path):
    import mocapzip
    from mocapzip.archive import SettingsError

    inputs = forced[0]
    summary = mocapzip.compress(inputs, tmp_path / "db.mcz", model="tensor", modes=MODES)
    assert summary["clips"] == 4 and summary["largest_mean_error_cm"] <= 1.0
    with pytest.raises(SettingsError, match="needs --modes"):
        mocapzip.compress(inputs, tmp_path / "no.mcz", model="tensor")
    with mocapzip.open(forced[1]) as archive:  # a tensor class's clips read as any other
        assert archive[WALKS[0]].channels.shape[0] == read_bvh(inputs / WALKS[0]).n_frames


def test_a_class_too_large_for_a_tensor_stays_pca(shared_data, tmp_path, monkeypatch):
    inputs = linked(tmp_path / "in", *(shared_data / "bvh-bandai" / name for name in WALKS))
    monkeypatch.setattr(tensor, "_pays", lambda tensor_bytes, best_bytes: True)
    monkeypatch.setattr(tensor, "MAX_TENSOR_VALUES", 1000)
    assert compress(inputs, tmp_path / "db.mcz", "--model", "tensor", "--modes", MODES).exit_code == 0
    with Archive(tmp_path / "db.mcz") as opened:
        assert [row["model"] for row in opened.meta["classes"]] == ["pca"]
