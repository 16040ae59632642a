"""`mcz remove` and `mcz append`: an archive rewritten with clips dropped or added, the streams of
every clip it keeps copied as they are (so each decodes to the same bytes and keeps its stored
errors), and only the indices that name rows, classes and skeletons renumbered (docs/editing.md).

Appended clips are coded by compress's passes with the archive's settings, as classes of their own,
and each also in the stored class nearest it (`passes.stored_classes`); a clip stays in the stored
class where that measures fewer bytes (`_cheaper_in_stored`). Their clip streams are coded again
from the archive's priors (coefficient coder "primed"): the same coefficients, so their rows'
errors hold. The new archive is written as compress writes one
(`formats.mcz.ArchiveWriter`: streams parked in an unnamed spool, the file built under a temporary
name and renamed over the target), so the old one is intact until the new one is complete.
"""

from __future__ import annotations

import copy
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import PurePosixPath
from typing import Callable

from mocapzip import __version__
from mocapzip.archive.meta import class_counts
from mocapzip.archive.reader import Archive, path_matches
from mocapzip.archive.passes.check import check
from mocapzip.archive.passes.class_coding import ClassRecord, CodedClasses, clip_record, code_classes
from mocapzip.archive.passes.classes import Classes, classes_of
from mocapzip.archive.passes.entropy_pass import StoredClips
from mocapzip.archive.passes.first_pass import first_pass
from mocapzip.archive.passes.stored_classes import code_in_stored
from mocapzip.archive.passes.write import assemble, commit
from mocapzip.codec.entropy.priors import INTERIM_CODER, primed_streams
from mocapzip.defaults import DEFAULT_CACHE_MB
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.mcz import FORMAT_VERSION, ArchiveWriter
from mocapzip.inputs.registry import stored_format
from mocapzip.parallel import one_blas_thread


@dataclass(frozen=True)
class _Part:
    """Rows of one archive (or of clips just coded) that go into the archive written."""

    meta: dict
    texts: list[bytes]  # its skeletons' texts
    read: Callable[[str], bytes]  # its streams by name
    rows: list[int]  # the rows kept, in order
    shared: dict[int, int] = field(default_factory=dict)  # its classes that are the archive's: their numbers there


@one_blas_thread
def remove(archive_path, patterns, output=None, force: bool = False) -> dict:
    """Write `archive_path` without the clips whose stored path or file name matches one of `patterns`
    (globs, as `decompress --clip`) to `output` (None: in place, which needs `force`); the summary."""
    started = time.perf_counter()
    output = os.fspath(archive_path if output is None else output)
    with _opened(archive_path) as old:
        rows = old.clips
        gone = [i for i, row in enumerate(rows) if any(path_matches(row["path"], p) for p in patterns)]
        if not gone:
            raise MocapFormatError(f"no clip matches {', '.join(patterns)}", archive_path)
        if len(gone) == len(rows):
            raise MocapFormatError(f"{', '.join(patterns)} would remove every clip: delete the archive instead",
                                   archive_path)
        _refuse_part_of_a_grid(old, set(gone))
        kept = [i for i in range(len(rows)) if i not in set(gone)]
        with ArchiveWriter(output, tool_version=__version__, overwrite=force) as new:
            size = _written([_old_part(old, kept)], old, new)
    return {"output": output, "removed": [rows[i]["path"] for i in gone], "clips": len(kept), "output_bytes": size,
            "seconds": time.perf_counter() - started}


@one_blas_thread
def append(archive_path, inputs, output=None, force: bool = False, jobs: int = 1, under: str | None = None,
           asf=None, units: str | None = None, cache_bytes: int | None = DEFAULT_CACHE_MB << 20) -> dict:
    """Write `archive_path` with the clips under `inputs` added (stored under the folder `under`, if
    given) to `output` (None: in place, which needs `force`); the summary. A clip whose stored path
    the archive holds is refused before any is read."""
    started = time.perf_counter()
    output = os.fspath(archive_path if output is None else output)
    with _opened(archive_path) as old:
        settings = old.settings
        if not settings.lossless:  # held as rate control codes them, then primed from the archive's priors
            settings = replace(settings, coefficient_coder=INTERIM_CODER)
        job = check(inputs, output, settings, asf, force=True, units=units)  # the output is refused below
        if under is not None:
            job = replace(job, sources=tuple(replace(s, relpath=f"{stored_folder(under)}/{s.relpath}") for s in job.sources))
        stored = {row["path"] for row in old.clips}
        clash = next((s for s in job.sources if s.relpath in stored), None)
        if clash is not None:
            raise MocapFormatError(f"the archive already holds a clip stored as '{clash.relpath}' "
                                   "(mcz remove it first)", clash.motion)
        with ArchiveWriter(output, tool_version=__version__, overwrite=force) as new, \
                ArchiveWriter(output, tool_version=__version__, overwrite=True) as staged:  # never committed
            reader = job.clip_reader(cache_bytes)
            plan, target = job.settings.class_plan(), job.settings.coding_target()
            clips = first_pass(job, reader, job.settings.clip_reading(), plan, staged, jobs)
            classes = classes_of(clips, reader, plan, target, jobs)
            found = None
            if not (plan.lossless or plan.segment or plan.modes is not None):  # whole clips, PCA classes alone
                bases = [old.basis(k) for k in range(len(old.meta["classes"]))]
                found = code_in_stored(list(classes.units), bases, reader, target, jobs)
            coded = code_classes(clips, classes, reader, plan, target, jobs)
            streams = _stored(coded.interim, old, jobs)
            shared = {}
            if found is not None and any(found):
                classes, coded, streams, shared = _cheaper_in_stored(classes, coded, streams, found, old, jobs)
            added, texts, _ = assemble(job, clips, classes, coded, StoredClips(old.settings.coefficient_coder, streams),
                                       staged)
            size = _written([_old_part(old, range(len(old.clips))),
                             _Part(added, texts, staged.read, list(range(len(added["clips"]))), shared)], old, new)
    return {"output": output, "added": [row["path"] for row in added["clips"]], "clips": len(old.clips) + len(added["clips"]),
            "in_stored_classes": [row["path"] for row in added["clips"] if row["class"] in shared],
            "output_bytes": size, "seconds": time.perf_counter() - started}


def _stored(interim: dict[str, bytes], old: Archive, jobs: int) -> dict[str, bytes]:
    """Clip streams as rate control coded them, as the archive stores them: primed from its priors if it has them."""
    return interim if old.priors is None else primed_streams(interim, old.priors, jobs)


def _cheaper_in_stored(classes: Classes, coded: CodedClasses, streams: dict[str, bytes], found: list, old: Archive,
                       jobs: int) -> tuple[Classes, CodedClasses, dict[str, bytes], dict[int, int]]:
    """The appended clips moved to the stored classes `found` (per clip: (class, coding) or None)
    where that measures fewer bytes as stored; (classes, coded, stored streams, the classes that
    are the archive's by their number here).

    Per new class: all its clips moved and its basis dropped, if each has a stored class and their
    bytes there are at most the basis's and theirs in it; else each clip moved whose bytes in its
    stored class are fewer than in the new one (the new class keeps its basis for the others:
    their codings were measured with it)."""
    interim = {f"clip/{i:05d}": f[1].payload for i, f in enumerate(found) if f is not None}
    moved = _stored(interim, old, jobs)

    def there(i: int) -> int:  # clip i's bytes in its stored class
        return len(moved[f"clip/{i:05d}"]) + found[i][1].patch_bytes + found[i][1].stance_bytes

    def here(i: int) -> int:  # clip i's bytes in its new class
        return sum(len(part.get(f"{kind}/{i:05d}", b"")) for part, kind in
                   ((streams, "clip"), (coded.streams, "patch"), (coded.streams, "plant")))

    members_of = [sorted({classes.units[u].clip for u in classes.members(g)}) for g in range(len(classes.names))]
    chosen = set()
    for g, members in enumerate(members_of):
        cheaper = {i for i in members if found[i] is not None and there(i) < here(i)}
        mixed = len(coded.streams[f"class/{g:04d}"]) + sum(there(i) if i in cheaper else here(i) for i in members)
        if all(found[i] is not None for i in members) and sum(there(i) for i in members) <= mixed:
            cheaper = set(members)
        chosen |= cheaper
    kept = [g for g in range(len(classes.names)) if set(members_of[g]) - chosen]
    borrowed = sorted({found[i][0] for i in chosen})
    number = {g: n for n, g in enumerate(kept)} | {("stored", k): len(kept) + j for j, k in enumerate(borrowed)}

    def class_of(clip: int, g: int) -> int:
        return number["stored", found[clip][0]] if clip in chosen else number[g]

    classes = replace(classes, names=tuple(classes.names[g] for g in kept) +
                      tuple(old.meta["classes"][k]["name"] for k in borrowed),
                      unit_class=tuple(class_of(unit.clip, g) for unit, g in zip(classes.units, classes.unit_class)),
                      clip_class=tuple(class_of(i, g) for i, g in enumerate(classes.clip_class)))
    kept_streams = {name: data for name, data in coded.streams.items() if not name.startswith("class/")
                    and int(name.rsplit("/", 1)[1]) not in chosen}  # patch/, plant/ of the clips that stay
    kept_streams |= {f"class/{number[g]:04d}": coded.streams[f"class/{g:04d}"] for g in kept}
    records = list(coded.clips)
    for i in sorted(chosen):
        coding = found[i][1]
        records[i] = clip_record(i, coding.achieved, coding.patches, coding.stances, coding.twists, kept_streams)
    stored_classes = tuple(ClassRecord(old.meta["classes"][k]["name"], old.meta["classes"][k]["components"], 0, 0)
                           for k in borrowed)  # counted again as the archive is written (`_written`)
    coded = CodedClasses(tuple(coded.classes[g] for g in kept) + stored_classes, tuple(records), kept_streams,
                         coded.interim | {f"clip/{i:05d}": interim[f"clip/{i:05d}"] for i in chosen})
    streams = streams | {f"clip/{i:05d}": moved[f"clip/{i:05d}"] for i in chosen}
    return classes, coded, streams, {len(kept) + j: k for j, k in enumerate(borrowed)}


def _opened(archive_path) -> Archive:
    """The archive, its checksums checked; refused unless of the newest format, whose streams are copied as they are."""
    old = Archive(archive_path)
    try:
        old.verify_checksums()
        if old.format_version != FORMAT_VERSION:
            raise MocapFormatError(f"an archive of format {old.format_version}: only format {FORMAT_VERSION} is "
                                   "edited (decompress it and compress it again)", archive_path)
    except BaseException:
        old.__exit__()
        raise
    return old


def stored_folder(under: str) -> str:
    """`under` as the folder of stored paths: relative, no '.' or '..' (meta's checks say the rest at the write)."""
    parts = PurePosixPath(under).parts
    if not parts or under.startswith("/") or any(part in (".", "..") for part in under.split("/")):
        raise ValueError(f"under must be a relative folder without '.' or '..', got {under!r}")
    return "/".join(parts)


def _refuse_part_of_a_grid(old: Archive, gone: set[int]) -> None:
    """A tensor class's clips fill its grid (docs/format.md §6.3): they go all together or none."""
    for k, members in enumerate(class_counts(old.meta)[0] if not old.settings.lossless else []):
        if old.meta["classes"][k].get("model") == "tensor" and 0 < len(members & gone) < len(members):
            some = old.clips[min(members & gone)]["path"]
            raise MocapFormatError(f"{some} is in tensor class {k}, whose clips fill its grid: remove all "
                                   f"{len(members)} of them or none", old.path)


def _old_part(old: Archive, rows) -> _Part:
    texts = [old.skeleton_text(k).encode("latin-1") for k in range(len(old.meta["skeletons"]))]
    return _Part(old.meta, texts, old.stream, list(rows))


def _written(parts: list[_Part], old: Archive, new: ArchiveWriter) -> int:
    """The rows of `parts`, in order, with their classes, skeletons and streams, into `new`, with
    `old`'s settings, priors and informative fields; committed, its size."""
    meta = {"tool": f"mocapzip {__version__}", "settings": old.meta["settings"], "skeletons": [], "classes": [],
            "clips": []}
    for field in ("auto_classes", "skipped"):  # what compress found for the clips it was given: informative
        if field in old.meta:
            meta[field] = old.meta[field]
    texts: list[bytes] = []
    for part in parts:
        _copy_part(part, meta, texts, new)
    if not old.settings.lossless:
        clips, frames = class_counts(meta)
        for row, members, coded in zip(meta["classes"], clips, frames):
            row.update(clips=len(members), frames=coded)
        if old.priors is not None:
            new.add("priors", old.stream("priors"))
    is_asf = [stored_format(entry).asf_skeletons for entry in meta["skeletons"]]
    return commit(new, meta, texts, is_asf, new.path)


def _copy_part(part: _Part, meta: dict, texts: list[bytes], new: ArchiveWriter) -> None:
    """Append `part`'s rows to `meta`: skeletons shared where the entry and text are the same, its
    classes after those there, every stream of a row under its new number."""
    rows = [part.meta["clips"][i] for i in part.rows]
    skeleton_of = {}
    for k in sorted({row["skeleton"] for row in rows}):
        entry, text = part.meta["skeletons"][k], part.texts[k]
        same = next((j for j, (there, its) in enumerate(zip(meta["skeletons"], texts)) if its == text and there == entry),
                    None)
        if same is None:
            meta["skeletons"].append(entry)
            texts.append(text)
            same = len(texts) - 1
        skeleton_of[k] = same
    lossless = meta["settings"]["lossless"]
    class_of = dict(part.shared)  # the archive's own classes, which its part put first under their numbers
    if not lossless:
        for k in sorted({part_row["class"] for row in rows for part_row in row.get("segments", [row])} - set(class_of)):
            class_of[k] = len(meta["classes"])
            meta["classes"].append(copy.deepcopy(part.meta["classes"][k]))
            new.add(f"class/{class_of[k]:04d}", part.read(f"class/{k:04d}"))
            if meta["classes"][-1].get("model") == "tensor":
                new.add(f"tensor/{class_of[k]:04d}", part.read(f"tensor/{k:04d}"))
    for i, source in zip(part.rows, rows):
        j, row = len(meta["clips"]), copy.deepcopy(source)
        row["skeleton"] = skeleton_of[row["skeleton"]]
        meta["clips"].append(row)
        if lossless:
            new.add(f"clip/{j:05d}", part.read(f"clip/{i:05d}"))
            continue
        row["class"] = class_of[row["class"]]
        for s, segment in enumerate(row.get("segments", [])):
            name = f"clip/{j:05d}/{s:03d}"
            new.add(name, part.read(segment["stream"]))
            segment.update(stream=name, **{"class": class_of[segment["class"]]})
        claimed = {"clip": "segments" not in row, "extra_root": row.get("bvh", {}).get("extra_root", False),
                   "patch": "patched_frames" in row, "plant": "planted_stances" in row, "warp": "tensor_at" in row}
        for kind in (kind for kind, present in claimed.items() if present):
            new.add(f"{kind}/{j:05d}", part.read(f"{kind}/{i:05d}"))
