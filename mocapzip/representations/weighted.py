"""The space the codec works in: a representation's poses with weighted columns, and the one
decode tail from it back to AMC channels, used by `mcz decompress`, by the encoder's error
check and by `mcz bench` alike.
"""

from __future__ import annotations

import numpy as np

from mocapzip.formats.amc import Motion
from mocapzip.motion.skeleton import ChannelLayout, SkeletonModel
from mocapzip.representations import aligned
from mocapzip.representations.base import Encoded, Representation


def pose_weights(model: SkeletonModel, representation_name: str, width: int, axis_weight_cm: float) -> np.ndarray:
    """Per-column weights of a pose: joint positions (cm) count 1, bone axis vectors (unit
    vectors) count `axis_weight_cm`, the distance at which an axis error becomes a position
    error. PCA and the uniform quantiser then spend bits where they move joints.
    Channels (angles) are left unweighted.
    """
    weights = np.ones(width)
    if representation_name != "channels":
        weights[joint_position_columns(model, representation_name).stop:] = axis_weight_cm
    return weights


def joint_position_columns(model: SkeletonModel, representation_name: str) -> slice:
    """The pose columns that hold joint positions (cm): the first 3 per joint stored by the
    marker representations; none for channels."""
    if representation_name == "channels":
        return slice(0, 0)
    return slice(0, 3 * model.n_joints if representation_name == "positions" else aligned.position_columns(model))


def skeleton_params(model: SkeletonModel, representation: Representation, layout: ChannelLayout) -> dict:
    """The representation's per-clip parameters; they depend on the skeleton only, so the
    decoder re-derives them (from a one-frame rest pose) instead of storing them."""
    rest = Motion(list(layout.bones), list(layout.counts), np.zeros((1, layout.width)), np.array([1]),
                  [":RADIANS" if layout.angle_unit == "rad" else ":DEGREES"])
    return representation.forward(model, rest).params


def channels_from_weighted(model: SkeletonModel, representation: Representation, layout: ChannelLayout,
                           weighted_poses: np.ndarray, root: np.ndarray | None, params: dict,
                           axis_weight_cm: float) -> np.ndarray:
    """The decode tail: the codec's weighted poses and root track -> AMC channel values in `layout`.

    `params`: the representation's (`skeleton_params`, or the original clip's when encoding),
    with "twist", the solved bones' choice of solution (`positions.TwistChoice`), if any.
    """
    weights = pose_weights(model, representation.name, weighted_poses.shape[1], axis_weight_cm)
    return representation.inverse(model, Encoded(weighted_poses / weights, root, params), layout)
