"""Time warping (mocapzip.motion.timewarp): DTW's paths on sequences whose answer is known, the
multiscale search's economy, and on real HDM05 takes of one motion by three actors, every step
matched to a step of the same foot."""

from __future__ import annotations

import numpy as np
import pytest

from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.motion.contacts import foot_strikes
from mocapzip.motion.kinematics import forward
from mocapzip.motion.physics import physics_features
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.motion.timewarp import dtw, levels, multiscale_dtw, path_moves, path_of_moves


def features(n_frames: int, seed: int = 0) -> np.ndarray:
    """Smooth random feature curves, (frames, 3 features, 3)."""
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.normal(size=(n_frames, 3, 3)), axis=0)


def check_path(path: np.ndarray, n: int, m: int) -> None:
    assert tuple(path[0]) == (0, 0) and tuple(path[-1]) == (n - 1, m - 1)
    steps = np.diff(path, axis=0)
    assert {tuple(s) for s in steps} <= {(1, 0), (0, 1), (1, 1)}


@pytest.mark.parametrize("search", ["plain", "multiscale"])
def test_a_motion_against_itself_is_the_diagonal_at_no_cost(search):
    x = features(300)
    warping = dtw(x, x) if search == "plain" else multiscale_dtw(x, x, 120.0)
    np.testing.assert_array_equal(warping.path, np.stack([np.arange(300)] * 2, axis=1))
    assert warping.cost == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("search", ["plain", "multiscale"])
def test_a_motion_played_at_half_speed_maps_each_frame_to_its_two(search):
    x = features(200, seed=1)
    slow = np.repeat(x, 2, axis=0)
    warping = dtw(x, slow) if search == "plain" else multiscale_dtw(x, slow, 120.0)
    check_path(warping.path, 200, 400)
    np.testing.assert_allclose(warping.carried(np.arange(400), onto=0), 2 * np.arange(200) + 0.5)
    np.testing.assert_allclose(warping.carried(x, onto=1), slow)  # the motion itself, played slower
    assert warping.cost == pytest.approx(0.0, abs=1e-9)


def test_plain_dtw_is_optimal_and_the_multiscale_search_fills_a_tenth_of_its_cells_at_300_frames():
    a, b = features(300, seed=2), features(310, seed=3)
    plain, multiscale = dtw(a, b), multiscale_dtw(a, b, 120.0)
    check_path(plain.path, 300, 310)
    check_path(multiscale.path, 300, 310)
    assert plain.cells == 300 * 310
    assert plain.cost <= multiscale.cost + 1e-9
    assert multiscale.cells < plain.cells / 10
    assert 0 <= plain.cost <= len(plain.path)  # every cell costs between 0 and 1


def test_a_feature_that_is_zero_costs_nothing():
    a, b = features(50, seed=4), features(50, seed=5)
    a[:, 1] = 0.0  # the second feature absent in one motion: only the others are compared
    with_zero = dtw(a, b)
    assert with_zero.cost <= dtw(a[:, [0, 2]], b[:, [0, 2]]).cost * 2 / 3 + 1e-9


def test_levels_reach_about_4_hz():
    assert levels(120.0) == 6  # 120 Hz down to 3.75 Hz, as the seed's six levels from 4 Hz
    assert levels(30.0) == 4  # Bandai's BVH
    assert levels(4.0) == 1 and levels(1.0) == 1


def test_bad_features_are_refused():
    infinite, missing = features(5), features(5)
    infinite[2, 1, 0], missing[3, 0, 2] = np.inf, np.nan
    for bad in (np.zeros((0, 2, 3)), np.zeros((5, 3)), np.zeros((5, 2, 2)), infinite, missing):
        with pytest.raises(ValueError):
            dtw(bad, features(5))
        with pytest.raises(ValueError):
            multiscale_dtw(features(5), bad, 120.0)


@pytest.mark.parametrize("motion", ["jogLeftCircle4StepsRstart", "sneak2StepsLStart"])
def test_steps_of_other_actors_land_on_the_same_foot(shared_data, motion):
    """HDM05 takes of one motion (same steps, same starting foot) by three actors, each aligned
    to the first on the physics features: every step of each take maps to within 25 frames of
    the reference's nearest step, and that step is of the same foot."""
    takes = sorted(shared_data.glob(f"hdm05/*/*{motion}*"))
    assert len(takes) >= 3
    loaded = []
    for path in takes:
        skeleton = read_asf(next(path.parent.glob("*.asf")))
        model = SkeletonModel.from_asf(skeleton)
        clip = read_amc(path, skeleton)
        pose = forward(model, clip.values, clip)
        loaded.append((physics_features(model, pose.positions, pose.rotations, 120.0), foot_strikes(model, pose.positions, 120.0)))
    reference, reference_steps = loaded[0]
    assert sum(map(len, reference_steps.values())) >= 2
    for take, steps in loaded[1:]:
        # each frame of the take, in the reference's time
        in_reference = multiscale_dtw(reference, take, 120.0).carried(np.arange(len(reference)), onto=1)
        for side, frames in steps.items():
            for frame in frames:
                distance, nearest_side = min((abs(in_reference[frame] - f), s)
                                             for s, fs in reference_steps.items() for f in fs)
                assert nearest_side == side and distance <= 25, (side, frame, nearest_side, distance)


# ------------------------------------------------------------------------ a path as stored (--model tensor)

def test_a_path_goes_through_its_moves_and_back():
    features = np.random.default_rng(7).normal(size=(90, 5, 3))
    path = multiscale_dtw(features, features[::2], 120.0).path
    moves = path_moves(path)
    assert set(moves) <= {0, 1, 2} and len(moves) == len(path) - 1
    np.testing.assert_array_equal(path_of_moves(moves, 90, 45), path)


@pytest.mark.parametrize("path", [[[1, 0], [2, 1]], [[0, 0], [0, 0]], [[0, 0], [2, 1]], [[0, 0], [1, -1]]])
def test_what_is_no_warping_path_has_no_moves(path):
    with pytest.raises(ValueError, match="not a warping path"):
        path_moves(np.array(path))


def test_stored_moves_must_be_moves_and_end_at_both_last_frames():
    with pytest.raises(ValueError, match="moves are 0, 1 or 2"):
        path_of_moves(bytes([2, 3]), 3, 3)
    with pytest.raises(ValueError, match=r"ends at \(2, 1\), not at \(2, 2\)"):
        path_of_moves(bytes([2, 0]), 3, 3)
    np.testing.assert_array_equal(path_of_moves(b"", 1, 1), [[0, 0]])
