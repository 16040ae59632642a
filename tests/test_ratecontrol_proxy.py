"""The rate control's error proxies measure what they say (synthetic data: this is their maths;
real clips are coded end to end in test_codec_roundtrip.py)."""

import math

import numpy as np
import pytest

from mocapzip.codec.clip_stream import scale_root, unscale_root
from mocapzip.codec.quantise import UniformQuantiser
from mocapzip.motion.rotations import axis_rotation
from mocapzip.ratecontrol.proxy import CodingProxy, TruncationProxy, mean_joint_error
from mocapzip.stages import get_stage

FRAMES, JOINTS, AXES = 96, 4, 3  # poses: 3 columns per joint, then 3 weighted bone-axis columns
COLUMNS = slice(0, 3 * JOINTS)


def joint_errors(error: np.ndarray, columns: slice, shift: np.ndarray | None = None) -> np.ndarray:
    """The definition `mean_joint_error` computes in one pass, in numpy: per frame and joint, the
    norm of its position columns plus `shift` and of the axis columns spread over the joints."""
    positions = error[:, columns].reshape(len(error), -1, 3)
    if shift is not None:
        positions = positions + shift
    rest = (error[:, columns.stop:] ** 2).sum(axis=1, keepdims=True)
    if positions.shape[1] == 0:
        return np.sqrt(rest)
    return np.sqrt((positions**2).sum(axis=2) + rest / positions.shape[1])


@pytest.mark.parametrize("frames", [1, 7, 96])
@pytest.mark.parametrize("columns", [slice(0, 0), slice(0, 3), COLUMNS, slice(0, 3 * JOINTS + AXES)])
def test_mean_joint_error_is_its_definition(frames, columns):
    rng = np.random.default_rng(frames)
    error = rng.normal(size=(frames, 3 * JOINTS + AXES))
    assert mean_joint_error(error, columns) == pytest.approx(joint_errors(error, columns).mean(), rel=1e-12)


@pytest.mark.parametrize("frames", [1, 7, 96])
def test_mean_joint_error_moves_joints_by_the_root_error(frames):
    rng = np.random.default_rng(frames)
    error = rng.normal(size=(frames, 3 * JOINTS + AXES))
    root = rng.normal(size=(frames, 4))
    to_character = np.swapaxes(axis_rotation("y", rng.uniform(-np.pi, np.pi, frames)), -1, -2)  # not contiguous
    lever = rng.normal(scale=30.0, size=(frames, JOINTS, 3))
    shift = root[:, None, :3] @ to_character
    joints = joint_errors(error, COLUMNS, shift + root[:, 3, None, None] * lever)
    expected = (joints.sum() + np.sqrt((shift**2).sum(axis=2)).sum()) / (joints.size + frames)
    assert mean_joint_error(error, COLUMNS, root, to_character, lever) == pytest.approx(expected, rel=1e-12)


def orthonormal_basis(rng, width: int, q: int) -> np.ndarray:
    return np.linalg.qr(rng.normal(size=(width, q)))[0]


def smooth_curves(rng, frames: int, count: int, scale: float) -> np.ndarray:
    return np.cumsum(rng.normal(scale=scale, size=(frames, count)), axis=0)


def decoded_curves(coef, transform, step, dead_zone, band):
    quantiser = UniformQuantiser(step, dead_zone)
    ints = quantiser.quantise(coef)
    ints[math.ceil(band * len(coef)):] = 0
    return transform.inverse(quantiser.dequantise(ints), len(coef))


@pytest.mark.parametrize("transform_id", ["dct", "dct-edges", "dwt", "identity"])
@pytest.mark.parametrize("step,band", [(1e-4, 1.0), (0.5, 1.0), (2.0, 0.3), (8.0, 0.1)])
def test_without_a_root_track_the_proxy_is_the_error_of_the_decoded_poses(transform_id, step, band):
    rng = np.random.default_rng(3)
    transform = get_stage("transform", {"id": transform_id})
    basis = orthonormal_basis(rng, 3 * JOINTS + AXES, 5)
    mean = rng.normal(size=3 * JOINTS + AXES)
    poses = mean + smooth_curves(rng, FRAMES, 3 * JOINTS + AXES, 1.0)
    projected = (poses - mean) @ basis
    coef = transform.forward(projected)
    sample = slice(None, None, 3)
    proxy = CodingProxy(coef, None, basis, COLUMNS, poses - mean - projected @ basis.T, transform, 0.2, None, sample)
    decoded = mean + decoded_curves(coef, transform, step, 0.2, band) @ basis.T
    expected = joint_errors(poses - decoded, COLUMNS)[sample].mean()
    assert proxy(step, 1.0, band) == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize("transform_id", ["dct", "dct-edges"])  # dct-edges: the pose's and root's first columns
@pytest.mark.parametrize("band", [1.0, 0.3])
def test_a_root_track_error_is_measured_in_the_world(band, transform_id):
    """The linearised root track error agrees with the exact one while it is small."""
    rng = np.random.default_rng(5)
    transform = get_stage("transform", {"id": transform_id})
    local = rng.normal(scale=40.0, size=(FRAMES, JOINTS, 3))  # joints in the character frame, cm
    poses = np.concatenate([local.reshape(FRAMES, -1), rng.normal(size=(FRAMES, AXES))], axis=1)
    basis = np.eye(poses.shape[1])  # keeps everything: the error is the root track's and the quantiser's
    root = np.column_stack([smooth_curves(rng, FRAMES, 3, 2.0), np.cumsum(rng.normal(scale=0.05, size=FRAMES))])
    pose_coef, root_coef = transform.forward(poses), transform.forward(scale_root(root))
    proxy = CodingProxy(pose_coef, root_coef, basis, COLUMNS, np.zeros_like(poses), transform, 0.0,
                        (local, root[:, 3]))
    step, root_step = 0.05, 0.02
    decoded = decoded_curves(pose_coef, transform, step, 0.0, band)
    decoded_root = unscale_root(decoded_curves(root_coef, transform, root_step, 0.0, band))

    def world(local_positions, track):
        return local_positions @ axis_rotation("y", track[:, 3]) + track[:, None, :3]

    joints = np.linalg.norm(world(local, root) - world(decoded[:, COLUMNS].reshape(FRAMES, JOINTS, 3), decoded_root),
                            axis=2)
    axes = ((poses - decoded)[:, COLUMNS.stop:] ** 2).sum(axis=1, keepdims=True) / JOINTS
    root_joint = np.linalg.norm((root - decoded_root)[:, :3], axis=1)[:, None]
    exact = np.concatenate([np.sqrt(joints**2 + axes), root_joint], axis=1).mean()
    assert proxy(step, root_step, band) == pytest.approx(exact, rel=0.02)


@pytest.mark.parametrize("transform_id", ["dct", "dct-edges"])
@pytest.mark.parametrize("frames", [97, 1000, 1009])  # 1009 is prime: its DCT is slow, so more rows are synthesised
@pytest.mark.parametrize("band", [0.02, 0.1, 0.3, 1.0])
def test_a_band_decoded_by_synthesis_measures_what_the_inverse_transform_does(frames, band, transform_id):
    rng = np.random.default_rng(frames)
    transform = get_stage("transform", {"id": transform_id})
    width = 3 * JOINTS + AXES
    basis = orthonormal_basis(rng, width, 5)
    poses = smooth_curves(rng, frames, width, 1.0)
    root = np.column_stack([smooth_curves(rng, frames, 3, 2.0), smooth_curves(rng, frames, 1, 0.01)])
    character = (poses[:, COLUMNS].reshape(frames, -1, 3), root[:, 3])
    args = (transform.forward(poses @ basis), transform.forward(scale_root(root)), basis, COLUMNS,
            poses - poses @ basis @ basis.T, transform, 0.2, character, slice(None, None, 8))
    synthesised, inverted = CodingProxy(*args), CodingProxy(*args)
    inverted._synthesised_rows = 0
    assert synthesised.kept_rows(band) <= synthesised._synthesised_rows or band == 1.0
    for step in (0.05, 0.5, 3.0):
        assert synthesised(step, step / 4, band) == pytest.approx(inverted(step, step / 4, band), rel=1e-12)


def test_the_truncation_proxy_is_the_error_of_the_truncated_poses():
    rng = np.random.default_rng(7)
    width = 3 * JOINTS + AXES
    components = orthonormal_basis(rng, width, width)
    mean = rng.normal(size=width)
    poses = mean + smooth_curves(rng, FRAMES, width, 1.0)
    proxy = TruncationProxy(poses, mean, components, COLUMNS)
    for q in (0, 3, width):
        truncated = mean + (poses - mean) @ components[:, :q] @ components[:, :q].T
        assert proxy(q) == pytest.approx(joint_errors(poses - truncated, COLUMNS).mean(), rel=1e-9, abs=1e-12)
    assert proxy(width) == pytest.approx(0.0, abs=1e-9)


def test_root_and_pose_errors_that_cancel_in_the_world_are_not_counted():
    """Joints standing still in the world while the heading wobbles fast: the character frame
    wobbles the other way, a narrow band drops both wobbles, and the world hardly moves."""
    rng = np.random.default_rng(11)
    transform = get_stage("transform", {"id": "dct"})
    still = rng.normal(scale=40.0, size=(1, JOINTS, 3))
    heading = 0.05 * np.sin(np.arange(FRAMES) * 2.5)  # fast: above the band kept below
    local = still @ np.swapaxes(axis_rotation("y", heading), -1, -2)
    poses = np.concatenate([local.reshape(FRAMES, -1), np.zeros((FRAMES, AXES))], axis=1)
    root = np.column_stack([np.zeros((FRAMES, 3)), heading])
    proxy = CodingProxy(transform.forward(poses), transform.forward(scale_root(root)), np.eye(poses.shape[1]), COLUMNS,
                        np.zeros_like(poses), transform, 0.0, (local, heading))
    dropped = CodingProxy(transform.forward(poses), None, np.eye(poses.shape[1]), COLUMNS, np.zeros_like(poses),
                          transform, 0.0)
    assert dropped(1e-6, 1e-6, 0.2) > 1.0  # the pose alone loses centimetres ...
    assert proxy(1e-6, 1e-6, 0.2) < 0.1 * dropped(1e-6, 1e-6, 0.2)  # ... which the root track gives back
