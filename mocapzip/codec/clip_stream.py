"""A clip's quantised transform coefficients as the archive stores them (`clip/NNNNN`), and
the way back from them to weighted poses and root track.

Layout (format 2 on; docs/format.md): `f32 pose_step`, `f32 root_step`, then one matrices
stream of the coefficient coder named in the settings ("context" or "primed",
`mocapzip.codec.entropy.coefficients`): the frames x Q pose coefficients and, for the
representations with a root track, its frames x `Representation.root_width` coefficients
(x, y, z, yaw: `representations.base.ROOT_TRACK_WIDTH`). Format 1's layout is read by
`mocapzip.legacy.streams`.

The root track is scaled into the pose's units (cm) before its transform, yaw by a typical
joint radius, because a yaw error moves a joint by (distance from root) x (angle).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from mocapzip.codec.basis import ClassBasis, unpack
from mocapzip.codec.entropy.coefficients import Priors, matrix_shapes
from mocapzip.codec.quantise import UniformQuantiser
from mocapzip.stages import get_stage

YAW_RADIUS_CM = 50.0  # a typical joint's distance from the root: yaw error x this = cm


@dataclass
class CodedClip:
    """A clip's quantised coefficients: what the archive stores for it."""

    pose_step: float
    pose_ints: np.ndarray  # (frames, Q) transform coefficients
    root_step: float
    root_ints: np.ndarray | None  # (frames, ROOT_TRACK_WIDTH), or None for representations without a root track

    @property
    def matrices(self) -> list[np.ndarray]:
        return [self.pose_ints] if self.root_ints is None else [self.pose_ints, self.root_ints]

    def payload(self, coder: str = "context", priors: Priors | None = None) -> bytes:
        """The stream, its matrices coded by the coefficient coder `coder` (`priors`: the archive's, for "primed")."""
        return struct.pack("<ff", self.pose_step, self.root_step) + coefficient_coder(coder).encode(self.matrices, priors)

    @classmethod
    def from_payload(cls, blob: bytes, coder: str = "context", shapes=None,
                     priors: Priors | None = None) -> "CodedClip":
        """`shapes`: the pose and root matrices' shapes when the caller knows them (checked first).

        The payload may come from anyone: its matrix count and shapes are checked (against
        `shapes` and the limits) before anything is allocated for them.
        """
        pose_step, root_step = unpack("<ff", blob, 0)
        count = len(matrix_shapes(blob[8:]))
        if not 1 <= count <= 2:
            raise ValueError(f"clip payload holds {count} matrices")
        arrays = coefficient_coder(coder, reading=True).decode(blob[8:], shapes, priors)
        return cls(pose_step, arrays[0], root_step, arrays[1] if len(arrays) > 1 else None)


def coefficient_coder(coder: str, reading: bool = False):
    """The registered coefficient coder `coder`; a decode-only one (an old format's) only for `reading`."""
    stage = get_stage("coefficient coder", {"id": coder})
    if getattr(stage, "decode_only", False) and not reading:
        raise ValueError(f"coefficient coder {coder!r} is read only (format 1); it is never written")
    return stage


def scale_root(root: np.ndarray) -> np.ndarray:
    """Root track (x, y, z cm, yaw rad) in cm-equivalent units."""
    return root * np.array([1.0, 1.0, 1.0, YAW_RADIUS_CM])


def unscale_root(scaled: np.ndarray) -> np.ndarray:
    return scaled / np.array([1.0, 1.0, 1.0, YAW_RADIUS_CM])


def dequantise_curves(ints: np.ndarray, step: float, transform, dead_zone: float, n_frames: int) -> np.ndarray:
    return transform.inverse(UniformQuantiser(step, dead_zone).dequantise(ints), n_frames)


def reconstruct(coded: CodedClip, basis: ClassBasis, transform, dead_zone: float, n_frames: int,
                frames=slice(None)):
    """Weighted poses and root track (unscaled) of `frames` from a clip's quantised coefficients."""
    coef = dequantise_curves(coded.pose_ints, coded.pose_step, transform, dead_zone, n_frames)[frames]
    poses = basis.reconstruct(coef)
    root = None
    if coded.root_ints is not None:
        root = unscale_root(dequantise_curves(coded.root_ints, coded.root_step, transform, dead_zone, n_frames)[frames])
    return poses, root
