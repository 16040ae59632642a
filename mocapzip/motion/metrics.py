"""Error and size measures for a reconstructed clip against its original.

Joint errors follow Hou et al.: the Euclidean distance (cm) between original
and reconstructed joint positions, averaged over frames and joints. The skin
error is the thesis's eq. 3.1 on a faux mesh (see `skin_vertices`). The shell
error is ACL's (Animation Compression Library) metric: virtual vertices a shell
distance from every bone, worst over bones and frames (see `shell_errors`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np

from mocapzip.defaults import ACL_SHELL_CM
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


class ShellBones(NamedTuple):
    """The rigid frames ACL's metric measures on a skeleton model, as a game engine's skeleton of it
    has them: one per model joint j at the START of its bone (the joint it turns about; the root at
    the root position), turned by j's world rotation, so its axes are the world's in the model's
    base pose; and one more at the end of every leaf bone ("<name>_end", a BVH End Site), turned
    with it. Every joint position that mcz's joint errors measure is thus some frame's origin."""

    names: tuple[str, ...]
    parents: np.ndarray  # (B,) the parent frame of each frame, -1 for the root's
    rotation_of: np.ndarray  # (B,) the model joint whose world rotation turns the frame
    origin_at: np.ndarray  # (B,) the model joint whose position is the frame's origin


def shell_bones(model: SkeletonModel) -> ShellBones:
    """The frames of `model` that `shell_errors` measures (see ShellBones)."""
    parents = model.parents
    joints = np.arange(model.n_joints)
    leaves = np.setdiff1d(joints, parents)
    return ShellBones(
        names=tuple(model.names) + tuple(f"{model.names[j]}_end" for j in leaves),
        parents=np.concatenate([parents, leaves]),
        rotation_of=np.concatenate([joints, leaves]),
        origin_at=np.concatenate([np.maximum(parents, 0), leaves]),
    )


def shell_frames(model: SkeletonModel, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
    """((F, B, 3, 3) axes, (F, B, 3) origins in cm) of the `shell_bones` frames of a posed clip, in
    object space (ACL's: the root's parent space, here the clip's world). Row k of a frame's axes
    is its local k axis in the world (the row convention of `mocapzip.motion.rotations`)."""
    bones = shell_bones(model)
    return pose.rotations[:, bones.rotation_of], pose.positions[:, bones.origin_at]


@dataclass(frozen=True)
class ShellError:
    """ACL's error of a clip: per frame and bone the worst of its three shell vertices (cm)."""

    errors: np.ndarray  # (F, B) cm
    names: tuple[str, ...]  # the B frames (`shell_bones`)

    @cached_property
    def worst(self) -> float:
        """ACL's max error: the worst vertex of any bone in any frame (cm)."""
        return float(self.errors.max())

    @cached_property
    def per_bone(self) -> np.ndarray:
        """(B,) each bone's worst over frames (cm)."""
        return self.errors.max(axis=0)

    @cached_property
    def per_frame(self) -> np.ndarray:
        """(F,) each frame's worst over bones (cm)."""
        return self.errors.max(axis=1)

    @property
    def worst_bone(self) -> str:
        return self.names[int(np.argmax(self.per_bone))]

    @property
    def worst_frame(self) -> int:
        return int(np.argmax(self.per_frame))


def shell_errors(model: SkeletonModel, original: Pose, reconstructed: Pose, shell_cm: float = ACL_SHELL_CM) -> ShellError:
    """ACL's transform error metric (its qvvf_transform_error_metric, as acl_compressor reports it):
    for every `shell_bones` frame, the vertices `shell_cm` along its local x, y and z axes, carried by
    the frame in object space; the error of a bone in a frame is the largest distance between a
    vertex in `original` and in `reconstructed`. It sees what joint positions cannot: a twist of
    an end bone about itself moves no joint, but moves the vertices off its axis."""
    errors = shell_vertex_errors(*shell_frames(model, original), *shell_frames(model, reconstructed), shell_cm)
    return ShellError(errors, shell_bones(model).names)


def shell_vertex_errors(axes: np.ndarray, origins: np.ndarray, new_axes: np.ndarray, new_origins: np.ndarray,
                        shell_cm: float = ACL_SHELL_CM) -> np.ndarray:
    """(F, B) the worst distance of the three shell vertices between two sets of frames (axes
    (F, B, 3, 3) with rows the local axes, origins (F, B, 3) cm): `shell_errors` on frames that come
    from elsewhere (a decode of ACL's, read back)."""
    moved = (new_origins - origins)[:, :, None, :] + shell_cm * (new_axes - axes)  # (F, B, 3 vertices, 3)
    return np.linalg.norm(moved, axis=-1).max(axis=-1)


def bytes_per_frame(n_bytes: int, n_frames: int) -> float:
    """Compressed size per frame of animation (thesis 3.1.1), so clips of any length compare."""
    return n_bytes / n_frames
