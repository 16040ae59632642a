"""ACL's error metric in the archive (format 13): every lossy row stores its worst shell vertex,
and `--max-vertex-error` bounds every vertex of every frame. Checked against the source files
by the API's own scoring (`Clip.shell_error`: numpy forward kinematics of the decoded clip), not
by the encoder's compiled kernel that chose the patches."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import mocapzip
from mocapzip.archive import Archive
from mocapzip.cli.main import main

GOLDEN = Path(__file__).parent / "golden"


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def worst_vertices(archive, folder, shell_cm: float) -> dict[str, tuple[float, float]]:
    """{path: (worst vertex measured against the source in `folder`, the row's max_vertex_error_cm)}."""
    out = {}
    with mocapzip.open(archive) as opened, Archive(archive) as rows:
        for row in rows.clips:
            clip = opened[row["path"]]
            measured = clip.shell_error(folder / row["path"], shell_cm=shell_cm).worst
            assert clip.error.vertex_cm == row["max_vertex_error_cm"]  # the API reports what the row stores
            out[row["path"]] = (measured, row["max_vertex_error_cm"])
    return out


@pytest.mark.parametrize("inputs, bound", [("cmu/09", 2.0), ("bvh-bandai/dataset-1_walk_normal_001.bvh", 1.5)])
def test_every_vertex_of_every_frame_within_the_bound(shared_data, tmp_path, inputs, bound):
    source = shared_data / inputs
    folder = source if source.is_dir() else source.parent
    plain, bounded = tmp_path / "plain.mcz", tmp_path / "bounded.mcz"
    assert run("compress", source, "-o", plain, "-q", "-j", "1").exit_code == 0
    result = run("compress", source, "-o", bounded, "-q", "-j", "1", "--max-vertex-error", bound)
    assert result.exit_code == 0, result.output
    before = worst_vertices(plain, folder, 3.0)
    after = worst_vertices(bounded, folder, 3.0)
    assert max(measured for measured, _ in before.values()) > bound  # the bound had work to do
    for path, (measured, stored) in {**before, **after}.items():
        assert measured <= stored <= measured + 2e-6, path  # the row tells what the file achieves, rounded up
    assert all(measured <= bound for measured, _ in after.values())
    with Archive(bounded) as opened:
        assert opened.meta["settings"]["vertex_error_cm"] == bound and "shell_cm" not in opened.meta["settings"]
        assert any(row.get("patched_frames") for row in opened.clips)
        assert all(row["error_cm"] <= 1.0 for row in opened.clips)  # the mean target still holds
    assert f"every vertex <= {bound} cm" in run("info", bounded).output


def test_a_shell_of_0_cm_sees_the_joints(shared_data, tmp_path):
    """With no shell the vertices are the bones' origins, which are every joint: the worst vertex
    is the worst joint, and a vertex bound is a joint bound."""
    archive = tmp_path / "joints.mcz"
    result = run("compress", shared_data / "cmu" / "09" / "09_01.amc", "-o", archive, "-q", "--shell-cm", "0",
                 "--max-vertex-error", "3", "--max-error", "none")
    assert result.exit_code == 0, result.output
    with Archive(archive) as opened:
        row = opened.clips[0]
        assert opened.meta["settings"]["shell_cm"] == 0
        assert row["max_vertex_error_cm"] == row["max_error_cm"] <= 3.0 and row.get("patched_frames")


def test_info_shows_the_worst_vertex_and_old_archives_have_none(shared_data, tmp_path):
    archive = tmp_path / "09.mcz"
    assert run("compress", shared_data / "cmu" / "09" / "09_01.amc", "-o", archive, "-q").exit_code == 0
    info = run("info", archive)
    assert info.exit_code == 0 and "worst vertex" in info.output and "vertex cm" in info.output
    old = run("info", GOLDEN / "lossy_v12.mcz")
    assert old.exit_code == 0 and "worst vertex" not in old.output
    assert all(line.split()[-2] == "-" for line in old.output.splitlines() if line.startswith("09_01.amc"))


@pytest.mark.parametrize("args, message", [
    (["--max-vertex-error", "0"], "--max-vertex-error"),
    (["--max-vertex-error", "-2"], "--max-vertex-error"),
    (["--shell-cm", "-1"], "--shell-cm"),
    (["--max-vertex-error", "2", "--lossless"], "--max-vertex-error"),
    (["--shell-cm", "2", "--lossless"], "--shell-cm"),
])
def test_vertex_usage_errors(shared_data, tmp_path, args, message):
    result = run("compress", shared_data / "cmu" / "09" / "09_01.amc", "-o", tmp_path / "x.mcz", *args)
    assert result.exit_code == 2 and message in result.output
    assert not (tmp_path / "x.mcz").exists()


def test_compiled_shell_distances_match_the_metric(shared_data):
    """The encoder's kernel (`ChannelTables.shell_distances`) is `metrics.shell_errors` exactly."""
    from mocapzip.inputs.clip import ClipReader
    from mocapzip.inputs.discover import find_clips
    from mocapzip.motion.kinematics import forward
    from mocapzip.motion.metrics import shell_errors

    sources = find_clips([shared_data / "cmu" / "09" / "09_01.amc", shared_data / "bvh-bandai" /
                          "dataset-1_walk_normal_001.bvh"])
    rng = np.random.default_rng(7)
    for source in sources:
        clip = ClipReader("aligned", 12.0).read(source)
        values = clip.motion.values
        noisy = values + rng.normal(0.0, 0.5, values.shape)
        expected = shell_errors(clip.model, forward(clip.model, values, clip.layout),
                                forward(clip.model, noisy, clip.layout), 2.0).errors
        np.testing.assert_allclose(clip.decode_tail.shell_distances(noisy, values, 2.0), expected, atol=1e-9)
