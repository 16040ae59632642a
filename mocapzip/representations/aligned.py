"""`aligned`: positions with the root's translation and heading (yaw) moved to a root track.

Each frame is expressed in a frame that moves with the character: translated so
the root is at the origin (the root position is then always zero and is not
stored) and turned about the vertical (+Y, the Acclaim/CMU up axis) by minus
the heading. The root track holds x, y, z (cm) and the heading (radians,
unwrapped) per frame. Columns: as `positions` without the root position
(CMU: 30 positions + 30 axes = 180; 30 + 13 = 129 with solved bones).

Heading. The thesis projects the root's x axis on the ground, which fails when
that axis points up and flips by 180 degrees upside down. Here the heading is
the twist about the vertical in a swing-twist split of the root rotation: the
yaw closest to it (`rotations.angle_about`). Its reliability is
c = cos^2(tilt / 2), tilt being how far the root's up axis is from vertical:
1 upright, 0.5 lying down, 0 upside down, where the twist is undefined. Frames
with c < MIN_HEADING_CONFIDENCE (tilt > 120 degrees: mid back flip, head
spin) take a heading interpolated, over time, between the reliable frames
around them, so a flip neither jumps nor spins; the unwrapped heading is
continuous. The inverse uses the stored heading, whatever it is, so the round
trip is exact by construction.
"""

from __future__ import annotations

from abc import abstractmethod
from functools import partial

import numpy as np

from mocapzip.motion.kinematics import Pose, forward, inverse
from mocapzip.motion.rotations import angle_about, axis_rotation
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.representations.base import ROOT_TRACK_WIDTH, Encoded, PoseDecoder, Representation
from mocapzip.representations.positions import (MarkerDecoder, decode_markers, encode_markers, marker_weights,
                                                marker_width)
from mocapzip.representations.weighted import ChannelTables
from mocapzip.stages import register

MIN_HEADING_CONFIDENCE = 0.25


def heading(root_rotations: np.ndarray) -> np.ndarray:
    """(F,) unwrapped heading in radians of root rotations (F, 3, 3); see the module doc."""
    twist = angle_about("y", root_rotations)
    r = root_rotations
    confidence = np.hypot(r[:, 2, 0] - r[:, 0, 2], r[:, 0, 0] + r[:, 2, 2]) / 2.0
    reliable = np.flatnonzero(confidence >= MIN_HEADING_CONFIDENCE)
    if reliable.size == 0:
        return np.zeros(len(r))
    return np.interp(np.arange(len(r)), reliable, np.unwrap(twist[reliable]))


def to_character_frame(pose: Pose, root_track: np.ndarray) -> Pose:
    """World pose -> pose relative to the root position and heading of `root_track`."""
    undo = np.swapaxes(axis_rotation("y", root_track[:, 3]), -1, -2)
    return Pose(pose.rotations @ undo[:, None], (pose.positions - root_track[:, None, :3]) @ undo)


def position_columns(model: SkeletonModel) -> int:
    """The leading columns of an aligned matrix that hold joint positions (3 per bone)."""
    return 3 * (model.n_joints - 1)


@register
class Aligned(Representation):
    codec_id = "aligned"
    root_width = ROOT_TRACK_WIDTH

    def forward(self, model: SkeletonModel, motion) -> Encoded:
        pose = forward(model, motion.values, motion)
        root = np.column_stack([pose.positions[:, 0], heading(pose.rotations[:, 0])])
        local = to_character_frame(pose, root)
        return Encoded(encode_markers(model, local, with_root=False, axes_from_positions=self.axes_from_positions), root)

    def inverse(self, model: SkeletonModel, encoded: Encoded, layout) -> np.ndarray:
        local = decode_markers(model, encoded.poses, with_root=False, axes_from_positions=self.axes_from_positions,
                               twist=encoded.params.get("twist"))
        turn = axis_rotation("y", encoded.root[:, 3])
        return inverse(model, local.rotations @ turn[:, None], encoded.root[:, :3], layout)

    def joint_position_columns(self, model: SkeletonModel) -> slice:
        return slice(0, position_columns(model))

    def column_weights(self, model: SkeletonModel, layout, axis_weight_cm: float) -> np.ndarray:
        return marker_weights(marker_width(model, False, self.axes_from_positions),
                              self.joint_position_columns(model), axis_weight_cm)

    def decoder(self, tables: ChannelTables, params: dict, axis_weight_cm: float) -> MarkerDecoder:
        return MarkerDecoder(tables, self.column_weights(tables.model, tables.layout, axis_weight_cm), False,
                             self.axes_from_positions)


class RescaledAligned(Representation):
    """`aligned` with its joint positions rescaled per clip (`scaled`: by one factor,
    `normalised`: bone by bone). A subclass gives `forward` and `to_aligned`, the rescaling
    undone; its inverse and its decoder are `aligned`'s after `to_aligned`, so the two agree."""

    root_width = ROOT_TRACK_WIDTH

    def __init__(self, axes_from_positions: bool = False):
        super().__init__(axes_from_positions)
        self.aligned = Aligned(axes_from_positions)

    @abstractmethod
    def to_aligned(self, model: SkeletonModel, poses: np.ndarray, params: dict) -> np.ndarray:
        """This representation's (unweighted) `poses` as `aligned` poses, a copy."""

    def inverse(self, model: SkeletonModel, encoded: Encoded, layout) -> np.ndarray:
        poses = self.to_aligned(model, encoded.poses, encoded.params)
        return self.aligned.inverse(model, Encoded(poses, encoded.root, encoded.params), layout)

    def joint_position_columns(self, model: SkeletonModel) -> slice:
        return self.aligned.joint_position_columns(model)

    def column_weights(self, model: SkeletonModel, layout, axis_weight_cm: float) -> np.ndarray:
        return self.aligned.column_weights(model, layout, axis_weight_cm)

    def decoder(self, tables: ChannelTables, params: dict, axis_weight_cm: float) -> PoseDecoder:
        return MarkerDecoder(tables, self.column_weights(tables.model, tables.layout, axis_weight_cm), False,
                             self.axes_from_positions, to_markers=partial(self.to_aligned, tables.model, params=params))
