"""`positions`: joint positions plus one bone-aligned axis per bone ("virtual markers").

Thesis 3.2.1, compact form. For each bone j the aligned frame A_j = B_j R_j
(B_j the fixed faux matrix of `SkeletonModel.faux`) has its x axis along the
bone, so x is recomputed from the joint positions as child minus parent; only
the y axis is stored, and z = x cross y. The root's rotation is not stored when
a root child has no rotation channels (its rotation *is* the root's; CMU:
lhipjoint). CMU: 31 positions + 30 y axes = 183 values per frame.

Special cases, each stored explicitly so the inverse stays exact:
- short bones (< SHORT_BONE_CM, e.g. Vicon Blade's zero-length hand joints):
  their direction is unusable, so their faux matrix is the identity and their
  x axis is stored as well (3 more values each);
- skeletons whose root children all rotate: the root's x and y axes (6 values).
Leaf bones need nothing special: their end point is a joint position too.

Solved bones (`axes_from_positions`, the codec's default since format 4): a bone
with at most two rotation dofs, none of them about the bone itself, has its
rotation fixed by its parent's rotation and its own direction, so its y axis is
not stored; the inverse solves its angles from the joint positions
(`solved_bones`, `solve_local`). CMU: 17 of 30 bones (knees, feet, toes,
clavicles, elbows, hands, fingers, thumbs, rhipjoint), 183 -> 132 values per
frame. Their y axes are nearly functions of the positions, but not linear ones,
so PCA spent components on them (sizes: `benchmarks/solved_bones.py`,
docs/architecture.md). A 2-dof bone has two solutions half a turn apart, which the
positions cannot tell apart: `TwistChoice` says which.

Column order: positions (root first unless the caller drops it), y axes of
bones 1..J-1 (solved bones left out), x axes of short bones, root axes.

`MarkerDecoder` decodes every marker representation (this one, `aligned`, `scaled`,
`normalised`) as `decode_markers` and `kinematics.inverse` do, compiled (`motion.compiled`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mocapzip.motion import compiled
from mocapzip.motion.kinematics import Pose, forward, inverse
from mocapzip.motion.rotations import AXIS_INDEX, axis_rotation, euler_matrix, orthonormal_frame, wrap
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.representations.base import ROOT_TRACK_WIDTH, Encoded, PoseDecoder, Representation
from mocapzip.representations.weighted import ChannelTables
from mocapzip.stages import register

# A dof axis closer to the bone than this cosine (60 degrees) mostly twists the bone
# about itself, which its direction cannot show: such a bone keeps its stored axis.
TWIST_COSINE = 0.5
# The decode kernel keeps each joint's local rotations over all frames for its Euler fits, 72 bytes
# a joint and frame: a clip at the limits (135,300 frames of 31 joints) took 300 MB at once, and
# with the rest passed 1 GB of address space. Beyond this many bytes it runs again per range of
# joints (`MarkerDecoder.channels`): the same numbers, the frame loop once more per range (clips
# over ~28,000 frames).
LOCAL_ROTATIONS_BYTES = 64 << 20


def solved_bones(model: SkeletonModel) -> np.ndarray:
    """(J,) bool: bones whose rotation the inverse solves from joint positions (module doc).

    Not the root proxy (its axes give the root's rotation) nor short bones (no usable
    direction); at most two distinct rotation dofs, each at least 60 degrees from the bone.
    """
    out = np.zeros(model.n_joints, bool)
    for j in range(1, model.n_joints):
        axes = model.rotation_axes(j)
        if model.short[j] or j == model.root_proxy or len(axes) > 2 or len(set(axes)) < len(axes):
            continue
        direction = model.offsets[j] / model.lengths[j]
        out[j] = all(abs(model.axis[j][AXIS_INDEX[a]] @ direction) < TWIST_COSINE for a in axes)
    return out


@dataclass
class TwistChoice:
    """Which of its two solutions each frame of a 2-dof solved bone takes (see `solve_local`).

    The two solutions differ by half a turn of the bone about itself, which moves no joint,
    so the joint positions cannot choose. By default the solution with the smaller largest
    angle is taken; `flips[j]` (F,) marks the frames of bone j that take the other one. The
    encoder, which knows the true local rotations (`reference[j]`, (F, 3, 3)), decodes with
    the solution nearer to them and records the frames where that is not the default in
    `flips`, so the decoder makes the same choice.
    """

    flips: dict[int, np.ndarray] = field(default_factory=dict)
    reference: dict[int, np.ndarray] | None = None


def twisted_bones(model: SkeletonModel) -> list[int]:
    """The solved bones with two rotation dofs: the ones with two solutions (`TwistChoice`)."""
    return [int(j) for j in np.flatnonzero(solved_bones(model)) if len(model.rotation_axes(j)) == 2]


def true_twists(model: SkeletonModel, values: np.ndarray, layout) -> TwistChoice:
    """The encoder's TwistChoice for a clip: the 2-dof solved bones' true local rotations,
    from the clip's channel `values` (F, C) in `layout` (bones the clip leaves out: identity)."""
    layout = model.layout(layout)
    columns = layout.columns()
    to_rad = np.pi / 180.0 if layout.angle_unit == "deg" else 1.0
    reference = {}
    for j in twisted_bones(model):
        axes = model.rotation_axes(j)
        if model.names[j] in columns:
            rotation_columns = [k for k, channel in enumerate(model.channels[j]) if channel[0] == "r"]
            angles = values[:, columns[model.names[j]]][:, rotation_columns] * to_rad
            reference[j] = euler_matrix(angles, axes)
        else:
            reference[j] = np.broadcast_to(np.eye(3), (len(values), 3, 3))
    return TwistChoice(reference=reference)


def flip_ranges(flips: dict[int, np.ndarray], model: SkeletonModel) -> dict[str, list[int]]:
    """TwistChoice.flips as stored in an archive row: {bone name: [start, end, start, end, ...]},
    the half-open frame ranges that take the other solution; bones without any left out."""
    out = {}
    for j, flags in flips.items():
        edges = np.flatnonzero(np.diff(np.concatenate([[0], flags.astype(np.int8), [0]])))
        if len(edges):
            out[model.names[j]] = edges.tolist()
    return out


def flips_from_ranges(ranges: dict[str, list[int]], model: SkeletonModel, n_frames: int) -> TwistChoice:
    """The decoder's TwistChoice from `flip_ranges` output."""
    flips = {}
    for name, edges in ranges.items():
        flags = np.zeros(n_frames, bool)
        for start, end in zip(edges[::2], edges[1::2]):
            flags[start:end] = True
        flips[model.index[name]] = flags
    return TwistChoice(flips)


def _angle_about(axis: str, u: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Angle of the rotation about `axis` taking direction u towards t (row convention:
    it turns the two other coordinates (b, c) as the complex number b + ic)."""
    b, c = (AXIS_INDEX[axis] + 1) % 3, (AXIS_INDEX[axis] + 2) % 3
    return np.arctan2(t[..., c], t[..., b]) - np.arctan2(u[..., c], u[..., b])


def solve_local(model: SkeletonModel, j: int, parent_rotation: np.ndarray, bone: np.ndarray,
                twist: TwistChoice) -> np.ndarray:
    """Local rotations M (F, 3, 3) of solved bone j, from its parent's world rotation
    (F, 3, 3) and its vector `bone` (F, 3): child minus parent position.

    With R_j = C^T M C R_p (kinematics), the bone vector is V C^T M C R_p, so in the
    joint's axis frame M must turn u = V C^T towards t = bone R_p^T C^T. One dof about
    axis a: a closed-form angle. Two dofs M = R_a(s) R_b(r): R_b keeps the b coordinate,
    so (u R_a(s))_b = t_b fixes s up to two solutions, and r follows as for one dof;
    `twist` says which solution each frame takes.
    """
    c = model.axis[j]
    u = model.offsets[j] @ c.T
    u = u / np.linalg.norm(u)
    t = (bone[:, None, :] @ np.swapaxes(parent_rotation, -1, -2) @ c.T)[:, 0]
    t = t / np.maximum(np.linalg.norm(t, axis=-1, keepdims=True), 1e-300)
    axes = model.rotation_axes(j)
    if not axes:
        return np.broadcast_to(np.eye(3), parent_rotation.shape)
    if len(axes) == 1:
        return axis_rotation(axes, _angle_about(axes, u, t))
    first, second = axes
    b, c_ = (AXIS_INDEX[first] + 1) % 3, (AXIS_INDEX[first] + 2) % 3
    radius, phase = np.hypot(u[b], u[c_]), np.arctan2(u[c_], u[b])  # u_b + i u_c = radius e^(i phase)
    if AXIS_INDEX[second] == b:  # radius cos(phase + s) = t_b
        turn = np.arccos(np.clip(t[:, b] / radius, -1.0, 1.0))
        turns = (turn, -turn)
    else:  # radius sin(phase + s) = t_c
        turn = np.arcsin(np.clip(t[:, c_] / radius, -1.0, 1.0))
        turns = (turn, np.pi - turn)
    angles = []
    for turn in turns:
        s = wrap(turn - phase)
        angles.append((s, wrap(_angle_about(second, u @ axis_rotation(first, s), t))))  # (3,) @ (F, 3, 3)
    (s0, r0), (s1, r1) = angles
    other = np.maximum(np.abs(s1), np.abs(r1)) < np.maximum(np.abs(s0), np.abs(r0))  # the default
    if twist.reference is not None:
        solutions = [axis_rotation(first, s) @ axis_rotation(second, r) for s, r in angles]
        nearness = [np.einsum("fij,fij->f", m, twist.reference[j]) for m in solutions]  # trace(M^T M_ref)
        chosen = nearness[1] > nearness[0]
        twist.flips[j] = chosen != other
        other = chosen
    elif j in twist.flips:
        other = other != twist.flips[j]
    return axis_rotation(first, np.where(other, s1, s0)) @ axis_rotation(second, np.where(other, r1, r0))


def stored_axes(model: SkeletonModel, axes_from_positions: bool) -> np.ndarray:
    """(J - 1,) bool: bones 1..J-1 whose y axis is stored."""
    return ~solved_bones(model)[1:] if axes_from_positions else np.ones(model.n_joints - 1, bool)


def marker_width(model: SkeletonModel, with_root: bool, axes_from_positions: bool = False) -> int:
    """Columns of an encoding: positions, y axes, short-bone x axes, root axes."""
    positions = model.n_joints - (0 if with_root else 1)
    y_axes = int(stored_axes(model, axes_from_positions).sum())
    root_axes = 2 if model.root_proxy is None else 0
    return 3 * (positions + y_axes + int(model.short.sum()) + root_axes)


def encode_markers(model: SkeletonModel, pose: Pose, with_root: bool, axes_from_positions: bool = False) -> np.ndarray:
    """Pose -> (F, M) marker matrix; without root, the root position is dropped (it must be 0)."""
    n_frames = len(pose.positions)
    aligned = model.faux[None, 1:] @ pose.rotations[:, 1:]
    parts = [
        pose.positions[:, 0 if with_root else 1 :].reshape(n_frames, -1),
        aligned[:, stored_axes(model, axes_from_positions), 1].reshape(n_frames, -1),
        pose.rotations[:, np.flatnonzero(model.short), 0].reshape(n_frames, -1),
    ]
    if model.root_proxy is None:
        parts.append(pose.rotations[:, 0, :2].reshape(n_frames, -1))
    return np.concatenate(parts, axis=1)


def decode_markers(model: SkeletonModel, poses: np.ndarray, with_root: bool, axes_from_positions: bool = False,
                   twist: TwistChoice | None = None) -> Pose:
    """(F, M) marker matrix -> Pose. Rotations are re-orthonormalised, so a lossy
    matrix still gives proper rotations; positions are returned as stored. `twist`:
    the 2-dof solved bones' choices (default: `TwistChoice()`)."""
    poses = np.asarray(poses, dtype=np.float64)
    width = marker_width(model, with_root, axes_from_positions)
    if poses.ndim != 2 or poses.shape[1] != width:
        raise ValueError(f"poses have shape {poses.shape}, this skeleton needs (frames, {width})")
    n_frames, n_joints = len(poses), model.n_joints
    first = 0 if with_root else 1
    short = np.flatnonzero(model.short)
    stored = stored_axes(model, axes_from_positions)
    cuts = np.cumsum([3 * (n_joints - first), 3 * int(stored.sum()), 3 * len(short)])
    positions = np.zeros((n_frames, n_joints, 3))
    positions[:, first:] = poses[:, : cuts[0]].reshape(n_frames, -1, 3)
    y_axes = np.broadcast_to(model.faux[1:, 1], (n_frames, n_joints - 1, 3)).copy()  # solved bones: replaced below
    y_axes[:, stored] = poses[:, cuts[0] : cuts[1]].reshape(n_frames, -1, 3)
    x_axes = positions[:, 1:] - positions[:, model.parents[1:]]
    x_axes[:, short - 1] = poses[:, cuts[1] : cuts[2]].reshape(n_frames, -1, 3)
    rotations = np.empty((n_frames, n_joints, 3, 3))
    rotations[:, 1:] = np.swapaxes(model.faux[1:], -1, -2) @ orthonormal_frame(x_axes, y_axes)  # R = B^T A
    if model.root_proxy is None:
        root_axes = poses[:, cuts[2] :].reshape(n_frames, 2, 3)
        rotations[:, 0] = orthonormal_frame(root_axes[:, 0], root_axes[:, 1])
    else:
        rotations[:, 0] = rotations[:, model.root_proxy]
    twist = twist if twist is not None else TwistChoice()
    for j in np.flatnonzero(~stored) + 1:  # parents come first, so each parent is final here
        p = model.parents[j]
        local = solve_local(model, j, rotations[:, p], positions[:, j] - positions[:, p], twist)
        rotations[:, j] = model.axis[j].T @ local @ model.axis[j] @ rotations[:, p]
    return Pose(rotations, positions)


MIN_DIRECTION = 1e-6  # cm for a bone from its parent, else a unit vector's length: shorter is no direction


class DegeneratePose(ValueError):
    """Decoded poses with a bone or axis of no direction (`MarkerDecoder.check_directions`)."""


def _across(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """y less its part along x, as `frame(x, y)` makes it (docs/format.md §10.1) before it normalises it."""
    unit = x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-300)
    return y - np.sum(y * unit, axis=-1, keepdims=True) * unit


def marker_weights(width: int, joint_positions: slice, axis_weight_cm: float) -> np.ndarray:
    """Column weights of a marker pose: joint positions (cm) count 1, the bone axis vectors after
    them (unit vectors) `axis_weight_cm`, the distance at which an axis error becomes a position
    error (`Representation.column_weights`)."""
    weights = np.ones(width)
    weights[joint_positions.stop:] = axis_weight_cm
    return weights


class MarkerDecoder(PoseDecoder):
    """The compiled decode of marker poses (`compiled.markers_to_channels`): `decode_markers`,
    then `kinematics.inverse` (the aligned family turned by their root track first), for one
    skeleton and channel layout. `with_root`: the poses hold the root position (`positions`),
    otherwise a root track of x, y, z and heading comes beside them (`aligned`). `to_markers`, if
    given, takes a representation's unweighted poses to aligned markers first, in numpy
    (`aligned.RescaledAligned.to_aligned`: `scaled`, `normalised`); like the decoder, it must
    pickle (no lambda), as clips go to worker processes with their decode tail."""

    def __init__(self, tables: ChannelTables, weights: np.ndarray, with_root: bool, axes_from_positions: bool,
                 to_markers=None):
        self.tables, self.weights, self.with_root, self.to_markers = tables, weights, with_root, to_markers
        model, joints = tables.model, tables.model.n_joints
        first = 0 if with_root else 1
        stored = stored_axes(model, axes_from_positions)
        short = np.flatnonzero(model.short)
        cuts = np.cumsum([3 * (joints - first), 3 * int(stored.sum()), 3 * len(short)])
        self.marker_width = int(cuts[2]) + (6 if model.root_proxy is None else 0)  # `marker_width`
        if len(weights) != self.marker_width:
            raise ValueError(f"{len(weights)} column weights for poses of {self.marker_width} columns")
        self.position_column = np.full(joints, -1, np.int64)
        self.position_column[first:] = 3 * np.arange(joints - first)
        self.y_column = np.full(joints, -1, np.int64)
        self.y_column[1:][stored] = cuts[0] + 3 * np.arange(int(stored.sum()))
        self.x_column = np.full(joints, -1, np.int64)
        self.x_column[short] = cuts[1] + 3 * np.arange(len(short))
        self.root_axes_column = int(cuts[2]) if model.root_proxy is None else -1
        self.root_proxy = -1 if model.root_proxy is None else int(model.root_proxy)
        self.faux = np.ascontiguousarray(model.faux)
        self._solved_tables(model, stored)

    def _solved_tables(self, model: SkeletonModel, stored: np.ndarray) -> None:
        """The constants of the solved bones' closed forms (`solve_local`), and where the 2-dof
        ones' angles sit in the layout (`twist_reference`)."""
        joints = model.n_joints
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
        # the 2-dof solved bones in `true_twists`' order, and their angle columns
        self.twisted = np.array(twisted_bones(model), np.int64)
        self.twist_index[self.twisted] = np.arange(len(self.twisted))
        columns = self.tables.layout.columns()
        self.twist_columns = np.full((len(self.twisted), 2), -1, np.int64)
        self.twist_axes = np.zeros((len(self.twisted), 2), np.int64)
        for r, j in enumerate(self.twisted):
            self.twist_axes[r] = [AXIS_INDEX[a] for a in model.rotation_axes(j)]
            if model.names[j] in columns:
                rotations = [k for k, (kind, _) in enumerate(model.channels[j]) if kind == "r"]
                self.twist_columns[r] = columns[model.names[j]].start + np.array(rotations[:2])

    def check_directions(self, weighted_poses: np.ndarray) -> None:
        """ValueError naming the first bone and frame whose direction is shorter than MIN_DIRECTION
        (docs/format.md §10.8): a bone on its parent, an axis of zero length, a y axis along its x
        axis. Their `frame` is rounding noise, and two decoders that sum in other orders wrote
        angles thousands of degrees apart (a tensor model of zeros). Compress never stores one: a
        bone of 1 cm or more (shorter ones are short, their x axis stored) is coded within its error."""
        poses = np.asarray(weighted_poses, dtype=np.float64) / self.weights
        if self.to_markers is not None:
            poses = self.to_markers(poses)
        if compiled.directions_clear(np.ascontiguousarray(poses), self.tables.parents, self.position_column,
                                     self.y_column, self.x_column, self.root_axes_column, MIN_DIRECTION):
            return
        model = self.tables.model
        positions = np.zeros((len(poses), model.n_joints, 3))
        placed = self.position_column >= 0
        positions[:, placed] = poses[:, self.position_column[placed, None] + np.arange(3)]
        x = positions[:, 1:] - positions[:, model.parents[1:]]
        short = self.x_column[1:] >= 0
        x[:, short] = poses[:, self.x_column[1:][short, None] + np.arange(3)]
        names = list(model.names[1:])
        checks = [("x", x, names)]
        stored = self.y_column[1:] >= 0
        if stored.any():
            checks.append(("y", _across(x[:, stored], poses[:, self.y_column[1:][stored, None] + np.arange(3)]),
                           [n for n, s in zip(names, stored) if s]))
        if self.root_axes_column >= 0:
            axes = poses[:, self.root_axes_column:self.root_axes_column + 6].reshape(len(poses), 2, 3)
            checks.append(("x", axes[:, :1], [model.names[0]]))
            checks.append(("y", _across(axes[:, :1], axes[:, 1:]), [model.names[0]]))
        for axis, vectors, bones in checks:
            lengths = np.linalg.norm(vectors, axis=-1)
            if not np.all(lengths >= MIN_DIRECTION):
                frame, bone = np.argwhere(~(lengths >= MIN_DIRECTION))[0]
                raise DegeneratePose(f"bone {bones[bone]!r} in frame {frame}: {axis} axis of length "
                                     f"{lengths[frame, bone]:.3g}, below {MIN_DIRECTION:g}")

    def twist_reference(self, original_values: np.ndarray) -> np.ndarray:
        """(F, 2-dof solved bones, 3, 3): their true local rotations (`true_twists`)."""
        return compiled.twist_reference(np.ascontiguousarray(original_values, dtype=np.float64), self.twisted,
                                        self.twist_columns, self.twist_axes[:, 0].copy(),
                                        self.twist_axes[:, 1].copy(), self.tables.to_rad)

    def channels(self, weighted_poses: np.ndarray, root: np.ndarray | None, reference: np.ndarray | None = None,
                 flips: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        poses = np.ascontiguousarray(weighted_poses, dtype=np.float64)
        n_frames = len(poses)
        if poses.ndim != 2 or poses.shape[1] != self.marker_width:
            raise ValueError(f"poses have shape {poses.shape}, this skeleton needs (frames, {self.marker_width})")
        if not self.with_root and (root is None or np.shape(root) != (n_frames, ROOT_TRACK_WIDTH)):
            raise ValueError(f"root track has shape {np.shape(root)}, expected ({n_frames}, {ROOT_TRACK_WIDTH})")
        weights = self.weights
        if self.to_markers is not None:  # unweighted here, so the kernel reads them as they are
            poses = np.ascontiguousarray(self.to_markers(poses / weights))
            weights = np.ones_like(weights)
        use_reference = reference is not None
        if reference is None:
            reference = np.zeros((1, max(len(self.twisted), 1), 3, 3))
        if flips is None:
            flips = np.zeros((len(self.twisted), n_frames), np.bool_)
        root = np.zeros((1, ROOT_TRACK_WIDTH)) if root is None else np.ascontiguousarray(root, dtype=np.float64)
        t = self.tables
        values = np.zeros((n_frames, t.width))
        joints = len(t.parents)
        per_call = max(1, LOCAL_ROTATIONS_BYTES // (72 * max(n_frames, 1)))  # joints whose rotations fit
        for first in range(0, joints, per_call):
            values, out_flips = compiled.markers_to_channels(
                poses, weights, root, self.with_root, t.parents, self.faux, self.position_column, self.y_column,
                self.x_column, self.root_axes_column, self.root_proxy, self.solved, self.bone_direction,
                self.solved_dofs, self.solved_first_axis, self.solved_second_axis, self.solved_radius,
                self.solved_phase, self.twist_index, reference, use_reference, np.ascontiguousarray(flips), t.axis,
                t.first_column, t.n_channels, t.channel_kind, t.channel_axis, t.n_rotations, t.rotation_axes,
                t.rotation_channel, float(t.model.cm_per_unit), 1.0 / t.to_rad, t.width, values, first,
                min(joints, first + per_call))
        return values, out_flips


@register
class Positions(Representation):
    codec_id = "positions"

    def forward(self, model: SkeletonModel, motion) -> Encoded:
        pose = forward(model, motion.values, motion)
        return Encoded(encode_markers(model, pose, with_root=True, axes_from_positions=self.axes_from_positions))

    def inverse(self, model: SkeletonModel, encoded: Encoded, layout) -> np.ndarray:
        pose = decode_markers(model, encoded.poses, with_root=True, axes_from_positions=self.axes_from_positions,
                              twist=encoded.params.get("twist"))
        return inverse(model, pose.rotations, pose.positions[:, 0], layout)

    def joint_position_columns(self, model: SkeletonModel) -> slice:
        return slice(0, 3 * model.n_joints)

    def column_weights(self, model: SkeletonModel, layout, axis_weight_cm: float) -> np.ndarray:
        return marker_weights(marker_width(model, True, self.axes_from_positions),
                              self.joint_position_columns(model), axis_weight_cm)

    def decoder(self, tables: ChannelTables, params: dict, axis_weight_cm: float) -> MarkerDecoder:
        return MarkerDecoder(tables, self.column_weights(tables.model, tables.layout, axis_weight_cm), True,
                             self.axes_from_positions)
