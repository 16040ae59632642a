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
from mocapzip.representations.aligned import Aligned, position_columns
from mocapzip.representations.base import Encoded, Representation
from mocapzip.stages import register
from mocapzip.representations.universal import universal_lengths


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
class Normalised(Representation):
    codec_id = "normalised"
    has_root_track = True

    def __init__(self, axes_from_positions: bool = False):
        super().__init__(axes_from_positions)
        self.aligned = Aligned(axes_from_positions)

    def forward(self, model: SkeletonModel, motion) -> Encoded:
        encoded = self.aligned.forward(model, motion)
        lengths = model.lengths
        norm = np.divide(universal_lengths(model), lengths, out=np.ones_like(lengths), where=lengths > 0)
        encoded.poses = rescale_bones(model, encoded.poses, norm)
        encoded.params["norm"] = norm
        return encoded

    def inverse(self, model: SkeletonModel, encoded: Encoded, layout) -> np.ndarray:
        poses = rescale_bones(model, encoded.poses, 1.0 / encoded.params["norm"])
        return self.aligned.inverse(model, Encoded(poses, encoded.root, encoded.params), layout)
