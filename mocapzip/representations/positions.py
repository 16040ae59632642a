"""`positions`: joint positions plus one bone-aligned axis per bone ("virtual markers").

Thesis 3.2.1, compact form. For each bone j the aligned frame A_j = B_j R_j
(B_j the fixed faux matrix of `SkeletonModel.faux`) has its x axis along the
bone, so x is recomputed from the joint positions as child minus parent; only
the y axis is stored, and z = x cross y. The root's rotation is not stored when
a root child has no rotation channels (its rotation *is* the root's; CMU:
lhipjoint). CMU: 31 positions + 30 y axes = 183 values per frame.

Special cases, each stored explicitly so the inverse stays exact:
- short bones (< SHORT_BONE_CM, e.g. Vicon Blade's zero-length hand joints):
  their direction is unusable, so their faux matrix is the identity and their
  x axis is stored as well (3 more values each);
- skeletons whose root children all rotate: the root's x and y axes (6 values).
Leaf bones need nothing special: their end point is a joint position too.

Column order: positions (root first unless the caller drops it), y axes of
bones 1..J-1, x axes of short bones, root axes.
"""

from __future__ import annotations

import numpy as np

from ..kinematics import Pose, forward, inverse
from ..rotations import orthonormal_frame
from ..skeleton import SkeletonModel
from .base import Encoded


def marker_width(model: SkeletonModel, with_root: bool) -> int:
    """Columns of an encoding: positions, y axes, short-bone x axes, root axes."""
    positions = model.n_joints - (0 if with_root else 1)
    root_axes = 2 if model.root_proxy is None else 0
    return 3 * (positions + (model.n_joints - 1) + int(model.short.sum()) + root_axes)


def encode_markers(model: SkeletonModel, pose: Pose, with_root: bool) -> np.ndarray:
    """Pose -> (F, M) marker matrix; without root, the root position is dropped (it must be 0)."""
    n_frames = len(pose.positions)
    aligned = model.faux[None, 1:] @ pose.rotations[:, 1:]
    parts = [
        pose.positions[:, 0 if with_root else 1 :].reshape(n_frames, -1),
        aligned[:, :, 1].reshape(n_frames, -1),
        pose.rotations[:, np.flatnonzero(model.short), 0].reshape(n_frames, -1),
    ]
    if model.root_proxy is None:
        parts.append(pose.rotations[:, 0, :2].reshape(n_frames, -1))
    return np.concatenate(parts, axis=1)


def decode_markers(model: SkeletonModel, poses: np.ndarray, with_root: bool) -> Pose:
    """(F, M) marker matrix -> Pose. Rotations are re-orthonormalised, so a lossy
    matrix still gives proper rotations; positions are returned as stored."""
    poses = np.asarray(poses, dtype=np.float64)
    width = marker_width(model, with_root)
    if poses.ndim != 2 or poses.shape[1] != width:
        raise ValueError(f"poses have shape {poses.shape}, this skeleton needs (frames, {width})")
    n_frames, n_joints = len(poses), model.n_joints
    first = 0 if with_root else 1
    short = np.flatnonzero(model.short)
    cuts = np.cumsum([3 * (n_joints - first), 3 * (n_joints - 1), 3 * len(short)])
    positions = np.zeros((n_frames, n_joints, 3))
    positions[:, first:] = poses[:, : cuts[0]].reshape(n_frames, -1, 3)
    y_axes = poses[:, cuts[0] : cuts[1]].reshape(n_frames, -1, 3)
    x_axes = positions[:, 1:] - positions[:, model.parents[1:]]
    x_axes[:, short - 1] = poses[:, cuts[1] : cuts[2]].reshape(n_frames, -1, 3)
    rotations = np.empty((n_frames, n_joints, 3, 3))
    rotations[:, 1:] = np.swapaxes(model.faux[1:], -1, -2) @ orthonormal_frame(x_axes, y_axes)  # R = B^T A
    if model.root_proxy is None:
        root_axes = poses[:, cuts[2] :].reshape(n_frames, 2, 3)
        rotations[:, 0] = orthonormal_frame(root_axes[:, 0], root_axes[:, 1])
    else:
        rotations[:, 0] = rotations[:, model.root_proxy]
    return Pose(rotations, positions)


class Positions:
    name = "positions"

    def forward(self, model: SkeletonModel, motion) -> Encoded:
        return Encoded(encode_markers(model, forward(model, motion.values, motion), with_root=True))

    def inverse(self, model: SkeletonModel, encoded: Encoded, layout) -> np.ndarray:
        pose = decode_markers(model, encoded.poses, with_root=True)
        return inverse(model, pose.rotations, pose.positions[:, 0], layout)
