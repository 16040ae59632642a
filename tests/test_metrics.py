"""Error measures on cases small enough to work out by hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mocapzip.archive.reader import Archive
from mocapzip.defaults import ACL_SHELL_CM
from mocapzip.formats.asf import parse_asf, read_asf
from mocapzip.formats.amc import read_amc
from mocapzip.motion.kinematics import Pose, forward
from mocapzip.motion.metrics import (
    SKIN_RADIUS,
    bytes_per_frame,
    frame_errors,
    joint_distances,
    max_joint_error,
    mean_joint_error,
    shell_bones,
    shell_errors,
    shell_frames,
    skin_error,
    skin_vertices,
)
from mocapzip.motion.rotations import axis_rotation, rotation_angle
from mocapzip.motion.skeleton import ChannelLayout, SkeletonModel

GOLDEN = Path(__file__).parent / "golden"

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


def test_shell_bones_put_a_frame_at_each_bone_start_and_at_the_leaf_ends():
    bones = shell_bones(one_bone())
    assert bones.names == ("root", "arm", "arm_end")
    np.testing.assert_array_equal(bones.parents, [-1, 0, 1])
    np.testing.assert_array_equal(bones.rotation_of, [0, 1, 1])  # the end turns with its bone
    np.testing.assert_array_equal(bones.origin_at, [0, 0, 1])  # the arm turns about the root position


def test_a_twist_of_an_end_bone_moves_no_joint_but_its_shell_vertices_by_the_chord():
    # The arm twists theta about its own x axis: both joints stay, the vertices 3 cm along y and z
    # travel the chord 2 sin(theta / 2) x 3 cm, the one along x stays; the root does not move.
    assert ACL_SHELL_CM == 3.0
    model = one_bone()
    theta = np.array([0.0, 10.0, 90.0, 180.0])
    original = forward(model, np.zeros((4, 7)), LAYOUT)
    twisted = forward(model, np.column_stack([np.zeros((4, 6)), theta]), LAYOUT)
    assert max_joint_error(original.positions, twisted.positions) < 1e-12
    error = shell_errors(model, original, twisted)
    chord = 2 * np.sin(np.radians(theta) / 2) * 3.0
    np.testing.assert_allclose(error.errors, np.column_stack([np.zeros(4), chord, chord]), atol=1e-12)
    assert error.worst == pytest.approx(6.0)
    assert error.worst_frame == 3 and error.worst_bone == "arm"  # the first of the arm's two frames
    np.testing.assert_allclose(error.per_frame, chord, atol=1e-12)
    np.testing.assert_allclose(error.per_bone, [0, 6, 6], atol=1e-12)
    assert shell_errors(model, original, twisted, shell_cm=1.0).worst == pytest.approx(2.0)


def test_a_translation_moves_every_vertex_by_as_much():
    model = one_bone()
    values = np.zeros((3, 7))
    values[:, 6] = [0.0, 30.0, 60.0]  # a bent arm: the frames are not all the world's axes
    original = forward(model, values, LAYOUT)
    shift = np.array([1.0, -2.0, 2.0])  # 3 cm
    error = shell_errors(model, original, Pose(original.rotations, original.positions + shift))
    np.testing.assert_allclose(error.errors, np.full((3, 3), 3.0), rtol=1e-12)


def test_shell_error_is_bounded_by_joint_moves_and_turns_on_a_decoded_cmu_clip(shared_data):
    # A golden archive's decode of real CMU clips (1 cm mean, 3 cm worst joint). For a frame
    # whose origin moves by d and whose axes turn by theta, each vertex moves by d plus a chord
    # c = 2 sin(theta / 2) x 3 cm at most (triangle inequality), so the worst of the three lies in
    # [d - c, d + c]; and as the squared sines of the three axes to the turn's axis sum to 2, one of
    # them is at least sqrt(2/3): the worst vertex is at least c sqrt(2/3) - d.
    with Archive(GOLDEN / "lossy_v12.mcz") as archive:
        rows = [(i, row) for i, row in enumerate(archive.clips) if "bvh" not in row]
        assert rows
        for i, row in rows:
            folder = shared_data / "cmu" / row["path"].split("_")[0]
            model = SkeletonModel.from_asf(read_asf(folder / f"{folder.name}.asf"))
            source, decoded = read_amc(folder / row["path"]), archive.decode(i)
            original, reconstructed = forward(model, source.values, source), forward(model, decoded.values, decoded)
            error = shell_errors(model, original, reconstructed)
            axes, origins = shell_frames(model, original)
            new_axes, new_origins = shell_frames(model, reconstructed)
            moved = np.linalg.norm(new_origins - origins, axis=-1)
            chord = 2 * np.sin(rotation_angle(axes, new_axes) / 2) * ACL_SHELL_CM
            assert error.errors.shape == moved.shape == (source.n_frames, model.n_joints + 7)  # 7 leaves: toes, head, fingers, thumbs
            assert np.all(error.errors <= moved + chord + 1e-9)
            assert np.all(error.errors >= moved - chord - 1e-9)
            assert np.all(error.errors >= chord * np.sqrt(2 / 3) - moved - 1e-9)
            # every joint mcz measures is a frame's origin: its distance is one of `moved`'s columns
            distances = joint_distances(original.positions, reconstructed.positions)
            for j in range(model.n_joints):
                assert np.any(np.all(np.isclose(moved, distances[:, j:j + 1], atol=1e-12), axis=0)), model.names[j]
            assert error.worst >= distances.max() - chord.max()
            assert error.worst_bone in error.names and 0 <= error.worst_frame < source.n_frames
