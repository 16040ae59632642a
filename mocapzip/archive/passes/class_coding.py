"""The class coding (lossy): each class's basis fitted and its clips coded within the target
(`ratecontrol.encode.encode_class`; a class whose clips fill a grid of natural modes under
--model tensor, `ratecontrol.tensor.encode_tensor_class`), and the segments of each cut take
joined and held to the target as a whole (`ratecontrol.segments.joined_take`).

Here, one class after the other, each spread over the `jobs` local workers; a class's clips are
forgotten by the reader once it is coded, a cut take's once its segments are joined. On a Dask
cluster, each class is one task (`_class_task`) and all are in flight at once, the largest
started first: a class's maps wait for their last clip, and a cluster of many workers would
idle through every class's barriers.
"""

from __future__ import annotations

from collections import defaultdict
from contextlib import closing
from dataclasses import dataclass

from mocapzip.archive.passes.classes import Classes, Unit
from mocapzip.archive.passes.first_pass import ClipsRead
from mocapzip.classes.modes import NaturalModes, natural_modes
from mocapzip.classes.plan import ClassPlan
from mocapzip.codec.basis import ClassBasis
from mocapzip.codec.foot_lock import Stances
from mocapzip.codec.patches import FramePatches
from mocapzip.codec.pca import CovarianceAccumulator
from mocapzip.inputs.clip import ClipReader, ClipsOnDemand, LoadedClip
from mocapzip.parallel import imap, kept_workers, on_a_cluster, worker_state
from mocapzip.progress import progress
from mocapzip.ratecontrol.encode import ClassCoding, encode_class
from mocapzip.ratecontrol.max_error import Achieved
from mocapzip.ratecontrol.segments import SegmentCoding, joined_take
from mocapzip.ratecontrol.target import CodingTarget
from mocapzip.ratecontrol.tensor import TensorClass, encode_tensor_class
from mocapzip.stages import get_stage


@dataclass(frozen=True)
class ClassRecord:
    """A class as meta records it."""

    name: str
    components: int  # its basis's
    clips: int  # clips with a unit in it
    frames: int  # frames coded in it
    model: str | None = None  # --model tensor: "tensor" or "pca", whichever it took; None without
    grid: NaturalModes | None = None  # a tensor class's natural modes and their levels


@dataclass(frozen=True)
class SegmentRecord:
    """A segment of a cut take as its take's row records it."""

    first: int
    frames: int
    class_index: int
    stream: str  # its stream's name, clip/NNNNN/SSS
    error: tuple[float, float]  # mean and max joint error on its coded frames, cm


@dataclass(frozen=True)
class ClipRecord:
    """A clip's coding as its row in meta records it."""

    achieved: Achieved
    twist_flips: dict
    patched_frames: int | None = None  # frames its `patch/NNNNN` stream patches
    planted_stances: int | None = None  # stances its `plant/NNNNN` stream holds
    tensor_at: tuple[int, ...] | None = None  # its place in its tensor class's grid
    segments: tuple[SegmentRecord, ...] = ()  # a cut take's, in frame order


@dataclass(frozen=True)
class CodedClasses:
    """What the class coding stores."""

    classes: tuple[ClassRecord, ...]  # in class order
    clips: tuple[ClipRecord, ...]  # in clip order; none in a lossless archive
    streams: dict[str, bytes]  # class/NNNN, tensor/NNNN, warp/NNNNN, patch/NNNNN, plant/NNNNN
    interim: dict[str, bytes]  # the clip streams (clip/NNNNN, clip/NNNNN/SSS), coded INTERIM_CODER until stored


@dataclass(frozen=True)
class _ClassWork:
    """What coding a class takes: its units, its weighted poses if the first pass summed them,
    and the grid of natural modes its clips fill under --model tensor."""

    units: tuple[Unit, ...]
    poses: CovarianceAccumulator | None
    grid: NaturalModes | None

    @property
    def frames(self) -> int:
        return sum(unit.coded_frames for unit in self.units)


@dataclass(frozen=True)
class _ClassCoding:
    """A class coded: its basis, each unit's coding, and its tensor model if it took one."""

    basis: ClassBasis
    codings: list[ClassCoding]
    tensor: TensorClass | None


def code_classes(clips: ClipsRead, classes: Classes, reader: ClipReader, plan: ClassPlan, target: CodingTarget,
                 jobs: int = 1) -> CodedClasses:
    """Every class coded within `target` (lossy; nothing for a lossless archive, whose clips the
    first pass coded), as `plan`'s model: a tensor where a class's clips fill a grid of its modes."""
    if plan.lossless:
        return CodedClasses((), (), {}, {})
    transform = get_stage("transform", target.transform)
    members_of = [classes.members(k) for k in range(len(classes.names))]
    work = [_ClassWork(tuple(classes.units[u] for u in members), classes.poses.get(name),
                       natural_modes([classes.units[u].source.relpath for u in members], plan.modes)
                       if plan.modes is not None else None)
            for name, members in zip(classes.names, members_of)]
    records, streams, interim, rows = [], {}, {}, {}
    segments: dict[int, list] = defaultdict(list)  # take -> (unit index, class, SegmentCoding) of its segments
    _CODING["reader"] = reader  # the kept workers fork from the first class's first map
    try:
        # counted in frames, not classes: one subject is one class, and a bar at 0/1 tells nothing
        with progress(total=sum(w.frames for w in work), desc="code", unit="frame") as bar, kept_workers(jobs), \
                closing(_class_codings(work, transform, target, jobs)) as coded:
            for k, (name, members, class_work, coding) in enumerate(zip(classes.names, members_of, work, coded)):
                streams[f"class/{k:04d}"] = coding.basis.encode()
                records.append(_class_record(name, class_work, coding, plan.modes is not None))
                if coding.tensor is not None:
                    streams[f"tensor/{k:04d}"] = coding.tensor.model_stream
                for j, (u, unit_coding) in enumerate(zip(members, coding.codings)):
                    unit = classes.units[u]
                    if unit.coded is not None:  # a segment: held until its take's segments are all coded
                        segments[unit.clip].append((u, k, SegmentCoding(
                            unit.first, unit.frames, unit.coded_frames, coding.basis, unit_coding.payload,
                            (unit_coding.achieved.mean, unit_coding.achieved.max))))
                        continue
                    tensor_at = None
                    if coding.tensor is not None:
                        tensor_at = coding.tensor.at[j]
                        streams[f"warp/{unit.clip:05d}"] = coding.tensor.moves[j]
                    interim[f"clip/{unit.clip:05d}"] = unit_coding.payload
                    rows[unit.clip] = clip_record(unit.clip, unit_coding.achieved, unit_coding.patches,
                                                   unit_coding.stances, unit_coding.twists, streams, tensor_at)
                    reader.forget([unit.source])
                bar.update(class_work.frames)
    finally:
        _CODING.clear()
    for clip, parts in sorted(segments.items()):
        parts.sort(key=lambda part: part[0])  # by unit: in frame order
        units = [classes.units[u] for u, _, _ in parts]
        joined = joined_take(reader.load(clips.sources[clip]), [segment for _, _, segment in parts],
                             [unit.load(reader) for unit in units], transform, target)
        names = [f"clip/{clip:05d}/{s:03d}" for s in range(len(parts))]
        interim.update(zip(names, joined.streams))
        rows[clip] = clip_record(clip, joined.achieved, joined.patches, None, joined.twists, streams,
                                  segments=tuple(SegmentRecord(unit.first, unit.frames, k, name, error)
                                                 for unit, (_, k, _), name, error
                                                 in zip(units, parts, names, joined.errors)))
        reader.forget([clips.sources[clip]])
    return CodedClasses(tuple(records), tuple(rows[i] for i in range(len(clips.sources))), streams, interim)


def _class_record(name: str, work: _ClassWork, coding: _ClassCoding, tensor: bool) -> ClassRecord:
    clips = len({unit.clip for unit in work.units})
    if not tensor:
        return ClassRecord(name, coding.basis.q, clips, work.frames)
    if coding.tensor is None:
        return ClassRecord(name, coding.basis.q, clips, work.frames, "pca")
    return ClassRecord(name, coding.basis.q, clips, work.frames, "tensor", work.grid)


def clip_record(clip: int, achieved: Achieved, patches: FramePatches | None, stances: Stances | None,
                 twist_flips: dict, streams: dict[str, bytes], tensor_at: tuple[int, ...] | None = None,
                 segments: tuple[SegmentRecord, ...] = ()) -> ClipRecord:
    """A clip's record; its frame patches and its foot lock's stances, if any, go to `streams` as
    patch/NNNNN and plant/NNNNN."""
    if patches is not None:
        streams[f"patch/{clip:05d}"] = patches.payload()
    if stances is not None:
        streams[f"plant/{clip:05d}"] = stances.payload()
    return ClipRecord(achieved, twist_flips, None if patches is None else len(patches.frames),
                      None if stances is None else len(stances), tensor_at, segments)


def _class_codings(work: list[_ClassWork], transform, target: CodingTarget, jobs: int):
    """Each class coded (`_coding_of`), in order: here one after the other; on a Dask cluster all
    at once, as tasks (`_class_task`), the largest started first."""
    if not on_a_cluster():
        for class_work in work:
            yield _coding_of(class_work, transform, target, jobs)
        return
    _SHARED.update(work=work, transform=transform, target=target)
    try:
        yield from imap(_class_task, range(len(work)), jobs, priorities=[class_work.frames for class_work in work])
    finally:
        _SHARED.clear()


_SHARED = worker_state(__name__)  # what a Dask worker's class tasks read (`_class_task`)


def _class_task(k: int) -> _ClassCoding:
    """In a Dask worker: class k coded there, on one core (a worker process runs one task at a
    time: `cluster._task`); its clips, kept by the worker's reader while the class is coded,
    forgotten after."""
    work = _SHARED["work"][k]
    coding = _coding_of(work, _SHARED["transform"], _SHARED["target"], 1)
    _CODING["reader"].forget([unit.source for unit in work.units])
    return coding


def _coding_of(work: _ClassWork, transform, target: CodingTarget, jobs: int) -> _ClassCoding:
    """One class coded: `encode_class`, or `encode_tensor_class` for a class with a grid (coded
    in one process, its clips all loaded)."""
    clips = ClipsOnDemand(list(work.units), _load_unit)
    if work.grid is None:
        return _ClassCoding(*encode_class(clips, transform, target, jobs, work.poses), None)
    return _ClassCoding(*encode_tensor_class(list(clips), list(work.grid.at), transform, target))


# the reader of the clips being coded, which the kept workers inherit (`_load_unit`); a Dask worker
# gets it with each map instead
_CODING = worker_state(f"{__name__}.reader", shipped=True)


def _load_unit(unit: Unit) -> LoadedClip:
    """A class's clip, as `encode_class` indexes it here or in a kept worker: a module-level
    function, so that the class's clips pickle as their units alone (`parallel.kept_workers`)."""
    return unit.load(_CODING["reader"])
