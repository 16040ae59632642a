"""`normalised`: aligned positions rebuilt with universal bone lengths.

Thesis 3.2.1: Norm_i = U_i / B_i per bone (U universal, B the clip's length),
Denorm_i = 1 / Norm_i. Each bone vector (child minus parent position) is
scaled by its factor and the joints re-accumulated from the root, so a changed
length moves every joint below it; axes and the root track are untouched.
params["norm"] holds Norm (J,), 1 for the root, short bones and bones the
universal table does not know.
"""

from __future__ import annotations

import numpy as np

from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.representations.aligned import RescaledAligned, position_columns
from mocapzip.representations.base import Encoded
from mocapzip.representations.universal import universal_lengths
from mocapzip.stages import register


def rescale_bones(model: SkeletonModel, poses: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """A copy of aligned `poses` with every bone vector multiplied by factors[j]."""
    out = np.array(poses, dtype=np.float64)
    n_frames, width = len(out), position_columns(model)
    positions = np.zeros((n_frames, model.n_joints, 3))
    positions[:, 1:] = out[:, :width].reshape(n_frames, -1, 3)
    bones = positions - positions[:, np.maximum(model.parents, 0)]
    out[:, :width] = (model.ancestors @ (bones * factors[:, None]))[:, 1:].reshape(n_frames, -1)
    return out


@register
class Normalised(RescaledAligned):
    codec_id = "normalised"

    def forward(self, model: SkeletonModel, motion) -> Encoded:
        encoded = self.aligned.forward(model, motion)
        lengths = model.lengths
        norm = np.divide(universal_lengths(model), lengths, out=np.ones_like(lengths), where=lengths > 0)
        encoded.poses = rescale_bones(model, encoded.poses, norm)
        encoded.params["norm"] = norm
        return encoded

    def to_aligned(self, model: SkeletonModel, poses: np.ndarray, params: dict) -> np.ndarray:
        return rescale_bones(model, poses, 1.0 / params["norm"])
