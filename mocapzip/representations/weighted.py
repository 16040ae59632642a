"""The space the codec works in: a representation's poses with weighted columns
(`Representation.column_weights`), and the one decode tail from it back to AMC channels, used by
`mcz decompress`, by the encoder's error check and by `mcz bench` alike: a skeleton's channel
tables (`ChannelTables`) and the representation's own decoder (`Representation.decoder`).
"""

from __future__ import annotations

from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from mocapzip.formats.amc import Motion
from mocapzip.motion import compiled
from mocapzip.motion.metrics import shell_bones
from mocapzip.motion.rotations import AXIS_INDEX
from mocapzip.motion.skeleton import ChannelLayout, SkeletonModel
from mocapzip.representations.base import Representation

if TYPE_CHECKING:
    from mocapzip.representations.positions import TwistChoice


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
    return DecodeTail(model, representation, layout, params, axis_weight_cm).decode(weighted_poses, root,
                                                                                   params.get("twist"))


class ChannelTables:
    """A skeleton's channel layout as the compiled kernels (`motion.compiled`) read it, built
    once per skeleton and layout, and the compiled forward kinematics and joint distances on it."""

    def __init__(self, model: SkeletonModel, layout: ChannelLayout):
        self.model = model
        self.layout = model.layout(layout)
        self.width = self.layout.width
        self.to_rad = np.pi / 180.0 if self.layout.angle_unit == "deg" else 1.0
        self._channel_tables(model)

    def _channel_tables(self, model: SkeletonModel) -> None:
        """Per joint: its first column in the layout (-1: not in the clip), its channels (kind
        0 rotation / 1 translation, axis), its rotation channels; the rest pose's links."""
        joints, columns = model.n_joints, self.layout.columns()
        self.parents = model.parents.astype(np.int64)
        self.axis = np.ascontiguousarray(model.axis)
        self.link = np.array([model.axis[j] if model.parents[j] < 0 else model.axis[j] @ model.axis[model.parents[j]].T
                              for j in range(joints)])
        self.offset_in_axes = np.array([model.offsets[j] @ model.axis[j].T for j in range(joints)])
        self.first_column = np.full(joints, -1, np.int64)
        self.n_channels = np.zeros(joints, np.int64)
        self.channel_kind = np.zeros((joints, 6), np.int64)
        self.channel_axis = np.zeros((joints, 6), np.int64)
        self.n_rotations = np.zeros(joints, np.int64)
        self.rotation_axes = np.zeros((joints, 3), np.int64)
        self.rotation_channel = np.zeros((joints, 3), np.int64)
        for j, name in enumerate(model.names):
            channels = model.channels[j]
            self.n_channels[j] = len(channels)
            for k, (kind, axis) in enumerate(channels):
                self.channel_kind[j, k] = 0 if kind == "r" else 1
                self.channel_axis[j, k] = AXIS_INDEX[axis]
            if name in columns:
                self.first_column[j] = columns[name].start
            rotations = [k for k, (kind, _) in enumerate(channels) if kind == "r"]
            self.n_rotations[j] = len(rotations)
            for i, k in enumerate(rotations):
                self.rotation_channel[j, i] = k
                self.rotation_axes[j, i] = AXIS_INDEX[channels[k][1]]

    def positions(self, values: np.ndarray) -> np.ndarray:
        """Forward kinematics of channel `values`: joint positions (F, J, 3) in cm."""
        return compiled.fk_positions(np.ascontiguousarray(values, dtype=np.float64), *self.fk_tables())

    def probed_positions(self, values: np.ndarray, cols: np.ndarray, shifts: np.ndarray) -> np.ndarray:
        """`positions` (F, K, J, 3) of each frame with column cols[k] moved by shifts[k], bit for bit
        as `positions` of those frames: finite differences, only the moved joints made again."""
        return compiled.fk_probed(np.ascontiguousarray(values, dtype=np.float64), np.asarray(cols, np.int64),
                                  np.asarray(shifts, np.float64), *self.fk_tables())

    def error(self, values: np.ndarray, original_positions: np.ndarray) -> tuple[float, float]:
        """(mean, max) distance in cm between the joints of channel `values` and `original_positions`."""
        return compiled.fk_distances(np.ascontiguousarray(values, dtype=np.float64),
                                     np.ascontiguousarray(original_positions, dtype=np.float64), *self.fk_tables())

    def joint_distances(self, values: np.ndarray, original_positions: np.ndarray) -> np.ndarray:
        """(F, J) distance in cm between each joint of channel `values` and of `original_positions`."""
        return compiled.fk_joint_distances(np.ascontiguousarray(values, dtype=np.float64),
                                           np.ascontiguousarray(original_positions, dtype=np.float64),
                                           *self.fk_tables())

    def shell_distances(self, values: np.ndarray, original_values: np.ndarray, shell_cm: float) -> np.ndarray:
        """(F, B) ACL's error (`metrics.shell_errors`) of channel `values` against `original_values`: per
        frame and `shell_bones` frame, its worst vertex `shell_cm` from the bone, cm."""
        bones = self.shell_bones
        return compiled.fk_shell_distances(np.ascontiguousarray(values, dtype=np.float64),
                                           np.ascontiguousarray(original_values, dtype=np.float64), float(shell_cm),
                                           bones.origin_at, bones.rotation_of, self._axes, *self.fk_tables())

    @cached_property
    def shell_bones(self):
        return shell_bones(self.model)

    @cached_property
    def _axes(self) -> np.ndarray:
        return np.ascontiguousarray(self.model.axis, dtype=np.float64)

    def fk_tables(self) -> tuple:
        return (self.parents, self.link, self.offset_in_axes, np.ascontiguousarray(self.model.axis[0]),
                self.first_column, self.n_channels, self.channel_kind, self.channel_axis, self.to_rad,
                float(self.model.cm_per_unit))


class DecodeTail(ChannelTables):
    """`channels_from_weighted` for one skeleton, layout and representation: the channel tables
    and the representation's decoder, built once, so the encoder's error check, which decodes a
    clip many times, pays for them once.

    What it decodes is what `representation.decoder` makes of the poses: no representation is
    named here. It gives what `representation.inverse` gives (to about 1e-11 degrees), which
    stays the readable definition; `tests/test_compiled_decode.py` holds the two together for
    every registered representation.
    """

    def __init__(self, model: SkeletonModel, representation: Representation, layout: ChannelLayout,
                 params: dict, axis_weight_cm: float):
        super().__init__(model, layout)
        self.decoder = representation.decoder(self, params, axis_weight_cm)

    def decode(self, weighted_poses: np.ndarray, root: np.ndarray | None, twist: TwistChoice | None) -> np.ndarray:
        """The decoder's channel values: twists as `twist` stored them (None: the default solution)."""
        flips = self.decoder.flip_flags({} if twist is None else twist.flips, len(weighted_poses))
        values, _ = self.decoder.channels(weighted_poses, root, flips=flips)
        return values
