"""The archive's `meta` stream: its schema, and every check a reader makes before using it.

Meta comes from a file that may come from anyone, so nothing in it is used until it has
passed `validate`: a JSON Schema for shapes and types (`SCHEMA`, compiled once per process), then the
checks a schema cannot state: indices in range, sizes within `limits`, and output paths
that stay inside the folder the user named (docs/format.md, "Limits" and "Paths").
A failure is one `ArchiveError` naming the archive and the field.
"""

from __future__ import annotations

import functools
import math
import fastjsonschema
import pywt

from mocapzip.archive.settings import MAX_ERROR_CM
from mocapzip.classes.modes import MAX_PATTERN_CHARS, compiled_modes
from mocapzip.codec.segments import coded_range
from mocapzip.formats.amc import MAX_FRAME_NUMBER
from mocapzip.formats.text import MAX_FRAME_RATE
from mocapzip.formats.mcz import ArchiveError
from mocapzip.inputs.registry import InputFormat, input_formats, stored_format
from mocapzip.legacy import format_of
from mocapzip.schema import NEWLINE, record
from mocapzip.limits import MAX_BONES_PER_SKELETON, MAX_NATURAL_MODES, MAX_FRAMES_PER_CLIP, MAX_PATH_BYTES, MAX_VALUES_PER_CLIP, MAX_VALUES_PER_FRAME
from mocapzip.stages import stage_classes, stage_ids

MAX_NAME_BYTES = 255  # one path component: what POSIX file systems allow
MAX_DOF_PER_BONE = 7  # an ASF bone's channels: rx ry rz tx ty tz l

_COUNT = {"type": "integer", "minimum": 0}
_ERROR = {"type": "number", "minimum": 0}
_POSITIVE = {"type": "number", "minimum": 0, "exclusiveMinimum": True}
_STRING = {"type": "string"}


_STYLE = record({
    "notation": {"enum": ["g", "f"]},
    "digits": {"type": "integer", "minimum": 0, "maximum": 40},
    "exponent_digits": {"type": "integer", "minimum": 1, "maximum": 4},
    "name_separator": {"type": "string", "pattern": "^[ \t]{1,16}$"},
    "newline": NEWLINE,
    "header_newline": {"anyOf": [NEWLINE, {"type": "null"}]},
    "frame_newline": {"anyOf": [NEWLINE, {"type": "null"}]},
    "final_newline": {"type": "boolean"},
    "encoding": {"enum": ["utf-8", "latin-1"]},
})

_FRAME_NUMBER = {"type": "integer", "minimum": 0, "maximum": MAX_FRAME_NUMBER}

_SEGMENT = record({
    "first": _COUNT, "frames": {"type": "integer", "minimum": 1}, "class": _COUNT, "stream": _STRING,
    "error_cm": _ERROR, "max_error_cm": _ERROR,
})


def _clip(formats: tuple[InputFormat, ...]) -> dict:
    """A clip's row, with the row fields of `formats` (`InputFormat.row_field`)."""
    return record(
        {
            "path": _STRING,
            "frames": {"type": "integer", "minimum": 1, "maximum": MAX_FRAMES_PER_CLIP},
            "first_frame": {"type": "integer", "minimum": 0, "maximum": MAX_FRAME_NUMBER},
            "header": {"type": "array", "items": _STRING},
            "bones": {"type": "array", "minItems": 1, "maxItems": MAX_BONES_PER_SKELETON + 1,
                      "items": {"type": "string", "pattern": r"^\S+$"}},
            "counts": {"type": "array", "items": {"type": "integer", "minimum": 0, "maximum": MAX_DOF_PER_BONE}},
            "angle_unit": {"enum": ["deg", "rad"]},
            "style": _STYLE,
            "skeleton": _COUNT,
            "class": _COUNT,
            "error_cm": _ERROR,
            "max_error_cm": _ERROR,
        },
        {
            "dropped_frames": {"type": "integer", "minimum": 1},
            "twist_flips": {"type": "object", "additionalProperties": {"type": "array", "items": _COUNT}},
            "p99_error_cm": _ERROR,
            "max_vertex_error_cm": _ERROR,  # format 13 on: the worst shell vertex, ACL's metric (settings.shell_cm)
            "patched_frames": {"type": "integer", "minimum": 1, "maximum": MAX_FRAMES_PER_CLIP},
            "planted_stances": {"type": "integer", "minimum": 1, "maximum": MAX_FRAMES_PER_CLIP},  # format 9 on
            # format 11 on
            "tensor_at": {"type": "array", "minItems": 1, "maxItems": MAX_NATURAL_MODES, "items": _COUNT},
            "segments": {"type": "array", "minItems": 2, "items": _SEGMENT},
            "segment_overlap": {"type": "integer", "minimum": 0, "maximum": MAX_FRAMES_PER_CLIP},
            "fps": {"type": "number", "minimum": 0, "exclusiveMinimum": True, "maximum": MAX_FRAME_RATE},  # format 7 on
            **{f.row_field: f.row_schema for f in formats if f.row_field},  # format 8 on: "bvh", a BVH clip's
            # --repair-glitches (format 6 on): [first, last AMC frame numbers, largest joint error in cm] per run
            "repaired": {"type": "array", "maxItems": MAX_FRAMES_PER_CLIP, "items": {
                "type": "array", "minItems": 3, "maxItems": 3,
                "items": [_FRAME_NUMBER, _FRAME_NUMBER, _ERROR]}},
        },
    )


# one record per registered transform: its id and its parameters' schemas (`param_schema`)
_TRANSFORM = {"anyOf": [record({"id": {"enum": [codec_id]}, **cls.param_schema})
                        for codec_id, cls in stage_classes("transform").items()]}

_SETTINGS = record(
    {
        "error_cm": _POSITIVE,
        "representation": {"enum": list(stage_ids("representation"))},
        "transform": _TRANSFORM,
        "classes": _STRING,
        "split": {"anyOf": [{"type": "null"}, {"type": "array", "minItems": 3, "maxItems": 3, "items": _ERROR}]},
        "dead_zone": {"type": "number", "minimum": 0, "maximum": 0.5, "exclusiveMaximum": True},  # as UniformQuantiser
        "basis_precision": _POSITIVE,
        "axis_weight_cm": _POSITIVE,
        "fps": _POSITIVE,
        "lossless": {"type": "boolean"},
    },
    {
        "segment": {"type": "boolean"},
        "max_error_cm": _POSITIVE,
        "contact_error_cm": _POSITIVE,  # format 6 on
        "vertex_error_cm": _POSITIVE,  # format 13 on
        "shell_cm": {"type": "number", "minimum": 0, "maximum": MAX_ERROR_CM},  # format 13 on; absent: 3
        "repair_glitches": {"type": "boolean"},  # format 6 on
        "plant_feet": {"type": "boolean"},  # format 9 on
        "fps_from_files": {"type": "boolean"},  # format 7 on; absent: true
        "coefficient_coder": {"enum": [*stage_ids("coefficient coder"), "auto"]},
        "axes_from_positions": {"type": "boolean"},
        "model": {"enum": ["tensor"]},  # format 11 on; absent: pca
        "modes": {"type": "string", "maxLength": MAX_PATTERN_CHARS},
    },
)

_AUTO_GROUP = record(
    {"width": _COUNT, "clips": _COUNT, "k": _COUNT, "method": _STRING, "estimated_bytes": _COUNT,
     "candidates": {"type": "array", "items": record({"k": _COUNT, "method": _STRING, "bytes": _COUNT},
                                                       {"seed": {"type": ["integer", "null"]}})}},
)


def schema(formats: tuple[InputFormat, ...]) -> dict:
    """Meta's schema, with the fields in meta of `formats` (`InputFormat.row_schema`, `entry_schema`)."""
    return {"$schema": "http://json-schema.org/draft-04/schema#", **record(
        {
            "tool": _STRING,
            "settings": _SETTINGS,
            "skeletons": {"type": "array", "items": record({"name": _STRING}, {  # format 8 on: BVH hierarchies
                "format": _STRING,  # an input format's name ("bvh"; `inputs.registry`); absent: an ASF
                **{name: kind for f in formats for name, kind in f.entry_schema.items()}})},
            "classes": {"type": "array", "items": record({"name": _STRING, "components": _COUNT, "clips": _COUNT,
                                                           "frames": _COUNT}, {  # --model tensor (format 11 on)
                "model": {"enum": ["pca", "tensor"]},
                "modes": {"type": "array", "minItems": 1, "maxItems": MAX_NATURAL_MODES, "items": _STRING},
                "levels": {"type": "array", "items": {"type": "array", "items": _STRING}}})},
            "clips": {"type": "array", "items": _clip(formats)},
        },
        {
            "auto_classes": {"type": "array", "items": _AUTO_GROUP},
            "skipped": {"type": "array", "items": record({"path": _STRING, "error": _STRING})},
        },
    )}  # draft 4: an "integer" is one in the JSON text too (later drafts also take 5.0)


SCHEMA = schema(tuple(input_formats()))  # of the formats mcz registers itself (docs/format.md renders it)


@functools.cache
def _schema_check(detailed: bool, formats: tuple[InputFormat, ...]):
    """The schema of `formats` compiled. Archives are checked without detailed exceptions, whose code took
    0.03 s more to compile in every process that opens an archive; meta that fails is checked
    again with them, for the failing field's name and the whole problem (`validate`)."""
    return fastjsonschema.compile(schema(formats), detailed_exceptions=detailed)


def validate(meta, stream_names: list[str], archive_path: str, format_version: int) -> dict[str, tuple[str, int]]:
    """Check `meta` of a `format_version` archive against the schema and every rule between its
    fields (ArchiveError if one fails); return every file a full decompress writes (`_output_files`)."""

    def fail(field: str, problem: str) -> ArchiveError:
        return ArchiveError(f"meta: {field}: {problem}", archive_path)

    formats = tuple(input_formats())
    try:
        _schema_check(False, formats)(meta)
    except fastjsonschema.JsonSchemaValueException as exc:
        try:
            _schema_check(True, formats)(meta)  # the same checks, naming the failing field
        except fastjsonschema.JsonSchemaValueException as named:
            exc = named
        name = exc.name or ""
        field = name.removeprefix("data").lstrip(".") or "(top level)"
        raise fail(field, exc.message.removeprefix(name).strip()) from None
    settings = meta["settings"]
    for added, part, name in format_of(format_version).later_fields:  # refused, as that format's readers did
        rows = [settings] if part == "settings" else meta[part]
        where = next((i for i, row in enumerate(rows) if name in row), None)
        if where is not None:
            field = f"settings.{name}" if part == "settings" else f"{part}[{where}].{name}"
            raise fail(field, f"format {added} on; this archive is format {format_version}")
    transform = settings["transform"]
    if transform["id"] == "dwt" and transform["wavelet"] not in pywt.wavelist(kind="discrete"):
        raise fail("settings.transform.wavelet", f"unknown wavelet {transform['wavelet'][:40]!r}")
    if not settings["lossless"] and settings.get("coefficient_coder") == "auto":
        raise fail("settings.coefficient_coder", "'auto' is for compress; a lossy archive names its coder")
    n_classes = len(meta["classes"])
    for k, skeleton in enumerate(meta["skeletons"]):
        _check_file_name(skeleton["name"], f"skeletons[{k}].name", fail)
        _check_skeleton_entry(skeleton, k, settings["lossless"], fail)
    needed = {"meta", "skeletons"}
    if not settings["lossless"]:
        needed.update(f"class/{k:04d}" for k in range(n_classes))
        if settings.get("coefficient_coder") == "primed":
            needed.add("priors")
    for i, row in enumerate(meta["clips"]):
        needed.update(_check_clip(row, i, settings, meta["skeletons"], n_classes, fail))
    _check_class_counts(meta, fail)
    needed.update(_check_tensor_classes(meta, fail))
    missing = sorted(needed - set(stream_names))
    if missing:
        raise ArchiveError(f"{missing[0]}: stream missing", archive_path)
    unclaimed = sorted(set(stream_names) - needed)  # the spec defines no such stream: refused, not ignored
    if unclaimed:
        raise ArchiveError(f"{unclaimed[0]}: a stream that no part of meta claims", archive_path)
    return _output_files(meta, fail)


def _check_class_counts(meta: dict, fail) -> None:
    """Each class's `clips` and `frames` are those its rows code, as compress counts them: the
    clips with a row or a segment in it, at least one, and the frames coded (a whole clip's
    `frames`, a segment's coded range). A lossless archive codes no class, so it lists none."""
    classes = meta["classes"]
    if meta["settings"]["lossless"]:
        if classes:
            raise fail("classes", "a lossless archive has no classes")
        return
    clips, frames = class_counts(meta)  # indices and segments already checked (`_check_clip`)
    for k, row in enumerate(classes):
        if not clips[k]:
            raise fail(f"classes[{k}]", "no clip or segment is in this class")
        if row["clips"] != len(clips[k]):
            raise fail(f"classes[{k}].clips", f"{row['clips']}, but {len(clips[k])} clips have a row or segment "
                                              "in this class")
        if row["frames"] != frames[k]:
            raise fail(f"classes[{k}].frames", f"{row['frames']}, but its clips and segments code {frames[k]}")


def class_counts(meta: dict) -> tuple[list[set], list[int]]:
    """Per class of a lossy meta, the clips with a row or a segment in it and the frames it codes
    (a whole clip's `frames`, a segment's coded range), as compress counts them."""
    clips, frames = [set() for _ in meta["classes"]], [0] * len(meta["classes"])
    for i, row in enumerate(meta["clips"]):
        if "segments" not in row:
            clips[row["class"]].add(i)
            frames[row["class"]] += row["frames"]
            continue
        for part in row["segments"]:
            lo, hi = coded_range(part["first"], part["frames"], row["frames"], row["segment_overlap"])
            clips[part["class"]].add(i)
            frames[part["class"]] += hi - lo
    return clips, frames


def _check_tensor_classes(meta: dict, fail) -> list[str]:
    """`--model tensor`'s fields: the setting and its pattern come together, in a lossy archive
    without segments, and the pattern compiles (`classes.modes.compiled_modes`); a tensor class's
    modes are named groups of it, none twice, and agree with its levels, none twice in a mode;
    its clips fill its grid, one at each place, and no other clip or segment is in it; return
    the streams they need."""
    settings = meta["settings"]
    tensor = settings.get("model") == "tensor"
    if ("model" in settings) != ("modes" in settings):
        raise fail("settings.modes", "model and modes come together")
    if tensor and (settings["lossless"] or settings.get("segment")):
        raise fail("settings.model", "a tensor model is lossy and never segmented")
    groups = {}
    if "modes" in settings:  # compiled, never matched: decoding needs no path matched, and a match may backtrack
        try:
            groups = compiled_modes(settings["modes"]).groupindex
        except ValueError as exc:
            raise fail("settings.modes", str(exc)) from None
    needed, places = [], {}  # (class, tensor_at) -> clip
    for k, row in enumerate(meta["classes"]):
        if ("model" in row) != tensor or (row.get("model") == "tensor") != ("modes" in row) or \
                ("modes" in row) != ("levels" in row):
            raise fail(f"classes[{k}]", "--model tensor names each class's model, and a tensor class its modes "
                                        "and levels; other archives none of them")
        if "modes" in row:
            if len(set(row["modes"])) != len(row["modes"]):
                raise fail(f"classes[{k}].modes", "a mode named twice")
            unknown = [mode for mode in row["modes"] if mode not in groups]
            if unknown:
                raise fail(f"classes[{k}].modes", f"{unknown[0][:40]!r} is not a named group of settings.modes")
            if len(row["levels"]) != len(row["modes"]) or any(len(levels) < 2 for levels in row["levels"]):
                raise fail(f"classes[{k}].levels", "two or more levels for each mode")
            twice = next((m for m, levels in enumerate(row["levels"]) if len(set(levels)) != len(levels)), None)
            if twice is not None:
                raise fail(f"classes[{k}].levels[{twice}]", f"a level of mode {row['modes'][twice][:40]!r} named twice")
            needed.append(f"tensor/{k:04d}")
    for i, row in enumerate(meta["clips"]):
        segmented_or_lossless = "segments" in row or row["class"] >= len(meta["classes"])
        class_row = {} if segmented_or_lossless else meta["classes"][row["class"]]
        if ("tensor_at" in row) != ("modes" in class_row):
            raise fail(f"clips[{i}].tensor_at", "a clip has its place in the grid if and only if its class is a tensor")
        if "tensor_at" in row:
            if len(row["tensor_at"]) != len(class_row["modes"]) or any(
                    at >= len(levels) for at, levels in zip(row["tensor_at"], class_row["levels"])):
                raise fail(f"clips[{i}].tensor_at", f"not a place in its class's grid of {class_row['modes']}")
            place = (row["class"], tuple(row["tensor_at"]))
            if places.setdefault(place, i) != i:
                raise fail(f"clips[{i}].tensor_at", f"clip {places[place]}'s place in its class's grid")
            needed.append(f"warp/{i:05d}")
    for k, row in enumerate(meta["classes"]):
        filled = sum(place[0] == k for place in places)
        if "levels" in row and filled != math.prod(map(len, row["levels"])):
            raise fail(f"classes[{k}].levels", f"a grid of {math.prod(map(len, row['levels'])):,} places, "
                                               f"{filled} of them with a clip: its clips fill it")
    return needed


def _check_clip(row: dict, i: int, settings: dict, skeletons: list[dict], n_classes: int, fail) -> list[str]:
    """Rules of one clip row beyond its schema; return the streams it needs."""
    where, n_skeletons = f"clips[{i}]", len(skeletons)
    _check_relative_path(row["path"], f"{where}.path", fail)
    if len(row["bones"]) != len(row["counts"]):
        raise fail(f"{where}.counts", f"{len(row['counts'])} counts for {len(row['bones'])} bones")
    width = sum(row["counts"])
    if width > MAX_VALUES_PER_FRAME or width * row["frames"] > MAX_VALUES_PER_CLIP:
        raise fail(where, f"{row['frames']} frames of {width} values exceed the limits "
                          f"({MAX_VALUES_PER_FRAME} values per frame, {MAX_VALUES_PER_CLIP} per clip)")
    if row["first_frame"] + row["frames"] - 1 > MAX_FRAME_NUMBER:
        raise fail(f"{where}.first_frame", f"frame numbers would pass {MAX_FRAME_NUMBER}")
    if row["skeleton"] >= n_skeletons:
        raise fail(f"{where}.skeleton", f"index {row['skeleton']} but the archive has {n_skeletons} skeletons")
    clip_format = stored_format(skeletons[row["skeleton"]])  # a clip's format is its skeleton's
    for other in input_formats():
        if other.row_field is not None and (other.row_field in row) != (other is clip_format):
            kind = other.name.upper()
            raise fail(f"{where}.{other.row_field}", f"a {kind} clip has this field and a {kind} skeleton, other "
                                                     "clips neither")
    kept = clip_format.check_row(row, i, fail)  # the format's rules, and streams it keeps beside the clip's
    for n, line in enumerate(row["header"]):
        stripped = line.strip(" \t\f\v")
        if "\r" in line or "\n" in line or "\0" in line or (stripped and stripped[0] not in "#:"):
            raise fail(f"{where}.header[{n}]", "a header line is blank, a '#' comment or a ':' keyword, on one line")
    encoding = row["style"]["encoding"]
    for field in ("header", "bones"):
        try:
            "".join(row[field]).encode(encoding)
        except UnicodeEncodeError:
            raise fail(f"{where}.{field}", f"not encodable as {encoding}") from None
    last_frame = row["first_frame"] + row["frames"] - 1
    for n, (first, last, _) in enumerate(row.get("repaired", [])):
        if not row["first_frame"] <= first <= last <= last_frame:
            raise fail(f"{where}.repaired[{n}]", f"frames {first}-{last} are not a run within the clip's "
                                                 f"{row['first_frame']}-{last_frame}")
    for bone, edges in row.get("twist_flips", {}).items():
        if len(edges) % 2 or any(b <= a for a, b in zip(edges, edges[1:])) or (edges and edges[-1] > row["frames"]):
            raise fail(f"{where}.twist_flips", f"ranges of {bone[:40]!r} are not increasing pairs within the clip")
    if settings["lossless"]:
        if ("segments" in row or "twist_flips" in row or "patched_frames" in row or "planted_stances" in row
                or "max_vertex_error_cm" in row or kept):
            raise fail(where, "a lossless clip has no segments, twist flips, patches, stances, vertex error or extra "
                              "root stream")
        return [f"clip/{i:05d}"]
    bounded = "max_error_cm" in settings or "contact_error_cm" in settings or "vertex_error_cm" in settings
    for field, on, setting in (("patched_frames", bounded, "max_error_cm, contact_error_cm or vertex_error_cm"),
                               ("planted_stances", settings.get("plant_feet"), "plant_feet"),
                               ("repaired", settings.get("repair_glitches"), "repair_glitches")):
        if field in row and not on:  # what the spec does not define is refused, not ignored
            raise fail(f"{where}.{field}", f"written only with settings.{setting}, which this archive has not")
    if row.get("patched_frames", 0) > row["frames"]:
        raise fail(f"{where}.patched_frames", f"{row['patched_frames']} patched frames in a clip of {row['frames']}")
    patches = [f"patch/{i:05d}"] if "patched_frames" in row else []
    patches += kept
    if row.get("planted_stances", 0) > row["frames"]:
        raise fail(f"{where}.planted_stances", f"{row['planted_stances']} stances in a clip of {row['frames']} frames")
    patches += [f"plant/{i:05d}"] if "planted_stances" in row else []
    if "segments" not in row:
        if row["class"] >= n_classes:
            raise fail(f"{where}.class", f"index {row['class']} but the archive has {n_classes} classes")
        return [f"clip/{i:05d}", *patches]
    if not settings.get("segment") or "segment_overlap" not in row:
        raise fail(f"{where}.segments", "segments need the setting 'segment' and the row's 'segment_overlap'")
    if row["segment_overlap"] > min(part["frames"] for part in row["segments"]):
        raise fail(f"{where}.segment_overlap", "reaches past a whole segment (each segment would decode the take)")
    first, streams = 0, []
    for s, part in enumerate(row["segments"]):
        stream = f"clip/{i:05d}/{s:03d}"
        if part["first"] != first or part["stream"] != stream or part["class"] >= n_classes:
            raise fail(f"{where}.segments[{s}]", f"expected first frame {first}, stream {stream!r} and a class "
                                                 f"below {n_classes}")
        first += part["frames"]
        streams.append(stream)
    if first != row["frames"]:
        raise fail(f"{where}.segments", f"segments cover {first} frames, the clip has {row['frames']}")
    if row["class"] != row["segments"][0]["class"]:
        raise fail(f"{where}.class", "a segmented take's class is its first segment's")
    return streams + patches


def _check_skeleton_entry(entry: dict, k: int, lossless: bool, fail) -> None:
    """A skeleton's entry names an input format mcz reads (or none: an ASF) and has that format's
    fields (`InputFormat.entry_fields`), no others."""
    input_format = stored_format(entry)
    if input_format is None:
        known = ", ".join(f.name for f in input_formats() if not f.asf_skeletons)
        raise fail(f"skeletons[{k}].format", f"{entry['format'][:40]!r} is not a format an entry names ({known}; "
                                             "an ASF's names none)")
    fields = {"name", *(() if input_format.asf_skeletons else ("format",)), *input_format.entry_fields}
    if entry.keys() != fields:
        raise fail(f"skeletons[{k}]", f"{input_format.skeleton_kind} entries have exactly {', '.join(sorted(fields))}")
    input_format.check_entry(entry, k, lossless, fail)


def _check_relative_path(path: str, field: str, fail) -> None:
    """A stored path names a file below the output folder: relative, and no part empty, '.' or '..'."""
    if not path or len(path.encode("utf-8", "surrogatepass")) > MAX_PATH_BYTES:
        raise fail(field, f"a path is 1 to {MAX_PATH_BYTES} bytes long")
    for part in path.split("/"):
        _check_file_name(part, field, fail, whole=path)


def _check_file_name(name: str, field: str, fail, whole: str | None = None) -> None:
    shown = repr((whole or name)[:80])
    if name in ("", ".", ".."):
        raise fail(field, f"{shown} leaves the output folder or names no file" if whole or name else "empty name")
    try:  # a name read from disk keeps bytes that are not UTF-8 as surrogate escapes (os.fsdecode)
        size = len(name.encode("utf-8", "surrogateescape"))
    except UnicodeEncodeError:
        raise fail(field, f"{shown} is not a file name this system can write") from None
    if "/" in name or "\0" in name or size > MAX_NAME_BYTES:
        raise fail(field, f"{shown} is not one file name of at most {MAX_NAME_BYTES} bytes without '/' or NUL")


def _output_files(meta: dict, fail) -> dict[str, tuple[str, int]]:
    """Every file a full decompress writes: relative path -> ("motion", clip) or ("skeleton", skeleton).

    Two things may not share a path, and no file may be the folder of another, so no file
    written replaces or hides another one of the same archive.
    """
    files: dict[str, tuple[str, int]] = {}

    def claim(path: str, what: tuple[str, int], field: str) -> None:
        kind, index = files.setdefault(path, what)
        if (kind, index) != what:
            raise fail(field, f"{path[:80]!r} is written twice (already {'clip' if kind == 'motion' else 'skeleton'} "
                              f"{index}'s file)")

    for i, row in enumerate(meta["clips"]):
        claim(row["path"], ("motion", i), f"clips[{i}].path")
    for i, row in enumerate(meta["clips"]):
        entry = meta["skeletons"][row["skeleton"]]
        if stored_format(entry).skeleton_suffix is None:
            continue  # the clip's file holds its skeleton (BVH)
        folder = row["path"].rpartition("/")[0]
        claim(f"{folder}/{entry['name']}".lstrip("/"), ("skeleton", row["skeleton"]), f"clips[{i}].skeleton")
    folders = set()
    for path in files:
        while "/" in path:
            path = path.rpartition("/")[0]
            folders.add(path)
    clash = sorted(folders & files.keys())
    if clash:
        raise fail("clips", f"{clash[0][:80]!r} is both a file and a folder")
    return files


# The clips table's columns: where, then each clip's achieved joint errors in cm (an older format
# has fewer: `legacy.Format.contents_columns`).
CONTENTS_COLUMNS = ["path", "frames", "fps", "skeleton", "mean_error_cm", "p99_error_cm", "max_error_cm"]
# Errors to 10 micrometres: enough to read, and the shared CMU archive's index is 550 bytes (0.2 %)
# smaller than with meta's digits (measured: 3,731 against 4,279 bytes deflated). Meta keeps them all.
CONTENTS_ERROR_DECIMALS = 3


def contents_of(meta: dict, columns: int = len(CONTENTS_COLUMNS)) -> dict:
    """What the index's `contents` holds: the clips table, for `h5dump -a index` and anyone
    without mcz to read. Readers never use it; `mcz test` checks it against meta. `columns`:
    how many of `CONTENTS_COLUMNS` the archive's format has (default: the newest's, all)."""
    fps, skeletons = meta["settings"]["fps"], meta["skeletons"]

    def errors(row: dict) -> list:
        return [None if error is None else round(error, CONTENTS_ERROR_DECIMALS)
                for error in (row["error_cm"], row.get("p99_error_cm"), row["max_error_cm"])]

    return {"columns": CONTENTS_COLUMNS[:columns],
            "clips": [[row["path"], row["frames"], row.get("fps", fps), skeletons[row["skeleton"]]["name"],
                       *errors(row)][:columns] for row in meta["clips"]]}
