"""The write: meta assembled from the passes' records, checked as every reader checks it, the
skeletons stream (`archive.skeletons`), and the archive committed with every stream."""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, replace

from mocapzip import __version__
from mocapzip.archive.dictionaries import STREAM_DICTIONARIES, dictionary
from mocapzip.archive.meta import contents_of
from mocapzip.archive.meta import validate as validate_meta
from mocapzip.archive.passes.check import Job
from mocapzip.archive.passes.class_coding import ClassRecord, ClipRecord, CodedClasses
from mocapzip.archive.passes.classes import Classes
from mocapzip.archive.passes.entropy_pass import StoredClips
from mocapzip.archive.passes.first_pass import ClipsRead
from mocapzip.archive.settings import Settings
from mocapzip.archive.skeletons import encode_skeletons
from mocapzip.codec.entropy.zstd import encode_bytes, pack_blobs
from mocapzip.codec.segments import OVERLAP
from mocapzip.defaults import ACL_SHELL_CM
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.mcz import FORMAT_VERSION, ArchiveWriter
from mocapzip.limits import MAX_DECODED_STREAM_BYTES

# Settings that meta leaves out at these values: a reader takes them as absent, and absent means
# off (segment, repair_glitches, plant_feet), pca (model; format 11 on: tensor, with its modes),
# a rate from the files where they state one (fps_from_files; format 7 on) and no bound.
ABSENT_SETTINGS = {"segment": False, "repair_glitches": False, "plant_feet": False, "model": "pca", "modes": None,
                   "fps_from_files": True, "max_error_cm": None, "contact_error_cm": None,
                   "vertex_error_cm": None, "shell_cm": ACL_SHELL_CM}


@dataclass(frozen=True)
class Written:
    """The archive written."""

    rows: tuple[dict, ...]  # the clips' rows in its meta
    skipped: tuple[dict, ...]  # the clips left out, with skip_bad: {"path", "error"} each
    size: int  # its bytes


def write(job: Job, clips: ClipsRead, classes: Classes, coded: CodedClasses, stored: StoredClips,
          archive: ArchiveWriter) -> Written:
    """Meta and the skeletons stream, and every stream the passes hold, to `archive`, committed."""
    meta, texts, is_asf = assemble(job, clips, classes, coded, stored, archive)
    return Written(tuple(meta["clips"]), clips.skipped, commit(archive, meta, texts, is_asf, job.output))


def assemble(job: Job, clips: ClipsRead, classes: Classes, coded: CodedClasses, stored: StoredClips,
             archive: ArchiveWriter) -> tuple[dict, list[bytes], list[bool]]:
    """Every stream the passes hold, added to `archive`; (meta, the skeletons' texts, whether each
    is an ASF) for `commit` (`archive.edit` merges them into another archive's first)."""
    codings = coded.clips or (None,) * len(clips.rows)  # none in a lossless archive
    rows = [_clip_row(*parts) for parts in zip(clips.rows, clips.skeleton_of, classes.clip_class, codings)]
    meta = {
        "tool": f"mocapzip {__version__}",
        "settings": _stored_settings(job.settings if stored.coder is None else  # lossless: the settings' coder
                                     replace(job.settings, coefficient_coder=stored.coder)),
        "skeletons": [stored.format.entry(stored.path.name, stored.skeleton) for stored in clips.skeletons],
        "classes": [_class_row(record) for record in coded.classes],
        "clips": rows,
    }
    if classes.auto_plans is not None:
        meta["auto_classes"] = classes.auto_plans
    if clips.skipped:
        meta["skipped"] = list(clips.skipped)
    streams = {f"extra_root/{i:05d}": stream for i, stream in enumerate(clips.extra_roots) if stream is not None}
    for name, stream in {**streams, **coded.streams, **stored.streams}.items():
        archive.add(name, stream)
    return (meta, [stored.skeleton.text for stored in clips.skeletons],
            [stored.format.asf_skeletons for stored in clips.skeletons])


def commit(archive: ArchiveWriter, meta: dict, texts: list[bytes], is_asf: list[bool], output: str) -> int:
    """`meta` checked as every reader checks it against the streams `archive` holds (compress never
    writes an archive a reader refuses), it and the skeletons stream of `texts` added, and the
    archive written; its size."""
    order = ["meta", "skeletons", *sorted(archive.names)]
    validate_meta(meta, order, output, FORMAT_VERSION)
    unpacked = {"meta": json.dumps(meta, sort_keys=True).encode(), "skeletons": pack_blobs(texts)}
    for name, data in unpacked.items():
        if len(data) > MAX_DECODED_STREAM_BYTES:
            raise MocapFormatError(f"the archive's {name} would take {len(data):,} bytes, more than the "
                                   f"{MAX_DECODED_STREAM_BYTES:,} a reader accepts: compress fewer clips at once",
                                   output)
    archive.add("meta", encode_bytes(unpacked["meta"], dictionary(STREAM_DICTIONARIES["meta"])))
    archive.add("skeletons", encode_skeletons(texts, is_asf))
    return archive.commit(order, contents_of(meta))


def summary(job: Job, clips: ClipsRead, written: Written, seconds: float) -> dict:
    """What `compress` returns (and the command line prints)."""
    rows, size = written.rows, written.size
    frames = sum(r["frames"] for r in rows)
    largest_mean = max(r["error_cm"] for r in rows)
    return {
        "output": job.output,
        "clips": len(rows),
        "frames": frames,
        "input_bytes": sum(os.path.getsize(s.motion) for s in clips.sources)  # and the skeletons in files of their own
        + sum(os.path.getsize(p) for p in {s.path for s in clips.skeletons} - {s.motion for s in clips.sources}),
        "output_bytes": size,
        "bytes_per_frame": size / frames,
        "worst_error_cm": largest_mean,  # kept for old readers: largest_mean_error_cm
        "largest_mean_error_cm": largest_mean,  # what -e bounds
        "largest_max_error_cm": max(r["max_error_cm"] for r in rows),
        "largest_max_vertex_error_cm": max((r["max_vertex_error_cm"] for r in rows if "max_vertex_error_cm" in r),
                                           default=None),  # lossy: ACL's metric (settings.shell_cm)
        "seconds": seconds,
        "skipped": list(written.skipped),
        "repaired": [{"path": r["path"], "first": first, "last": last, "error_cm": cm}
                     for r in rows for first, last, cm in r.get("repaired", [])],
    }


def _stored_settings(settings: Settings) -> dict:
    """The settings as meta stores them: whole, but for those at their ABSENT_SETTINGS value."""
    return {name: value for name, value in asdict(settings).items()
            if name not in ABSENT_SETTINGS or value != ABSENT_SETTINGS[name]}


def _class_row(record: ClassRecord) -> dict:
    row = {"name": record.name, "components": record.components, "clips": record.clips, "frames": record.frames}
    if record.model is not None:  # --model tensor: which model the class took, and a tensor's grid
        row["model"] = record.model
    if record.grid is not None:
        row.update(modes=list(record.grid.modes), levels=[list(v) for v in record.grid.levels])
    return row


def _clip_row(own: dict, skeleton: int, class_index: int, coding: ClipRecord | None) -> dict:
    """A clip's row: what the clip itself tells (`first_pass`), its skeleton and class, and what its
    coding achieved (lossy; a lossless clip's errors, all 0, are in its own row)."""
    row = {**own, "skeleton": skeleton, "class": class_index}
    if coding is None:
        return row
    achieved = coding.achieved
    # Mean and max are the bounds: stored rounded up to a millionth of a cm, never below what was
    # measured (0.998697 takes 9 fewer digits of meta than 0.9986969546376016). p99 only informs.
    row.update(error_cm=_rounded_up(achieved.mean), p99_error_cm=round(achieved.p99, 4),
               max_error_cm=_rounded_up(achieved.max))
    if achieved.vertex is not None:  # a bound too, with --max-vertex-error: rounded up like max
        row["max_vertex_error_cm"] = _rounded_up(achieved.vertex)
    if achieved.repaired:
        row["repaired"] = [list(r) for r in achieved.repaired]
    if coding.patched_frames is not None:
        row["patched_frames"] = coding.patched_frames
    if coding.planted_stances is not None:
        row["planted_stances"] = coding.planted_stances
    if coding.twist_flips:
        row["twist_flips"] = coding.twist_flips
    if coding.tensor_at is not None:
        row["tensor_at"] = list(coding.tensor_at)
    if coding.segments:
        row.update(segment_overlap=OVERLAP, segments=[
            {"first": s.first, "frames": s.frames, "class": s.class_index, "stream": s.stream,
             "error_cm": s.error[0], "max_error_cm": s.error[1]} for s in coding.segments])
    return row


def _rounded_up(cm: float) -> float:
    """`cm` rounded up to 6 decimals (float rounding may leave it a hair below `cm`: then one step up)."""
    stored = math.ceil(cm * 1e6) / 1e6
    return stored if stored >= cm else stored + 1e-6
