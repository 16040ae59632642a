"""`--max-error`: every joint of every frame of every clip comes back within the bound, checked on
the AMC files `mcz decompress` writes, read back by the project's reader and run through its
(numpy) forward kinematics, not on the codec's own estimate."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mocapzip.archive import Archive
from mocapzip.cli.main import main
from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def joint_errors(source: Path, written: Path, asf: Path) -> np.ndarray:
    """(frames, joints) cm between the source AMC's joints and the written one's."""
    model = SkeletonModel.from_asf(read_asf(asf))
    with warnings.catch_warnings():  # a source cut short mid-frame (64/golf_01): its last frame dropped, as compress did
        warnings.simplefilter("ignore", UserWarning)
        a = read_amc(source)
    b = read_amc(written)
    return np.linalg.norm(forward(model, a.values, a).positions - forward(model, b.values, b).positions, axis=-1)


def check_within(archive: Path, out: Path, inputs: Path, bound: float, mean_bound: float) -> int:
    """Every clip of `archive`, as decompressed into `out`, against its source under `inputs`;
    returns the number of patched frames."""
    patched = 0
    with Archive(archive) as opened:
        assert opened.settings.max_error_cm == bound
        for row in opened.clips:
            source = inputs / row["path"]
            asf = next(source.parent.glob("*.asf"))
            errors = joint_errors(source, out / row["path"], asf)
            assert errors.max() <= bound, row["path"]
            assert errors.mean() <= mean_bound + 1e-9, row["path"]
            # what the row reports is what the written file achieves
            assert errors.max() == pytest.approx(row["max_error_cm"], abs=1e-6), row["path"]
            assert errors.mean() == pytest.approx(row["error_cm"], abs=1e-6), row["path"]
            assert np.percentile(errors, 99) == pytest.approx(row["p99_error_cm"], abs=6e-5), row["path"]  # 4 decimals
            patched += row.get("patched_frames", 0)
    return patched


def test_a_clip_with_a_source_glitch_comes_back_within_the_bound(shared_data, tmp_path):
    """01_06 flips rfemur ry to about 177 degrees and back for a few frames. By default the bound
    holds against the source as written: the glitch comes back."""
    folder = shared_data / "cmu" / "01"
    archive, out = tmp_path / "glitch.mcz", tmp_path / "out"
    assert run("compress", folder / "01_06.amc", "-o", archive, "-q", "-e", "1", "--max-error", "3").exit_code == 0
    assert run("decompress", archive, "-o", out, "-q").exit_code == 0
    assert check_within(archive, out, folder, 3.0, 1.0) > 0
    source, written = read_amc(folder / "01_06.amc"), read_amc(out / "01_06.amc")
    column = int(np.sum(source.counts[: source.bones.index("rfemur")])) + 1  # rfemur's ry
    ry = source.values[:, column], written.values[:, column]
    flipped = np.abs(ry[0] - np.median(ry[0])) > 90
    assert 0 < flipped.sum() < 20
    # the flip, kept: its joints are within the bound (above), so its angle is near the source's,
    # not the clip's usual one (a patch takes the least change, not the source's value)
    assert np.all(np.abs(ry[1][flipped] - np.median(ry[0])) > 90)
    np.testing.assert_allclose(ry[1][flipped], ry[0][flipped], atol=10.0)


@pytest.mark.parametrize("error, bound", [("1", 5.0), ("0.5", 2.5)])
def test_the_default_bound_is_five_times_the_mean_target(shared_data, tmp_path, error, bound):
    archive = tmp_path / "default.mcz"
    assert run("compress", shared_data / "cmu" / "07" / "07_01.amc", "-o", archive, "-q", "-e", error).exit_code == 0
    with Archive(archive) as opened:
        assert opened.settings.max_error_cm == bound and opened.meta["settings"]["max_error_cm"] == bound
        assert opened.clips[0]["max_error_cm"] <= bound
    assert f"every joint <= {bound} cm" in run("info", archive).output


def test_max_error_none_stores_no_bound_and_no_patches(shared_data, tmp_path):
    archive = tmp_path / "plain.mcz"
    result = run("compress", shared_data / "cmu" / "07" / "07_01.amc", "-o", archive, "-q", "--max-error", "none")
    assert result.exit_code == 0
    with Archive(archive) as opened:
        assert opened.settings.max_error_cm is None and "max_error_cm" not in opened.meta["settings"]
        row = opened.clips[0]
        assert "patched_frames" not in row and row["error_cm"] < row["p99_error_cm"] < row["max_error_cm"]
    info = run("info", archive)
    assert info.exit_code == 0 and "p99 cm" in info.output and "every joint" not in info.output


@pytest.mark.parametrize("args, message", [
    (["--max-error", "0"], "above 0, or 'none'"),
    (["--max-error", "-1"], "above 0, or 'none'"),
    (["--max-error", "nan"], "above 0, or 'none'"),
    (["--max-error", "2", "--lossless"], "--max-error"),
    (["--max-error", "none", "--lossless"], "--max-error"),
    (["--contact-error", "0"], "above 0, or 'none'"),
    (["--contact-error", "1", "--lossless"], "--contact-error"),
    (["--repair-glitches", "--lossless"], "--repair-glitches"),
])
def test_max_error_usage_errors(shared_data, tmp_path, args, message):
    result = run("compress", shared_data / "cmu" / "07" / "07_01.amc", "-o", tmp_path / "x.mcz", *args)
    assert result.exit_code == 2 and message in result.output
    assert not (tmp_path / "x.mcz").exists()


@pytest.mark.slow
def test_every_joint_of_the_shared_cmu_set_within_3_cm(shared_data, tmp_path):
    """The issue's acceptance run: `mcz compress ../shared/data/cmu -e 1 --max-error 3`, then decompress."""
    folder = shared_data / "cmu"
    archive, out = tmp_path / "cmu.mcz", tmp_path / "out"
    result = run("compress", folder, "-o", archive, "-q", "-e", "1", "--max-error", "3", "-j", "2")
    assert result.exit_code == 0, result.output
    assert run("decompress", archive, "-o", out, "-q", "-j", "2").exit_code == 0
    assert check_within(archive, out, folder, 3.0, 1.0) > 0
    info = run("info", archive)
    assert "every joint <= 3.0 cm" in info.output


def test_repair_glitches_lets_only_the_glitch_past_the_bound(shared_data, tmp_path):
    """--repair-glitches: 01_06's rfemur flip is smoothed over, not patched back. The joints it
    throws off are the only ones past the bound, and the row lists the range with its error."""
    folder = shared_data / "cmu" / "01"
    archive, out = tmp_path / "repaired.mcz", tmp_path / "out"
    result = run("compress", folder / "01_06.amc", "-o", archive, "-e", "1", "--max-error", "2", "--repair-glitches")
    assert result.exit_code == 0 and "repaired in 1 clip" in result.stderr
    assert "jumps and limits smoothed over" in result.stderr and "kept as written, the errors" not in result.stderr
    assert run("decompress", archive, "-o", out, "-q").exit_code == 0
    with Archive(archive) as opened:
        assert opened.meta["settings"]["repair_glitches"] is True
        row = opened.clips[0]
    errors = joint_errors(folder / "01_06.amc", out / "01_06.amc", next(folder.glob("*.asf")))
    source = read_amc(folder / "01_06.amc")
    inside = np.zeros(len(errors), bool)
    for first, last, cm in row["repaired"]:
        frames = (source.frame_numbers >= first) & (source.frame_numbers <= last)
        inside |= frames
        assert cm == pytest.approx(errors[frames].max(), abs=1.1e-3)  # rounded up to 0.001 cm
    assert errors[~inside].max() <= 2.0
    assert errors.mean() <= 1.0 + 1e-9
    flip = [r for r in row["repaired"] if r[0] <= 4756 <= r[1]]
    assert flip and flip[0][2] > 20
    flipped = (source.frame_numbers >= 4756) & (source.frame_numbers <= 4760)
    assert np.all(errors[flipped].max(axis=1) > 20)  # in no frame is the flip brought back
    assert errors.max() == pytest.approx(row["max_error_cm"], abs=1e-6)  # the row's max counts the repaired frames
    assert "4755-4761" in run("info", archive).output


def test_contact_error_holds_planted_feet(shared_data, tmp_path):
    """--contact-error 1: every foot joint the source plants (`motion.contacts`) within 1 cm."""
    from mocapzip.motion.contacts import contacts

    folder = shared_data / "cmu" / "07"
    archive, out = tmp_path / "feet.mcz", tmp_path / "out"
    assert run("compress", folder / "07_01.amc", "-o", archive, "-q", "--contact-error", "1").exit_code == 0
    assert run("decompress", archive, "-o", out, "-q").exit_code == 0
    model = SkeletonModel.from_asf(read_asf(folder / "07.asf"))
    source = read_amc(folder / "07_01.amc")
    planted = contacts(model, forward(model, source.values, source).positions, 120.0)
    assert planted.sum() > 100  # a walk: its feet are down much of the time
    errors = joint_errors(folder / "07_01.amc", out / "07_01.amc", folder / "07.asf")
    assert errors[planted].max() <= 1.0
    assert errors.max() > 1.0 and errors.max() <= 10.0  # the rest: the default bound
    with Archive(archive) as opened:
        assert opened.meta["settings"]["contact_error_cm"] == 1.0 and opened.clips[0]["patched_frames"] > 0
    assert "planted feet <= 1.0 cm" in run("info", archive).output


def test_a_patch_takes_the_least_change_that_puts_the_joints_back(shared_data):
    """A joint's position leaves whole turns, a bone's twist about itself and an Euler triple's
    other branch free, and a patch must not pay for them: on 01_09 (angles stored up to 990
    degrees) decoded values a whole turn off in every rotation channel, and a knee 4 cm off by
    a femur turned 5 degrees, get a correction of the femur (and less than half a degree
    elsewhere) that puts every joint back within 0.05 cm, not the source's values."""
    from mocapzip.codec.patches import channel_steps
    from mocapzip.inputs.clip import load_clips
    from mocapzip.inputs.discover import find_clips
    from mocapzip.ratecontrol.max_error import _chain_channels, _least_corrections

    (clip,) = load_clips(find_clips([shared_data / "cmu" / "01" / "01_09.amc"]), "aligned", 12.0)
    source = clip.motion.values[:40]
    labels = [f"{bone}.{channel}" for bone, count in zip(clip.layout.bones, clip.layout.counts)
              for channel in clip.model.channels[clip.model.index[bone]][:count]]
    rotations = np.array([label.split(".")[1].startswith("r") for label in labels])
    femur = labels.index("rfemur.rx")
    decoded = source + 360.0 * rotations  # a whole turn off: no joint moves
    decoded[:, femur] += 5.0
    tail, original = clip.decode_tail, clip.positions[:40]
    before = tail.joint_distances(decoded, original)
    assert before.max() > 3  # the knee and everything below it are off
    steps = channel_steps(clip.model, clip.layout)
    free = (_chain_channels(clip)[np.argmax(before.max(axis=0))] > 0)[None].repeat(len(source), axis=0)
    held = np.ones(before.shape, bool)
    change, least = _least_corrections(tail, decoded, original, free, held, steps, source - decoded,
                                       np.full(before.shape, 1.0), before)
    assert least.all()
    assert tail.joint_distances(decoded + change, original).max() < 0.05
    assert np.abs(change[:, femur] + 5.0).max() < 0.01
    others = np.delete(np.abs(change), femur, axis=1)
    assert others.max() < 0.5  # degrees: no turn, no other branch
