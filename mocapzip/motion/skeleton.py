"""The skeleton as kinematics needs it: joints, parents, axis matrices, offsets in cm.

A `SkeletonModel` is built once from a parsed ASF file. Joint 0 is the root,
joint j >= 1 is the ASF bone of the same name, and parents always come before
their children. Joint j's *position* is the end point of bone j (the root's
position is the root translation), so a CMU skeleton has 31 joint positions.

All matrices use the row-vector convention of `mocapzip.motion.rotations`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mocapzip.formats.asf import ROOT, Skeleton
from mocapzip.formats.errors import MocapFormatError
from mocapzip.motion.rotations import euler_matrix

# Bones shorter than this (cm) are "short": their direction cannot be read back
# reliably from two nearby joint positions once those are compressed, so the
# position-based representations store their full orientation instead.
SHORT_BONE_CM = 1.0

SIDE_SUFFIX = re.compile(r"[_.]([lr])$")  # Bandai's Foot_L, Hand_R
SIDE_PREFIX = re.compile(r"^(l|r)(?:eft|ight)?")  # CMU's and HDM05's lfoot, BVH's lHand, LeftFoot


def side_of(name: str) -> str | None:
    """"l" or "r": the side a limb joint's name says (a suffix before a prefix: LowerLeg_R is
    right), or None. Only for joints already known to be a left or a right one (feet, hands): any
    name starting with l or r reads as a side, "root" too."""
    name = name.lower()
    found = SIDE_SUFFIX.search(name) or SIDE_PREFIX.match(name)
    return found.group(1) if found else None


@dataclass(frozen=True)
class ChannelLayout:
    """Which AMC columns belong to which joint: the bone order and value counts of
    a clip's lines (Motion.bones / Motion.counts), and the unit of its angles."""

    bones: tuple[str, ...]
    counts: tuple[int, ...]
    angle_unit: str  # 'deg' or 'rad'

    @property
    def width(self) -> int:
        return int(sum(self.counts))

    def columns(self) -> dict[str, slice]:
        starts = np.concatenate([[0], np.cumsum(self.counts)]).astype(int)
        return {b: slice(starts[i], starts[i + 1]) for i, b in enumerate(self.bones)}


@dataclass(frozen=True, eq=False)
class SkeletonModel:
    """An ASF skeleton as arrays, joints in topological order (see the module doc)."""

    names: tuple[str, ...]  # joint names, 'root' first, parents before children
    parents: np.ndarray  # (J,) parent joint index, -1 for the root
    axis: np.ndarray  # (J, 3, 3) the ASF axis matrix C of each joint
    offsets: np.ndarray  # (J, 3) bone vector in cm in the base pose (direction * length); root: zeros
    channels: tuple[tuple[str, ...], ...]  # AMC values of each joint, in file order ('tx', 'rx', ...)
    cm_per_unit: float  # file length unit -> cm
    angle_unit: str  # 'deg' or 'rad', from the ASF units
    points: tuple[str, ...] | None = None  # what each joint's position is called, where not its name (BVH)

    def point_name(self, j: int) -> str:
        """The name of joint j's position (its end point) for messages: an ASF bone's, or the BVH
        joint or End Site there (`motion.bvh_skeleton`)."""
        return self.names[j] if self.points is None else self.points[j]

    @classmethod
    def from_asf(cls, skeleton: Skeleton) -> "SkeletonModel":
        """Build from a parsed ASF. The root's C comes from `orientation` in `root_axis`
        order, each bone's from `axis` in its axis order; angles in the ASF's unit."""
        to_rad = np.pi / 180.0 if skeleton.angle_unit == "deg" else 1.0
        children: dict[str, list[str]] = {}
        for parent, kids in skeleton.hierarchy:
            children.setdefault(parent, []).extend(kids)
        names, parents = [ROOT], [-1]
        stack = [(child, 0) for child in reversed(children.get(ROOT, []))]
        while stack:  # depth-first, children in file order: limbs stay contiguous
            name, parent = stack.pop()
            names.append(name)
            parents.append(parent)
            stack.extend((child, len(names) - 1) for child in reversed(children.get(name, [])))
        bones = {b.name: b for b in skeleton.bones}
        unreachable = set(bones) - set(names)
        if unreachable:
            raise MocapFormatError(f"bone '{sorted(unreachable)[0]}' is not connected to the root", skeleton.path)

        root_channels = tuple(c.lower() for c in skeleton.root_order)
        valid = {"tx", "ty", "tz", "rx", "ry", "rz"}
        if len(set(root_channels)) != len(root_channels) or not set(root_channels) <= valid:
            raise MocapFormatError(f"unsupported root order {' '.join(skeleton.root_order)}", skeleton.path)
        axis = [euler_matrix(skeleton.root_orientation * to_rad, skeleton.root_axis.lower())]
        offsets = [np.zeros(3)]
        channels = [root_channels]
        for name in names[1:]:
            bone = bones[name]
            unsupported = [d for d in bone.dof if d not in ("rx", "ry", "rz")]
            if unsupported:
                raise MocapFormatError(
                    f"bone '{name}': dof {unsupported[0]!r} is not supported (rotations only)", skeleton.path
                )
            axis.append(euler_matrix(bone.axis * to_rad, bone.axis_order.lower()))
            offsets.append(np.asarray(bone.direction, dtype=np.float64) * bone.length * skeleton.cm_per_unit)
            channels.append(tuple(bone.dof))
        return cls(
            names=tuple(names),
            parents=np.array(parents, dtype=np.int64),
            axis=np.array(axis),
            offsets=np.array(offsets),
            channels=tuple(channels),
            cm_per_unit=float(skeleton.cm_per_unit),
            angle_unit=skeleton.angle_unit,
        )

    @property
    def n_joints(self) -> int:
        return len(self.names)

    @cached_property
    def index(self) -> dict[str, int]:
        return {name: j for j, name in enumerate(self.names)}

    @cached_property
    def lengths(self) -> np.ndarray:
        """(J,) bone lengths in cm (root: 0)."""
        return np.linalg.norm(self.offsets, axis=1)

    @cached_property
    def short(self) -> np.ndarray:
        """(J,) bool: bones too short to give a direction (see SHORT_BONE_CM); root False."""
        out = self.lengths < SHORT_BONE_CM
        out[0] = False
        return out

    def rotation_axes(self, joint: int) -> str:
        """The joint's rotation channels as Euler axes in file order, e.g. 'xyz', 'xz', ''."""
        return "".join(c[1] for c in self.channels[joint] if c.startswith("r"))

    @cached_property
    def root_proxy(self) -> int | None:
        """A child of the root without rotation channels, if there is one: its world
        rotation equals the root's (C^-1 I C R_root), so the root's rotation can be
        read from it (CMU: lhipjoint; Vicon Blade: LeftUpLeg_dum)."""
        for j in range(1, self.n_joints):
            if self.parents[j] == 0 and not self.rotation_axes(j):
                return j
        return None

    @cached_property
    def ancestors(self) -> np.ndarray:
        """(J, J) float: [j, k] = 1 when k is j or one of its ancestors. Summing bone
        vectors through it turns per-bone offsets into joint positions in one product."""
        out = np.zeros((self.n_joints, self.n_joints))
        for j in range(self.n_joints):
            k = j
            while k >= 0:
                out[j, k] = 1.0
                k = self.parents[k]
        return out

    @cached_property
    def faux(self) -> np.ndarray:
        """(J, 3, 3) fixed per-bone "faux" base matrices B (thesis 3.2.1, positions).

        Row 0 is the unit bone direction, so the aligned frame B @ R of a posed bone
        has its x axis along the bone and that axis can be recomputed from joint
        positions. Row 1 is the world axis least parallel to the bone, made
        perpendicular to it; row 2 completes a right-handed frame. Root and short
        bones get the identity (their orientation is stored whole).
        """
        out = np.broadcast_to(np.eye(3), (self.n_joints, 3, 3)).copy()
        for j in range(1, self.n_joints):
            if self.short[j]:
                continue
            x = self.offsets[j] / self.lengths[j]
            helper = np.eye(3)[np.argmin(np.abs(x))]
            y = helper - (helper @ x) * x
            y /= np.linalg.norm(y)
            out[j] = np.stack([x, y, np.cross(x, y)])
        return out

    def base_positions(self) -> np.ndarray:
        """(J, 3) joint positions in cm of the base pose (all rotations identity, root at 0)."""
        return self.ancestors @ self.offsets

    def layout(self, source) -> ChannelLayout:
        """The ChannelLayout of a Motion (or a ChannelLayout, returned checked).

        Angle unit: an explicit ':RADIANS' / ':DEGREES' in the AMC header wins,
        otherwise the ASF's `:units angle` applies.
        """
        if isinstance(source, ChannelLayout):
            layout = source
        else:
            header = {line.strip().upper() for line in getattr(source, "header", [])}
            unit = "rad" if ":RADIANS" in header else "deg" if ":DEGREES" in header else self.angle_unit
            layout = ChannelLayout(tuple(source.bones), tuple(int(c) for c in source.counts), unit)
        for bone, count in zip(layout.bones, layout.counts):
            if bone not in self.index:
                raise MocapFormatError(f"motion bone '{bone}' is not in the skeleton")
            expected = len(self.channels[self.index[bone]])
            if count != expected:
                raise MocapFormatError(f"motion bone '{bone}' has {count} values, the skeleton gives it {expected}")
        return layout
