"""A BVH skeleton as the codec's `SkeletonModel`, and a BVH clip as channels of that model.

BVH and Acclaim turn bones differently. In BVH a joint's rotation turns the OFFSETs of its
children; in Acclaim a bone's rotation turns the bone itself, which starts at its parent's
end point. So the rotation channels of each BVH joint P turn the model bone from P to its
first child (a joint or its End Site), named P; each further child hangs from that bone's end
by a link bone (no channels, named "P>child" or "P>end") that the same rotation turns. Every
BVH joint and End Site is thus the end point of exactly one model bone, and joint positions are
the same points (only a leaf without an End Site adds a bone of zero length, for its rotation).
Rotation order: BVH's `Zrotation Xrotation Yrotation` is v' = Rz Rx Ry v, the last channel
turning first, while an Acclaim `dof rz rx ry` turns rz first; the model lists each joint's
rotations reversed.

The *mover* is the model's root: the BVH root, or its only child where that child has position
channels too (Bandai's `joint_Root` above `Hips`: an extra root). Position channels give a
joint's offset from its parent, in place of its OFFSET, as MotionBuilder writes them.

Lossy coding codes the mover's position and every rotation through the codec; an extra root's
channels go beside them exactly where any is not 0 (`above`: a game's root motion; Bandai's are
0 but in 4 clips),
and as the model hangs below the extra root, its errors are those of the file's joints. The
other channels are *fixed*: the position channels of the other joints (Bandai writes all of
them, equal to their OFFSETs). A decode writes each the OFFSET it stands for, so a clip whose
fixed channels move by more than FIXED_TOLERANCE_CM is refused for lossy coding. Lossless
coding keeps every channel as it is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapzip.defaults import UNITS_CM
from mocapzip.formats.amc import AmcStyle, Motion
from mocapzip.formats.bvh import Bvh, BvhJoint, joint_columns
from mocapzip.formats.errors import MocapFormatError
from mocapzip.motion.rotations import euler_matrix
from mocapzip.motion.skeleton import SkeletonModel

_LOSSY_KEEPS = "lossy coding keeps only the root's position channels and the rotations: use --lossless"
FIXED_TOLERANCE_CM = 1e-4  # how far a fixed channel may stray from its value (Bandai: 9e-6 cm)


# A human's longest path through the skeleton (hand to foot) is 100 to 400 cm; its length
# in a file's units tells the unit where only one unit puts it in that range.
_HUMAN_SPAN_CM = (100.0, 400.0)


@dataclass(frozen=True, eq=False)
class BvhSkeleton:
    """A BVH hierarchy, its model, and where each model channel is in the BVH's frame lines."""

    joints: list[BvhJoint]
    units: str | None  # of the OFFSETs and position channels: a UNITS_CM name (None: unknown, `unmodelled`)
    model: SkeletonModel | None  # None: `unmodelled`
    bones: tuple[str, ...]  # the lossy clip's bones (the model joints with channels), in model order
    counts: tuple[int, ...]  # their channel counts
    coded: np.ndarray  # (C,) the BVH column of each of the lossy clip's columns
    above: np.ndarray  # the extra root's BVH columns, kept exactly (empty without an extra root)
    fixed: np.ndarray  # the other BVH columns
    fixed_values: np.ndarray  # what each fixed column stands for, in file units
    path: str | None = None

    @property
    def cm_per_unit(self) -> float:
        return UNITS_CM[self.units]

    @property
    def width(self) -> int:
        """Values per BVH frame line."""
        return len(self.coded) + len(self.above) + len(self.fixed)

    def motion(self, bvh: Bvh, lossless: bool) -> Motion:
        """The clip as the codec takes it: every BVH column in file order (`lossless`), else the
        coded columns in model order, after checking that the fixed ones stand still."""
        frames = np.arange(1, bvh.n_frames + 1)
        if lossless:
            bones, counts = file_layout(bvh.joints)
            return Motion(bones, counts, np.asarray(bvh.values), frames, [], bvh.path, AmcStyle(encoding=bvh.encoding))
        if bvh.values.shape[1] != self.width:
            raise MocapFormatError(f"{bvh.values.shape[1]} channels, the skeleton has {self.width}", bvh.path)
        self.check_fixed(bvh)
        # a lossy decode is written as the file's numbers: %.<p>g or %.<p>f (repr's shortest forms: %.6g)
        notation, digits = ("g", 6) if bvh.style.number == "repr" else (bvh.style.number[0], int(bvh.style.number[1:]))
        return Motion(list(self.bones), list(self.counts), bvh.values[:, self.coded], frames, [], bvh.path,
                      AmcStyle(notation=notation, digits=digits, encoding=bvh.encoding))

    def check_fixed(self, bvh: Bvh, why: str = _LOSSY_KEEPS) -> None:
        """MocapFormatError if a fixed channel strays from its value (`why` that matters): the
        model would lose it."""
        if not len(self.fixed):
            return
        stray = np.abs(bvh.values[:, self.fixed] - self.fixed_values).max(axis=0) * self.cm_per_unit
        worst = int(np.argmax(stray))
        if stray[worst] > FIXED_TOLERANCE_CM:
            joint, channel = joint_columns(self.joints)[self.fixed[worst]]
            raise MocapFormatError(
                f"joint '{self.joints[joint].name}' {channel} moves {stray[worst]:.3g} cm from its OFFSET; {why}",
                bvh.path)

    def above_values(self, bvh: Bvh) -> np.ndarray | None:
        """The extra root's channels of a clip; None where there are none or all are 0."""
        above = bvh.values[:, self.above]
        return np.ascontiguousarray(above) if np.any(above) else None

    def file_values(self, values: np.ndarray, above: np.ndarray | None) -> np.ndarray:
        """A lossy clip's columns (model order) and its extra root's (None: all 0) -> the BVH frame
        values, fixed columns filled in."""
        out = np.zeros((len(values), self.width))
        out[:, self.coded] = values
        if above is not None:
            out[:, self.above] = above
        out[:, self.fixed] = self.fixed_values
        return out


def bvh_skeleton(joints: list[BvhJoint], units: str | None, path: str | None = None) -> BvhSkeleton:
    """Build the model of a BVH hierarchy whose lengths are in `units` (a UNITS_CM name; None:
    `infer_units`); see the module doc. MocapFormatError if it has no model or no unit."""
    if sum(j.parent < 0 for j in joints) != 1:
        raise MocapFormatError(f"{sum(j.parent < 0 for j in joints)} ROOT joints; mcz takes one skeleton per file",
                               path)
    units = _known_units(joints, units, path)
    cm_per_unit = UNITS_CM[units]
    columns = joint_columns(joints)
    first_column = np.cumsum([0] + [len(j.channels) for j in joints])
    children: dict[int, list[int]] = {}
    for j, joint in enumerate(joints):
        children.setdefault(joint.parent, []).append(j)
    mover, extra = 0, None
    only = children.get(0, [])
    if len(only) == 1 and joints[0].end_site is None and _positions(joints[only[0]]):
        mover, extra = only[0], 0
    if len(_positions(joints[mover])) != 3:
        raise MocapFormatError(f"root joint '{joints[mover].name}' needs Xposition, Yposition and Zposition", path)

    names: list[str] = [joints[mover].name]
    points: list[str] = [joints[mover].name]  # the BVH joint or End Site at each model joint's end
    parents, offsets = [-1], [np.zeros(3)]
    channels: list[tuple[str, ...]] = []
    coded: list[int] = []

    def own(j: int, with_positions: bool) -> tuple[tuple[str, ...], list[int]]:
        """Joint j's rotation channels (and position channels first, `with_positions`) as model
        channels ('tx', 'rz', ...), the rotations reversed, and their BVH columns."""
        listed = list(enumerate(joints[j].channels))
        pairs = [(k, c) for k, c in listed if with_positions and c.endswith("position")]
        pairs += [(k, c) for k, c in listed if c.endswith("rotation")][::-1]
        return (tuple(("t" if c.endswith("position") else "r") + c[0].lower() for _, c in pairs),
                [int(first_column[j]) + k for k, _ in pairs])

    def add(name: str, point: str, parent: int, offset: np.ndarray, joint_channels: tuple[str, ...]) -> int:
        if name in names:
            raise MocapFormatError(f"joint name {name!r} clashes with the name of a link bone", path)
        names.append(name)
        points.append(point)
        parents.append(parent)
        offsets.append(np.asarray(offset, dtype=np.float64) * cm_per_unit)
        channels.append(joint_channels)
        return len(names) - 1

    def kids(p: int) -> list[tuple[str, np.ndarray, int | None]]:
        """(point name, offset, joint or None for the End Site) of each child of BVH joint p."""
        out = [(joints[c].name, joints[c].offset, c) for c in children.get(p, [])]
        if joints[p].end_site is not None:
            out.append((f"{joints[p].name} End Site", joints[p].end_site, None))
        return out

    def link_name(p: int, child: int | None) -> str:
        return f"{joints[p].name}>{'end' if child is None else joints[child].name}"

    def place(p: int, end: int) -> None:
        """Model the subtree of BVH joint p, whose position is the end point of model joint `end`."""
        rotations, cols = own(p, False)
        below = kids(p)
        holder, start = end, np.zeros(3)  # what the links hang from, and where that ends, from p
        if rotations:
            coded.extend(cols)
            if not below:  # a leaf without an End Site: its rotation moves no point
                add(joints[p].name, joints[p].name, end, np.zeros(3), rotations)
                return
            name, start, child = below[0]
            holder = add(joints[p].name, name, end, start, rotations)
            if child is not None:
                place(child, holder)
            below = below[1:]
        for name, offset, child in below:
            link = add(link_name(p, child), name, holder, np.asarray(offset) - start, ())
            if child is not None:
                place(child, link)

    root_channels, root_columns = own(mover, True)
    channels.append(root_channels)
    coded.extend(root_columns)
    for name, offset, child in kids(mover):
        link = add(link_name(mover, child), name, 0, offset, ())
        if child is not None:
            place(child, link)

    model = SkeletonModel(names=tuple(names), parents=np.array(parents, dtype=np.int64),
                          axis=np.broadcast_to(np.eye(3), (len(names), 3, 3)).copy(), offsets=np.array(offsets),
                          channels=tuple(channels), cm_per_unit=float(cm_per_unit), angle_unit="deg",
                          points=tuple(points))
    above = np.array([k for k, (j, _) in enumerate(columns) if j == extra], dtype=np.int64)
    fixed = np.array(sorted(set(range(len(columns))) - set(coded) - set(above.tolist())), dtype=np.int64)
    fixed_values = np.array([joints[columns[k][0]].offset["XYZ".index(columns[k][1][0])] for k in fixed])
    with_channels = [j for j in range(len(names)) if channels[j]]
    return BvhSkeleton(joints, units, model, tuple(names[j] for j in with_channels),
                       tuple(len(channels[j]) for j in with_channels), np.array(coded, dtype=np.int64), above,
                       fixed, fixed_values, path)


def file_layout(joints: list[BvhJoint]) -> tuple[list[str], list[int]]:
    """(joints with channels, their channel counts): the layout of a clip's frame lines as
    lossless coding keeps them (a lossy clip's is `BvhSkeleton.bones` and `counts`)."""
    with_channels = [joint for joint in joints if joint.channels]
    return [joint.name for joint in with_channels], [len(joint.channels) for joint in with_channels]


def unmodelled(joints: list[BvhJoint], units: str | None, path: str | None = None) -> BvhSkeleton:
    """A hierarchy `bvh_skeleton` refuses (two roots, a root without position channels, a unit it
    cannot tell), as far as lossless coding needs it: its joints, whose values it keeps as they are."""
    none = np.zeros(0, dtype=np.int64)
    return BvhSkeleton(joints, units, None, (), (), none, none, none, np.zeros(0), path)


def point_names(joints: list[BvhJoint]) -> tuple[str, ...]:
    """Every joint and End Site ("<joint> End Site") of a hierarchy, in file order."""
    return tuple(name for joint in joints
                 for name in (joint.name, *((f"{joint.name} End Site",) if joint.end_site is not None else ())))


def file_positions(bvh: Bvh, units: str | None = None) -> np.ndarray:
    """(frames, points, 3) positions in cm of every joint and End Site (`point_names`) of a BVH
    clip, as the file's channels put them: any channel may move (unlike the codec's model, whose
    bones other than the root keep their OFFSET). `units`: of its lengths; None: `infer_units`."""
    return file_pose(bvh, units, turns=False)[1]


def file_pose(bvh: Bvh, units: str | None = None, turns: bool = True) -> tuple[np.ndarray | None, np.ndarray]:
    """(world rotations (frames, points, 3, 3) in row vectors, or None unless `turns`; positions)
    of `file_positions`' points: an End Site turns with its joint."""
    units = _known_units(bvh.joints, units, bvh.path)
    frames, column = bvh.n_frames, 0
    turns_of: list[np.ndarray] = []  # each joint's world rotation, row vectors (F, 3, 3)
    places: list[np.ndarray] = []  # each joint's position (F, 3)
    out, rotations = [], []
    for joint in bvh.joints:
        offset = np.repeat(np.asarray(joint.offset, dtype=np.float64)[None], frames, axis=0)
        axes, angles = "", []
        for channel in joint.channels:
            if channel.endswith("position"):
                offset[:, "XYZ".index(channel[0])] = bvh.values[:, column]
            else:
                axes, angles = channel[0].lower() + axes, [bvh.values[:, column]] + angles  # reversed: row vectors
            column += 1
        turn = euler_matrix(np.radians(np.stack(angles, axis=-1)), axes) if axes else np.eye(3)[None]
        if joint.parent >= 0:
            offset = places[joint.parent] + np.einsum("fi,fij->fj", offset, turns_of[joint.parent])
            turn = turn @ turns_of[joint.parent]
        places.append(offset)
        turns_of.append(np.broadcast_to(turn, (frames, 3, 3)))
        out.append(offset)
        rotations.append(turns_of[-1])
        if joint.end_site is not None:
            out.append(offset + np.einsum("i,fij->fj", np.asarray(joint.end_site, dtype=np.float64), turns_of[-1]))
            rotations.append(turns_of[-1])
    return (np.stack(rotations, axis=1) if turns else None), np.stack(out, axis=1) * UNITS_CM[units]


def point_parents(joints: list[BvhJoint]) -> np.ndarray:
    """The parent of each of `point_names`' points (-1: none): a joint's parent joint, an End Site's joint."""
    at, parents = [], []
    for joint in joints:
        at.append(len(parents))
        parents.append(-1 if joint.parent < 0 else at[joint.parent])
        if joint.end_site is not None:
            parents.append(at[-1])
    return np.array(parents, dtype=np.int64)


def _known_units(joints: list[BvhJoint], units: str | None, path: str | None) -> str:
    """`units`, or those `infer_units` finds; MocapFormatError if it finds none."""
    units = units or infer_units(joints)
    if units is None:
        raise MocapFormatError("cannot tell the unit of its OFFSETs (not a human's size in cm, mm or m): "
                               f"give it (--units {'|'.join(UNITS_CM)})", path)
    return units


def infer_units(joints: list[BvhJoint]) -> str | None:
    """The unit of a hierarchy's OFFSETs (a UNITS_CM name) when the skeleton's longest path (hand
    to foot, for a human) is 100 to 400 cm in exactly one of cm, mm and m; else None (`--units`
    says). Inches are never guessed: a human in inches is a child's size in cm."""
    span = _longest_path(joints)
    fits = [unit for unit, cm in UNITS_CM.items() if unit != "in" and _HUMAN_SPAN_CM[0] <= span * cm <= _HUMAN_SPAN_CM[1]]
    return fits[0] if len(fits) == 1 else None


def _longest_path(joints: list[BvhJoint]) -> float:
    """The longest path between two points of the skeleton along its OFFSETs, in file units; the
    root's child with position channels (an extra root's) does not count its OFFSET."""
    edges: dict[object, list[tuple[object, float]]] = {}

    def connect(a, b, length: float) -> None:
        edges.setdefault(a, []).append((b, length))
        edges.setdefault(b, []).append((a, length))

    for j, joint in enumerate(joints):
        if joint.parent >= 0:
            moves = joints[joint.parent].parent < 0 and _positions(joint)
            connect(joint.parent, j, 0.0 if moves else float(np.linalg.norm(joint.offset)))
        if joint.end_site is not None:
            connect(j, ("end", j), float(np.linalg.norm(joint.end_site)))

    def farthest(start) -> tuple[object, float]:
        distance, stack = {start: 0.0}, [start]
        while stack:
            node = stack.pop()
            for other, length in edges.get(node, []):
                if other not in distance:
                    distance[other] = distance[node] + length
                    stack.append(other)
        far = max(distance, key=distance.get)
        return far, distance[far]

    return farthest(farthest(0)[0])[1]


def _positions(joint: BvhJoint) -> list[str]:
    return [c for c in joint.channels if c.endswith("position")]


