"""Old archive formats, decode only, in one place (as zstd keeps `lib/legacy`, and ACL reads old
versions behind one version selector).

`format_of(version)` is the one switch: it says what an archive of `format_version` lays out or
means differently from the newest format (`formats.mcz.FORMAT_VERSION`, the only one written),
and is the only code that compares format versions. The container (`formats/mcz.py`) and the
reader (`archive/reader.py`, `archive/meta.py`) read its answer; what an old format lays out
differently is decoded here: `container` (formats 1 to 6's index) and `streams` (formats 1 and
2's class and clip streams, format 1's coefficient coder, formats 1 to 9's `skeletons`).

| format_version | differs from the newest in |
|---|---|
| 1 | as format 2 but: class and clip streams of `streams.class_v1` and `clip_v1` (coder "zstd", `streams.ZstdCoder`); no `coefficient_coder` setting (read as "zstd") |
| 2 | as format 3 but: class streams of `streams.class_v2`; coder "context" only |
| 3 | as format 4 but: no `axes_from_positions` setting (read as false: every bone stores its axis) |
| 4 to 6 | as format 7 but: the container of `container` (a header CRC, the index a zstd frame in a dataset); `meta` and `skeletons` without dictionaries, `skeletons` a JSON list of texts (`streams.skeleton_texts`) |
| 7 to 9 | as format 10 but: no `contents` in the index; `skeletons` the texts packed (`streams.skeleton_texts`) |
| 10, 11 | the index's clips table without its three error columns |
| 12 | as format 13 but: no vertex error (`max_vertex_error_cm` in rows, `vertex_error_cm` and `shell_cm` in settings); no transform `dct-edges` |
| 13 | nothing: it is the newest |

Every format also refuses the meta fields later ones added (`FIELDS_ADDED_IN`).

The lossless channel code keeps its own layout number in each stream (1: the first format-1
writers, before the rANS residual coder; 2: every later writer), read by `mocapzip.codec.lossless`.
This `__init__` imports nothing of mocapzip (its modules do), so that the container, below every
other package, can ask it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

# The meta fields each format added: an older archive carrying one is refused, as that format's readers did.
FIELDS_ADDED_IN = {
    2: (("settings", "coefficient_coder"),),
    4: (("settings", "axes_from_positions"), ("clips", "twist_flips")),
    5: (("settings", "max_error_cm"), ("clips", "p99_error_cm"), ("clips", "patched_frames")),
    6: (("settings", "contact_error_cm"), ("settings", "repair_glitches"), ("clips", "repaired")),
    7: (("settings", "fps_from_files"), ("clips", "fps")),
    8: (("skeletons", "format"), ("clips", "bvh")),
    9: (("settings", "plant_feet"), ("clips", "planted_stances")),
    11: (("settings", "model"), ("settings", "modes"), ("classes", "model"), ("classes", "modes"),
         ("classes", "levels"), ("clips", "tensor_at")),
    13: (("settings", "vertex_error_cm"), ("settings", "shell_cm"), ("clips", "max_vertex_error_cm")),
}
# The transforms each format added (`settings.transform.id`): an older lossy archive naming one is refused.
TRANSFORMS_ADDED_IN = {13: ("dct-edges",)}
# What an archive from before a setting was added meant by its absence, where that is not
# `archive.settings.Settings`' default.
MEANT_WHEN_ABSENT = {"coefficient_coder": "zstd", "axes_from_positions": False}


@dataclass(frozen=True)
class Format:
    """What format `version` does differently from the newest; each default is the newest's.

    Layouts are named by the format that first wrote them."""

    version: int
    container: int = 7  # 1: formats 1 to 6's index (`container`); 7: `formats.mcz`'s
    index_contents: bool = True  # the index may hold `contents`, a clips table (format 10 on)
    contents_columns: int = 7  # how many of `archive.meta.CONTENTS_COLUMNS` that table has
    stream_dictionaries: bool = True  # `meta` and `skeletons` are zstd frames on the format's dictionaries
    skeletons: int = 10  # 1: a JSON list, 7: packed texts (`streams.skeleton_texts`); 10: `archive.skeletons`
    class_stream: int = 3  # 1, 2: `streams.CLASS_DECODERS`; 3: `codec.basis.ClassBasis.decode`
    clip_stream: int = 2  # 1: `streams.CLIP_DECODERS`; 2: `codec.clip_stream.CodedClip.from_payload`
    coders: tuple[str, ...] = ("context", "primed")  # the coefficient coders the format writes
    settings_defaults: dict = field(default_factory=dict)  # settings it never stores, as it meant them
    later_fields: tuple[tuple[int, str, str], ...] = ()  # (format, part, name): meta fields of later formats
    later_transforms: tuple[str, ...] = ()  # transforms only later formats write


def format_of(version: int) -> Format:
    """What format `version` (1 to `FORMAT_VERSION`, checked by the container) does differently
    from the newest: the one place that compares format versions."""
    later_fields = tuple((added, part, name) for added, fields in FIELDS_ADDED_IN.items() if version < added
                         for part, name in fields)
    return Format(
        version=version,
        container=1 if version <= 6 else 7,
        index_contents=version >= 10,
        contents_columns=7 if version >= 12 else 4,
        stream_dictionaries=version >= 7,
        skeletons=1 if version <= 6 else 7 if version <= 9 else 10,
        class_stream=min(version, 3),
        clip_stream=min(version, 2),
        coders={1: ("zstd",), 2: ("context",)}.get(version, ("context", "primed")),
        settings_defaults={name: MEANT_WHEN_ABSENT[name] for _, part, name in later_fields
                           if part == "settings" and name in MEANT_WHEN_ABSENT},
        later_fields=later_fields,
        later_transforms=tuple(t for added, ids in TRANSFORMS_ADDED_IN.items() if version < added for t in ids),
    )
