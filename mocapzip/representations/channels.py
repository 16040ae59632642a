"""`channels`: the AMC values as they are (62 per frame for CMU), angles in the file's unit."""

from __future__ import annotations

import numpy as np

from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.representations.base import Encoded, Representation
from mocapzip.stages import register


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
