"""`channels`: the AMC values as they are (62 per frame for CMU), angles in the file's unit."""

from __future__ import annotations

import numpy as np

from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.representations.base import Encoded, PoseDecoder, Representation
from mocapzip.representations.weighted import ChannelTables
from mocapzip.stages import register


class AsStored(PoseDecoder):
    """`channels`' decode: its unweighted poses are the channel values."""

    def __init__(self, weights: np.ndarray):
        self.weights = weights

    def channels(self, weighted_poses: np.ndarray, root: np.ndarray | None, reference: np.ndarray | None = None,
                 flips: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        poses = np.ascontiguousarray(weighted_poses, dtype=np.float64)
        if poses.ndim != 2 or poses.shape[1] != len(self.weights):
            raise ValueError(f"poses have shape {poses.shape}, this layout needs (frames, {len(self.weights)})")
        return poses / self.weights, np.zeros((0, len(poses)), np.bool_)


@register
class Channels(Representation):
    codec_id = "channels"

    def forward(self, model: SkeletonModel, motion) -> Encoded:
        model.layout(motion)  # checks the clip against the skeleton, like the other representations
        return Encoded(np.array(motion.values, dtype=np.float64))

    def inverse(self, model: SkeletonModel, encoded: Encoded, layout) -> np.ndarray:
        width = model.layout(layout).width
        if encoded.poses.shape[1] != width:
            raise ValueError(f"poses have {encoded.poses.shape[1]} columns, the layout has {width}")
        return np.array(encoded.poses, dtype=np.float64)

    def joint_position_columns(self, model: SkeletonModel) -> slice:
        return slice(0, 0)

    def column_weights(self, model: SkeletonModel, layout, axis_weight_cm: float) -> np.ndarray:
        return np.ones(model.layout(layout).width)  # angles and translations as they are

    def decoder(self, tables: ChannelTables, params: dict, axis_weight_cm: float) -> AsStored:
        return AsStored(self.column_weights(tables.model, tables.layout, axis_weight_cm))
