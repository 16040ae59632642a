"""The classes: what the codec codes on its own (a whole clip, or with --segment each segment of
a take cut at its PPCA change points, `classes.segment`), and the class each is coded in: by
path or table as the first pass named it (`--classes pooled`: small subjects pooled,
`classes.by_name.pooled_classes`), or from the poses (`-c auto`, `classes.auto`)."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, replace

from mocapzip.archive.passes.first_pass import ClipsRead
from mocapzip.classes.auto import auto_classes, parse_auto
from mocapzip.classes.by_name import pooled_classes
from mocapzip.classes.plan import ClassPlan
from mocapzip.classes.segment import segment_take
from mocapzip.codec.pca import CovarianceAccumulator
from mocapzip.codec.segments import coded_range
from mocapzip.formats.amc import Motion
from mocapzip.inputs.clip import ClipReader, LoadedClip
from mocapzip.inputs.discover import ClipSource
from mocapzip.progress import progress
from mocapzip.ratecontrol.target import CodingTarget
from mocapzip.representations.base import Encoded


@dataclass(frozen=True)
class Unit:
    """What the codec codes on its own: a whole clip, or (--segment) one segment of a take."""

    clip: int  # the take's place among the archive's clips
    source: ClipSource  # the take's files
    first: int  # the segment's first frame in the take (0 for a whole clip)
    frames: int  # the segment's frame count, up to the next cut
    coded: tuple[int, int] | None = None  # a segment's frames coded: it and OVERLAP frames past its cuts

    def load(self, reader: ClipReader) -> LoadedClip:
        clip = reader.load(self.source)
        return clip if self.coded is None else _frames_of(clip, *self.coded)

    @property
    def coded_frames(self) -> int:
        return self.frames if self.coded is None else self.coded[1] - self.coded[0]


@dataclass(frozen=True)
class Classes:
    """Each unit's class."""

    units: tuple[Unit, ...]  # in clip order, a take's segments in frame order
    names: tuple[str, ...]  # the classes, sorted: a class's number in meta is its place here
    unit_class: tuple[int, ...]  # each unit's class, by its place in `names`
    clip_class: tuple[int, ...]  # each clip's class in its row: a take's is its first segment's
    poses: dict[str, CovarianceAccumulator]  # weighted poses summed by class name, where the first pass summed them
    auto_plans: list | None  # -c auto: the plan of each pose width (meta's `auto_classes`)

    def members(self, k: int) -> list[int]:
        """The units of class k, by their place in `units`."""
        return [u for u, c in enumerate(self.unit_class) if c == k]


def classes_of(clips: ClipsRead, reader: ClipReader, plan: ClassPlan, target: CodingTarget, jobs: int = 1) -> Classes:
    """The units of `clips` and the class of each; -c auto sizes its classes as `target` codes them."""
    path_classes, poses = clips.path_classes, clips.poses
    if plan.classes == "pooled" and not plan.lossless:
        path_classes, poses = _pooled(clips)
    units = _units(clips, reader, plan.segment)
    auto_report: dict = {}
    if path_classes:  # a take's segments share its class
        unit_names = [path_classes[unit.clip] for unit in units]
    else:
        unit_names = auto_classes([unit.load(reader) for unit in units], parse_auto(plan.classes), target,
                                  jobs=jobs, report=auto_report)
    names = tuple(sorted(set(unit_names)))
    number = {name: k for k, name in enumerate(names)}
    unit_class = tuple(number[name] for name in unit_names)
    clip_class = tuple(k for unit, k in zip(units, unit_class) if unit.first == 0)
    return Classes(tuple(units), names, unit_class, clip_class, poses, auto_report.get("groups"))


def _pooled(clips: ClipsRead) -> tuple[tuple[str, ...], dict[str, CovarianceAccumulator]]:
    """`--classes pooled`: each clip's class, the clips of small subjects renamed to their pool
    (`classes.by_name.pooled_classes`), and the poses summed by class, a pool's in the order its
    subjects came (deterministic sums). The first pass's sums are left as they were."""
    frames = Counter()
    for name, row in zip(clips.path_classes, clips.rows):
        frames[name] += row["frames"]
    widths: dict[str, int] = {}
    for name, width in zip(clips.path_classes, clips.pose_widths):
        widths.setdefault(name, width)
    rename = pooled_classes(frames, widths)
    subjects_of: dict[str, list[CovarianceAccumulator]] = {}
    for name, accumulator in clips.poses.items():
        subjects_of.setdefault(rename[name], []).append(accumulator)
    poses = {}
    for name, subjects in subjects_of.items():
        if len(subjects) == 1:
            poses[name] = subjects[0]
        else:  # summed afresh: merged into an empty sum, the first subject's comes out as it was
            poses[name] = CovarianceAccumulator(subjects[0].dim)
            for accumulator in subjects:
                poses[name].merge(accumulator)
    return tuple(rename[name] for name in clips.path_classes), poses


def _units(clips: ClipsRead, reader: ClipReader, segment: bool) -> list[Unit]:
    """Every clip as one unit, or with `segment` cut at its PPCA change points (`segment.segment_take`)."""
    units = []
    for i, source in enumerate(progress(clips.sources, desc="segment", unit="clip") if segment else clips.sources):
        n = clips.rows[i]["frames"]
        cuts = segment_take(reader.load(source).poses) if segment else [0, n]
        if len(cuts) == 2:
            units.append(Unit(i, source, 0, n))
        else:
            units.extend(Unit(i, source, a, b - a, coded_range(a, b - a, n)) for a, b in zip(cuts[:-1], cuts[1:]))
    return units


def _frames_of(clip: LoadedClip, a: int, b: int) -> LoadedClip:
    """Frames a..b-1 of a clip as a clip of their own (representations map each frame on its own)."""
    m, e = clip.motion, clip.encoded
    motion = Motion(m.bones, m.counts, m.values[a:b], m.frame_numbers[a:b], m.header, m.path, m.style)
    encoded = Encoded(e.poses[a:b], None if e.root is None else e.root[a:b], e.params)
    return replace(clip, motion=motion, encoded=encoded, positions=clip.positions[a:b])
