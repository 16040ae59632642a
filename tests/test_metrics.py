"""Error measures on cases small enough to work out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from mocapzip.formats.asf import parse_asf
from mocapzip.motion.kinematics import Pose, forward
from mocapzip.motion.metrics import (
    SKIN_RADIUS,
    bytes_per_frame,
    frame_errors,
    joint_distances,
    max_joint_error,
    mean_joint_error,
    skin_error,
    skin_vertices,
)
from mocapzip.motion.rotations import axis_rotation
from mocapzip.motion.skeleton import ChannelLayout, SkeletonModel

# One 10 cm bone along x (1 file unit = 1 cm), twisting about itself.
ONE_BONE_ASF = b"""\
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
    name arm
    direction 1 0 0
    length 10
    axis 0 0 0 XYZ
    dof rx
  end
:hierarchy
  begin
    root arm
  end
"""
LAYOUT = ChannelLayout(("root", "arm"), (6, 1), "deg")


def one_bone() -> SkeletonModel:
    return SkeletonModel.from_asf(parse_asf(ONE_BONE_ASF))


def test_joint_errors_by_hand():
    original = np.zeros((2, 2, 3))
    reconstructed = np.array([[[3.0, 4, 0], [0, 0, 0]], [[0, 0, 1], [0, 6, 8]]])
    np.testing.assert_allclose(joint_distances(original, reconstructed), [[5, 0], [1, 10]])
    assert mean_joint_error(original, reconstructed) == pytest.approx(4.0)
    assert max_joint_error(original, reconstructed) == pytest.approx(10.0)
    np.testing.assert_allclose(frame_errors(original, reconstructed), [2.5, 5.5])


def test_skin_vertices_form_an_octahedron_on_the_bone():
    assert SKIN_RADIUS == 0.2
    pose = forward(one_bone(), np.zeros((1, 7)), LAYOUT)
    vertices = skin_vertices(one_bone(), pose)
    assert vertices.shape == (1, 1, 6, 3)
    # Tips on the joints, sides 0.2 x 10 cm = 2 cm from the midpoint across the bone.
    expected = [[0, 0, 0], [10, 0, 0], [5, 2, 0], [5, 0, 2], [5, -2, 0], [5, 0, -2]]
    np.testing.assert_allclose(vertices[0, 0], expected, atol=1e-12)


def test_skin_error_of_a_shift_by_hand():
    # Every one of the 6 vertices moves 1 cm in each of 4 frames: ||skin_i - orig_i|| = sqrt(6);
    # eq. 3.1 sums over the 4 frames and divides by N - 1 = 3.
    model = one_bone()
    values = np.zeros((4, 7))
    original = forward(model, values, LAYOUT)
    shifted = Pose(original.rotations, original.positions + [1.0, 0, 0])
    assert skin_error(model, original, shifted) == pytest.approx(4 * np.sqrt(6) / 3)
    assert skin_error(model, original, original) == 0.0


def test_skin_error_sees_a_twist_that_joint_positions_miss():
    # A quarter twist of the bone about itself keeps both joints in place, but each of the four
    # side vertices travels a chord of 2 * sqrt(2) cm: per frame sqrt(4 * 8) = sqrt(32).
    model = one_bone()
    original = forward(model, np.zeros((2, 7)), LAYOUT)
    twisted = forward(model, np.array([[0, 0, 0, 0, 0, 0, 90.0]] * 2), LAYOUT)
    assert max_joint_error(original.positions, twisted.positions) < 1e-12
    np.testing.assert_allclose(twisted.rotations[:, 1], np.broadcast_to(axis_rotation("x", np.pi / 2), (2, 3, 3)), atol=1e-15)
    assert skin_error(model, original, twisted) == pytest.approx(2 * np.sqrt(32))


def test_bytes_per_frame():
    assert bytes_per_frame(1000, 250) == 4.0
