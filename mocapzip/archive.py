"""`mcz compress` / `decompress` / `info`: clips on disk <-> the streams of one .mcz archive.

Streams (see docs/format.md, "Streams written by the codec"):
  meta        zstd JSON: settings, skeleton and class tables, one row per clip
  skeletons   zstd JSON list of the ASF texts, byte for byte (they compress well together)
  class/NNNN  a class's quantised PCA mean and basis (lossy mode)
  priors      zstd bytes: where the clip streams' models start (coefficient coder "primed")
  clip/NNNNN  a clip's coefficient payload (lossy) or lossless channel code
  clip/NNNNN/SSS  segment SSS of a take cut by --segment (its row in meta lists the segments)
"""

from __future__ import annotations

import fnmatch
import json
import math
import os
import secrets
import time
from collections import defaultdict
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path, PurePosixPath

import numpy as np

from . import __version__
from .autoclass import auto_classes, parse_auto
from .classes import class_namer
from .clip import ClipReader, ClipsOnDemand, LoadedClip, channels_from, pose_weights, skeleton_params
from .codec import get_stage
from .codec.coefficients import Priors, check_matrix_shape
from .codec.entropy import decode_bytes, encode_bytes
from .codec.lossless import decode_channels, encode_channels
from .codec.pca import CovarianceAccumulator
from .formats.amc import AmcStyle, Motion, format_amc
from .formats.asf import parse_asf
from .formats.errors import MocapFormatError
from .formats.text import MAX_ABS_VALUE, read_regular_file
from .formats.mcz import FORMAT_VERSION, ArchiveError, ArchiveReader, ArchiveWriter
from .inputs import ClipSource, find_clips, record_skip
from .meta import parse_json
from .meta import validate as validate_meta
from .limits import MAX_COEFFICIENTS_PER_MATRIX, MAX_DECODED_STREAM_BYTES
from .lossy import ClassBasis, CodedClip, TargetError, code_clip, encode_class, interim_coder, reconstruct
from .skeleton import ChannelLayout, SkeletonModel
from .progress import progress
from .representations import get_representation
from .representations.base import Encoded
from .representations.positions import flips_from_ranges
from .segment import OVERLAP, coded_range, join_segments, segment_take

DEFAULT_ERROR_CM = 1.0
TIGHTENINGS = 8  # times a segmented take's segments are coded again, 10 % tighter, if the joined take misses
WRITTEN_CODERS = ("auto", "primed", "context")  # clip stream coders compress writes; "zstd" is read only
DEFAULT_CACHE_MB = 512  # clips kept in memory between compress's passes (clip.ClipReader)


@dataclass
class Settings:
    """Everything that decides the archive's content; stored in it as JSON."""

    error_cm: float = DEFAULT_ERROR_CM
    representation: str = "aligned"
    transform: dict = field(default_factory=lambda: {"id": "dct"})
    classes: str = "subject"
    split: list[float] | None = None  # forced R, P, T shares of error_cm
    dead_zone: float = 0.2
    basis_precision: float = 0.02  # basis rounding error per direction, as a share of error_cm
    axis_weight_cm: float = 12.0  # weight of bone axis vectors against positions (clip.pose_weights; solved_bones.py)
    fps: float = 120.0
    lossless: bool = False
    segment: bool = False  # cut long takes at PPCA change points, each segment coded on its own
    # clip streams: "primed" (codec/coefficients.py, models start from the archive's priors; format 3),
    # "context" (models start at 1/2; format 2), "zstd" (format 1); "auto" (compress only): "primed"
    # when the priors pay for themselves, else "context". Archives store the coder used.
    coefficient_coder: str = "auto"
    # bones whose rotation follows from joint positions store no axis (representations.positions.solved_bones);
    # absent, in formats 1 to 3: false
    axes_from_positions: bool = True


def compress(inputs, output, settings: Settings, asf=None, force: bool = False, jobs: int = 1,
             skip_bad: bool = False, cache_bytes: int | None = DEFAULT_CACHE_MB << 20) -> dict:
    """Compress every clip under `inputs` into `output`; return the summary (also stored in meta).

    With `skip_bad`, clips that cannot be read are left out and listed in the summary's
    `skipped` (and the archive's meta) instead of stopping the run.

    Clips stream through, so a database larger than memory compresses (docs/architecture.md):
    a first pass reads each clip to check it, note its row and code it (lossless) or add its
    poses to its class's covariance; then each class is coded, its clips read again unless
    they were kept in memory, which they are while they fit in `cache_bytes` (None: no limit).
    `--classes auto` and `--segment` analyse the poses of all clips together: they keep every
    clip in memory.
    """
    settings = _checked_settings(settings)
    if not force and os.path.lexists(output):
        raise FileExistsError(None, "already exists", os.fspath(output))
    started = time.perf_counter()
    skipped = [] if skip_bad else None  # {"path", "error"} per clip left out
    sources = find_clips(inputs, asf=asf, skipped=skipped)
    if not sources and not skipped:
        raise MocapFormatError("no AMC clips found", ", ".join(map(os.fspath, inputs)))
    _refuse_input_as_output(output, [p for s in sources for p in (s.amc, s.asf)]
                            + [p for p in (asf, settings.classes) if p is not None and os.path.isfile(p)])
    keeps_all = not settings.lossless and (settings.segment or parse_auto(settings.classes) is not False)
    reader = ClipReader(None if settings.lossless else settings.representation, settings.axis_weight_cm,
                        None if keeps_all else cache_bytes, settings.axes_from_positions)
    with ArchiveWriter(output, tool_version=__version__, overwrite=force) as writer:
        scan = _first_pass(sources, reader, settings, writer, skipped, accumulate=not keeps_all)
        if not scan.sources:
            raise MocapFormatError(f"nothing to compress: all {len(skipped)} inputs were skipped",
                                   ", ".join(map(os.fspath, inputs)))
        sources, rows = scan.sources, scan.rows
        skeleton_paths = sorted({s.asf for s in sources})  # only the skeletons of the clips kept
        for source, row in zip(sources, rows):
            row["skeleton"] = skeleton_paths.index(source.asf)
        units = _units(scan, reader, settings.segment and not settings.lossless)
        auto_report: dict = {}
        unit_class = _unit_classes(scan, units, reader, settings, jobs, auto_report)
        class_names = sorted(set(unit_class))
        for unit, name in zip(units, unit_class):
            if unit.first == 0:  # a take's class is its first segment's
                rows[unit.clip]["class"] = class_names.index(name)
        classes_meta = []
        if not settings.lossless:
            classes_meta, interim = _code_classes(scan, units, unit_class, class_names, reader, settings, writer, jobs)
            coder, clip_streams = _serialise_clips(interim, settings.coefficient_coder)
            for name, stream in clip_streams.items():
                writer.add(name, stream)
            settings = replace(settings, coefficient_coder=coder)

        stored_settings = asdict(settings)
        if not settings.segment:
            del stored_settings["segment"]  # absent means off: archives without segments are written as before
        meta = {
            "tool": f"mocapzip {__version__}",
            "settings": stored_settings,
            "skeletons": [{"name": p.name} for p in skeleton_paths],
            "classes": classes_meta,
            "clips": rows,
        }
        if auto_report:
            meta["auto_classes"] = auto_report["groups"]
        if skipped:
            meta["skipped"] = skipped
        order = ["meta", "skeletons", *sorted(writer.names)]
        skeleton_texts = [read_regular_file(p).decode("latin-1") for p in skeleton_paths]
        # Checked as every reader checks them: compress never writes an archive a reader refuses.
        validate_meta(meta, order, os.fspath(output))
        for name, value in (("meta", meta), ("skeletons", skeleton_texts)):
            text = json.dumps(value, sort_keys=name == "meta").encode()
            if len(text) > MAX_DECODED_STREAM_BYTES:
                raise MocapFormatError(f"the archive's {name} would take {len(text):,} bytes, more than the "
                                       f"{MAX_DECODED_STREAM_BYTES:,} a reader accepts: compress fewer clips at once",
                                       output)
            writer.add(name, encode_bytes(text))
        size = writer.commit(order)
    frames = sum(r["frames"] for r in rows)
    largest_mean = max(r["error_cm"] for r in rows)
    return {
        "output": os.fspath(output),
        "clips": len(rows),
        "frames": frames,
        "input_bytes": sum(os.path.getsize(s.amc) for s in sources) + sum(os.path.getsize(p) for p in skeleton_paths),
        "output_bytes": size,
        "bytes_per_frame": size / frames,
        "worst_error_cm": largest_mean,  # kept for old readers: largest_mean_error_cm
        "largest_mean_error_cm": largest_mean,  # what -e bounds
        "largest_max_error_cm": max(r["max_error_cm"] for r in rows),
        "seconds": time.perf_counter() - started,
        "skipped": skipped or [],
    }


class SettingsError(ValueError):
    """Settings an archive of this format cannot hold; raised before any input is read."""


def _checked_settings(settings: Settings) -> Settings:
    """`settings` with the transform's config as its stage writes it (pywt takes 'DB4' for
    'db4'; readers check the name), or SettingsError for an unknown stage or representation,
    a number that is not finite, or clip streams in format 1's "zstd" layout (read, never written)."""
    if settings.coefficient_coder not in WRITTEN_CODERS:
        raise SettingsError(f"coefficient_coder {settings.coefficient_coder!r} is not written by format "
                            f"{FORMAT_VERSION}; choose one of {', '.join(WRITTEN_CODERS)}")
    numbers = [settings.error_cm, settings.dead_zone, settings.basis_precision, settings.axis_weight_cm,
               settings.fps, *(settings.split or [])]
    if not all(math.isfinite(x) for x in numbers):
        raise SettingsError("settings must be finite numbers (no inf or nan)")
    try:
        transform = get_stage(settings.transform).get_config()
        get_representation(settings.representation)
    except (ValueError, KeyError) as exc:
        raise SettingsError(str(exc).strip('"')) from None
    return replace(settings, transform=transform)


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


def _first_pass(sources: list[ClipSource], reader: ClipReader, settings: Settings, writer: ArchiveWriter,
                skipped: list | None, accumulate: bool) -> _FirstPass:
    """Read every clip once: check it, note its row and class, and code it (lossless) or, with
    `accumulate`, add its poses to its class's covariance; then offer it to `reader` to keep.

    A clip that cannot be read raises MocapFormatError or OSError; with a `skipped` list it
    is left out and recorded there instead (`inputs.record_skip`).
    """
    if parse_auto(settings.classes) is False:
        name_class = class_namer(settings.classes)
    else:  # lossless clips share no basis: there is nothing to group
        name_class = (lambda source: "all") if settings.lossless else None
    scan = _FirstPass()
    for source in progress(sources, desc="read", unit="clip"):
        try:
            clip = reader.read(source)
            if not settings.lossless:
                _check_codable(clip)
        except (MocapFormatError, OSError) as exc:
            if skipped is None:
                raise
            record_skip(skipped, source, exc)
            continue
        scan.rows.append(_clip_row(clip))
        if name_class is not None:
            scan.classes.append(name_class(source))
        if settings.lossless:
            writer.add(f"clip/{len(scan.sources):05d}", encode_channels(clip.motion.values))
            scan.rows[-1].update(error_cm=0.0, max_error_cm=0.0)
        else:
            if accumulate:
                dim = clip.poses.shape[1]
                scan.poses.setdefault(scan.classes[-1], CovarianceAccumulator(dim)).add(clip.poses)
            reader.keep(clip)
        scan.sources.append(source)
    return scan


def _check_codable(clip: LoadedClip) -> None:
    """Refuse a clip whose coefficients (frames x pose values) or class basis (pose values x at
    most as many components) would pass the limits every reader holds to: never write what
    cannot be read back."""
    frames, width = clip.poses.shape
    if max(frames, width) * width > MAX_COEFFICIENTS_PER_MATRIX:
        raise MocapFormatError(f"{frames:,} frames of {width:,} pose values are more than a lossy archive may hold "
                               f"({MAX_COEFFICIENTS_PER_MATRIX:,} per matrix); use --lossless", clip.source.amc)


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
    share its class), or `auto[:K]` from the poses (`autoclass.auto_classes`, its plan in `report`)."""
    if scan.classes:
        return [scan.classes[unit.clip] for unit in units]
    clips = [unit.load(reader) for unit in units]
    return auto_classes(clips, parse_auto(settings.classes), settings, jobs=jobs, report=report)


def _serialise_clips(interim: dict[str, bytes], coder: str) -> tuple[str, dict[str, bytes]]:
    """The clip streams as stored, and the coder they use, from the streams as `encode_class`
    holds them (`lossy.interim_coder`). For "primed" the archive's priors are trained on every
    clip (in stream order), the clips coded again from them, and the priors stored as the
    "priors" stream. "auto" takes "primed" when that is smaller, counting the priors (about
    400 bytes: they pay from roughly 10,000 frames on), else "context"."""
    if coder in ("context", "zstd"):
        return coder, interim
    names = sorted(interim)

    def decoded(name: str) -> CodedClip:  # one at a time: the coefficients of all clips may be large
        return CodedClip.from_payload(interim[name], interim_coder(coder))

    priors = Priors.train(decoded(name).matrices for name in progress(names, desc="priors", unit="clip"))
    primed = {name: decoded(name).payload("primed", priors) for name in names}
    primed["priors"] = encode_bytes(priors.encode())
    if coder == "primed" or sum(map(len, primed.values())) < sum(map(len, interim.values())):
        return "primed", primed
    return "context", interim


def _code_classes(scan: _FirstPass, units: list[_Unit], unit_class: list[str], class_names: list[str],
                  reader: ClipReader, settings: Settings, writer: ArchiveWriter,
                  jobs: int) -> tuple[list[dict], dict[str, bytes]]:
    """Code every class (lossy): add its basis to `writer`, fill in the clips' rows; return the
    classes' rows in meta and the clip streams as held until `_serialise_clips` (small: coded).
    A class's clips are forgotten by `reader` once coded; a segmented take's are kept until its
    segments are joined (`_segmented_take`)."""
    transform = get_stage(settings.transform)
    classes_meta, interim = [], {}
    segments = {}  # unit index -> (class index, basis, payload, error) of a take's segments
    members_of = [[u for u, c in enumerate(unit_class) if c == name] for name in class_names]
    frames = [sum(units[u].coded_frames for u in members) for members in members_of]
    # counted in frames, not classes: one subject is one class, and a bar at 0/1 tells nothing
    with progress(total=sum(frames), desc="code", unit="frame") as bar:
        for k, (name, members) in enumerate(zip(class_names, members_of)):
            clips = ClipsOnDemand([units[u] for u in members], lambda unit: unit.load(reader))
            basis, payloads, errors, twists = encode_class(clips, transform, settings, jobs, scan.poses.get(name))
            writer.add(f"class/{k:04d}", basis.encode(settings.coefficient_coder))
            classes_meta.append({"name": name, "components": basis.q, "clips": len({units[u].clip for u in members}),
                                 "frames": frames[k]})
            for u, payload, (mean_err, max_err), twist_flips in zip(members, payloads, errors, twists):
                unit = units[u]
                if unit.coded is None:
                    interim[f"clip/{unit.clip:05d}"] = payload
                    scan.rows[unit.clip].update(error_cm=mean_err, max_error_cm=max_err)
                    if twist_flips:
                        scan.rows[unit.clip]["twist_flips"] = twist_flips
                    reader.forget([unit.source])
                else:
                    segments[u] = (k, basis, payload, (mean_err, max_err))
            bar.update(frames[k])
    parts_of = defaultdict(list)  # clip index -> its segments' unit indices
    for u in segments:
        parts_of[units[u].clip].append(u)
    for i, parts in sorted(parts_of.items()):
        take = [units[u] for u in parts]
        for name, payload in _segmented_take(scan.rows[i], i, reader.load(scan.sources[i]), take,
                                             [unit.load(reader) for unit in take], [segments[u] for u in parts],
                                             transform, settings).items():
            interim[name] = payload
        reader.forget([scan.sources[i]])
    return classes_meta, interim


def _segmented_take(row: dict, index: int, clip: LoadedClip, units: list[_Unit], unit_clips: list[LoadedClip],
                    coded: list, transform, settings: Settings) -> dict[str, bytes]:
    """Streams of a take cut into segments; fills its row's `segments`, `segment_overlap`, `class`
    (the first segment's) and its achieved error, measured on the take joined as `Archive.decode` does.

    `coded`: each segment's (class index, basis, payload, error) from `encode_class`. Every
    segment met the target on its coded frames, and the crossfade only mixes frames both
    decode well, so the take nearly always meets it at once; if not, its segments are coded
    again against a tighter target until it does.
    """
    target, dz, coder = settings.error_cm, settings.dead_zone, interim_coder(settings.coefficient_coder)
    cores = [(unit.first, unit.frames) for unit in units]
    payloads, errors = [c[2] for c in coded], [c[3] for c in coded]
    for _ in range(TIGHTENINGS):
        decoded = [reconstruct(CodedClip.from_payload(payload, coder, [(unit.coded_frames, c[1].q),
                                                                       (unit.coded_frames, 4)]),
                               c[1], transform, dz, unit.coded_frames)
                   for payload, c, unit in zip(payloads, coded, units)]
        joined = _joined(decoded, cores, clip.motion.n_frames, OVERLAP)
        (mean_err, max_err), twist_flips = clip.final_check(*joined)
        if mean_err <= target:
            break
        target *= 0.9
        codes, errors, _ = zip(*(code_clip(unit_clip, c[1], transform, target, dz, settings.split)
                                 for unit_clip, c in zip(unit_clips, coded)))
        payloads = [code.payload(coder) for code in codes]
    else:
        raise TargetError(f"segments joined to {mean_err:.4f} cm, above {settings.error_cm:g} cm; use a larger -e",
                          clip.source.amc)
    streams, segments = {}, []
    for s, (unit, c, payload, (seg_mean, seg_max)) in enumerate(zip(units, coded, payloads, errors)):
        name = f"clip/{index:05d}/{s:03d}"
        streams[name] = payload
        segments.append({"first": unit.first, "frames": unit.frames, "class": c[0], "stream": name,
                         "error_cm": seg_mean, "max_error_cm": seg_max})
    row.update(segments=segments, segment_overlap=OVERLAP, error_cm=mean_err, max_error_cm=max_err)
    if twist_flips:
        row["twist_flips"] = twist_flips
    row["class"] = segments[0]["class"]
    return streams


def _joined(decoded: list, cores: list[tuple[int, int]], n_frames: int, overlap: int):
    """(poses, root) of a take from its segments' decoded (poses, root) (`segment.join_segments`)."""
    poses = join_segments([p for p, _ in decoded], cores, n_frames, overlap)
    root = None if decoded[0][1] is None else join_segments([r for _, r in decoded], cores, n_frames, overlap)
    return poses, root


def _clip_row(clip: LoadedClip) -> dict:
    """A clip's row in meta as far as the clip itself tells (its skeleton, class and errors come later)."""
    m = clip.motion
    row = {
        "path": clip.source.relpath,
        "frames": m.n_frames,
        "first_frame": int(m.frame_numbers[0]) if m.n_frames else 1,
        "header": m.header,
        "bones": m.bones,
        "counts": m.counts,
        "angle_unit": clip.layout.angle_unit,
        "style": asdict(m.style),  # how the source wrote numbers and lines, to write it back alike
    }
    if m.dropped_frames:  # an incomplete last frame left out: the archive says so, not only a warning
        row["dropped_frames"] = m.dropped_frames
    return row


class Archive:
    """An opened .mcz: metadata up front, clips decoded on demand (random access)."""

    def __init__(self, path):
        self.path = os.fspath(path)
        self._reader = ArchiveReader(path)
        try:
            self.meta = self._json("meta")
            # every file a full decompress writes, each path checked to stay inside the output folder
            self.files = validate_meta(self.meta, self._reader.names(), self.path)
            self._skeleton_texts = self._skeletons()
        except BaseException:
            self._reader.close()
            raise
        # fields older formats did not have, as those formats meant them
        self.settings = Settings(**{"coefficient_coder": "zstd", "axes_from_positions": False, **self.meta["settings"]})
        self._priors: Priors | None = None
        self._bases: dict[int, ClassBasis] = {}
        self._models: dict[int, SkeletonModel] = {}
        self._transform = get_stage(self.settings.transform)

    def _json(self, name):
        try:
            return parse_json(decode_bytes(self._reader.read(name)))
        except KeyError:
            raise ArchiveError(f"{name}: stream missing", self.path) from None
        except (ValueError, RecursionError) as exc:  # also bad UTF-8, bad JSON and JSON nested too deep
            raise ArchiveError(f"{name}: {exc}", self.path) from exc

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._reader.close()

    @property
    def clips(self) -> list[dict]:
        return self.meta["clips"]

    def _skeletons(self) -> list[str]:
        """The ASF texts, one per skeleton in meta, each as it was read (Latin-1: one character per byte)."""
        texts = self._json("skeletons")
        if not (isinstance(texts, list) and len(texts) == len(self.meta["skeletons"])
                and all(isinstance(t, str) and max(t, default="\0") <= "\xff" for t in texts)):
            raise ArchiveError(f"skeletons: expected {len(self.meta['skeletons'])} ASF texts, as meta lists",
                               self.path)
        return texts

    def skeleton_text(self, index: int) -> str:
        return self._skeleton_texts[index]

    @property
    def priors(self) -> Priors | None:
        """Where the clip streams' models start (coefficient coder "primed"), else None."""
        if self.settings.coefficient_coder != "primed" or self.settings.lossless:
            return None
        if self._priors is None:
            try:
                self._priors = Priors.decode(decode_bytes(self._reader.read("priors")))
            except KeyError:
                raise ArchiveError("priors: stream missing", self.path) from None
            except ValueError as exc:
                raise ArchiveError(f"priors: damaged ({exc})", self.path) from exc
        return self._priors

    def decode(self, index: int) -> Motion:
        """The clip's motion as decoded (lossy: within the stored error of the original)."""
        row = self.clips[index]
        name = f"clip/{index:05d}"
        try:
            if self.settings.lossless:
                values = decode_channels(self._reader.read(name))
            else:
                model = self._model(row["skeleton"])
                layout = model.layout(ChannelLayout(tuple(row["bones"]), tuple(row["counts"]), row["angle_unit"]))
                name_ = self.settings.representation
                if "segments" in row:  # --segment: the segments joined, then turned into channels in one go
                    decoded, cores = [], []
                    for part in row["segments"]:
                        name = part["stream"]
                        lo, hi = coded_range(part["first"], part["frames"], row["frames"], row["segment_overlap"])
                        decoded.append(self._reconstruct(name, part["class"], hi - lo))
                        cores.append((part["first"], part["frames"]))
                    poses, root = _joined(decoded, cores, row["frames"], row["segment_overlap"])
                else:
                    poses, root = self._reconstruct(name, row["class"], row["frames"])
                poses = poses / pose_weights(model, name_, poses.shape[1], self.settings.axis_weight_cm)
                params = {**skeleton_params(model, name_, layout),
                          "twist": flips_from_ranges(row.get("twist_flips", {}), model, row["frames"])}
                values = channels_from(model, name_, layout, poses, root, params, self.settings.axes_from_positions)
        except ArchiveError:
            raise
        except (ValueError, KeyError, IndexError, EOFError, MocapFormatError) as exc:
            raise ArchiveError(f"{name} ({row['path']}): damaged ({exc})", self.path) from exc
        if values.shape != (row["frames"], sum(row["counts"])):
            raise ArchiveError(f"{name} ({row['path']}): decoded shape {values.shape} does not match", self.path)
        frames = np.arange(row["first_frame"], row["first_frame"] + row["frames"])
        return Motion(row["bones"], row["counts"], values, frames, row["header"], row["path"], AmcStyle(**row["style"]))

    def file_bytes(self, kind: str, index: int) -> bytes:
        """The bytes `decompress` writes for an entry of `files`: ("amc", clip) or ("asf", skeleton).

        An AMC that mcz could not read back (values it refuses) is an error here, not a file.
        """
        if kind == "asf":
            return self.skeleton_text(index).encode("latin-1")
        motion = self.decode(index)
        if not np.all(np.abs(motion.values) <= MAX_ABS_VALUE):
            raise ArchiveError(f"clip/{index:05d} ({motion.path}): damaged (decoded values beyond "
                               f"+-{MAX_ABS_VALUE:g}, which no AMC reader accepts)", self.path)
        return format_amc(motion).encode(motion.style.encoding)

    def _reconstruct(self, stream: str, class_index: int, n_frames: int):
        """Weighted poses and root track of one coefficient stream (a clip, or a segment's coded frames)."""
        basis = self._basis(class_index)
        check_matrix_shape(n_frames, basis.mean.size)  # the decoded poses: bounded before they are made
        coded = CodedClip.from_payload(self._reader.read(stream), self.settings.coefficient_coder,
                                       [(n_frames, basis.q), (n_frames, 4)], self.priors)
        return reconstruct(coded, basis, self._transform, self.settings.dead_zone, n_frames)

    def _model(self, k: int) -> SkeletonModel:
        if k not in self._models:
            try:
                asf = parse_asf(self.skeleton_text(k).encode("latin-1"), self.meta["skeletons"][k]["name"])
                self._models[k] = SkeletonModel.from_asf(asf)
            except (MocapFormatError, ValueError) as exc:
                if isinstance(exc, ArchiveError):
                    raise
                raise ArchiveError(f"skeletons: skeleton {k} is not a valid ASF ({exc})", self.path) from exc
        return self._models[k]

    def _basis(self, k: int) -> ClassBasis:
        if k not in self._bases:
            name = f"class/{k:04d}"
            try:
                self._bases[k] = ClassBasis.decode(self._reader.read(name), self.settings.coefficient_coder)
            except (ValueError, KeyError) as exc:
                raise ArchiveError(f"{name}: damaged ({exc})", self.path) from exc
        return self._bases[k]

    def stream_sizes(self) -> dict[str, int]:
        return self._reader.sizes()

    @property
    def format_version(self) -> int:
        return self._reader.format_version

    def verify_checksums(self) -> None:
        """Check every stream's CRC32 without decoding: cheap, so `info` and `decompress` run it first."""
        paths = {f"clip/{i:05d}": row["path"] for i, row in enumerate(self.clips)}
        for name in self._reader.names():
            try:
                self._reader.read(name)
            except ArchiveError as exc:
                clip = paths.get(name[:10])  # clip/NNNNN and its segments clip/NNNNN/SSS
                if clip is None:
                    raise
                raise ArchiveError(f"{exc.message} (clip {clip})", self.path) from exc

    def verify(self) -> None:
        """Check every stream's checksum and make every file a full `decompress` writes, in memory
        (`mcz test`): an archive that passes decompresses, disk space and permissions aside."""
        self.verify_checksums()
        for kind, index in progress(list(self.files.values()), desc="test", unit="file"):
            self.file_bytes(kind, index)


def decompress(archive_path, out_dir, patterns=(), force: bool = False) -> dict:
    """Write the ASF and AMC files of the clips matching `patterns` (all by default) under `out_dir`.

    Every path comes from the archive's meta, checked on opening to be relative, free of '.'
    and '..' and unique (`meta.validate`); each file is also refused if its folder resolves
    outside `out_dir` through a symbolic link already there.
    """
    out = Path(out_dir)
    with Archive(archive_path) as archive:
        archive.verify_checksums()  # a damaged archive is refused before any file is written
        chosen = {i for i, row in enumerate(archive.clips)
                  if not patterns or any(fnmatch.fnmatch(row["path"], p) for p in patterns)}
        if not chosen:
            raise MocapFormatError(f"no clip matches {', '.join(patterns)}", archive_path)
        folders = {PurePosixPath(archive.clips[i]["path"]).parent for i in chosen}
        targets = {out.joinpath(*path.split("/")): (kind, index) for path, (kind, index) in archive.files.items()
                   if (index in chosen if kind == "amc" else PurePosixPath(path).parent in folders)}
        root = os.path.realpath(out)
        for path in targets:
            if os.path.commonpath([root, os.path.realpath(path.parent)]) != root:
                raise MocapFormatError("its folder leads outside the output folder through a symbolic link; "
                                       "refusing to write it", path)
        existing = [p for p in targets if os.path.lexists(p)]
        if existing and not force:
            raise FileExistsError(None, "already exists", os.fspath(existing[0]))
        frames = 0
        for path, (kind, index) in progress(list(targets.items()), desc="decompress", unit="file"):
            _write_atomically(path, archive.file_bytes(kind, index))
            frames += archive.clips[index]["frames"] if kind == "amc" else 0
    return {"clips": len(chosen), "frames": frames, "files": len(targets), "output": os.fspath(out)}


def _write_atomically(path: Path, data: bytes) -> None:
    """A new file under a random name, created exclusively (never through a link planted there),
    then renamed over `path`: an interrupted run never leaves half an AMC behind."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".mcz-{secrets.token_hex(8)}.tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o666)
    except OSError as exc:
        raise OSError(exc.errno, os.strerror(exc.errno), os.fspath(path)) from exc
    try:
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError) and exc.errno and exc.filename is None:  # e.g. a full disk: name the file
            raise OSError(exc.errno, os.strerror(exc.errno), os.fspath(path)) from exc
        raise


def info(archive_path) -> dict:
    """What `mcz info` shows: settings, classes, per-clip frames and achieved errors, sizes."""
    size = os.path.getsize(archive_path)
    with Archive(archive_path) as archive:
        archive.verify_checksums()  # info on a damaged archive says so (decoding is left to `mcz test`)
        meta, format_version = archive.meta, archive.format_version
        stream_sizes = defaultdict(int)
        for name, length in archive.stream_sizes().items():
            stream_sizes[name.split("/")[0]] += length
    frames = sum(r["frames"] for r in meta["clips"])
    largest_mean = max((r["error_cm"] for r in meta["clips"]), default=0.0)
    return {
        "path": os.fspath(archive_path),
        "format_version": format_version,
        "tool": meta["tool"],
        "settings": meta["settings"],
        "skeletons": len(meta["skeletons"]),
        "classes": meta["classes"],
        "auto_classes": meta.get("auto_classes", []),
        "clips": [_info_row(r) for r in meta["clips"]],
        "frames": frames,
        "bytes": size,
        "bytes_per_frame": size / frames if frames else 0.0,
        "stream_bytes": dict(stream_sizes),
        "worst_error_cm": largest_mean,  # = largest_mean_error_cm, kept for old readers
        "largest_mean_error_cm": largest_mean,  # what -e bounds
        "largest_max_error_cm": max((r["max_error_cm"] for r in meta["clips"]), default=0.0),
        "skipped": meta.get("skipped", []),  # clips left out by compress --skip-bad
        "dropped_frames": sum(r.get("dropped_frames", 0) for r in meta["clips"]),  # of truncated inputs
    }


def _info_row(row: dict) -> dict:
    """A clip as `info` lists it; a segmented take (--segment) with its segments' frames, classes and errors."""
    out = {k: row[k] for k in ("path", "frames", "class", "error_cm", "max_error_cm")}
    if "dropped_frames" in row:
        out["dropped_frames"] = row["dropped_frames"]
    if "segments" in row:
        out["segments"] = [{k: s[k] for k in ("first", "frames", "class", "error_cm", "max_error_cm")}
                           for s in row["segments"]]
    return out
