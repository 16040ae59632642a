"""Error and size measures for a reconstructed clip against its original.

Joint errors follow Hou et al.: the Euclidean distance (cm) between original
and reconstructed joint positions, averaged over frames and joints. The skin
error is the thesis's eq. 3.1 on a faux mesh (see `skin_vertices`).
"""

from __future__ import annotations

import numpy as np

from mocapzip.motion.kinematics import Pose
from mocapzip.motion.skeleton import SkeletonModel

# Faux mesh: the four side vertices of each bone's octahedron sit this fraction of
# the bone's length away from its midpoint.
SKIN_RADIUS = 0.2


def joint_distances(original: np.ndarray, reconstructed: np.ndarray) -> np.ndarray:
    """(F, J) distance in cm between joint positions (F, J, 3) of two clips."""
    return np.linalg.norm(np.asarray(reconstructed) - np.asarray(original), axis=-1)


def mean_joint_error(original: np.ndarray, reconstructed: np.ndarray) -> float:
    """Mean over frames and joints of the joint distance (cm)."""
    return float(joint_distances(original, reconstructed).mean())


def max_joint_error(original: np.ndarray, reconstructed: np.ndarray) -> float:
    """Largest distance (cm) of any joint in any frame."""
    return float(joint_distances(original, reconstructed).max())


def frame_errors(original: np.ndarray, reconstructed: np.ndarray) -> np.ndarray:
    """(F,) mean joint distance of each frame (cm): feed np.percentile for tails."""
    return joint_distances(original, reconstructed).mean(axis=1)


def skin_vertices(model: SkeletonModel, pose: Pose) -> np.ndarray:
    """(F, J-1, 6, 3) vertices in cm of a faux mesh: one octahedron per bone.

    Bone j's octahedron has its two tips on the bone's joints (start and end)
    and four side vertices around the midpoint, SKIN_RADIUS x length away along
    the faux frame's y and z axes (`SkeletonModel.faux`), so a twist of the bone
    moves them. Vertices are built in the base pose and carried by the bone's
    world rotation: v = T_parent + v_base R_j. Zero-length bones collapse to a point.
    """
    offsets, faux = model.offsets[1:], model.faux[1:]
    side = SKIN_RADIUS * model.lengths[1:, None, None] * faux[:, 1:]  # (J-1, 2, 3): r y, r z
    mid = offsets[:, None] / 2
    base = np.concatenate([np.zeros_like(mid), offsets[:, None], mid + side, mid - side], axis=1)  # (J-1, 6, 3)
    start = pose.positions[:, model.parents[1:]]
    return start[:, :, None] + base[None] @ pose.rotations[:, 1:]


def skin_error(model: SkeletonModel, original: Pose, reconstructed: Pose) -> float:
    """Thesis eq. 3.1: (1 / (N - 1)) sum_i || skin_i - skinOrig_i ||, in cm.

    skin_i stacks all mesh vertices of frame i into one vector (540 values for
    CMU's 30 bones); N is the number of frames. The thesis's N - 1 is kept for
    comparability (a one-frame clip divides by 1).
    """
    diff = skin_vertices(model, reconstructed) - skin_vertices(model, original)
    per_frame = np.sqrt(np.sum(diff.reshape(len(diff), -1) ** 2, axis=1))
    return float(per_frame.sum() / max(len(per_frame) - 1, 1))


def bytes_per_frame(n_bytes: int, n_frames: int) -> float:
    """Compressed size per frame of animation (thesis 3.1.1), so clips of any length compare."""
    return n_bytes / n_frames
