"""The five representations: exact round trips on real clips, widths, heading, scaling."""

from __future__ import annotations

import dataclasses
import json
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapzip.formats.amc import Motion, read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.motion.kinematics import forward
from mocapzip.representations import get_representation
from mocapzip.stages import stage_ids
from mocapzip.representations.aligned import heading, position_columns
from mocapzip.representations.positions import decode_markers, flip_ranges, flips_from_ranges, solved_bones, true_twists
from mocapzip.representations.universal import UNIVERSAL_HEIGHT_CM, UNIVERSAL_LENGTHS_CM, skeleton_height
from mocapzip.motion.rotations import axis_rotation, euler_angles, rotation_angle
from mocapzip.motion.skeleton import SkeletonModel

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"

# Clips from every data folder, with frames subsampled to keep the suite fast.
CLIPS = {
    "cmu-walk": ("cmu/07/07.asf", "cmu/07/07_01.amc"),
    "cmu-dance": ("cmu/05/05.asf", "cmu/05/pirouette.amc"),
    "hdm05-lie-down": ("hdm05/bd/HDM_bd.asf", "hdm05/bd/HDM_bd_lieDownFloor_001_120.amc"),
    "cmu-edited": ("cmu-edited/05/moderndance_namespace.asf", "cmu/05/05_01.amc"),
    "cmu-edited-headerless": ("cmu/07/07.asf", "cmu-edited/07/headerless_slow_walk_1.amc"),
    "vicon-blade": ("other-vicon-blade/trial1_200fps/trial1.asf", "other-vicon-blade/trial1_200fps/trial1.amc"),
}
STEP = 7
pytestmark = pytest.mark.filterwarnings("ignore:.*unknown ASF section:UserWarning")  # cmu-edited :namespace line


@lru_cache(maxsize=None)
def load(key: str, step: int = STEP) -> tuple[SkeletonModel, Motion]:
    asf, amc = CLIPS[key]
    motion = read_amc(DATA / amc)
    return SkeletonModel.from_asf(read_asf(DATA / asf)), dataclasses.replace(motion, values=motion.values[::step])


def with_values(motion: Motion, values: np.ndarray) -> Motion:
    return dataclasses.replace(motion, values=values)


def round_trip_errors(name: str, model: SkeletonModel, motion: Motion,
                      axes_from_positions: bool = False) -> tuple[float, float]:
    """Worst joint distance (cm) and bone rotation error (rad) after forward + inverse; solved
    bones' twists chosen as the encoder chooses them (towards the clip's own rotations)."""
    rep = get_representation(name, axes_from_positions)
    encoded = rep.forward(model, motion)
    encoded.params["twist"] = true_twists(model, motion.values, motion)
    values = rep.inverse(model, encoded, motion)
    original, back = forward(model, motion.values, motion), forward(model, values, motion)
    position = np.linalg.norm(back.positions - original.positions, axis=-1).max()
    return float(position), float(rotation_angle(back.rotations, original.rotations).max())


@pytest.mark.parametrize("axes_from_positions", [False, True])
@pytest.mark.parametrize("name", stage_ids("representation"))
@pytest.mark.parametrize("key", sorted(CLIPS))
def test_round_trip_is_exact(key, name, axes_from_positions):
    position, rotation = round_trip_errors(name, *load(key), axes_from_positions)
    assert position < 1e-4
    assert rotation < 1e-5


def test_solved_bones_of_cmu_are_those_without_twist():
    model, motion = load("cmu-walk")
    solved = {model.names[j] for j in np.flatnonzero(solved_bones(model))}
    limbs = {"hipjoint", "tibia", "foot", "toes", "clavicle", "radius", "hand", "fingers", "thumb"}
    assert solved == {side + limb for side in "lr" for limb in limbs} - {"lhipjoint"}  # lhipjoint: root proxy
    assert "lwrist" not in solved  # its one dof (ry) turns the forearm about itself
    widths = {name: get_representation(name, True).forward(model, motion).poses.shape[1] for name in stage_ids("representation")}
    assert widths == {"channels": 62, "positions": 183 - 51, "aligned": 180 - 51, "scaled": 129, "normalised": 129}


def test_twist_flips_choose_between_the_two_solutions():
    # Subject 64 holds its left thumb (rx rz) in the solution the default rule does not take:
    # positions cannot tell the two apart, the stored flips can.
    model = SkeletonModel.from_asf(read_asf(DATA / "cmu/64/64.asf"))
    motion = read_amc(DATA / "cmu/64/64_01.amc")
    rep = get_representation("positions", axes_from_positions=True)
    encoded = rep.forward(model, motion)
    original = forward(model, motion.values, motion)
    thumb = model.index["lthumb"]

    def decoded_with(twist):
        encoded.params["twist"] = twist
        return forward(model, rep.inverse(model, encoded, motion), motion)

    by_default = decoded_with(None)
    assert np.abs(by_default.positions - original.positions).max() < 1e-6
    assert rotation_angle(by_default.rotations, original.rotations)[:, thumb].max() > 3.0  # half a turn

    chosen = true_twists(model, motion.values, motion)
    decoded_with(chosen)
    ranges = flip_ranges(chosen.flips, model)
    assert set(ranges) == {"lthumb"}
    stored = flips_from_ranges(json.loads(json.dumps(ranges)), model, motion.n_frames)  # as a row keeps them
    assert rotation_angle(decoded_with(stored).rotations, original.rotations).max() < 1e-6


def test_flip_ranges_round_trip():
    model, _ = load("cmu-walk")
    rng = np.random.default_rng(2)
    flips = {model.index["lfoot"]: rng.random(50) < 0.3, model.index["rhand"]: np.ones(50, bool),
             model.index["lthumb"]: np.zeros(50, bool)}
    ranges = flip_ranges(flips, model)
    assert set(ranges) == {"lfoot", "rhand"} and ranges["rhand"] == [0, 50]
    back = flips_from_ranges(ranges, model, 50).flips
    assert set(back) == {model.index["lfoot"], model.index["rhand"]}
    assert all(np.array_equal(back[j], flips[j]) for j in back)


def test_registry():
    assert stage_ids("representation") == ("channels", "positions", "aligned", "scaled", "normalised")
    assert all(get_representation(name).name == name for name in stage_ids("representation"))
    with pytest.raises(ValueError, match="unknown representation id 'quaternions'"):
        get_representation("quaternions")


def test_cmu_widths_match_the_thesis():
    model, motion = load("cmu-walk")
    widths = {name: get_representation(name).forward(model, motion).poses.shape[1] for name in stage_ids("representation")}
    # 62 channels; 31 positions + 30 axes; aligned drops the root position (always 0).
    assert widths == {"channels": 62, "positions": 183, "aligned": 180, "scaled": 180, "normalised": 180}
    assert get_representation("positions").forward(model, motion).root is None
    root = get_representation("aligned").forward(model, motion).root
    assert root.shape == (motion.n_frames, 4)


def test_positions_columns_are_joint_positions_and_bone_axes():
    model, motion = load("cmu-walk")
    poses = get_representation("positions").forward(model, motion).poses
    pose = forward(model, motion.values, motion)
    np.testing.assert_allclose(poses[:, :93].reshape(-1, 31, 3), pose.positions)
    axes = poses[:, 93:].reshape(-1, 30, 3)
    np.testing.assert_allclose(np.linalg.norm(axes, axis=-1), 1.0)
    bones = pose.positions[:, 1:] - pose.positions[:, model.parents[1:]]
    np.testing.assert_allclose(np.sum(axes * bones, axis=-1), 0.0, atol=1e-9)  # y axes are across the bone


def test_short_bones_and_leaves_are_recovered():
    # Vicon Blade has zero-length bones with dofs (Spine1, the hands); their x axis is stored.
    model, motion = load("vicon-blade")
    assert model.short[model.index["Spine1"]] and model.channels[model.index["Spine1"]] == ("rx", "ry", "rz")
    decoded = decode_markers(model, get_representation("positions").forward(model, motion).poses, with_root=True)
    pose = forward(model, motion.values, motion)
    assert rotation_angle(decoded.rotations, pose.rotations).max() < 1e-12  # every joint, leaves too


def test_root_rotation_is_stored_when_no_root_child_shows_it():
    # Give CMU's hip joints dofs (absent from the AMC, so the motion is unchanged): no child of
    # the root rotates with it any more, and the root's two axes join the matrix.
    skeleton = read_asf(DATA / "cmu/07/07.asf")
    for name in ("lhipjoint", "rhipjoint"):
        skeleton.bone(name).dof = ("rx", "ry", "rz")
    model = SkeletonModel.from_asf(skeleton)
    _, motion = load("cmu-walk")
    assert model.root_proxy is None
    assert get_representation("positions").forward(model, motion).poses.shape[1] == 183 + 6
    for name in ("positions", "aligned"):
        position, rotation = round_trip_errors(name, model, motion)
        assert position < 1e-4 and rotation < 1e-5


def test_lossy_positions_still_decode_to_rotations():
    model, motion = load("cmu-walk")
    poses = get_representation("positions").forward(model, motion).poses
    noisy = poses + np.random.default_rng(4).normal(0, 0.05, poses.shape)
    rotations = decode_markers(model, noisy, with_root=True).rotations
    np.testing.assert_allclose(rotations @ np.swapaxes(rotations, -1, -2), np.broadcast_to(np.eye(3), rotations.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(rotations), 1.0)


# --- heading / aligned --------------------------------------------------------


def test_heading_of_a_turning_upright_character():
    yaw = np.linspace(0, 3 * np.pi, 50)  # beyond 180 degrees: unwrapped
    tilt = axis_rotation("x", 0.3 * np.sin(yaw))  # leaning, as people do
    np.testing.assert_allclose(heading(tilt @ axis_rotation("y", yaw)), yaw, atol=1e-12)


@pytest.mark.parametrize("axis_degrees", [0, 30, 90])
def test_back_flip_has_no_heading_jump(axis_degrees):
    """A real walk with a synthetic full turn of the root about a horizontal axis, in 0.5 s."""
    model, motion = load("cmu-walk", step=1)
    pose = forward(model, motion.values, motion)
    frames = motion.n_frames
    turn = np.clip((np.arange(frames) - 100) / 60, 0, 1) * 2 * np.pi
    axis = np.array([np.cos(np.radians(axis_degrees)), 0.0, np.sin(np.radians(axis_degrees))])
    flip = np.swapaxes(Rotation.from_rotvec(turn[:, None] * axis).as_matrix(), 1, 2)
    values = motion.values.copy()
    root = motion.columns()["root"]
    values[:, root.start + 3 : root.stop] = np.degrees(euler_angles(pose.rotations[:, 0] @ flip, "xyz"))
    flipped = with_values(motion, values)

    encoded = get_representation("aligned").forward(model, flipped)
    world = forward(model, values, flipped)
    n = position_columns(model)

    def largest_step(positions):
        return np.linalg.norm(np.diff(positions.reshape(frames, -1, 3), axis=0), axis=-1).max()

    # Without the heading fix the whole body swings by ~100 cm in one frame mid-flip.
    relative = world.positions[:, 1:] - world.positions[:, :1]
    assert largest_step(encoded.poses[:, :n]) < 1.1 * largest_step(relative)
    assert np.abs(np.diff(encoded.root[:, 3])).max() < np.radians(3)
    position, rotation = round_trip_errors("aligned", model, flipped)
    assert position < 1e-4 and rotation < 1e-5


# --- scaled / normalised -----------------------------------------------------


def test_scaled_multiplies_aligned_positions_by_the_height_ratio():
    model, motion = load("hdm05-lie-down")
    aligned = get_representation("aligned").forward(model, motion)
    scaled = get_representation("scaled").forward(model, motion)
    scale = UNIVERSAL_HEIGHT_CM / skeleton_height(model)
    assert scaled.params["scale"] == pytest.approx(scale) and scale != pytest.approx(1.0)
    n = position_columns(model)
    np.testing.assert_allclose(scaled.poses[:, :n], aligned.poses[:, :n] * scale)
    np.testing.assert_array_equal(scaled.poses[:, n:], aligned.poses[:, n:])
    np.testing.assert_array_equal(scaled.root, aligned.root)


def test_universal_height_is_cmu_07s():
    model, _ = load("cmu-walk")
    assert skeleton_height(model) == pytest.approx(UNIVERSAL_HEIGHT_CM, abs=1e-3)
    blade, _ = load("vicon-blade")  # no CMU names: base-pose vertical extent
    up = blade.base_positions()[:, 1]
    assert skeleton_height(blade) == pytest.approx(up.max() - up.min())


def bone_lengths(model: SkeletonModel, aligned_poses: np.ndarray) -> np.ndarray:
    positions = np.zeros((len(aligned_poses), model.n_joints, 3))
    positions[:, 1:] = aligned_poses[:, : position_columns(model)].reshape(len(aligned_poses), -1, 3)
    return np.linalg.norm(positions[:, 1:] - positions[:, model.parents[1:]], axis=-1)


def test_normalised_bones_have_universal_lengths():
    model, motion = load("hdm05-lie-down")
    encoded = get_representation("normalised").forward(model, motion)
    universal = np.array([UNIVERSAL_LENGTHS_CM[name] for name in model.names[1:]])
    np.testing.assert_allclose(bone_lengths(model, encoded.poses), np.broadcast_to(universal, (motion.n_frames, 30)))
    np.testing.assert_allclose(encoded.params["norm"][1:], universal / model.lengths[1:])


def test_normalised_keeps_bones_the_table_does_not_know():
    model, motion = load("vicon-blade")
    encoded = get_representation("normalised").forward(model, motion)
    np.testing.assert_array_equal(encoded.params["norm"], 1.0)
    np.testing.assert_allclose(encoded.poses, get_representation("aligned").forward(model, motion).poses, atol=1e-12)
