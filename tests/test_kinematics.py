"""Rotations, skeleton model, forward and inverse kinematics."""

from __future__ import annotations

import itertools
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapzip.formats.amc import Motion, read_amc
from mocapzip.formats.asf import parse_asf, read_asf
from mocapzip.formats.errors import MocapFormatError
from mocapzip.motion.kinematics import forward, inverse
from mocapzip.motion.rotations import (
    angle_about,
    axis_rotation,
    euler_angles,
    euler_matrix,
    rotation_angle,
    wrap,
)
from mocapzip.motion.skeleton import ChannelLayout, SkeletonModel

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"

# One clip per data folder: (skeleton, motion).
CLIPS = {
    "cmu": ("cmu/07/07.asf", "cmu/07/07_01.amc"),
    "hdm05": ("hdm05/bd/HDM_bd.asf", "hdm05/bd/HDM_bd_lieDownFloor_001_120.amc"),
    "cmu-edited": ("cmu/07/07.asf", "cmu-edited/07/headerless_walk_1.amc"),
    "other-vicon-blade": ("other-vicon-blade/walk_200fps/walkMoCapVideo.asf", "other-vicon-blade/walk_200fps/walkMoCap2.amc"),
}


@lru_cache(maxsize=None)
def load(key: str) -> tuple[SkeletonModel, Motion]:
    asf, amc = CLIPS[key]
    return SkeletonModel.from_asf(read_asf(DATA / asf)), read_amc(DATA / amc)


# A two-bone skeleton small enough to work out by hand: 1 file unit = 1 cm.
TINY_ASF = b"""\
:units
  length 2.54
  angle deg
:root
  order TX TY TZ RX RY RZ
  axis XYZ
  position 0 0 0
  orientation 0 0 0
:bonedata
  begin
    name a
    direction 1 0 0
    length 1
    axis 0 0 0 XYZ
    dof rz
  end
  begin
    name b
    direction 1 0 0
    length 2
    axis 0 0 90 XYZ
    dof rx
  end
:hierarchy
  begin
    root a
    a b
  end
"""
TINY_LAYOUT = ChannelLayout(("root", "a", "b"), (6, 1, 1), "deg")


def tiny_model() -> SkeletonModel:
    return SkeletonModel.from_asf(parse_asf(TINY_ASF))


# --- rotations ---------------------------------------------------------------


def test_rotations_act_on_row_vectors():
    quarter = np.pi / 2
    np.testing.assert_allclose(np.array([1.0, 0, 0]) @ axis_rotation("z", quarter), [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(np.array([0.0, 1, 0]) @ axis_rotation("x", quarter), [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(np.array([0.0, 0, 1]) @ axis_rotation("y", quarter), [1, 0, 0], atol=1e-15)


def test_euler_matrix_applies_the_first_axis_first():
    # x by 90 takes y to z, then z by 90 leaves z alone: p = (0, 1, 0) ends at (0, 0, 1).
    m = euler_matrix([np.pi / 2, np.pi / 2], "xz")
    np.testing.assert_allclose(np.array([0.0, 1, 0]) @ m, [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(m, axis_rotation("x", np.pi / 2) @ axis_rotation("z", np.pi / 2))


@pytest.mark.parametrize("axes", ["".join(p) for p in itertools.permutations("xyz")])
def test_euler_matrix_matches_scipy_extrinsic(axes):
    angles = np.random.default_rng(1).uniform(-3, 3, (50, 3))
    column = Rotation.from_euler(axes, angles).as_matrix()
    np.testing.assert_allclose(euler_matrix(angles, axes), np.swapaxes(column, 1, 2), atol=1e-14)


def smooth_curves(n_axes: int, frames: int = 400) -> np.ndarray:
    """Angle curves that cross +-180 degrees, and whose middle angle passes the poles."""
    t = np.linspace(0, 1, frames)
    curves = [4 * np.pi * t, 2.2 * np.sin(3 * t), -3 * np.pi * t + 0.3]
    return np.stack(curves[:n_axes], axis=1) if n_axes == 3 else np.stack([curves[0], curves[2]][:n_axes], axis=1)


@pytest.mark.parametrize("axes", ["xyz", "zyx", "yzx", "xz", "ry", "x", "z"])
def test_euler_angles_recover_continuous_curves(axes):
    axes = axes.replace("r", "")
    original = smooth_curves(len(axes))
    recovered = euler_angles(euler_matrix(original, axes), axes)
    # Nearest solution to the previous frame + unwrapping follows the original curve exactly.
    np.testing.assert_allclose(recovered, original, atol=1e-9)


def test_euler_angles_in_gimbal_lock_stay_exact_and_continuous():
    frames = 20
    original = np.column_stack([np.linspace(0.2, 0.4, frames), np.full(frames, np.pi / 2), np.linspace(0.1, 0.0, frames)])
    m = euler_matrix(original, "xyz")
    recovered = euler_angles(m, "xyz")
    np.testing.assert_allclose(euler_matrix(recovered, "xyz"), m, atol=1e-12)
    assert np.abs(np.diff(recovered, axis=0)).max() < 0.05


def test_one_axis_fit_is_the_closest_rotation():
    m = Rotation.random(20, random_state=2).as_matrix()
    grid = np.linspace(-np.pi, np.pi, 3601)
    for axis in "xyz":
        best = angle_about(axis, m)
        closeness = np.einsum("fij,gij->fg", m, axis_rotation(axis, grid))  # trace(m^T R)
        fit = np.einsum("fij,fij->f", m, axis_rotation(axis, best))
        assert np.all(fit >= closeness.max(axis=1) - 1e-9)


def test_two_axis_fit_is_the_closest_rotation():
    # Rotations near expressible ones, as after lossy compression, then a brute-force check.
    rng = np.random.default_rng(3)
    exact = rng.uniform(-2, 2, (10, 2))
    noise = Rotation.from_rotvec(rng.normal(0, 0.15, (10, 3))).as_matrix()
    m = euler_matrix(exact, "xz") @ noise
    fit = euler_angles(m, "xz")
    grid = np.stack(np.meshgrid(np.linspace(-np.pi, np.pi, 721), np.linspace(-np.pi, np.pi, 721)), -1).reshape(-1, 2)
    candidates = euler_matrix(grid, "xz")
    for f in range(len(m)):
        best_grid = np.einsum("ij,gij->g", m[f], candidates).max()
        assert np.sum(m[f] * euler_matrix(fit[f], "xz")) >= best_grid - 1e-9


def test_rotation_angle_is_accurate_for_tiny_angles():
    a = axis_rotation("y", 0.3)
    assert rotation_angle(a, a @ axis_rotation("x", 1e-7)) == pytest.approx(1e-7, rel=1e-6)


# --- skeleton model ----------------------------------------------------------


def test_cmu_skeleton_model():
    model, _ = load("cmu")
    assert model.n_joints == 31 and model.names[0] == "root"
    assert all(model.parents[j] < j for j in range(1, 31))  # parents first
    assert model.names[model.parents[model.index["ltibia"]]] == "lfemur"
    assert model.channels[model.index["lfoot"]] == ("rx", "rz")
    assert model.cm_per_unit == pytest.approx(2.54 / 0.45)
    lfemur = read_asf(DATA / "cmu/07/07.asf").bone("lfemur")
    assert model.lengths[model.index["lfemur"]] == pytest.approx(lfemur.length * 2.54 / 0.45)
    assert model.names[model.root_proxy] == "lhipjoint"  # no dof: rotates with the root


def test_faux_matrices_put_x_along_the_bone():
    model, _ = load("other-vicon-blade")
    for j in range(1, model.n_joints):
        b = model.faux[j]
        np.testing.assert_allclose(b @ b.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(b) == pytest.approx(1.0)
        if not model.short[j]:
            np.testing.assert_allclose(b[0], model.offsets[j] / model.lengths[j], atol=1e-12)
    assert {model.names[j] for j in np.flatnonzero(model.short)} >= {"Spine1", "LeftHand", "RightHand"}


def test_layout_must_match_the_skeleton():
    model = tiny_model()
    with pytest.raises(MocapFormatError, match="not in the skeleton"):
        model.layout(ChannelLayout(("root", "nope"), (6, 1), "deg"))
    with pytest.raises(MocapFormatError, match="has 2 values"):
        model.layout(ChannelLayout(("root", "a"), (6, 2), "deg"))


# --- forward kinematics ------------------------------------------------------


def test_forward_by_hand():
    # root moved by (1, 2, 3) cm; a turns 90 degrees about z: its end (1, 0, 0) goes to (0, 1, 0).
    # b's axis is z by 90, so its rx turns about world y in the base pose: its (2, 0, 0) becomes
    # (0, 0, -2), then a's turn about z leaves that alone.
    pose = forward(tiny_model(), np.array([[1.0, 2, 3, 0, 0, 0, 90, 90]]), TINY_LAYOUT)
    np.testing.assert_allclose(pose.positions[0], [[1, 2, 3], [1, 3, 3], [1, 3, 1]], atol=1e-12)
    np.testing.assert_allclose(pose.rotations[0, 1], axis_rotation("z", np.pi / 2), atol=1e-15)


def reference_forward(skeleton, motion: Motion, frame: int):
    """Straight per-frame Acclaim FK in column vectors with scipy (an independent implementation)."""
    columns, row, cm = motion.columns(), motion.values[frame], skeleton.cm_per_unit
    order = [c.lower() for c in skeleton.root_order]
    root = row[columns["root"]]
    c = Rotation.from_euler(skeleton.root_axis.lower(), skeleton.root_orientation, degrees=True).as_matrix()
    m = Rotation.from_euler("".join(x[1] for x in order[3:]), root[3:], degrees=True).as_matrix()
    rotations, positions = {"root": c @ m @ c.T}, {"root": root[:3] * cm}
    for parent, children in skeleton.hierarchy:
        for name in children:
            bone = skeleton.bone(name)
            c = Rotation.from_euler(bone.axis_order.lower(), bone.axis, degrees=True).as_matrix()
            m = np.eye(3)
            if bone.dof:
                m = Rotation.from_euler("".join(d[1] for d in bone.dof), row[columns[name]], degrees=True).as_matrix()
            rotations[name] = rotations[parent] @ c @ m @ c.T
            positions[name] = positions[parent] + rotations[name] @ (bone.direction * bone.length * cm)
    return rotations, positions


@pytest.mark.parametrize("key", ["cmu", "other-vicon-blade"])
def test_forward_matches_an_independent_implementation(key):
    model, motion = load(key)
    skeleton = read_asf(DATA / CLIPS[key][0])
    pose = forward(model, motion.values, motion)
    for frame in (0, 57, motion.n_frames - 1):
        rotations, positions = reference_forward(skeleton, motion, frame)
        for j, name in enumerate(model.names):
            np.testing.assert_allclose(pose.positions[frame, j], positions[name], atol=1e-10)
            np.testing.assert_allclose(pose.rotations[frame, j], rotations[name].T, atol=1e-12)


# --- inverse kinematics ------------------------------------------------------


@pytest.mark.parametrize("key", sorted(CLIPS))
def test_inverse_reproduces_the_channels(key):
    model, motion = load(key)
    values = motion.values[::3]
    pose = forward(model, values, motion)
    recovered = inverse(model, pose.rotations, pose.positions[:, 0], motion)
    again = forward(model, recovered, motion)
    np.testing.assert_allclose(again.positions, pose.positions, atol=1e-9)
    assert rotation_angle(again.rotations, pose.rotations).max() < 1e-10
    if key == "cmu":
        # CMU's angles are the canonical solution, so the file's own values come back.
        # (HDM05 roots sometimes use the other Euler solution: same rotation, other numbers.)
        np.testing.assert_allclose(wrap(np.radians(recovered - values)), 0, atol=1e-9)


def test_inverse_fits_rotations_a_joint_cannot_make():
    # a has only rz: a world rotation about x must come back as the closest z rotation (none).
    model = tiny_model()
    rotations = np.broadcast_to(np.eye(3), (1, 3, 3, 3)).copy()
    rotations[0, 1] = rotations[0, 2] = axis_rotation("x", 0.4) @ axis_rotation("z", 0.7)
    values = inverse(model, rotations, np.zeros((1, 3)), TINY_LAYOUT)
    assert np.radians(values[0, 6]) == pytest.approx(angle_about("z", rotations[0, 1]))


def test_inverse_angles_are_continuous_in_time():
    # A bone spinning steadily past 180 degrees comes back as a rising curve, not a saw tooth.
    model = tiny_model()
    values = np.zeros((100, 8))
    values[:, 6] = np.linspace(0, 700, 100)
    pose = forward(model, values, TINY_LAYOUT)
    np.testing.assert_allclose(inverse(model, pose.rotations, pose.positions[:, 0], TINY_LAYOUT), values, atol=1e-9)
