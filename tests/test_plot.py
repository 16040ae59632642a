"""`mcz plot` and `mcz view` (issue 43, "Pictures"): the files they write from real clips, and how they fail."""

from __future__ import annotations

import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

import mocapzip
from mocapzip import plots
from mocapzip.bench.report import series_name
from mocapzip.bench.runner import BenchOptions, _mcz_label
from mocapzip.cli.main import main

BANDAI_CLIP = "dataset-1_bow_active_001.bvh"


def run(*args):
    return CliRunner().invoke(main, [os.fspath(a) for a in args])


@pytest.fixture(scope="module")
def archives(shared_data, tmp_path_factory):
    """A CMU clip (ASF/AMC, 120 fps) and a Bandai clip (BVH, 30 fps), each in an archive, and the folders they came from."""
    folder = tmp_path_factory.mktemp("archives")
    cmu, bandai = shared_data / "cmu" / "09", shared_data / "bvh-bandai"
    mocapzip.compress([cmu / "09.asf", cmu / "09_01.amc"], folder / "cmu.mcz", jobs=1, progress=False)
    mocapzip.compress([bandai / BANDAI_CLIP], folder / "bandai.mcz", error=0.5, jobs=1, progress=False)
    return {"cmu": (folder / "cmu.mcz", cmu), "bandai": (folder / "bandai.mcz", bandai)}


@pytest.mark.parametrize("name", ["cmu", "bandai"])
def test_the_errors_measured_against_the_source_are_the_ones_compress_measured(archives, name):
    """Source and decoded joints line up (same joints, same frames): their mean distance is the
    clip's mean error that compress measured and stored. For BVH, compress measures on its model's
    joints (docs/bvh.md), the API's positions are the file's joints and End Sites: close, not equal."""
    archive, folder = archives[name]
    with mocapzip.open(archive) as opened:
        clip = opened[0]
        errors = plots.joint_errors(clip, folder)
        assert errors.shape == (clip.frames, len(clip.joint_names))
        assert errors.mean() == pytest.approx(clip.error.mean_cm, rel=1e-3 if name == "cmu" else 0.1)
        if name == "cmu":
            assert errors.max() == pytest.approx(clip.error.max_cm, rel=1e-3)


def png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


@pytest.mark.parametrize("name, kind, size", [("cmu", "time", (800, 360)), ("bandai", "time", (800, 360)),
                                              ("cmu", "vertex", (800, 360))])
def test_plot_writes_a_png_of_error_over_time(archives, tmp_path, name, kind, size):
    archive, folder = archives[name]
    out = tmp_path / "errors.png"
    result = run("plot", archive, "--against", folder, "-o", out, "--kind", kind, "-q")
    assert result.exit_code == 0, result.stderr
    assert png_size(out.read_bytes()) == size  # 8 x 3.6 inches at 100 dpi


def test_plot_joints_writes_an_svg_with_every_joint_named(archives, tmp_path):
    archive, folder = archives["bandai"]
    out = tmp_path / "joints.svg"
    result = run("plot", archive, "--against", folder, "--clip", "*bow*", "-o", out, "--kind", "joints")
    assert result.exit_code == 0, result.stderr
    assert result.stderr == f"1 clip -> {out}\n"
    svg = out.read_text()
    assert svg.startswith("<?xml") and "<svg" in svg
    with mocapzip.open(archive) as opened:
        names = opened[0].joint_names
    assert all(f"<!-- {name} -->" in svg for name in names)  # matplotlib names each text it draws as paths


def test_view_writes_a_gif_at_the_fps_asked(archives, tmp_path):
    archive, folder = archives["cmu"]
    out = tmp_path / "view.gif"
    result = run("view", archive, "09_01.amc", "--against", folder, "-o", out)
    assert result.exit_code == 0, result.stderr
    from PIL import Image

    with mocapzip.open(archive) as opened:
        frames = opened[0].frames  # at 120 fps: every 4th frame drawn, at 30
    with Image.open(out) as gif:
        assert gif.format == "GIF" and gif.n_frames == -(-frames // 4)
    assert result.stderr == f"{-(-frames // 4)} frames drawn of {frames} -> {out}\n"


def test_view_without_the_source_caps_its_frames(archives, tmp_path):
    archive, _ = archives["cmu"]
    out = tmp_path / "view.gif"
    result = run("view", archive, "09_01", "-o", out, "--frames", "8:40", "--fps", "120", "--max-frames", "5")
    assert result.exit_code == 1 and result.stderr.startswith("mcz: error: no clip '09_01' in")  # a file name, whole
    result = run("view", archive, "09_01.amc", "-o", out, "--frames", "8:40", "--fps", "120", "--max-frames", "5")
    assert result.exit_code == 0, result.stderr
    from PIL import Image

    with Image.open(out) as gif:
        assert gif.n_frames == 5
    assert result.stderr == f"5 frames drawn of 32 -> {out}\n"


def test_view_html_is_one_page_that_loads_nothing_from_elsewhere(archives, tmp_path):
    archive, folder = archives["bandai"]
    out = tmp_path / "view.html"
    result = run("view", archive, BANDAI_CLIP, "--against", folder, "-o", out, "--overlay", "--max-frames", "12")
    assert result.exit_code == 0, result.stderr
    html = out.read_text()
    assert html.startswith("<!DOCTYPE html>") and html.rstrip().endswith("</html>")
    assert html.count("data:image/png;base64,") == 12
    assert "://" not in html and "<link" not in html and 'class="fa' not in html


@pytest.mark.parametrize("command", [["plot", "--kind", "joints"], ["view", "09_01.amc"]])
def test_without_matplotlib_a_usage_line_names_the_extra(archives, tmp_path, monkeypatch, command):
    archive, folder = archives["cmu"]
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # `import matplotlib` raises ImportError
    out = tmp_path / ("out.png" if command[0] == "plot" else "out.gif")
    result = run(command[0], archive, *command[1:], "--against", folder, "-o", out)
    assert result.exit_code == 2
    assert result.stderr == (f"mcz {command[0]}: {command[0]} needs matplotlib: pip install 'mocapzip[plot]' "
                             f"(see mcz {command[0]} --help)\n")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command, out, said", [
    (["plot"], "out.jpg", "mcz plot: Invalid value for '-o' / '--output': '{out}': plot writes .png or .svg files "
                          "(the suffix says which) (see mcz plot --help)"),
    (["view", "09_01.amc"], "out.png", "mcz view: Invalid value for '-o' / '--output': '{out}': view writes .gif, "
                                       ".mp4 or .html files (the suffix says which) (see mcz view --help)"),
    (["view", "09_01.amc"], "out.mp4", "mcz view: an .mp4 needs ffmpeg, which is not on PATH: install it, or write "
                                       ".gif or .html (see mcz view --help)"),
])
def test_a_file_it_cannot_write_is_a_usage_line(archives, tmp_path, monkeypatch, command, out, said):
    archive, folder = archives["cmu"]
    monkeypatch.setattr(plots, "ffmpeg_available", lambda: False)  # whether or not this machine has it
    out = tmp_path / out
    result = run(command[0], archive, *command[1:], "--against", folder, "-o", out)
    assert result.exit_code == 2
    assert result.stderr == said.format(out=out) + "\n"
    assert list(tmp_path.iterdir()) == []


def test_a_failure_writes_nothing(archives, tmp_path, shared_data):
    """A source folder without the clip's file, no clip matching --clip, an output there already: one line, exit 1."""
    archive, _ = archives["cmu"]
    out = tmp_path / "out.png"
    elsewhere = shared_data / "cmu" / "07"
    result = run("plot", archive, "--against", elsewhere, "-o", out)
    assert result.exit_code == 1 and result.stderr == f"mcz: error: {elsewhere / '09_01.amc'}: No such file or directory\n"
    result = run("plot", archive, "--against", shared_data / "cmu" / "09", "-o", out, "--clip", "10_*")
    assert result.exit_code == 1 and result.stderr == f"mcz: error: {archive}: no clip matches 10_*\n"
    assert list(tmp_path.iterdir()) == []
    out = out.with_suffix(".gif")
    out.write_bytes(b"mine")
    result = run("view", archive, "09_01.amc", "-o", out)
    assert result.exit_code == 1 and result.stderr == f"mcz: error: {out}: already exists (use -f/--force to overwrite)\n"
    assert list(tmp_path.iterdir()) == [out] and out.read_bytes() == b"mine"


def test_a_ratio_distortion_sweep_joins_its_error_targets_into_one_curve():
    """`mcz bench -e 1 -e 0.5 --plot`: each target's bound on every joint (5 x -e) was part of the
    curve's name, so every point was a curve of its own."""
    options = BenchOptions(inputs=[])
    task = {"representation": "aligned", "transform": "dct", "classes": "pooled", "split": None}
    runs = [{"codec": "mcz", "label": _mcz_label({**task, "error_cm": e}, options)} for e in (1.0, 0.5)]
    assert runs[0]["label"] != runs[1]["label"]
    assert series_name(runs[0]) == series_name(runs[1]) == "mcz, aligned, dct, classes pooled"
    other = {"codec": "mcz", "label": _mcz_label({**task, "error_cm": 1.0, "transform": "dwt"}, options)}
    assert series_name(other) != series_name(runs[0])


def test_mcz_help_lists_plot_and_view():
    result = run("--help")
    assert result.exit_code == 0
    listed = {line.split()[0] for line in result.stdout.splitlines() if line.startswith("  ") and line.split()}
    assert {"plot", "view"} <= listed


def test_the_command_line_does_not_import_matplotlib_until_asked():
    """The `plot` extra is optional: `mcz` and every other command start without it."""
    code = "import sys; from mocapzip.cli.main import main; import mocapzip.plots; print('matplotlib' in sys.modules)"
    found = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                           env={**os.environ, "PYTHONPATH": os.fspath(Path(plots.__file__).parents[1])})
    assert found.stdout == "False\n"
