"""The space the codec works in: a representation's poses with weighted columns, and the one
decode tail from it back to AMC channels, used by `mcz decompress`, by the encoder's error
check and by `mcz bench` alike.
"""

from __future__ import annotations

import numpy as np

from mocapzip.formats.amc import Motion
from mocapzip.motion import compiled
from mocapzip.motion.rotations import AXIS_INDEX
from mocapzip.motion.skeleton import ChannelLayout, SkeletonModel
from mocapzip.representations import aligned
from mocapzip.representations.base import ROOT_TRACK_WIDTH, Representation
from mocapzip.representations.normalised import rescale_bones
from mocapzip.representations.positions import TwistChoice, marker_width, stored_axes, twisted_bones

# The decode kernel keeps each joint's local rotations over all frames for its Euler fits, 72 bytes
# a joint and frame: a clip at the limits (135,300 frames of 31 joints) took 300 MB at once, and
# with the rest passed 1 GB of address space. Beyond this many bytes it runs again per range of
# joints (`channels`): the same numbers, the frame loop once more per range (clips over ~28,000 frames).
LOCAL_ROTATIONS_BYTES = 64 << 20


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
    return DecodeTail(model, representation, layout, params, axis_weight_cm).decode(weighted_poses, root,
                                                                                   params.get("twist"))


class DecodeTail:
    """`channels_from_weighted` for one skeleton, layout and representation, compiled
    (`motion.compiled`): the tables the kernels need are built once, so the encoder's error
    check, which decodes a clip many times, pays for them once.

    It gives what `representation.inverse` gives (to about 1e-11 degrees), which stays the
    readable definition; `tests/test_compiled_decode.py` holds the two together.
    """

    def __init__(self, model: SkeletonModel, representation: Representation, layout: ChannelLayout,
                 params: dict, axis_weight_cm: float):
        self.model = model
        self.name = representation.name
        self.layout = model.layout(layout)
        self.width = self.layout.width
        self.to_rad = np.pi / 180.0 if self.layout.angle_unit == "deg" else 1.0
        self.params = params
        self._channel_tables(model)
        if self.name == "channels":
            self.weights = np.ones(self.width)
            self.twisted = np.zeros(0, np.int64)
            return
        self._marker_tables(model, representation.axes_from_positions)
        self.weights = pose_weights(model, self.name, self.marker_width, axis_weight_cm)
        self.position_divisor = float(params["scale"]) if self.name == "scaled" else 1.0
        self.scaled_columns = aligned.position_columns(model) if self.name == "scaled" else 0

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

    def _marker_tables(self, model: SkeletonModel, axes_from_positions: bool) -> None:
        """Where each joint's position, y axis and (short bones) x axis sit in a pose, and the
        constants of the solved bones' closed forms (`positions.solve_local`)."""
        joints = model.n_joints
        self.with_root = self.name == "positions"
        first = 0 if self.with_root else 1
        stored = stored_axes(model, axes_from_positions)
        short = np.flatnonzero(model.short)
        self.marker_width = marker_width(model, self.with_root, axes_from_positions)
        cuts = np.cumsum([3 * (joints - first), 3 * int(stored.sum()), 3 * len(short)])
        self.position_column = np.full(joints, -1, np.int64)
        self.position_column[first:] = 3 * np.arange(joints - first)
        self.y_column = np.full(joints, -1, np.int64)
        self.y_column[1:][stored] = cuts[0] + 3 * np.arange(int(stored.sum()))
        self.x_column = np.full(joints, -1, np.int64)
        self.x_column[short] = cuts[1] + 3 * np.arange(len(short))
        self.root_axes_column = int(cuts[2]) if model.root_proxy is None else -1
        self.root_proxy = -1 if model.root_proxy is None else int(model.root_proxy)
        self.faux = np.ascontiguousarray(model.faux)
        self.solved = (np.flatnonzero(~stored) + 1).astype(np.int64)
        self.bone_direction = np.zeros((joints, 3))  # u = V C^T, normalised
        self.solved_dofs = np.zeros(joints, np.int64)
        self.solved_first_axis = np.zeros(joints, np.int64)
        self.solved_second_axis = np.zeros(joints, np.int64)
        self.solved_radius = np.ones(joints)
        self.solved_phase = np.zeros(joints)
        self.twist_index = np.full(joints, -1, np.int64)  # row of a 2-dof solved bone in flips
        for j in self.solved:
            u = model.offsets[j] @ model.axis[j].T
            u = u / np.linalg.norm(u)
            self.bone_direction[j] = u
            axes = model.rotation_axes(j)
            self.solved_dofs[j] = len(axes)
            if axes:
                a = AXIS_INDEX[axes[0]]
                b, c = (a + 1) % 3, (a + 2) % 3
                self.solved_first_axis[j] = a
                self.solved_phase[j] = np.arctan2(u[c], u[b])
                if len(axes) == 2:
                    self.solved_second_axis[j] = AXIS_INDEX[axes[1]]
                    self.solved_radius[j] = np.hypot(u[b], u[c])
        # the 2-dof solved bones in `positions.true_twists`' order, and their angle columns
        self.twisted = np.array(twisted_bones(model), np.int64)
        self.twist_index[self.twisted] = np.arange(len(self.twisted))
        columns = self.layout.columns()
        self.twist_columns = np.full((len(self.twisted), 2), -1, np.int64)
        self.twist_axes = np.zeros((len(self.twisted), 2), np.int64)
        for r, j in enumerate(self.twisted):
            self.twist_axes[r] = [AXIS_INDEX[a] for a in model.rotation_axes(j)]
            if model.names[j] in columns:
                rotations = [k for k, (kind, _) in enumerate(model.channels[j]) if kind == "r"]
                self.twist_columns[r] = columns[model.names[j]].start + np.array(rotations[:2])

    def flip_flags(self, flips: dict[int, np.ndarray], n_frames: int) -> np.ndarray:
        """TwistChoice.flips as the kernels take them: (2-dof solved bones, frames) bool."""
        flags = np.zeros((len(self.twisted), n_frames), np.bool_)
        for r, j in enumerate(self.twisted):
            if j in flips:
                flags[r] = flips[j]
        return flags

    def decode(self, weighted_poses: np.ndarray, root: np.ndarray | None, twist: TwistChoice | None) -> np.ndarray:
        """The decoder's channel values: twists as `twist` stored them (None: the default solution)."""
        flips = (twist or TwistChoice()).flips
        values, _ = self.channels(weighted_poses, root, flips=self.flip_flags(flips, len(weighted_poses)))
        return values

    def twist_reference(self, original_values: np.ndarray) -> np.ndarray:
        """(F, 2-dof solved bones, 3, 3): their true local rotations (`positions.true_twists`)."""
        return compiled.twist_reference(np.ascontiguousarray(original_values, dtype=np.float64), self.twisted,
                                        self.twist_columns, self.twist_axes[:, 0].copy(),
                                        self.twist_axes[:, 1].copy(), self.to_rad)

    def channels(self, weighted_poses: np.ndarray, root: np.ndarray | None, reference: np.ndarray | None = None,
                 flips: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(channel values (F, C), flips (2-dof solved bones, F)). Twists turn towards
        `reference` (the encoder, which knows the original: `twist_reference`) or follow
        `flips` (the decoder: `flip_flags`); with neither, the default solution."""
        poses = np.ascontiguousarray(weighted_poses, dtype=np.float64)
        n_frames = len(poses)
        if self.name == "channels":
            if poses.ndim != 2 or poses.shape[1] != self.width:
                raise ValueError(f"poses have shape {poses.shape}, this layout needs (frames, {self.width})")
            return poses / self.weights, np.zeros((0, n_frames), np.bool_)
        if poses.ndim != 2 or poses.shape[1] != self.marker_width:
            raise ValueError(f"poses have shape {poses.shape}, this skeleton needs (frames, {self.marker_width})")
        has_track = not self.with_root
        if has_track and (root is None or np.shape(root) != (n_frames, ROOT_TRACK_WIDTH)):
            raise ValueError(f"root track has shape {np.shape(root)}, expected ({n_frames}, {ROOT_TRACK_WIDTH})")
        weights = self.weights
        if self.name == "normalised":  # its bone lengths are rescaled in numpy first
            poses = rescale_bones(self.model, poses / weights, 1.0 / self.params["norm"])
            weights = np.ones_like(weights)
        use_reference = reference is not None
        if reference is None:
            reference = np.zeros((1, max(len(self.twisted), 1), 3, 3))
        if flips is None:
            flips = np.zeros((len(self.twisted), n_frames), np.bool_)
        root = np.zeros((1, ROOT_TRACK_WIDTH)) if root is None else np.ascontiguousarray(root, dtype=np.float64)
        values = np.zeros((n_frames, self.width))
        joints = len(self.parents)
        per_call = max(1, LOCAL_ROTATIONS_BYTES // (72 * max(n_frames, 1)))  # joints whose rotations fit
        for first in range(0, joints, per_call):
            values, out_flips = compiled.decode_channels(
                poses, weights, self.position_divisor, self.scaled_columns, root, has_track, self.with_root,
                self.parents, self.faux, self.position_column, self.y_column, self.x_column, self.root_axes_column,
                self.root_proxy, self.solved, self.bone_direction, self.solved_dofs, self.solved_first_axis,
                self.solved_second_axis, self.solved_radius, self.solved_phase, self.twist_index, reference,
                use_reference, np.ascontiguousarray(flips), self.axis, self.first_column, self.n_channels,
                self.channel_kind, self.channel_axis, self.n_rotations, self.rotation_axes, self.rotation_channel,
                float(self.model.cm_per_unit), 1.0 / self.to_rad, self.width, values, first,
                min(joints, first + per_call))
        return values, out_flips

    def positions(self, values: np.ndarray) -> np.ndarray:
        """Forward kinematics of channel `values`: joint positions (F, J, 3) in cm."""
        return compiled.fk_positions(np.ascontiguousarray(values, dtype=np.float64), *self.fk_tables())

    def error(self, values: np.ndarray, original_positions: np.ndarray) -> tuple[float, float]:
        """(mean, max) distance in cm between the joints of channel `values` and `original_positions`."""
        return compiled.fk_distances(np.ascontiguousarray(values, dtype=np.float64),
                                     np.ascontiguousarray(original_positions, dtype=np.float64), *self.fk_tables())

    def joint_distances(self, values: np.ndarray, original_positions: np.ndarray) -> np.ndarray:
        """(F, J) distance in cm between each joint of channel `values` and of `original_positions`."""
        return compiled.fk_joint_distances(np.ascontiguousarray(values, dtype=np.float64),
                                           np.ascontiguousarray(original_positions, dtype=np.float64),
                                           *self.fk_tables())

    def fk_tables(self) -> tuple:
        return (self.parents, self.link, self.offset_in_axes, np.ascontiguousarray(self.model.axis[0]),
                self.first_column, self.n_channels, self.channel_kind, self.channel_axis, self.to_rad,
                float(self.model.cm_per_unit))
