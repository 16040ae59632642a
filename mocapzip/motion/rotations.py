"""Rotation matrices and Euler angles, vectorised over frames.

Convention (the thesis's, and Acclaim's): **row vectors**. A point p (a row) is
rotated as ``p @ R``, the rows of R are the rotated x, y, z axes, and a product
``A @ B`` applies A first, then B. ``euler_matrix(angles, "xyz")`` is therefore
Rx @ Ry @ Rz: the x rotation is applied first, as an Acclaim ``dof rx ry rz``
line means. (The column-vector matrix of the same rotation is the transpose.)

Axes are given as strings of 'x', 'y', 'z' ("xyz", "zx", "y"). Angles are in
radians here; callers convert file degrees.
"""

from __future__ import annotations

import numpy as np

AXIS_INDEX = {"x": 0, "y": 1, "z": 2}

# Angles whose cosine of the middle Euler angle is below this are in gimbal lock:
# the first and last angle then describe the same rotation and only their
# combination is determined.
_GIMBAL = 1e-9
# Alternating 1-dof fits for 2-dof joints (see `euler_angles`): stop when no angle
# moves more than _TWO_DOF_TOLERANCE (one round when m is expressible), or after
# _TWO_DOF_ROUNDS (small residuals, as after lossy compression, need a few).
_TWO_DOF_ROUNDS = 20
_TWO_DOF_TOLERANCE = 1e-13


def _others(axis: int) -> tuple[int, int]:
    """The two axes after `axis` in cyclic order (x -> y, z; y -> z, x; z -> x, y)."""
    return (axis + 1) % 3, (axis + 2) % 3


def axis_rotation(axis: str, angles) -> np.ndarray:
    """Rotations by `angles` (radians, any shape S) about one axis: shape S + (3, 3)."""
    k = AXIS_INDEX[axis]
    b, c = _others(k)
    angles = np.asarray(angles, dtype=np.float64)
    cos, sin = np.cos(angles), np.sin(angles)
    out = np.zeros(angles.shape + (3, 3))
    out[..., k, k] = 1.0
    out[..., b, b] = cos
    out[..., c, c] = cos
    out[..., b, c] = sin  # row convention: the transpose of the textbook matrix
    out[..., c, b] = -sin
    return out


def euler_matrix(angles, axes: str) -> np.ndarray:
    """R_axes[0](angles[..., 0]) @ R_axes[1](...) @ ...: shape angles.shape[:-1] + (3, 3)."""
    angles = np.asarray(angles, dtype=np.float64)
    out = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for i, axis in enumerate(axes):
        out = out @ axis_rotation(axis, angles[..., i])
    return out


def rotate_rows_inplace(rows: np.ndarray, axis: str, cos: np.ndarray, sin: np.ndarray) -> None:
    """rows := R_axis @ rows for a stack stored as (3, 3, F) (row index first).

    Kinematics uses this to left-multiply by an elementary rotation touching only
    two rows, which is far cheaper than a general batched 3x3 product.
    """
    b, c = _others(AXIS_INDEX[axis])
    rb, rc = rows[b].copy(), rows[c]
    rows[b] = cos * rb + sin * rc
    rows[c] = cos * rc - sin * rb


def angle_about(axis: str, m: np.ndarray) -> np.ndarray:
    """The angle of the rotation about `axis` closest to m (..., 3, 3).

    Exact when m is such a rotation; otherwise it maximises trace(m^T R), i.e.
    minimises the angle between m and the result (the least-squares answer).
    """
    b, c = _others(AXIS_INDEX[axis])
    return np.arctan2(m[..., b, c] - m[..., c, b], m[..., b, b] + m[..., c, c])


def wrap(angles):
    """Angles mapped to [-pi, pi)."""
    return (np.asarray(angles) + np.pi) % (2 * np.pi) - np.pi


def euler_angles(m: np.ndarray, axes: str) -> np.ndarray:
    """Angles (F, len(axes)) with euler_matrix(angles, axes) closest to m (F, 3, 3).

    - 3 axes: exact decomposition. Of the two solutions each frame has, the one
      nearest the previous frame's is kept, then every angle is unwrapped over
      time, so curves stay smooth across +-180 degrees and through the poles.
    - 1 axis: closed form (`angle_about`).
    - 2 axes: least squares. Start from the 3-axis decomposition completed with
      the missing axis (its solution with the smallest third angle), then
      alternate the exact 1-axis fit of each angle with the other held fixed;
      every step can only bring the result closer to m.
    """
    m = np.asarray(m, dtype=np.float64)
    if len(axes) == 1:
        return np.unwrap(angle_about(axes, m))[:, None]
    if len(axes) == 3:
        return _continuous(*_tait_bryan(m, axes))
    if len(axes) == 2:
        return np.unwrap(_two_axis_fit(m, axes), axis=0)
    raise ValueError(f"Euler axes must name 1 to 3 distinct axes, got {axes!r}")


def _two_axis_fit(m: np.ndarray, axes: str) -> np.ndarray:
    """(F, 2) angles of the rotation R_axes[0] @ R_axes[1] closest to m (see `euler_angles`)."""
    missing = next(a for a in "xyz" if a not in axes)
    first, second, third = _tait_bryan(m, axes + missing)
    other_solution = np.abs(wrap(third + np.pi)) < np.abs(wrap(third))  # its third angle is nearer 0
    first = np.where(other_solution, first + np.pi, first)
    second = np.where(other_solution, np.pi - second, second)
    for _ in range(_TWO_DOF_ROUNDS):
        before = np.stack([first, second])
        first = angle_about(axes[0], m @ _transpose(axis_rotation(axes[1], second)))
        second = angle_about(axes[1], _transpose(axis_rotation(axes[0], first)) @ m)
        if np.abs(wrap(np.stack([first, second]) - before)).max() < _TWO_DOF_TOLERANCE:
            break
    return np.stack([first, second], axis=1)


def _transpose(m: np.ndarray) -> np.ndarray:
    return np.swapaxes(m, -1, -2)


def _tait_bryan(m: np.ndarray, axes: str):
    """One exact solution (a, b, c) of m = R_axes[0](a) @ R_axes[1](b) @ R_axes[2](c).

    The middle angle is in [-pi/2, pi/2]. In gimbal lock (middle angle at
    +-90 degrees) the first angle is carried over from the previous frame and the
    last solved for, which keeps curves continuous there too.
    """
    if len(set(axes)) != 3:
        raise ValueError(f"Euler axes must be three distinct axes, got {axes!r}")
    a, b, c = (AXIS_INDEX[x] for x in axes)
    sign = 1.0 if (b - a) % 3 == 1 else -1.0  # +1 for the cyclic orders xyz, yzx, zxy
    cos_middle = np.hypot(m[:, b, c], m[:, c, c])
    first = np.arctan2(sign * m[:, b, c], m[:, c, c])
    middle = np.arctan2(-sign * m[:, a, c], cos_middle)
    locked = cos_middle < _GIMBAL
    if np.any(locked):
        # index of the latest unlocked frame at or before each frame (-1: none yet -> angle 0)
        last_free = np.maximum.accumulate(np.where(locked, -1, np.arange(len(m))))
        carried = np.where(last_free >= 0, first[np.maximum(last_free, 0)], 0.0)
        first = np.where(locked, carried, first)
    residual = _transpose(axis_rotation(axes[0], first) @ axis_rotation(axes[1], middle)) @ m
    last = angle_about(axes[2], residual)
    return first, middle, last


def _continuous(first, middle, last) -> np.ndarray:
    """Pick per frame the Euler solution nearest the previous frame, then unwrap.

    Each frame has two solutions, (a, b, c) and (a + pi, pi - b, c + pi). The
    distance between consecutive frames is the same when both stay on their
    branch, and the same when either switches, so "nearest to the previous
    choice" reduces to: switch branch where switching is the shorter step, and
    the branch of each frame is the running parity of those switches.
    """
    canon = np.stack([first, middle, last], axis=1)
    alt = np.stack([first + np.pi, np.pi - middle, last + np.pi], axis=1)
    stay = np.sum(wrap(np.diff(canon, axis=0)) ** 2, axis=1)
    switch = np.sum(wrap(alt[1:] - canon[:-1]) ** 2, axis=1)
    branch = np.concatenate([[0], np.cumsum(switch < stay) % 2]).astype(bool)
    chosen = np.where(branch[:, None], alt, canon)
    return np.unwrap(chosen, axis=0)


def orthonormal_frame(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) with rows x, y', z: x normalised, y' the part of
    y perpendicular to x, normalised, z = x cross y'. Recovers a rotation from two
    of its (possibly noisy) axes."""
    x = x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-300)
    y = y - np.sum(y * x, axis=-1, keepdims=True) * x
    y = y / np.maximum(np.linalg.norm(y, axis=-1, keepdims=True), 1e-300)
    return np.stack([x, y, np.cross(x, y)], axis=-2)


def rotation_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (radians) of the rotation taking a to b, accurate for tiny angles."""
    chord = np.linalg.norm(np.asarray(a) - np.asarray(b), axis=(-2, -1))
    return 2.0 * np.arcsin(np.minimum(chord / np.sqrt(8.0), 1.0))
