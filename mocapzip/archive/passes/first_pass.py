"""The first pass: every clip read once, before any class is coded. Each clip is checked, its row
in meta noted as far as the clip itself tells, its class named where its path decides it, and it
is either coded at once (lossless) or its weighted poses summed into its class's covariance; the
reader keeps it for the passes after while it fits. The skeletons of the clips kept end it.

`jobs` worker processes read the clips (and code them, lossless), a few ahead of the one taken
in (CLIPS_AHEAD per job); everything else happens in this process, clip by clip in order, so the
archive, the skips and the messages are those of one process. On a Dask cluster, unless the
clips must all be kept here (-c auto, --segment), a worker also takes its clip (`_read_and_take`)
and sends back only what is kept of it, not its arrays: the client, alone, would otherwise bound
the whole run.
"""

from __future__ import annotations

import os
import warnings
from collections import Counter
from contextlib import closing
from dataclasses import asdict, dataclass, replace
from pathlib import Path

from mocapzip.archive.passes.check import Job
from mocapzip.classes.auto import parse_auto
from mocapzip.classes.by_name import class_namer
from mocapzip.classes.plan import ClassPlan
from mocapzip.codec.lossless import encode_channels
from mocapzip.codec.pca import CovarianceAccumulator
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.mcz import ArchiveWriter
from mocapzip.inputs.clip import ClipReader, ClipReading, LoadedClip
from mocapzip.inputs.discover import ClipSource, record_skip
from mocapzip.inputs.registry import InputFormat, SourceSkeleton
from mocapzip.limits import MAX_COEFFICIENTS_PER_MATRIX
from mocapzip.parallel import imap, on_a_cluster, worker_state
from mocapzip.progress import progress
from mocapzip.ratecontrol.max_error import TargetError

CLIPS_AHEAD = 2  # clips read ahead of the one taken in, per worker: each may be tens of MB


@dataclass(frozen=True)
class StoredSkeleton:
    """A skeleton as the archive keeps it: the file it came from, its input format and what that read."""

    path: Path  # the ASF, or the first BVH file of this hierarchy
    format: InputFormat
    skeleton: SourceSkeleton  # its text (what the skeletons stream keeps) and its entry's fields in meta


@dataclass(frozen=True)
class ClipsRead:
    """What one read of every clip learns before any class is coded."""

    sources: tuple[ClipSource, ...]  # the clips kept, in archive order
    rows: tuple[dict, ...]  # their rows in meta as far as each clip tells (lossless: with its errors, 0)
    path_classes: tuple[str, ...]  # each clip's class where paths decide it (not -c auto): a subject, a table's name
    poses: dict[str, CovarianceAccumulator]  # weighted poses summed by class (lossy, unless every clip is kept)
    pose_widths: tuple[int, ...]  # each clip's pose width (lossy)
    extra_roots: tuple[bytes | None, ...]  # each lossy BVH clip's extra root, kept exactly (its `extra_root/NNNNN`)
    skeletons: tuple[StoredSkeleton, ...]  # those of the clips kept, by path
    skeleton_of: tuple[int, ...]  # each clip's skeleton, by its place in `skeletons`
    skipped: tuple[dict, ...]  # with skip_bad, what was left out, the job's first: {"path", "error"} each


def first_pass(job: Job, reader: ClipReader, reading: ClipReading, plan: ClassPlan, archive: ArchiveWriter,
               jobs: int = 1) -> ClipsRead:
    """Read every clip of `job` once (see the module doc), through `reader` (made from `reading`);
    `plan` names the classes where paths decide them. A lossless clip's stream goes to `archive` at
    once (a lossy clip's is far smaller, and comes later: it is held until every class is coded).

    A clip that cannot be read raises MocapFormatError or OSError; with `job.skip_bad` it is left
    out and recorded in `skipped` instead (`inputs.record_skip`)."""
    accumulate = not plan.keeps_every_clip
    if parse_auto(plan.classes) is False:
        name_class = class_namer(plan.classes)
    else:  # lossless clips share no basis: there is nothing to group
        name_class = (lambda source: "all") if plan.lossless else None
    sources, rows, path_classes, pose_widths, extra_roots, poses, glitches = [], [], [], [], [], {}, Counter()
    skipped = list(job.skipped) if job.skip_bad else None
    _SHARED.update(reader=reader, reading=reading, accumulate=accumulate)  # the workers fork from here
    taken_there = on_a_cluster() and (accumulate or reading.lossless)
    try:
        with closing(imap(_read_and_take if taken_there else _read_clip, job.sources, jobs,
                          CLIPS_AHEAD * jobs)) as read:
            for source in progress(job.sources, desc="read", unit="clip"):
                try:  # the skeleton here, in order: its warnings and errors come as one process gives them
                    model, failure = reader.skeleton(source).model, None
                except (MocapFormatError, OSError) as exc:
                    model, failure = None, exc
                outcome = next(read)  # the clip or what stopped its reading (any other error stops the run)
                try:
                    failure = failure or (outcome if isinstance(outcome, Exception) else None)
                    if failure is not None:
                        raise failure
                    if isinstance(outcome, _Taken):  # taken by a Dask worker
                        taken = outcome
                    else:
                        clip, stream = outcome
                        clip.model = model
                        taken = _take(clip, stream, reading, accumulate)
                except (MocapFormatError, OSError) as exc:
                    if skipped is None:
                        raise
                    record_skip(skipped, source, exc)
                    continue
                if taken.glitches:
                    glitches.update(g.kind for g in taken.glitches)
                    glitches["clips"] += 1
                if name_class is not None:
                    path_classes.append(name_class(source))
                if reading.lossless:
                    archive.add(f"clip/{len(sources):05d}", taken.stream)
                    rows.append({**taken.row, "error_cm": 0.0, "p99_error_cm": 0.0, "max_error_cm": 0.0})
                else:
                    rows.append(taken.row)
                    if accumulate:
                        poses.setdefault(path_classes[-1], CovarianceAccumulator(taken.width)).merge(taken.poses)
                    if taken.clip is not None:
                        reader.keep(taken.clip)
                sources.append(source)
                pose_widths.append(taken.width)
                extra_roots.append(None if reading.lossless else taken.stream)
    finally:
        _SHARED.clear()
    _report_glitches(glitches, reading.repair_glitches)
    if not sources:
        raise _nothing_left(job, skipped)
    skeletons, skeleton_of = _skeletons_of(sources, reader)
    return ClipsRead(tuple(sources), tuple(rows), tuple(path_classes), poses, tuple(pose_widths), tuple(extra_roots),
                     skeletons, skeleton_of, tuple(skipped or ()))


def leave_out(clips: ClipsRead, refused: TargetError, job: Job, reader: ClipReader) -> ClipsRead:
    """`clips` as the first pass reads them without the clip that `refused` names (no coding of
    it meets its target or bound: `ratecontrol.max_error.TargetError`), which is listed in
    `skipped` instead. Raises `refused` if that clip is none of them, or without `job.skip_bad`.

    Its class's weighted poses are summed again from its other clips, read again (quietly) unless
    kept, in the order the first pass summed them, so what comes next is what a run without that
    clip in its inputs makes: no class basis, prior, skeleton or stream is left of it."""
    paths = [os.fspath(source.motion) for source in clips.sources]
    if not job.skip_bad or refused.path not in paths:
        raise refused
    gone = paths.index(refused.path)
    skipped = list(clips.skipped)
    record_skip(skipped, clips.sources[gone], refused)

    def kept(items: tuple) -> tuple:
        return items[:gone] + items[gone + 1:]

    sources = kept(clips.sources)
    if not sources:
        raise _nothing_left(job, skipped)
    poses = clips.poses
    if poses:  # summed by the first pass: its class's again, without it, the classes in the order their clips come
        name, path_classes = clips.path_classes[gone], kept(clips.path_classes)
        poses = {other: poses[other] for other in dict.fromkeys(path_classes)}
        if name in poses:
            poses[name] = CovarianceAccumulator(clips.pose_widths[gone])
            for source in (source for source, other in zip(sources, path_classes) if other == name):
                poses[name].merge(_pose_sums(reader.load(source)))
    skeletons, skeleton_of = _skeletons_of(sources, reader)
    return replace(clips, sources=sources, rows=kept(clips.rows), path_classes=kept(clips.path_classes), poses=poses,
                   pose_widths=kept(clips.pose_widths), extra_roots=kept(clips.extra_roots), skeletons=skeletons,
                   skeleton_of=skeleton_of, skipped=tuple(skipped))


def _nothing_left(job: Job, skipped: list) -> MocapFormatError:
    return MocapFormatError(f"nothing to compress: all {len(skipped)} inputs were skipped",
                            ", ".join(map(os.fspath, job.inputs)))


def _report_glitches(found: Counter, repair: bool) -> None:
    """One warning for the glitches found in the source: by default kept as written (the bounds
    hold against the source as written); with `repair` (--repair-glitches) the spikes are not."""
    total = sum(n for kind, n in found.items() if kind != "clips")
    if total:
        kinds = ", ".join(f"{kind} {found[kind]}" for kind in ("jump", "limits", "frozen", "zeroed") if found[kind])
        fate = ("jumps and limits smoothed over (--repair-glitches; `mcz info` lists the frames), the rest kept as "
                "written" if repair else "kept as written, the errors are measured against them")
        warnings.warn(f"{total} glitch{'' if total == 1 else 'es'} in the source, in {found['clips']} "
                      f"clip{'' if found['clips'] == 1 else 's'} ({kinds}); {fate}; `mcz inspect --check` lists them",
                      stacklevel=2)


def _skeletons_of(sources: list[ClipSource], reader: ClipReader) -> tuple[tuple[StoredSkeleton, ...], tuple[int, ...]]:
    """The archive's skeletons, by path, and each clip's place among them: every ASF is one; BVH
    files of one hierarchy share one, under the first of their paths."""
    first: dict = {}
    for path, source in sorted({s.skeleton: s for s in sources}.items()):
        skeleton = reader.skeleton(source)
        first.setdefault(id(skeleton), StoredSkeleton(path, source.format, skeleton))
    number = {key: k for k, key in enumerate(first)}
    return tuple(first.values()), tuple(number[id(reader.skeleton(source))] for source in sources)


_SHARED = worker_state(__name__)  # what the forked workers of the first pass read (`_read_clip`)


def _read_clip(source: ClipSource) -> tuple[LoadedClip, bytes | None] | MocapFormatError | OSError:
    """The first pass's work on one clip, in a worker (or here, with one job): the clip read,
    without its skeleton model (the caller has it: sent back, it would be a copy per clip), with
    its glitches (lossy: `inputs.glitches`), and its lossless stream (None if lossy); or the
    error that stopped its reading, to be raised (or the clip skipped) at its turn. The
    skeleton's warnings are the caller's to give."""
    reader = _SHARED["reader"]
    try:
        with warnings.catch_warnings():  # read once, quietly: the caller gives the skeleton's warnings
            warnings.simplefilter("ignore")
            reader.skeleton(source)
        clip = reader.read(source)
    except (MocapFormatError, OSError) as exc:
        return exc
    clip.model = None
    if clip.encoded is None:
        return clip, encode_channels(clip.motion.values)
    return clip, None if clip.extra_root is None else encode_channels(clip.extra_root)


@dataclass(frozen=True)
class _Taken:
    """What the first pass keeps of a clip: its row in meta, its glitches, its pose width, its
    weighted poses' count, mean and scatter (lossy, when summed: merged into its class's,
    exactly as adding the poses there would), its stream (lossless, or a BVH clip's extra root),
    and the clip itself unless a Dask worker took it."""

    row: dict
    glitches: list | None
    width: int
    poses: CovarianceAccumulator | None
    stream: bytes | None
    clip: LoadedClip | None


def _take(clip: LoadedClip, stream: bytes | None, reading: ClipReading, accumulate: bool) -> _Taken:
    """The first pass's take of a clip read (`_Taken`); MocapFormatError if a lossy archive cannot hold it."""
    if reading.lossless:
        return _Taken(_clip_row(clip, reading.fps), clip.glitches, 0, None, stream, clip)
    _check_codable(clip)
    poses = _pose_sums(clip) if accumulate else None
    return _Taken(_clip_row(clip, reading.fps), clip.glitches, clip.poses.shape[1], poses, stream, clip)


def _pose_sums(clip: LoadedClip) -> CovarianceAccumulator:
    """The clip's weighted poses summed on their own, to be merged into its class's in clip order."""
    sums = CovarianceAccumulator(clip.poses.shape[1])
    sums.add(clip.poses)
    return sums


def _read_and_take(source: ClipSource) -> _Taken | MocapFormatError | OSError:
    """On a Dask worker: `_read_clip`, then `_take`, without the clip (the client needs its row and sums)."""
    outcome = _read_clip(source)
    if isinstance(outcome, Exception):
        return outcome
    clip, stream = outcome
    clip.model = _SHARED["reader"].skeleton(source).model
    try:
        return replace(_take(clip, stream, _SHARED["reading"], _SHARED["accumulate"]), clip=None)
    except MocapFormatError as exc:
        return exc


def _check_codable(clip: LoadedClip) -> None:
    """Refuse a clip whose coefficients (frames x pose values) or class basis (pose values x at
    most as many components) would pass the limits every reader holds to: never write what
    cannot be read back."""
    frames, width = clip.poses.shape
    if max(frames, width) * width > MAX_COEFFICIENTS_PER_MATRIX:
        raise MocapFormatError(f"{frames:,} frames of {width:,} pose values are more than a lossy archive may hold "
                               f"({MAX_COEFFICIENTS_PER_MATRIX:,} per matrix); use --lossless", clip.source.motion)


def _clip_row(clip: LoadedClip, fps: float) -> dict:
    """A clip's row in meta as far as the clip itself tells (its skeleton, class and errors come later);
    `fps` is the settings' (`ClipReading.fps`), which the row repeats only where the clip's own differs."""
    m = clip.motion
    row = {
        "path": clip.source.relpath,
        "frames": m.n_frames,
        "first_frame": int(m.frame_numbers[0]) if m.n_frames else 1,
        "header": m.header,
        "bones": m.bones,
        "counts": m.counts,
        "angle_unit": clip.angle_unit,
        "style": asdict(m.style),  # how the source wrote numbers and lines, to write it back alike
    }
    if m.dropped_frames:  # an incomplete last frame left out: the archive says so, not only a warning
        row["dropped_frames"] = m.dropped_frames
    if clip.fps != fps:  # a rate its files state (format 7 on)
        row["fps"] = clip.fps
    row.update(clip.row_extras)  # its format's fields (format 8 on: a BVH clip's text, `bvh`)
    return row
