"""`mcz compress`: clips on disk -> the streams of one .mcz archive (the newest format, `FORMAT_VERSION`).

Streams (see docs/format.md, "Streams written by the codec"):
  meta        zstd JSON (dictionary meta.json): settings, skeleton and class tables, one row per clip
  skeletons   the ASF files and BVH hierarchies, byte for byte: the text between numbers by zstd, the numbers
              predicted from an earlier skeleton or a family's means and range coded (archive/skeletons.py)
  class/NNNN  a class's quantised PCA mean and basis (lossy mode)
  priors      zstd bytes: where the clip streams' models start (coefficient coder "primed")
  clip/NNNNN  a clip's coefficient payload (lossy) or lossless channel code
  clip/NNNNN/SSS  segment SSS of a take cut by --segment (its row in meta lists the segments)
  extra_root/NNNNN  a lossy BVH clip's extra root's channels, lossless channel code (format 8 on)
  patch/NNNNN  a lossy clip's frame patches (--max-error, --contact-error; format 5 on)
  plant/NNNNN  the stances a lossy clip's foot lock holds (--plant-feet; format 9 on)
  tensor/NNNN  a class's tensor model (--model tensor; format 11 on)
  warp/NNNNN   a clip's warping path onto its class's tensor model (format 11 on)
"""

from __future__ import annotations

import json
import math
import os
import time
import warnings
from collections import Counter, defaultdict
from contextlib import closing
from dataclasses import asdict, dataclass, field, replace

from mocapzip import __version__
from mocapzip.archive.dictionaries import STREAM_DICTIONARIES, dictionary
from mocapzip.archive.meta import contents_of
from mocapzip.archive.meta import validate as validate_meta
from mocapzip.archive.settings import Settings, checked
from mocapzip.archive.skeletons import encode_skeletons
from mocapzip.classes.auto import auto_classes, parse_auto
from mocapzip.classes.by_name import class_namer, pooled_classes
from mocapzip.classes.segment import OVERLAP, coded_range, join_decoded, segment_take
from mocapzip.classes.modes import NaturalModes, natural_modes
from mocapzip.codec.clip_stream import CodedClip, reconstruct
from mocapzip.codec.entropy.coefficients import Priors
from mocapzip.codec.entropy.zstd import encode_bytes, pack_blobs
from mocapzip.codec.foot_lock import Stances
from mocapzip.codec.lossless import encode_channels
from mocapzip.codec.patches import FramePatches
from mocapzip.codec.pca import CovarianceAccumulator
from mocapzip.formats.amc import Motion
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.mcz import FORMAT_VERSION, ArchiveWriter
from mocapzip.inputs.clip import ClipReader, ClipsOnDemand, LoadedClip
from mocapzip.inputs.discover import ClipSource, find_clips, no_clips, record_skip
from mocapzip.defaults import DEFAULT_CACHE_MB, UNITS_CM
from mocapzip.limits import MAX_COEFFICIENTS_PER_MATRIX, MAX_DECODED_STREAM_BYTES
from mocapzip.parallel import imap, kept_workers, on_a_cluster, one_blas_thread, parallel_map, shipped_with_tasks
from mocapzip.progress import progress
from mocapzip.ratecontrol.encode import TargetError, code_clip, encode_class
from mocapzip.ratecontrol.max_error import Achieved, Bounds, achieved
from mocapzip.ratecontrol.tensor import encode_tensor_class
from mocapzip.representations.base import ROOT_TRACK_WIDTH, Encoded
from mocapzip.stages import get_stage

TIGHTENINGS = 8  # times a segmented take's segments are coded again, 10 % tighter, if the joined take misses
# clip streams are held coded "context" until all are coded: "primed" needs priors trained on every clip
INTERIM_CODER = "context"


@one_blas_thread
def compress(inputs, output, settings: Settings, asf=None, force: bool = False, jobs: int = 1,
             skip_bad: bool = False, cache_bytes: int | None = DEFAULT_CACHE_MB << 20, units: str | None = None) -> dict:
    """Compress every clip under `inputs` into `output`; return the summary (also stored in meta).
    `units`: of BVH files' lengths (a `UNITS_CM` name), where they cannot be inferred.

    With `skip_bad`, clips that cannot be read are left out and listed in the summary's
    `skipped` (and the archive's meta) instead of stopping the run.

    Clips stream through, so a database larger than memory compresses (docs/architecture.md):
    a first pass reads each clip to check it, note its row and code it (lossless) or add its
    poses to its class's covariance; then each class is coded, its clips read again unless
    they were kept in memory, which they are while they fit in `cache_bytes` (None: no limit).
    `--classes auto` and `--segment` analyse the poses of all clips together: they keep every
    clip in memory.
    """
    settings = checked(settings)
    if units is not None and units not in UNITS_CM:
        raise ValueError(f"units must be one of {', '.join(UNITS_CM)}, got {units!r}")
    if not force and os.path.lexists(output):
        raise FileExistsError(None, "already exists", os.fspath(output))
    started = time.perf_counter()
    skipped = [] if skip_bad else None  # {"path", "error"} per clip left out
    sources = find_clips(inputs, asf=asf, skipped=skipped)
    if not sources and not skipped:
        raise no_clips(inputs)
    _refuse_input_as_output(output, [p for s in sources for p in (s.motion, s.skeleton)]
                            + [p for p in (asf, settings.classes) if p is not None and os.path.isfile(p)])
    keeps_all = not settings.lossless and (settings.segment or parse_auto(settings.classes) is not False)
    reader = ClipReader(None if settings.lossless else settings.representation, settings.axis_weight_cm,
                        None if keeps_all else cache_bytes, settings.axes_from_positions, settings.fps,
                        settings.fps_from_files, units)
    with ArchiveWriter(output, tool_version=__version__, overwrite=force) as writer:
        scan = _first_pass(sources, reader, settings, writer, skipped, accumulate=not keeps_all, jobs=jobs)
        if not scan.sources:
            raise MocapFormatError(f"nothing to compress: all {len(skipped)} inputs were skipped",
                                   ", ".join(map(os.fspath, inputs)))
        sources, rows = scan.sources, scan.rows
        skeletons = _skeletons_of(sources, reader)  # only the skeletons of the clips kept
        skeleton_paths = list(skeletons)
        number = {id(skeleton): k for k, (_, skeleton) in enumerate(skeletons.values())}
        for source, row in zip(sources, rows):
            row["skeleton"] = number[id(reader.skeleton(source))]
        coding_units = _units(scan, reader, settings.segment and not settings.lossless)
        auto_report: dict = {}
        unit_class = _unit_classes(scan, coding_units, reader, settings, jobs, auto_report)
        class_names = sorted(set(unit_class))
        for unit, name in zip(coding_units, unit_class):
            if unit.first == 0:  # a take's class is its first segment's
                rows[unit.clip]["class"] = class_names.index(name)
        classes_meta = []
        if not settings.lossless:
            classes_meta, interim = _code_classes(scan, coding_units, unit_class, class_names, reader, settings, writer,
                                                  jobs)
            coder, clip_streams = _serialise_clips(interim, settings.coefficient_coder, jobs)
            for name, stream in clip_streams.items():
                writer.add(name, stream)
            settings = replace(settings, coefficient_coder=coder)

        stored_settings = asdict(settings)
        for flag in ("segment", "repair_glitches", "plant_feet"):
            if not stored_settings[flag]:
                del stored_settings[flag]  # absent means off
        if stored_settings["model"] == "pca":
            del stored_settings["model"], stored_settings["modes"]  # absent means pca (format 11 on: tensor)
        if stored_settings["fps_from_files"]:
            del stored_settings["fps_from_files"]  # absent means on (format 7 on: rows say where it applied)
        for bound in ("max_error_cm", "contact_error_cm"):
            if stored_settings[bound] is None:
                del stored_settings[bound]  # absent means no such bound
        meta = {
            "tool": f"mocapzip {__version__}",
            "settings": stored_settings,
            "skeletons": [fmt.entry(p.name, skeleton) for p, (fmt, skeleton) in skeletons.items()],
            "classes": classes_meta,
            "clips": rows,
        }
        if auto_report:
            meta["auto_classes"] = auto_report["groups"]
        if skipped:
            meta["skipped"] = skipped
        order = ["meta", "skeletons", *sorted(writer.names)]
        # Checked as every reader checks them: compress never writes an archive a reader refuses.
        validate_meta(meta, order, os.fspath(output), FORMAT_VERSION)
        texts = [skeleton.text for _, skeleton in skeletons.values()]
        unpacked = {"meta": json.dumps(meta, sort_keys=True).encode(), "skeletons": pack_blobs(texts)}
        for name, data in unpacked.items():
            if len(data) > MAX_DECODED_STREAM_BYTES:
                raise MocapFormatError(f"the archive's {name} would take {len(data):,} bytes, more than the "
                                       f"{MAX_DECODED_STREAM_BYTES:,} a reader accepts: compress fewer clips at once",
                                       output)
        writer.add("meta", encode_bytes(unpacked["meta"], dictionary(STREAM_DICTIONARIES["meta"])))
        writer.add("skeletons", encode_skeletons(texts, [fmt.asf_skeletons for fmt, _ in skeletons.values()]))
        size = writer.commit(order, contents_of(meta))
    frames = sum(r["frames"] for r in rows)
    largest_mean = max(r["error_cm"] for r in rows)
    return {
        "output": os.fspath(output),
        "clips": len(rows),
        "frames": frames,
        "input_bytes": sum(os.path.getsize(s.motion) for s in sources)  # and the skeletons in files of their own
        + sum(os.path.getsize(p) for p in set(skeleton_paths) - {s.motion for s in sources}),
        "output_bytes": size,
        "bytes_per_frame": size / frames,
        "worst_error_cm": largest_mean,  # kept for old readers: largest_mean_error_cm
        "largest_mean_error_cm": largest_mean,  # what -e bounds
        "largest_max_error_cm": max(r["max_error_cm"] for r in rows),
        "seconds": time.perf_counter() - started,
        "skipped": skipped or [],
        "repaired": [{"path": r["path"], "first": first, "last": last, "error_cm": cm}
                     for r in rows for first, last, cm in r.get("repaired", [])],
    }


def _skeletons_of(sources: list[ClipSource], reader: ClipReader) -> dict:
    """The archive's skeletons, in order: path -> (input format, `SourceSkeleton`). Every ASF is
    one; BVH files of one hierarchy share one, under the first of their paths."""
    first: dict = {}
    for path, source in sorted({s.skeleton: s for s in sources}.items()):
        skeleton = reader.skeleton(source)
        first.setdefault(id(skeleton), (path, (source.format, skeleton)))
    return dict(first.values())


def _refuse_input_as_output(output, inputs: list) -> None:
    """`-o` naming one of the inputs (or a link to it) would replace it with the archive, even with -f."""
    if not os.path.exists(output):
        return
    target = os.stat(output)
    for path in inputs:
        try:
            same = path is not None and os.path.samestat(target, os.stat(path))
        except OSError:  # a dangling link: nothing there to destroy (the clip is refused or skipped on its own)
            continue
        if same:
            raise MocapFormatError(f"is also an input ({path}); refusing to replace it, even with -f", output)


@dataclass
class _FirstPass:
    """What one read of every clip learns before any class is coded."""

    sources: list[ClipSource] = field(default_factory=list)  # the clips kept, in archive order
    rows: list[dict] = field(default_factory=list)  # their rows in meta; class and errors come later
    classes: list[str] = field(default_factory=list)  # each clip's class, if paths decide it (not -c auto)
    poses: dict[str, CovarianceAccumulator] = field(default_factory=dict)  # weighted poses by class (lossy)
    widths: dict[str, int] = field(default_factory=dict)  # pose width by class (lossy)
    glitches: Counter = field(default_factory=Counter)  # glitches in the source by kind (lossy), and "clips"

    def pool(self) -> None:
        """`--classes pooled`: the clips of small subjects renamed to their pool
        (`classes.by_name.pooled_classes`), and their poses summed."""
        frames = Counter()
        for name, row in zip(self.classes, self.rows):
            frames[name] += row["frames"]
        rename = pooled_classes(frames, self.widths)
        self.classes = [rename[name] for name in self.classes]
        poses: dict[str, CovarianceAccumulator] = {}
        for name, accumulator in self.poses.items():  # in the order the subjects came: deterministic sums
            if rename[name] in poses:
                poses[rename[name]].merge(accumulator)
            else:
                poses[rename[name]] = accumulator
        self.poses = poses


def _first_pass(sources: list[ClipSource], reader: ClipReader, settings: Settings, writer: ArchiveWriter,
                skipped: list | None, accumulate: bool, jobs: int = 1) -> _FirstPass:
    """Read every clip once: check it, note its row and class, and code it (lossless) or, with
    `accumulate`, add its poses to its class's covariance; then offer it to `reader` to keep.

    `jobs` worker processes read the clips (and code them, lossless), a few ahead of the one
    taken in (CLIPS_AHEAD per job); everything else happens here, clip by clip in order, so
    the archive, the skips and the messages are those of one process.

    A clip that cannot be read raises MocapFormatError or OSError; with a `skipped` list it
    is left out and recorded there instead (`inputs.record_skip`).

    On a Dask cluster, unless the clips must all be kept here (`accumulate` off: -c auto,
    --segment), a worker also takes its clip (`_take`) and sends back only what is kept of it,
    not its arrays: the client, alone, would otherwise bound the whole run.
    """
    if parse_auto(settings.classes) is False:
        name_class = class_namer(settings.classes)
    else:  # lossless clips share no basis: there is nothing to group
        name_class = (lambda source: "all") if settings.lossless else None
    scan = _FirstPass()
    _SHARED.update(reader=reader, settings=settings, accumulate=accumulate)  # the workers fork from here
    taken_there = on_a_cluster() and (accumulate or settings.lossless)
    try:
        with closing(imap(_read_and_take if taken_there else _read_clip, sources, jobs, CLIPS_AHEAD * jobs)) as read:
            for source in progress(sources, desc="read", unit="clip"):
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
                        taken = _take(clip, stream, settings, accumulate)
                except (MocapFormatError, OSError) as exc:
                    if skipped is None:
                        raise
                    record_skip(skipped, source, exc)
                    continue
                scan.rows.append(taken.row)
                if taken.glitches:
                    scan.glitches.update(g.kind for g in taken.glitches)
                    scan.glitches["clips"] += 1
                if name_class is not None:
                    scan.classes.append(name_class(source))
                if settings.lossless:
                    writer.add(f"clip/{len(scan.sources):05d}", taken.stream)
                    scan.rows[-1].update(error_cm=0.0, p99_error_cm=0.0, max_error_cm=0.0)
                else:
                    if taken.stream is not None:  # a BVH clip's extra root, kept exactly
                        writer.add(f"extra_root/{len(scan.sources):05d}", taken.stream)
                    if name_class is not None:
                        scan.widths.setdefault(scan.classes[-1], taken.width)
                    if accumulate:
                        scan.poses.setdefault(scan.classes[-1], CovarianceAccumulator(taken.width)).merge(taken.poses)
                    if taken.clip is not None:
                        reader.keep(taken.clip)
                scan.sources.append(source)
    finally:
        _SHARED.clear()
    _report_glitches(scan.glitches, settings.repair_glitches)
    if settings.classes == "pooled" and not settings.lossless:
        scan.pool()
    return scan


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


CLIPS_AHEAD = 2  # clips read ahead of the one taken in, per worker: each may be tens of MB

_SHARED: dict = {}  # what the forked workers of the first pass read (`_read_clip`)


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


@dataclass
class _Taken:
    """What the first pass keeps of a clip: its row in meta, its glitches, its pose width, its
    weighted poses' count, mean and scatter (lossy, with `accumulate`: merged into its class's,
    exactly as adding the poses there would), its stream (lossless, or a BVH clip's extra root),
    and the clip itself unless a Dask worker took it."""

    row: dict
    glitches: list | None
    width: int
    poses: CovarianceAccumulator | None
    stream: bytes | None
    clip: LoadedClip | None


def _take(clip: LoadedClip, stream: bytes | None, settings: Settings, accumulate: bool) -> _Taken:
    """The first pass's take of a clip read (`_Taken`); MocapFormatError if a lossy archive cannot hold it."""
    if settings.lossless:
        return _Taken(_clip_row(clip, settings.fps), clip.glitches, 0, None, stream, clip)
    _check_codable(clip)
    poses = None
    if accumulate:
        poses = CovarianceAccumulator(clip.poses.shape[1])
        poses.add(clip.poses)
    return _Taken(_clip_row(clip, settings.fps), clip.glitches, clip.poses.shape[1], poses, stream, clip)


def _read_and_take(source: ClipSource) -> _Taken | MocapFormatError | OSError:
    """On a Dask worker: `_read_clip`, then `_take`, without the clip (the client needs its row and sums)."""
    outcome = _read_clip(source)
    if isinstance(outcome, Exception):
        return outcome
    clip, stream = outcome
    clip.model = _SHARED["reader"].skeleton(source).model
    try:
        return replace(_take(clip, stream, _SHARED["settings"], _SHARED["accumulate"]), clip=None)
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


@dataclass
class _Unit:
    """What the codec codes on its own: a whole clip, or (--segment) one segment of a take."""

    clip: int  # index of the take in the archive's clips
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


def _units(scan: _FirstPass, reader: ClipReader, segment: bool) -> list[_Unit]:
    """Every clip as one unit, or with `segment` cut at its PPCA change points (`segment.segment_take`)."""
    units = []
    for i, source in enumerate(progress(scan.sources, desc="segment", unit="clip") if segment else scan.sources):
        n = scan.rows[i]["frames"]
        cuts = segment_take(reader.load(source).poses) if segment else [0, n]
        if len(cuts) == 2:
            units.append(_Unit(i, source, 0, n))
        else:
            units.extend(_Unit(i, source, a, b - a, coded_range(a, b - a, n)) for a, b in zip(cuts[:-1], cuts[1:]))
    return units


def _frames_of(clip: LoadedClip, a: int, b: int) -> LoadedClip:
    """Frames a..b-1 of a clip as a clip of their own (representations map each frame on its own)."""
    m, e = clip.motion, clip.encoded
    motion = Motion(m.bones, m.counts, m.values[a:b], m.frame_numbers[a:b], m.header, m.path, m.style)
    encoded = Encoded(e.poses[a:b], None if e.root is None else e.root[a:b], e.params)
    return replace(clip, motion=motion, encoded=encoded, positions=clip.positions[a:b])


def _unit_classes(scan: _FirstPass, units: list[_Unit], reader: ClipReader, settings: Settings, jobs: int,
                  report: dict) -> list[str]:
    """The class name of each unit: by path or table, as the first pass named it (a take's segments
    share its class), or `auto[:K]` from the poses (`classes.auto.auto_classes`, its plan in `report`)."""
    if scan.classes:
        return [scan.classes[unit.clip] for unit in units]
    clips = [unit.load(reader) for unit in units]
    return auto_classes(clips, parse_auto(settings.classes), settings, jobs=jobs, report=report)


def _serialise_clips(interim: dict[str, bytes], coder: str, jobs: int = 1) -> tuple[str, dict[str, bytes]]:
    """The clip streams as stored, and the coder they use, from the streams as `encode_class`
    holds them (coded INTERIM_CODER). For "primed" the archive's priors are trained on every
    clip (in stream order), the clips coded again from them, and the priors stored as the
    "priors" stream. "auto" takes "primed" when that is smaller, counting the priors (about
    400 bytes: they pay from roughly 10,000 frames on), else "context".

    Training carries its models from clip to clip, so it runs here, in order (decoding its
    streams in workers measured slower: the matrices are larger than the streams and quick to
    decode); `jobs` worker processes code the clips again."""
    if coder == "context":
        return coder, interim
    names = sorted(interim)
    priors = Priors.train(_interim_matrices(interim[name]) for name in progress(names, desc="priors", unit="clip"))
    _SHARED["priors"] = priors  # the workers fork from here; each gets its clip's stream as its item
    try:
        primed = dict(zip(names, parallel_map(_primed_stream, [interim[name] for name in names], jobs)))
    finally:
        _SHARED.clear()
    primed["priors"] = encode_bytes(priors.encode())
    if coder == "primed" or sum(map(len, primed.values())) < sum(map(len, interim.values())):
        return "primed", primed
    return "context", interim


def _interim_matrices(stream: bytes) -> list:
    """A clip's coefficient matrices, decoded from its stream as `encode_class` coded it (one
    clip at a time: the coefficients of all clips may be large)."""
    return CodedClip.from_payload(stream, INTERIM_CODER).matrices


def _primed_stream(stream: bytes) -> bytes:
    """A clip's stream (as `encode_class` coded it) coded again, its models starting from the
    archive's priors ("primed")."""
    return CodedClip.from_payload(stream, INTERIM_CODER).payload("primed", _SHARED["priors"])


def _code_classes(scan: _FirstPass, units: list[_Unit], unit_class: list[str], class_names: list[str],
                  reader: ClipReader, settings: Settings, writer: ArchiveWriter,
                  jobs: int) -> tuple[list[dict], dict[str, bytes]]:
    """Code every class (lossy): add its basis and the clips' frame patches to `writer`, fill in the
    clips' rows; return the classes' rows in meta and the clip streams as held until
    `_serialise_clips` (small: coded).
    A class's clips are forgotten by `reader` once coded; a segmented take's are kept until its
    segments are joined (`_segmented_take`)."""
    transform = get_stage("transform", settings.transform)
    classes_meta, interim = [], {}
    segments = {}  # unit index -> (class index, basis, payload, error) of a take's segments
    members_of = [[u for u, c in enumerate(unit_class) if c == name] for name in class_names]
    frames = [sum(units[u].coded_frames for u in members) for members in members_of]
    # counted in frames, not classes: one subject is one class, and a bar at 0/1 tells nothing
    _CODING["reader"] = reader  # the kept workers fork from the first class's first map
    grids = [natural_modes([units[u].source.relpath for u in members], settings.modes)
             if settings.model == "tensor" else None for members in members_of]
    classes = [([units[u] for u in members], scan.poses.get(name), grid)
               for name, members, grid in zip(class_names, members_of, grids)]
    try:
        with progress(total=sum(frames), desc="code", unit="frame") as bar, kept_workers(jobs), \
                closing(_coded_classes(classes, transform, settings, jobs)) as coded:
            for k, (name, members, (basis, codings, tensor)) in enumerate(zip(class_names, members_of, coded)):
                writer.add(f"class/{k:04d}", basis.encode())
                classes_meta.append({"name": name, "components": basis.q,
                                     "clips": len({units[u].clip for u in members}), "frames": frames[k]})
                if settings.model == "tensor":  # which model each class took, and a tensor's grid
                    classes_meta[-1]["model"] = "pca" if tensor is None else "tensor"
                    if tensor is not None:
                        writer.add(f"tensor/{k:04d}", tensor.model_stream)
                        classes_meta[-1].update(modes=list(grids[k].modes), levels=[list(v) for v in grids[k].levels])
                for j, (u, coding) in enumerate(zip(members, codings)):
                    unit = units[u]
                    if tensor is not None:
                        scan.rows[unit.clip]["tensor_at"] = list(tensor.at[j])
                        writer.add(f"warp/{unit.clip:05d}", tensor.moves[j])
                    if unit.coded is None:
                        interim[f"clip/{unit.clip:05d}"] = coding.payload
                        _store_achieved(scan.rows[unit.clip], unit.clip, coding.achieved, coding.patches, writer,
                                        coding.stances)
                        if coding.twists:
                            scan.rows[unit.clip]["twist_flips"] = coding.twists
                        reader.forget([unit.source])
                    else:
                        segments[u] = (k, basis, coding.payload, (coding.achieved.mean, coding.achieved.max))
                bar.update(frames[k])
    finally:
        _CODING.clear()
    parts_of = defaultdict(list)  # clip index -> its segments' unit indices
    for u in segments:
        parts_of[units[u].clip].append(u)
    for i, parts in sorted(parts_of.items()):
        take = [units[u] for u in parts]
        for name, payload in _segmented_take(scan.rows[i], i, reader.load(scan.sources[i]), take,
                                             [unit.load(reader) for unit in take], [segments[u] for u in parts],
                                             transform, settings, writer).items():
            interim[name] = payload
        reader.forget([scan.sources[i]])
    return classes_meta, interim


def _coded_classes(classes: list[tuple[list[_Unit], CovarianceAccumulator | None, NaturalModes | None]], transform,
                   settings: Settings, jobs: int):
    """(basis, codings, TensorClass or None) of each class (its units, if summed its weighted poses,
    and the grid of natural modes its clips fill under --model tensor), in order (`encode_class`,
    or `encode_tensor_class` for a class with a grid: coded in one process, its clips all loaded).
    Here, one class after the other, each spread over the `jobs` local workers.
    On a Dask cluster, each class is one task and all are in flight at once, the largest started
    first: a class's maps wait for their last clip, and a cluster of many workers would idle
    through every class's barriers."""
    if not on_a_cluster():
        for members, accumulator, grid in classes:
            yield _class_coded(members, accumulator, grid, transform, settings, jobs)
        return
    _SHARED.update(classes=classes, transform=transform, settings=settings)
    try:
        sizes = [sum(unit.coded_frames for unit in members) for members, _, _ in classes]
        yield from imap(_coded_class, range(len(classes)), jobs, priorities=sizes)
    finally:
        _SHARED.clear()


def _coded_class(k: int):
    """In a Dask worker: class k coded there, on one core (a worker process runs one task at a
    time: `cluster._task`); its clips, kept by the worker's reader while the class is coded,
    forgotten after."""
    members, accumulator, grid = _SHARED["classes"][k]
    coded = _class_coded(members, accumulator, grid, _SHARED["transform"], _SHARED["settings"], 1)
    _CODING["reader"].forget([unit.source for unit in members])
    return coded


def _class_coded(members: list[_Unit], accumulator, grid: NaturalModes | None, transform, settings: Settings, jobs: int):
    clips = ClipsOnDemand(members, _load_unit)
    if grid is None:
        return (*encode_class(clips, transform, settings, jobs, accumulator), None)
    return encode_tensor_class(list(clips), list(grid.at), transform, settings)


_CODING: dict = {}  # the reader of the clips being coded, which the kept workers inherit (`_load_unit`)
shipped_with_tasks(__name__, "_CODING")  # a Dask worker gets it with each map instead


def _load_unit(unit: _Unit) -> LoadedClip:
    """A class's clip, as `encode_class` indexes it here or in a kept worker: a module-level
    function, so that the class's clips pickle as their units alone (`parallel.kept_workers`)."""
    return unit.load(_CODING["reader"])


def _rounded_up(cm: float) -> float:
    """`cm` rounded up to 6 decimals (float rounding may leave it a hair below `cm`: then one step up)."""
    stored = math.ceil(cm * 1e6) / 1e6
    return stored if stored >= cm else stored + 1e-6


def _store_achieved(row: dict, index: int, achieved: Achieved, patches: FramePatches | None,
                    writer: ArchiveWriter, stances: Stances | None = None) -> None:
    """A clip's achieved errors into its row, and its frame patches and foot lock's stances, if any,
    to `writer` as `patch/NNNNN` and `plant/NNNNN`."""
    # Mean and max are the bounds: stored rounded up to a millionth of a cm, never below what was
    # measured (0.998697 takes 9 fewer digits of meta than 0.9986969546376016). p99 only informs.
    row.update(error_cm=_rounded_up(achieved.mean), p99_error_cm=round(achieved.p99, 4),
               max_error_cm=_rounded_up(achieved.max))
    if achieved.repaired:
        row["repaired"] = [list(r) for r in achieved.repaired]
    if patches is not None:
        row["patched_frames"] = len(patches.frames)
        writer.add(f"patch/{index:05d}", patches.payload())
    if stances is not None:
        row["planted_stances"] = len(stances)
        writer.add(f"plant/{index:05d}", stances.payload())


def _segmented_take(row: dict, index: int, clip: LoadedClip, units: list[_Unit], unit_clips: list[LoadedClip],
                    coded: list, transform, settings: Settings, writer: ArchiveWriter) -> dict[str, bytes]:
    """Streams of a take cut into segments; fills its row's `segments`, `segment_overlap`, `class`
    (the first segment's) and its achieved error, measured on the take joined as `reader.Archive.decode` does.

    `coded`: each segment's (class index, basis, payload, error) from `encode_class`. Every
    segment met the target on its coded frames, and the crossfade only mixes frames both
    decode well, so the take nearly always meets it at once; if not, its segments are coded
    again against a tighter target until it does.
    """
    target, dz, coder = settings.error_cm, settings.dead_zone, INTERIM_CODER
    cores = [(unit.first, unit.frames) for unit in units]
    payloads, errors = [c[2] for c in coded], [c[3] for c in coded]
    for _ in range(TIGHTENINGS):
        decoded = [reconstruct(CodedClip.from_payload(payload, coder, [(unit.coded_frames, c[1].q),
                                                                       (unit.coded_frames, ROOT_TRACK_WIDTH)]),
                               c[1], transform, dz, unit.coded_frames)
                   for payload, c, unit in zip(payloads, coded, units)]
        joined = join_decoded(decoded, cores, clip.motion.n_frames, OVERLAP)
        check = clip.final_check(*joined)
        mean_err, twist_flips = check.error[0], check.twists
        if mean_err <= target:
            break
        target *= 0.9
        codings = [code_clip(unit_clip, c[1], transform, target, dz, settings.split)
                   for unit_clip, c in zip(unit_clips, coded)]
        payloads = [coding.coded.payload(coder) for coding in codings]
        errors = [coding.error for coding in codings]
    else:
        raise TargetError(f"segments joined to {mean_err:.4f} cm, above {settings.error_cm:g} cm; use a larger -e",
                          clip.source.motion)
    streams, segments = {}, []
    for s, (unit, c, payload, (seg_mean, seg_max)) in enumerate(zip(units, coded, payloads, errors)):
        name = f"clip/{index:05d}/{s:03d}"
        streams[name] = payload
        segments.append({"first": unit.first, "frames": unit.frames, "class": c[0], "stream": name,
                         "error_cm": seg_mean, "max_error_cm": seg_max})
    row.update(segments=segments, segment_overlap=OVERLAP)
    _store_achieved(row, index, *achieved(clip, check, Bounds.of(settings)), writer)
    if twist_flips:
        row["twist_flips"] = twist_flips
    row["class"] = segments[0]["class"]
    return streams


def _clip_row(clip: LoadedClip, fps: float) -> dict:
    """A clip's row in meta as far as the clip itself tells (its skeleton, class and errors come later);
    `fps` is the settings', which the row repeats only where the clip's own differs."""
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


