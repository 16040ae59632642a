"""BVH clips (format 8 on): the hierarchy, its Acclaim-style model, and the file's columns.

Implements docs/format.md §11, "Decoding a BVH clip (format 8 on)", with the `meta` items it relies
on (§6.1, `meta` "Fields": BVH entries of `skeletons`, with `format`, `encoding`, `units` and
`units_inferred`; rows' `bvh`) and the `extra_root/NNNNN` stream (§8.10). The model
is handed to `geometry` (§10.2 to §10.12, "Decoding a lossy clip") as a `Skeleton` whose axis
matrices are the identity; this module maps the decoded channel values back to the file's columns
and writes the file's text ("BVH text", §12.2).
"""

import math
import re

import numpy as np

from .geometry import Skeleton

# §6.1, skeletons: `units` -> cm_per_unit
CM_PER_UNIT = {"cm": 1.0, "mm": 0.1, "m": 100.0, "in": 2.54}
ENCODINGS = ("utf-8", "latin-1")
# "Decoding a BVH clip": channel names, any case
CHANNELS = ("xposition", "yposition", "zposition", "xrotation", "yrotation", "zrotation")
# §6.1, rows' `bvh.style`
NUMBER_STYLES = ("repr", "g6", "g7", "g8", "g9", "g10", "g15", "g17", "f3", "f4", "f5", "f6", "f7", "f8", "f9")
LINE_ENDS = ("\n", "\r\n", "\r")
# rows' `bvh.motion`: MOTION, Frames: <frames>, Frame Time: <seconds>; blanks and tabs around the
# words, any case, each line ending in CRLF, LF or CR
_END = r"(?:\r\n|\n|\r)"
MOTION = re.compile(rf"[ \t]*MOTION[ \t]*{_END}[ \t]*Frames[ \t]*:[ \t]*([0-9]+)[ \t]*{_END}"
                    rf"[ \t]*Frame[ \t]+Time[ \t]*:[ \t]*(\S+)[ \t]*{_END}\Z", re.IGNORECASE | re.ASCII)
MAX_VALUE = 1e9  # "BVH text": a decoded value of magnitude above 1e9 or not finite is refused


class Joint:
    """A BVH joint: its parent (index, -1 for the root), OFFSET (file units), channels (lower
    case, CHANNELS order), child joints (indices, file order) and End Site OFFSET or None."""

    def __init__(self, name, parent):
        self.name, self.parent = name, parent
        self.offset, self.channels, self.joints, self.end_site = None, None, [], None


class Hierarchy:
    """The BVH text before `MOTION` of a `skeletons` entry of `format` "bvh": joints in file order
    (pre-order) and the file's columns, (joint index, channel) joint after joint."""

    def __init__(self, raw: bytes, entry: dict):
        if sorted(k for k in entry if k != "name") != ["encoding", "format", "units", "units_inferred"]:
            raise ValueError(f"skeleton {entry.get('name')!r}: a BVH entry has format, encoding, units "
                             "and units_inferred together")
        # units null: a lossless archive's hierarchy that had no model; only lossy decoding needs them
        if entry["encoding"] not in ENCODINGS or (entry["units"] is not None and entry["units"] not in CM_PER_UNIT) \
                or not isinstance(entry["units_inferred"], bool):
            raise ValueError(f"skeleton {entry['name']!r}: bad encoding, units or units_inferred")
        self.raw, self.encoding = raw, entry["encoding"]
        self.cm_per_unit = None if entry["units"] is None else CM_PER_UNIT[entry["units"]]
        self.words = raw.decode(self.encoding).split()
        self.pos = 0
        self.joints = []
        self.expect("HIERARCHY")
        self.expect("ROOT")
        self.joint(-1)
        if self.pos != len(self.words):
            raise ValueError(f"BVH: {self.words[self.pos]!r} after the root joint (exactly one ROOT)")
        if len({joint.name for joint in self.joints}) != len(self.joints):
            raise ValueError("BVH: two joints of one name")
        self.columns = [(j, channel) for j, joint in enumerate(self.joints) for channel in joint.channels]
        self.column = {column: i for i, column in enumerate(self.columns)}

    # ------------------------------------------------------------------ parsing

    def next(self):
        if self.pos >= len(self.words):
            raise ValueError("BVH: the hierarchy ends early")
        self.pos += 1
        return self.words[self.pos - 1]

    def expect(self, word):
        got = self.next()
        if got != word:
            raise ValueError(f"BVH: {word!r} expected, got {got!r}")

    def numbers(self, count):
        values = []
        for _ in range(count):
            word = self.next()
            try:
                value = float(word)
            except ValueError:
                raise ValueError(f"BVH: not a number: {word!r}") from None
            if not math.isfinite(value):
                raise ValueError(f"BVH: not a finite number: {word!r}")
            values.append(value)
        return np.array(values)

    def joint(self, parent):
        """`name { ... }`: in any order OFFSET, at most one CHANNELS (before any JOINT), JOINTs, at most one
        End Site."""
        joint = Joint(self.next(), parent)
        index = len(self.joints)
        self.joints.append(joint)
        if parent >= 0:
            self.joints[parent].joints.append(index)
        self.expect("{")
        while (word := self.next()) != "}":
            if word == "OFFSET" and joint.offset is None:
                joint.offset = self.numbers(3)
            elif word == "CHANNELS" and joint.channels is None and not joint.joints:
                count = self.next()
                if not count.isdigit() or not 1 <= int(count) <= 6:
                    raise ValueError(f"BVH: joint {joint.name!r}: CHANNELS count {count!r} (1 to 6)")
                joint.channels = [self.next().lower() for _ in range(int(count))]
                if any(c not in CHANNELS for c in joint.channels) or len(set(joint.channels)) != len(joint.channels):
                    raise ValueError(f"BVH: joint {joint.name!r}: bad channels {joint.channels}")
            elif word == "JOINT":
                self.joint(index)
            elif word == "End" and joint.end_site is None:
                self.expect("Site")
                self.expect("{")
                self.expect("OFFSET")
                joint.end_site = self.numbers(3)
                self.expect("}")
            else:
                raise ValueError(f"BVH: joint {joint.name!r}: unexpected {word!r}")
        if joint.offset is None:
            raise ValueError(f"BVH: joint {joint.name!r} has no OFFSET")
        joint.channels = joint.channels or []

    # ------------------------------------------------------------------ lossless rows

    def layout(self):
        """"Lossless": the row's bones (the joints with channels, file order) and counts."""
        return ([joint.name for joint in self.joints if joint.channels],
                [len(joint.channels) for joint in self.joints if joint.channels])


def rotation_channels(joint):
    """A joint's model rotation channels: its rotation channels in reverse CHANNELS order, as r*."""
    return ["r" + channel[0] for channel in reversed(joint.channels) if channel.endswith("rotation")]


class Model:
    """"The model" (lossy): the Acclaim-style joints built from the hierarchy (mover first, then
    links and joints by placing the mover's children's subtrees), and for each channel of the row's
    layout the file column it came from."""

    def __init__(self, hierarchy: Hierarchy):
        self.hierarchy = h = hierarchy
        joints = h.joints
        root = joints[0]
        # Mover: the root, unless it has exactly one child joint, no End Site, and that child has a
        # position channel: then the child moves and the root is the extra root.
        if (len(root.joints) == 1 and root.end_site is None
                and any(c.endswith("position") for c in joints[root.joints[0]].channels)):
            self.extra_root, mover = 0, root.joints[0]
        else:
            self.extra_root, mover = None, 0
        self.mover = mover
        self.names, self.parent, self.offsets, self.channels, self.sources = [], [], [], [], []
        link_names, joint_names = set(), set()

        def add(name, parent, offset, channels, sources, link):
            (link_names if link else joint_names).add(name)
            self.names.append(name)
            self.parent.append(parent)
            self.offsets.append(np.asarray(offset, dtype=np.float64))
            self.channels.append(channels)
            self.sources.append(sources)
            return len(self.names) - 1

        def rotations(j):
            model = rotation_channels(joints[j])
            return model, [h.column[(j, c[1] + "rotation")] for c in model]

        def children(j):
            """A BVH joint's children: its child joints in file order, then its End Site."""
            kids = [(joints[k].name, joints[k].offset, k) for k in joints[j].joints]
            if joints[j].end_site is not None:
                kids.append(("end", joints[j].end_site, None))
            return kids

        def place(p, end):
            """Placing joint p with `end`, the model joint whose end point is p's position."""
            kids = children(p)
            channels, sources = rotations(p)
            if not channels:
                for name, offset, c in kids:
                    link = add(f"{joints[p].name}>{name}", end, offset, [], [], True)
                    if c is not None:
                        place(c, link)
            elif not kids:
                add(joints[p].name, end, np.zeros(3), channels, sources, False)
            else:
                _, o1, c1 = kids[0]
                me = add(joints[p].name, end, o1, channels, sources, False)
                if c1 is not None:
                    place(c1, me)
                for name, offset, c in kids[1:]:
                    link = add(f"{joints[p].name}>{name}", me, offset - o1, [], [], True)
                    if c is not None:
                        place(c, link)

        positions = [c for c in joints[mover].channels if c.endswith("position")]
        if sorted(positions) != ["xposition", "yposition", "zposition"]:
            raise ValueError(f"BVH: the mover {joints[mover].name!r} needs all three position channels")
        channels, sources = rotations(mover)
        add(joints[mover].name, -1, np.zeros(3), ["t" + c[0] for c in positions] + channels,
            [h.column[(mover, c)] for c in positions] + sources, False)
        for name, offset, c in children(mover):
            link = add(f"{joints[mover].name}>{name}", 0, offset, [], [], True)
            if c is not None:
                place(c, link)
        if link_names & joint_names:
            raise ValueError(f"BVH: a joint named as a link: {sorted(link_names & joint_names)}")
        self.bones = [name for name, channels in zip(self.names, self.channels) if channels]
        self.counts = [len(channels) for channels in self.channels if channels]
        self.source = np.array([s for sources in self.sources for s in sources], dtype=np.int64)

    def skeleton(self, axes_from_positions):
        """The model as geometry's Skeleton: V = offset · cm_per_unit (cm), C_j the identity."""
        cm = self.hierarchy.cm_per_unit
        return Skeleton.from_model(self.names, self.parent, [offset * cm for offset in self.offsets],
                                   self.channels, cm, axes_from_positions)

    def file_values(self, v, extra):
        """"From v to the file's values": coded columns from v, the extra root's from `extra` (its
        `extra_root/NNNNN` matrix) or 0, any other column the joint's OFFSET component."""
        h = self.hierarchy
        frames = v.shape[0]
        out = np.zeros((frames, len(h.columns)))
        coded = np.zeros(len(h.columns), dtype=bool)
        out[:, self.source] = v
        coded[self.source] = True
        for i, (j, channel) in enumerate(h.columns):
            if coded[i]:
                continue
            if j == self.extra_root:
                if extra is not None:
                    out[:, i] = extra[:, h.joints[j].channels.index(channel)]
            elif channel.endswith("position"):
                out[:, i] = h.joints[j].offset["xyz".index(channel[0])]
            else:
                raise ValueError(f"BVH: column {channel} of {h.joints[j].name!r} is fed by nothing")
        return out


def check_row(row, layout, lossless):
    """Rows' `bvh` (§6.1, §6.3): motion, style and extra_root; and the row's `header`,
    `first_frame`, `angle_unit`, and `bones` and `counts` (= `layout`) as a BVH row has them."""
    bvh = row["bvh"]
    if not set(bvh) <= {"motion", "style", "extra_root"} or not {"motion", "style"} <= set(bvh):
        raise ValueError(f"{row['path']}: bvh has fields {sorted(bvh)}")
    motion = MOTION.match(bvh["motion"])
    if motion is None or int(motion.group(1)) != row["frames"]:
        raise ValueError(f"{row['path']}: bvh.motion {bvh['motion']!r} (frames {row['frames']})")
    float(motion.group(2))
    style = bvh["style"]
    if (not {"line_end", "number", "separator", "trailing"} <= set(style)
            or not set(style) <= {"line_end", "number", "separator", "trailing", "final_line_end", "after"}
            or style["number"] not in NUMBER_STYLES
            or style["separator"] not in (" ", "\t") or style["line_end"] not in LINE_ENDS
            or style["trailing"].strip(" \t") or style.get("final_line_end", True) not in (True, False)
            or len(style.get("after", "")) > 64 or style.get("after", "").strip(" \t\r\n")):
        raise ValueError(f"{row['path']}: bvh.style {style}")
    if "extra_root" in bvh and (bvh["extra_root"] is not True or lossless):
        raise ValueError(f"{row['path']}: bvh.extra_root is true, in lossy rows only")
    if row["header"] or row["first_frame"] != 1 or row["angle_unit"] != "deg":
        raise ValueError(f"{row['path']}: a BVH row has no header, first_frame 1 and angle_unit deg")
    if (row["bones"], row["counts"]) != tuple(layout):
        raise ValueError(f"{row['path']}: bones/counts are not the BVH clip's channel layout")


def check_values(row, values):
    """"BVH text": a clip with a decoded value of magnitude above 1e9 or not finite is refused."""
    if not np.all(np.isfinite(values)) or np.any(np.abs(values) > MAX_VALUE):
        raise ValueError(f"{row['path']}: a decoded value not finite or beyond 1e9")
    return values


def text(hierarchy, row, values):
    """The file `decompress` writes: the hierarchy's bytes, then `motion` and the frame lines
    ("BVH text": values by `number`, joined by `separator`, then `trailing`, `line_end`), encoded
    with the skeleton's encoding."""
    check_values(row, values)
    style = row["bvh"]["style"]
    if style["number"] == "repr":
        number = repr
    else:
        number = f"%.{int(style['number'][1:])}{style['number'][0]}".__mod__
    lines = [style["separator"].join(number(value) for value in frame) + style["trailing"] + style["line_end"]
             for frame in values.tolist()]
    if lines and not style.get("final_line_end", True):
        lines[-1] = lines[-1][: len(lines[-1]) - len(style["line_end"])]
    return hierarchy.raw + (row["bvh"]["motion"] + "".join(lines) + style.get("after", "")).encode(hierarchy.encoding)
