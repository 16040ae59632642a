"""`--plant-feet`: the decoder holds the source's planted feet still (`codec.foot_lock`), chosen by
`ratecontrol.planted_feet`. Checked on the AMC files `mcz decompress` writes, read back by the
project's reader and run through its numpy forward kinematics, against the source."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from mocapzip.archive import Archive, Settings, SettingsError
from mocapzip.archive.settings import checked
from mocapzip.cli.main import main
from mocapzip.codec.entropy.coefficients import encode_matrices
from mocapzip.codec.foot_lock import Stances, hold
from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.motion.contacts import contacts, foot_joints, foot_skate
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.representations.weighted import DecodeTail, skeleton_params
from mocapzip.stages import get_stage

WALKS = ("07_01.amc", "07_02.amc")


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


# ----------------------------------------------------------------------------- the stream


def test_stances_come_back_from_their_stream():
    runs = [(2, 40, 30), (0, 5, 12), (0, 30, 1), (3, 0, 100), (2, 0, 8)]
    stances = Stances.of(runs)
    back = Stances.from_payload(stances.payload(), len(runs), 100, 4)
    assert sorted(zip(back.feet, back.first, back.frames)) == sorted(runs)
    assert list(back.feet) == sorted(back.feet)  # stored by foot, then by frame


@pytest.mark.parametrize("stored, problem", [
    ([(4, 0, 5)], "foot joints"),  # a fifth foot of four
    ([(-1, 0, 5)], "foot joints"),
    ([(1, 0, 5), (0, 10, 5)], "foot joints"),  # feet out of order
    ([(0, 0, 0)], "lengths"),
    ([(0, -1, 5)], "gaps"),
    ([(0, 95, 10)], "past the clip"),
    ([(0, 50, 30), (0, 30, 30)], "past the clip"),  # the second starts 30 frames after the first ends
])
def test_a_stance_stream_that_does_not_fit_its_clip_is_refused(stored, problem):
    blob = encode_matrices([np.array(stored, np.int64)])
    with pytest.raises(ValueError, match=problem):
        Stances.from_payload(blob, len(stored), 100, 4)


# ----------------------------------------------------------------------------- the lock itself


@pytest.fixture(scope="module")
def walk_tail(shared_data):
    """07_02's source values, as if decoded, and the DecodeTail the reader would use for them."""
    model = SkeletonModel.from_asf(read_asf(shared_data / "cmu" / "07" / "07.asf"))
    motion = read_amc(shared_data / "cmu" / "07" / "07_02.amc")
    representation = get_stage("representation", {"id": "aligned", "axes_from_positions": True})
    layout = model.layout(motion)
    tail = DecodeTail(model, representation, layout, skeleton_params(model, representation, layout), 12.0)
    return model, tail, motion.values.copy()


def locked(walk_tail, runs, values=None):
    model, tail, source = walk_tail
    values = source if values is None else values
    out = values.copy()
    hold(out, Stances.of(runs), model, tail)
    return tail.positions(values), tail.positions(out), out


@pytest.mark.parametrize("backwards", [False, True])
def test_a_joint_is_held_from_the_first_frame_or_to_the_last(walk_tail, backwards):
    """07_02 plants lfoot in its first 14 frames (played backwards: its last 14). The ease is cut
    at the clip's edge, the joint still held, and the frames beyond the ease are left alone."""
    model, tail, values = walk_tail
    values = values[::-1].copy() if backwards else values
    last = len(values)
    first = last - 14 if backwards else 0
    before, after, out = locked(walk_tail, [(0, first, 14)], values)
    held = after[first:first + 14, foot_joints(model)[0]]
    assert np.linalg.norm(held - held.mean(axis=0), axis=1).max() < 0.05
    assert np.all(np.isfinite(out))
    untouched = slice(0, last - 14 - 8) if backwards else slice(14 + 8, last)
    np.testing.assert_array_equal(out[untouched], values[untouched])


def test_a_one_frame_stance_holds_its_joint_where_it_is(walk_tail):
    model, tail, values = walk_tail
    before, after, out = locked(walk_tail, [(2, 100, 1)])
    joint = foot_joints(model)[2]
    np.testing.assert_allclose(after[100, joint], before[100, joint], atol=1e-9)
    np.testing.assert_array_equal(out[:100 - 8], values[:100 - 8])
    np.testing.assert_array_equal(out[101 + 8:], values[101 + 8:])


def test_close_stances_of_one_joint_share_the_frames_between_them():
    """Two stances 5 frames apart ease out and in over 2 frames each: their windows never overlap,
    so the joint's target never jumps from one anchor to the other."""
    stances = Stances.of([(0, 10, 20), (0, 35, 20), (1, 12, 20)])
    ease_in, ease_out = stances.eases()
    assert list(ease_in) == [8, 2, 8] and list(ease_out) == [2, 8, 8]
    lo, hi = stances.windows(60)
    assert list(lo) == [2, 33, 4] and list(hi) == [32, 60, 40]
    assert hi[0] <= lo[1]


def test_no_stance_changes_nothing(walk_tail):
    _, _, values = walk_tail
    before, after, out = locked(walk_tail, [])
    np.testing.assert_array_equal(out, values)


# ----------------------------------------------------------------------------- real walks


@pytest.fixture(scope="module")
def walks(shared_data, tmp_path_factory):
    """07_01 and 07_02 compressed at -e 1 with and without --plant-feet, decompressed."""
    folder = shared_data / "cmu" / "07"
    work = tmp_path_factory.mktemp("walks")
    made = {}
    for label, extra in (("plain", []), ("planted", ["--plant-feet"])):
        archive, out = work / f"{label}.mcz", work / label
        result = run("compress", *(folder / name for name in WALKS), "-o", archive, "-q", "-e", "1", *extra)
        assert result.exit_code == 0, result.output
        assert run("decompress", archive, "-o", out, "-q").exit_code == 0
        made[label] = archive, out
    model = SkeletonModel.from_asf(read_asf(folder / "07.asf"))
    return folder, model, made


def positions(model, path):
    motion = read_amc(path)
    return forward(model, motion.values, motion).positions


def test_planted_feet_slide_no_more_than_in_the_source(walks):
    """Without the lock a walk's planted feet slide several cm/s more than the source's; with it,
    no more than the source's (within 1 cm/s), and the archive stores the stances it holds."""
    folder, model, made = walks
    for name in WALKS:
        source = positions(model, folder / name)
        planted = contacts(model, source, 120.0)
        plain = foot_skate(source, positions(model, made["plain"][1] / name), planted, 120.0)
        held = foot_skate(source, positions(model, made["planted"][1] / name), planted, 120.0)
        assert plain > 3.0, name
        assert held < 1.0 and held < plain / 3, name
    with Archive(made["planted"][0]) as archive:
        assert archive.meta["settings"]["plant_feet"] is True
        assert all(row["planted_stances"] >= 4 for row in archive.clips)
    with Archive(made["plain"][0]) as archive:
        assert "plant_feet" not in archive.meta["settings"]
        assert not any("planted_stances" in row for row in archive.clips)


def test_the_bounds_hold_with_the_lock(walks):
    """The mean stays within -e and every joint within --max-error (5 x -e), on the written files,
    and each row's errors are those of its written file."""
    folder, model, made = walks
    archive, out = made["planted"]
    with Archive(archive) as opened:
        for row in opened.clips:
            errors = np.linalg.norm(positions(model, folder / row["path"]) - positions(model, out / row["path"]),
                                    axis=-1)
            assert errors.mean() <= 1.0 and errors.max() <= 10.0
            assert errors.mean() == pytest.approx(row["error_cm"], abs=1e-6)
            assert errors.max() == pytest.approx(row["max_error_cm"], abs=1e-6)


def test_each_stance_holds_its_joint_still(walks):
    """Over each stored stance the held joint stays where it is: across the floor within 0.4 cm of
    its mean in every frame (0.32 cm at most, measured), and within 0.5 cm in all. (A foot's ball and toe are each held at
    their own anchor, which one rigid foot cannot quite both reach: where one eases in or out, the
    other gives way by a few mm; and a straight leg barely reaches along its length.)"""
    folder, model, made = walks
    archive, out = made["planted"]
    feet = foot_joints(model)
    with Archive(archive) as opened:
        for index, row in enumerate(opened.clips):
            stances = Stances.from_payload(opened._reader.read(f"plant/{index:05d}"), row["planted_stances"],
                                           row["frames"], len(feet))
            decoded = positions(model, out / row["path"])
            for foot, first, frames in zip(stances.feet, stances.first, stances.frames):
                held = decoded[first:first + frames, feet[foot]]
                off = held - held.mean(axis=0)
                assert np.linalg.norm(off[:, [0, 2]], axis=1).max() < 0.4
                assert np.linalg.norm(off, axis=1).max() < 0.5


# ----------------------------------------------------------------------------- options


@pytest.mark.parametrize("other", ["segment", "lossless"])
def test_plant_feet_is_refused_with_segment_or_lossless(other):
    with pytest.raises(SettingsError, match=other):
        checked(Settings(plant_feet=True, **{other: True}))


@pytest.mark.parametrize("args, message", [
    (["--plant-feet", "--lossless"], "--plant-feet"),
    (["--plant-feet", "--segment"], "segment"),
])
def test_plant_feet_usage_errors(shared_data, tmp_path, args, message):
    result = run("compress", shared_data / "cmu" / "07" / "07_01.amc", "-o", tmp_path / "x.mcz", *args)
    assert result.exit_code == 2 and message in result.output
    assert not (tmp_path / "x.mcz").exists()


def test_info_says_feet_are_held(walks):
    _, _, made = walks
    assert "planted feet held" in run("info", made["planted"][0]).output
    assert "planted feet held" not in run("info", made["plain"][0]).output
