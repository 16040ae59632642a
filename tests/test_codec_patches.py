"""Frame patches (`codec.patches`): the stream round-trips, refuses what it cannot hold, and adds
exactly the corrections the encoder measured; `ratecontrol.max_error` brings every joint of every
frame of real clips within the bound, as written, without raising any frame's summed error."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.ndimage import uniform_filter1d

from mocapzip.codec.entropy.coefficients import encode_matrices
from mocapzip.codec.patches import LEVER_CM, MAX_LEVEL, FramePatches, channel_steps, frame_steps
from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.inputs.clip import ClipReader
from mocapzip.inputs.discover import find_clips
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.ratecontrol.max_error import achieved
from mocapzip.ratecontrol.target import Bounds


def random_patches(rng, n_frames: int, width: int, count: int) -> FramePatches:
    frames = np.sort(rng.choice(n_frames, count, replace=False))
    levels = rng.integers(0, 4, count)
    levels[1:4] = levels[0]  # a run of adjacent frames at one level: stored as differences
    frames[:4] = frames[0] + np.arange(4) if frames[0] + 4 < frames[4] else frames[:4]
    ints = rng.integers(-5000, 5000, (count, width)) * (rng.random((count, width)) < 0.4)
    return FramePatches(float(np.float32(2.5)), frames, levels, ints)


@pytest.mark.parametrize("count", [1, 2, 7, 60])
@pytest.mark.parametrize("width", [1, 6, 62])
def test_patches_round_trip(count, width):
    rng = np.random.default_rng(count * 100 + width)
    patches = random_patches(rng, 500, width, count) if count > 4 else FramePatches(
        0.75, np.sort(rng.choice(500, count, replace=False)), rng.integers(0, MAX_LEVEL + 1, count),
        rng.integers(-(2**40), 2**40, (count, width)))
    back = FramePatches.from_payload(patches.payload(), 500, width, count)
    assert back.step_cm == patches.step_cm
    np.testing.assert_array_equal(back.frames, patches.frames)
    np.testing.assert_array_equal(back.levels, patches.levels)
    np.testing.assert_array_equal(back.ints, patches.ints)


def test_adjacent_frames_at_one_level_cost_less_than_scattered_ones():
    """Neighbouring frames' residuals are alike: stored as differences they take fewer bytes."""
    smooth = np.cumsum(np.random.default_rng(1).integers(-2, 3, (40, 30)), axis=0) + 300
    levels = np.zeros(40, np.int64)
    adjacent = FramePatches(1.0, np.arange(40), levels, smooth)
    scattered = FramePatches(1.0, np.arange(40) * 3, levels, smooth)  # same ints, no runs
    assert len(adjacent.payload()) < 0.8 * len(scattered.payload())


@pytest.mark.parametrize("damage, message", [
    (lambda blob: blob[:3], "cut short"),
    (lambda blob: b"\x00\x00\xc0\x7f" + blob[4:], "not a positive number"),  # NaN step
    (lambda blob: b"\x00\x00\x80\xbf" + blob[4:], "not a positive number"),  # -1.0
])
def test_damaged_patch_streams_are_refused(damage, message):
    blob = FramePatches(1.0, np.array([3, 4]), np.array([0, 1]), np.ones((2, 5), np.int64)).payload()
    with pytest.raises(ValueError, match=message):
        FramePatches.from_payload(damage(blob), 10, 5, 2)


@pytest.mark.parametrize("frames, levels, n_frames, count, width, message", [
    ([3, 9], [0, 0], 9, 2, 5, "past the clip"),
    ([3, 4], [0, MAX_LEVEL + 1], 10, 2, 5, "levels within"),
    ([3, 4], [0, 0], 10, 3, 5, "shapes"),  # the row says 3 patched frames
    ([3, 4], [0, 0], 10, 2, 6, "shapes"),  # a layout of 6 values
])
def test_patches_that_do_not_fit_the_clip_are_refused(frames, levels, n_frames, count, width, message):
    blob = FramePatches(1.0, np.array(frames), np.array(levels), np.ones((2, 5), np.int64)).payload()
    with pytest.raises(ValueError, match=message):
        FramePatches.from_payload(blob, n_frames, width, count)


def test_negative_gaps_are_refused():
    """A gap below 0 would repeat or reorder frames: written by hand, since `payload` never makes one."""
    patches = FramePatches(1.0, np.array([5, 4]), np.array([0, 0]), np.ones((2, 3), np.int64))
    with pytest.raises(ValueError, match="gaps"):
        FramePatches.from_payload(patches.payload(), 10, 3, 2)


def test_gaps_and_runs_that_would_overflow_are_refused():
    """Gaps near 2**62 would wrap the frame sums round to a valid-looking frame; a run of adjacent
    rows of large differences would wrap the ints."""
    wrapping = FramePatches(1.0, np.array([0, 2**61, 2**62 - 2]), np.zeros(3, np.int64), np.ones((3, 2), np.int64))
    with pytest.raises(ValueError, match="gaps"):
        FramePatches.from_payload(wrapping.payload(), 10, 2, 3)
    big = 2**61 + 2**60
    run = FramePatches(1.0, np.arange(4), np.zeros(4, np.int64), np.zeros((4, 2), np.int64))
    blob = run.payload()
    stored = [np.column_stack([np.zeros(4, np.int64), np.zeros(4, np.int64)]), np.full((4, 2), big, np.int64)]
    blob = blob[:4] + encode_matrices(stored)
    with pytest.raises(ValueError, match="beyond 2"):
        FramePatches.from_payload(blob, 10, 2, 4)


def test_channel_steps_are_one_cm_of_joint_movement(shared_data):
    """Translations: 1 cm in file units; rotations: the angle that moves a joint LEVER_CM away by 1 cm."""
    model = SkeletonModel.from_asf(read_asf(shared_data / "cmu" / "07" / "07.asf"))
    motion = read_amc(shared_data / "cmu" / "07" / "07_01.amc")
    layout = model.layout(motion)
    steps = channel_steps(model, layout)
    assert steps.shape == (layout.width,)
    root = model.channels[0]
    for k, channel in enumerate(root):
        if channel.startswith("t"):
            assert steps[k] * model.cm_per_unit == pytest.approx(1.0)
        else:
            assert math.radians(steps[k]) * LEVER_CM == pytest.approx(1.0)
    assert np.all(steps[len(root):] == steps[len(root)])  # every other CMU channel is a rotation
    np.testing.assert_array_equal(frame_steps(steps, 3.0, 2), steps * 0.75)


def test_apply_adds_each_frames_ints_times_its_steps():
    steps = np.array([0.1, 0.2, 0.3])
    patches = FramePatches(2.0, np.array([1, 3]), np.array([0, 3]), np.array([[1, -2, 0], [8, 0, 4]]))
    values = np.zeros((5, 3))
    patches.apply(values, steps)
    expected = np.zeros((5, 3))
    expected[1] = [0.2, -0.8, 0.0]
    expected[3] = [0.2, 0.0, 0.3]
    np.testing.assert_allclose(values, expected, rtol=1e-15)


@pytest.fixture(scope="module")
def glitch_clip(shared_data):
    """01_06: its rfemur ry flips from about 9 to about 177 degrees and back for a few frames (a glitch in the source)."""
    source = next(s for s in find_clips([shared_data / "cmu" / "01"]) if s.motion.name == "01_06.amc")
    return ClipReader("aligned", 12.0, axes_from_positions=True).read(source)


@pytest.mark.parametrize("bound", [3.0, 1.0])
def test_max_error_holds_every_joint_of_every_frame_of_a_clip_with_a_glitch(glitch_clip, bound):
    """A crude decode (the poses low-passed, as a kept band smooths over fast events, and noisy): after
    patching, every joint of every frame, as written and read back, is within the bound; the errors
    reported are those of the written values, and no frame's summed error grew."""
    clip = glitch_clip
    rng = np.random.default_rng(7)
    poses = uniform_filter1d(clip.poses, 15, axis=0) + rng.normal(0, 0.3, clip.poses.shape)
    root = uniform_filter1d(clip.root, 15, axis=0)
    ry = clip.motion.values[:, clip.layout.columns()["rfemur"]][:, 1]
    glitch = np.flatnonzero(np.abs(np.diff(ry)) > 90)
    assert glitch.size, "01_06 should hold the rfemur flip"
    values = clip.final_check(poses, root).values.copy()
    before = clip.decode_tail.joint_distances(clip.as_written(values.copy()), clip.positions)
    assert before.max() > 20  # the flip is far from anything the noisy poses decode to
    errors, patches = achieved(clip, clip.final_check(poses, root), Bounds(max_error_cm=bound))
    assert patches is not None
    np.testing.assert_array_equal(patches.frames, np.flatnonzero(before.max(axis=1) > bound))  # those, and only those
    assert np.isin(glitch[0] + 1, patches.frames)
    patches = FramePatches.from_payload(patches.payload(), clip.motion.n_frames, clip.layout.width,
                                        len(patches.frames))
    patches.apply(values, channel_steps(clip.model, clip.layout))
    written = clip.as_written(values)
    positions = forward(clip.model, written, clip.motion).positions  # numpy kinematics, not the kernels
    after = np.linalg.norm(positions - clip.positions, axis=2)
    assert after.max() <= bound
    assert np.all(after.sum(axis=1) <= before.sum(axis=1) + 1e-9)
    assert errors.max == pytest.approx(after.max(), abs=1e-9) and errors.mean == pytest.approx(after.mean(), abs=1e-9)
    assert errors.p99 == pytest.approx(np.percentile(after, 99), abs=1e-9)
    untouched = np.setdiff1d(np.arange(clip.motion.n_frames), patches.frames)
    np.testing.assert_allclose(after[untouched], before[untouched], rtol=0, atol=1e-9)  # numpy FK vs the kernels


def test_without_a_bound_nothing_is_patched_and_the_mean_is_the_final_checks(glitch_clip):
    clip = glitch_clip
    poses = clip.poses + np.random.default_rng(3).normal(0, 0.3, clip.poses.shape)
    check = clip.final_check(poses, clip.root)
    errors, patches = achieved(clip, check)
    assert patches is None
    mean, largest = check.error
    written = clip.as_written(check.values.copy())
    assert (mean, largest) == clip.decode_tail.error(written, clip.positions)  # the searches' kernel, as written
    assert (errors.mean, errors.max) == (mean, largest)
    assert mean < errors.p99 < largest
