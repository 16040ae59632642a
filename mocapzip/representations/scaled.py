"""`scaled`: aligned positions times one per-clip factor, universal height / skeleton height.

Only the joint positions are scaled; the stored axes are unit vectors and the
root track stays in cm. The factor is kept in params["scale"].
"""

from __future__ import annotations

import numpy as np

from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.representations.aligned import RescaledAligned, position_columns
from mocapzip.representations.base import Encoded
from mocapzip.representations.universal import UNIVERSAL_HEIGHT_CM, skeleton_height
from mocapzip.stages import register


@register
class Scaled(RescaledAligned):
    codec_id = "scaled"

    def forward(self, model: SkeletonModel, motion) -> Encoded:
        encoded = self.aligned.forward(model, motion)
        scale = float(UNIVERSAL_HEIGHT_CM / skeleton_height(model))
        encoded.poses[:, : position_columns(model)] *= scale
        encoded.params["scale"] = scale
        return encoded

    def to_aligned(self, model: SkeletonModel, poses: np.ndarray, params: dict) -> np.ndarray:
        out = np.array(poses, dtype=np.float64)
        out[:, : position_columns(model)] /= params["scale"]
        return out
