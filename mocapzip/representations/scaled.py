"""`scaled`: aligned positions times one per-clip factor, universal height / skeleton height.

Only the joint positions are scaled; the stored axes are unit vectors and the
root track stays in cm. The factor is kept in params["scale"].
"""

from __future__ import annotations

import numpy as np

from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.representations.aligned import Aligned, position_columns
from mocapzip.representations.base import Encoded, Representation
from mocapzip.stages import register
from mocapzip.representations.universal import UNIVERSAL_HEIGHT_CM, skeleton_height


@register
class Scaled(Representation):
    codec_id = "scaled"
    has_root_track = True

    def __init__(self, axes_from_positions: bool = False):
        super().__init__(axes_from_positions)
        self.aligned = Aligned(axes_from_positions)

    def forward(self, model: SkeletonModel, motion) -> Encoded:
        encoded = self.aligned.forward(model, motion)
        scale = float(UNIVERSAL_HEIGHT_CM / skeleton_height(model))
        encoded.poses[:, : position_columns(model)] *= scale
        encoded.params["scale"] = scale
        return encoded

    def inverse(self, model: SkeletonModel, encoded: Encoded, layout) -> np.ndarray:
        poses = np.array(encoded.poses, dtype=np.float64)
        poses[:, : position_columns(model)] /= encoded.params["scale"]
        return self.aligned.inverse(model, Encoded(poses, encoded.root, encoded.params), layout)
