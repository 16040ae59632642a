"""Forward and inverse kinematics for Acclaim skeletons, vectorised over frames.

Acclaim convention in row vectors (thesis 3.2.1), for joint j with parent p:

    R_j = C_j^-1 M_j C_j R_p          world rotation (R_root's parent is the identity)
    T_j = T_p + V_j R_j               joint position: end point of bone j, in cm

C_j is the ASF axis matrix, M_j the rotation of the joint's AMC angles applied in
the order its `dof` line lists them (M = R_first @ R_second @ R_third), V_j the
bone vector (direction * length) in cm. The root's T is its TX TY TZ channels
converted to cm; the ASF `root position` is not added (AMC root translations
are absolute, as every CMU reader treats them).

The world rotations R are relative to the base pose: all R = identity draws
the skeleton as the ASF defines it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mocapzip.motion.rotations import euler_angles, rotate_rows_inplace
from mocapzip.motion.skeleton import SkeletonModel


class Pose(NamedTuple):
    """Forward-kinematics result for a clip."""

    rotations: np.ndarray  # (F, J, 3, 3) world rotation R of each joint (row convention)
    positions: np.ndarray  # (F, J, 3) cm: root position, then the end point of each bone


def _to_radians(layout) -> float:
    return np.pi / 180.0 if layout.angle_unit == "deg" else 1.0


def _link(model: SkeletonModel, j: int) -> np.ndarray:
    """K_j = C_j C_p^-1: with bone frames W = C R, the recursion is W_j = M_j K_j W_p."""
    p = model.parents[j]
    return model.axis[j] if p < 0 else model.axis[j] @ model.axis[p].T


def forward(model: SkeletonModel, values: np.ndarray, layout, turns: bool = True) -> Pose:
    """Channels (F, C) laid out as `layout` (a Motion or ChannelLayout) -> Pose (its rotations None
    unless `turns`: positions alone take a third less time).

    Works on bone frames W_j = C_j R_j stored as (3, 3, F) arrays, so each
    elementary rotation touches two rows of a contiguous block; loops run over
    joints and dofs only. Joints missing from the layout keep M = identity.
    """
    layout = model.layout(layout)
    values = np.asarray(values, dtype=np.float64)
    if values.ndim != 2 or values.shape[1] != layout.width:
        raise ValueError(f"values have shape {values.shape}, the layout needs (frames, {layout.width})")
    n_frames, n_joints = len(values), model.n_joints
    to_rad = _to_radians(layout)
    columns = layout.columns()
    frames: list[np.ndarray] = []
    rotations = np.empty((n_joints, 3, 3, n_frames)) if turns else None
    positions = np.zeros((n_joints, 3, n_frames))
    for j, name in enumerate(model.names):
        p = model.parents[j]
        if p < 0:
            frame = np.repeat(model.axis[0][:, :, None], n_frames, axis=2)
        else:
            frame = np.tensordot(_link(model, j), frames[p], axes=1)
        if name in columns:
            chan = values[:, columns[name]]
            for k in reversed(range(len(model.channels[j]))):  # M X = R_a (R_b (R_c X))
                kind, axis = model.channels[j][k]
                if kind == "r":
                    angle = chan[:, k] * to_rad
                    rotate_rows_inplace(frame, axis, np.cos(angle), np.sin(angle))
                else:
                    positions[j, "xyz".index(axis)] = chan[:, k] * model.cm_per_unit
        frames.append(frame)
        if turns:
            rotations[j] = np.tensordot(model.axis[j].T, frame, axes=1)
        if p >= 0:  # V R = (V C^T) W
            positions[j] = positions[p] + np.tensordot(model.offsets[j] @ model.axis[j].T, frame, axes=1)
    return Pose(
        np.ascontiguousarray(rotations.transpose(3, 0, 1, 2)) if turns else None,
        np.ascontiguousarray(positions.transpose(2, 0, 1)),
    )


def inverse(model: SkeletonModel, rotations: np.ndarray, root_positions: np.ndarray, layout) -> np.ndarray:
    """World rotations (F, J, 3, 3) and root positions (F, 3) in cm -> channels (F, C).

    Each joint's M = C_j R_j R_p^-1 C_j^-1 is turned into its dof angles: exact
    for 3-dof joints, the closest expressible rotation for 1- and 2-dof joints,
    and continuous over time (see `rotations.euler_angles`). Angles come out in
    the layout's unit, translations in file length units.
    """
    layout = model.layout(layout)
    rotations = np.asarray(rotations, dtype=np.float64)
    from_rad = 1.0 / _to_radians(layout)
    out = np.zeros((len(rotations), layout.width))
    for bone, cols in layout.columns().items():
        j = model.index[bone]
        p = model.parents[j]
        c_inv = model.axis[j].T
        # M = (C_j R_j)(C_j R_p)^T, written with constant factors on the right (one BLAS call each).
        bone_frame_t = _times(np.swapaxes(rotations[:, j], -1, -2), c_inv)
        if p < 0:
            local = _times(np.swapaxes(bone_frame_t, -1, -2), c_inv)
        else:
            local = np.swapaxes(bone_frame_t, -1, -2) @ _times(np.swapaxes(rotations[:, p], -1, -2), c_inv)
        names = model.channels[j]
        rot = [k for k, c in enumerate(names) if c[0] == "r"]
        if rot:
            axes = "".join(names[k][1] for k in rot)
            out[:, cols.start + np.array(rot)] = euler_angles(local, axes) * from_rad
        for k, c in enumerate(names):
            if c[0] == "t":
                out[:, cols.start + k] = root_positions[:, "xyz".index(c[1])] / model.cm_per_unit
    return out


def _times(stack: np.ndarray, k: np.ndarray) -> np.ndarray:
    """stack @ k for a stack (F, 3, 3) and one 3x3 matrix k, as a single BLAS product."""
    return (np.ascontiguousarray(stack).reshape(-1, 3) @ k).reshape(stack.shape)
