"""Hostile archives: each case a way a stranger's .mcz could attack `mcz test`, `info` and `decompress`.

Every archive is written by the project's own writer (`formats.mcz.write_archive`) from a
golden archive with one thing changed, so every checksum is valid and `mcz` has only its
own checks to stand on. tests/test_hostile_archives.py runs each case in a child process under
memory and time limits; `python tests/hostile_archives.py` does the same and prints each
case's outcome, time and peak memory.
"""

from __future__ import annotations

import json
import os
import resource
import struct
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import zstandard

import limited
from mocapzip.codec.entropy import zstd as entropy
from mocapzip.codec.clip_stream import CodedClip
from mocapzip.archive.dictionaries import dictionary
from mocapzip.archive.meta import contents_of
from mocapzip.archive.skeletons import TEMPLATES_AND_NUMBERS, WHOLE_TEXTS, encode_skeletons, template_dictionary
from mocapzip.codec.entropy.coefficients import Priors, encode_matrices
from mocapzip.codec.lossless import encode_channels
from mocapzip.codec.patches import FramePatches
from mocapzip.codec.tensor import TensorModel
from mocapzip.formats.mcz import ArchiveReader, write_archive

GOLDEN = Path(__file__).parent / "golden"
# format 7's; two clips, 09_01 (148 frames, 62 values, 25 of them patched) and 64_01
BASES = {"lossy": GOLDEN / "lossy_v7.mcz", "lossless": GOLDEN / "lossless_v7.mcz",
         # format 8's: the same two clips, then a BVH one (clip 2, skeleton 0: Bandai's walk-back_normal_001,
         # 31 frames, whose extra root moves, so it has a stream extra_root/00002)
         "lossy_bvh": GOLDEN / "lossy_v8.mcz", "lossless_bvh": GOLDEN / "lossless_v8.mcz",
         # format 9's: the same three clips; 64_01 (448 frames, 4 foot joints) has one stance, in plant/00001
         "lossy_plant": GOLDEN / "lossy_v9.mcz",
         # format 11's: the same three clips; 09_01 and 64_01 (clips 0 and 1) are class 1, a tensor model of
         # one mode (subject, 2 levels), with streams tensor/0001, warp/00000 and warp/00001; the BVH clip
         # is class 0, PCA
         "lossy_tensor": GOLDEN / "lossy_v11.mcz"}
BASE_PATCHED = 45  # the lossy base's clip 0 (09_01): its row's patched_frames
MEMORY_LIMIT = 1 << 30  # address space of each child: far below what any bomb here would take
COMMANDS = (("test", "-q"), ("info", "--json"), ("decompress", "-q", "-o"))


@dataclass
class Case:
    name: str
    base: str  # "lossy" or "lossless"
    edit: Callable[[dict, dict], None]  # changes (meta, streams) in place; meta is written back as JSON
    section: str  # the part of the archive the one-line error must name
    prepare: Callable[[Path], None] | None = None  # sets up the output folder before decompress
    decoded: bool = False  # found only by decoding a clip: `info`, which decodes none, may list the archive
    output: bool = False  # a fault of the output folder, not the archive: only decompress can see it


def _set(path: str, value) -> Callable[[dict, dict], None]:
    """An edit that sets one field of meta, e.g. "clips.0.path"."""
    keys = [int(k) if k.isdigit() else k for k in path.split(".")]

    def edit(meta: dict, streams: dict) -> None:
        target = meta
        for key in keys[:-1]:
            target = target[key]
        target[keys[-1]] = value

    return edit


def _delete(path: str) -> Callable[[dict, dict], None]:
    keys = [int(k) if k.isdigit() else k for k in path.split(".")]

    def edit(meta: dict, streams: dict) -> None:
        target = meta
        for key in keys[:-1]:
            target = target[key]
        del target[keys[-1]]

    return edit


def _stream(name: str, data: bytes | Callable[[], bytes] | None) -> Callable[[dict, dict], None]:
    """An edit that replaces a stream's bytes, or makes them when the case is built (None: removes the stream)."""

    def edit(meta: dict, streams: dict) -> None:
        if data is None:
            del streams[name]
        else:
            streams[name] = data() if callable(data) else data

    return edit


def _both(*edits) -> Callable[[dict, dict], None]:
    def edit(meta: dict, streams: dict) -> None:
        for one in edits:
            one(meta, streams)

    return edit


def _clip_frames(i: int, frames: int | Callable[[int], int]) -> Callable[[dict, dict], None]:
    """An edit that gives clip i `frames` frames (or `frames` of its count), its class's count of
    frames changed with it: meta stays consistent, so what is at fault is a stream."""

    def edit(meta: dict, streams: dict) -> None:
        row = meta["clips"][i]
        count = frames(row["frames"]) if callable(frames) else frames
        meta["classes"][row["class"]]["frames"] += count - row["frames"]
        row["frames"] = count

    return edit


def _segmented_09_01(row_class: int = 1, class_frames: tuple[int, int] = (121, 538)) -> Callable[[dict, dict], None]:
    """An edit of the format-8 base: clip 0 (09_01, 148 frames, class 1) becomes a take cut at
    frame 74, its first segment in class 1 and its second in class 0 (the BVH clip's), overlap 16,
    its streams clip/00000/000 and /001 (copies of its whole-clip stream, so a decoder refuses
    them); the row's `class` and the classes' frames as given. Coded, with the overlap, the
    segments span frames 0-89 and 58-147: class 0 codes 31 + 90 = 121 frames, class 1
    448 + 90 = 538, each of two clips."""

    def edit(meta: dict, streams: dict) -> None:
        meta["settings"]["segment"] = True
        row = meta["clips"][0]
        row.update({"class": row_class, "segment_overlap": 16, "segments": [
            {"first": 0, "frames": 74, "class": 1, "stream": "clip/00000/000", "error_cm": 0, "max_error_cm": 0},
            {"first": 74, "frames": 74, "class": 0, "stream": "clip/00000/001", "error_cm": 0, "max_error_cm": 0}]})
        streams["clip/00000/000"] = streams["clip/00000/001"] = streams.pop("clip/00000")
        for k, frames in enumerate(class_frames):
            meta["classes"][k].update(clips=2, frames=frames)

    return edit


def _class_of_no_clip(meta: dict, streams: dict) -> None:
    """A second class, its basis a copy of the first's, that no clip is in."""
    meta["classes"].append({**meta["classes"][0], "name": "empty", "clips": 0, "frames": 0})
    streams["class/0001"] = streams["class/0000"]


def _lossless_frames(frames: int) -> Callable[[dict, dict], None]:
    """The first clip's lossless stream, re-packed to claim `frames` frames (151 bytes or so)."""

    def edit(meta: dict, streams: dict) -> None:
        sections = entropy.unpack_blobs(streams["clip/00000"])
        header = entropy.decode_ints(sections[0])
        header[1] = frames
        streams["clip/00000"] = entropy.pack_blobs([entropy.encode_ints(header), *sections[1:]])
        meta["clips"][0]["frames"] = min(frames, meta["clips"][0]["frames"])

    return edit


def _without_root_track(meta: dict, streams: dict) -> None:
    """Clip 0's stream re-coded with its pose matrix only, in an archive whose representation has a root track."""
    priors = Priors.decode(entropy.decode_bytes(streams["priors"]))
    coded = CodedClip.from_payload(streams["clip/00000"], "primed", priors=priors)
    streams["clip/00000"] = CodedClip(coded.pose_step, coded.pose_ints, coded.root_step, None).payload("primed", priors)


def _stances(*stored: tuple[int, int, int]) -> Callable[[], bytes]:
    """A plant stream of stances stored as (foot, gap, frames)."""
    return lambda: encode_matrices([np.array(stored, np.int64).reshape(-1, 3)])


def _patches(frames: list[int], levels: list[int], value: int) -> Callable[[], bytes]:
    """A patch stream for clip 0 (62 values) of as many frames as the row claims (BASE_PATCHED):
    `frames` and `levels` first, the others after them; every int `value`."""

    def make() -> bytes:
        n = BASE_PATCHED
        first = list(frames) + list(range(max(frames) + 1, max(frames) + n + 1 - len(frames)))
        every = list(levels) + [0] * (n - len(levels))
        return FramePatches(1.0, np.array(first), np.array(every), np.full((n, 62), value, np.int64)).payload()

    return make


def _zstd_bomb(size: int) -> bytes:
    """One zstd frame of `size` spaces, without the content size in its header; built in pieces."""
    compressor = zstandard.ZstdCompressor(level=3, write_content_size=False)
    chunk = b" " * (1 << 24)
    parts = compressor.compressobj()
    out = [parts.compress(chunk) for _ in range(size // len(chunk))]
    return b"".join([*out, parts.flush()])


def _wide_basis() -> bytes:
    """A class basis (as `ClassBasis.encode` lays it out) of one zero direction over poses of 2^20
    values: within the basis limits, but decoding a clip with it would take 2^20 x frames values."""
    zeros = np.zeros((1 << 20, 1), np.int64)  # mean, reference offsets, basis integers
    return struct.pack("<II", len(zeros), 1) + np.ones(1, "<f4").tobytes() + encode_matrices([zeros] * 3)


def _meta_stream(text: bytes) -> bytes:
    """A `meta` stream holding `text`, as format 7 codes it (zstd with the meta dictionary)."""
    return entropy.encode_bytes(text, dictionary("meta.json"))


def _json_stream(value) -> bytes:
    return _meta_stream(json.dumps(value).encode())


def _skeletons_stream(texts: list[bytes]) -> bytes:
    """A `skeletons` stream of these texts in layout 0, whole texts (format 10: a layout byte, then
    what formats 7 to 9 held: packed, zstd with the ASF dictionary)."""
    return bytes([WHOLE_TEXTS]) + _packed_texts(texts)


def _packed_texts(texts: list[bytes]) -> bytes:
    return entropy.encode_bytes(entropy.pack_blobs(texts), dictionary("asf.txt"))


def _texts(stream: bytes) -> list[bytes]:
    """The texts of a layout-0 `skeletons` stream."""
    return entropy.unpack_blobs(entropy.decode_bytes(stream[1:], dictionary=dictionary("asf.txt")))


def _predicted_skeletons(change: Callable[[bytes], bytes]) -> Callable[[dict, dict], None]:
    """An edit that codes the skeletons in layout 1 (templates and numbers), then changes that stream."""

    def edit(meta: dict, streams: dict) -> None:
        texts = _texts(streams["skeletons"])
        coded = encode_skeletons(texts, [entry.get("format") != "bvh" for entry in meta["skeletons"]])
        assert coded[0] == TEMPLATES_AND_NUMBERS
        streams["skeletons"] = change(coded)

    return edit


def _many_numbers(count: int) -> Callable[[bytes], bytes]:
    """Layout 1 with one template of `count` numbers and a payload of zeros."""

    def change(coded: bytes) -> bytes:
        frame = entropy.encode_bytes(entropy.pack_blobs([b"\0" * count, b"x"]), template_dictionary())
        head = bytearray([TEMPLATES_AND_NUMBERS])
        entropy.write_varint(head, len(frame))
        return bytes(head) + frame + bytes(64)

    return change


def _symlink_outside(out: Path) -> None:
    out.mkdir(parents=True)
    (out.parent / "outside").mkdir()
    (out / "09").symlink_to(out.parent / "outside", target_is_directory=True)


def cases(watched: Path) -> list[Case]:
    """Every hostile case; `watched` is the temporary tree the checks watch (absolute paths point into it)."""
    escaped = (watched / "escaped").as_posix()
    c = []
    # 1. Paths that leave the output folder, or name no file.
    for label, path in (("dotdot", "../../x.amc"), ("dotdot_inside", "a/../../../x.amc"),
                        ("absolute", f"{escaped}/x.amc"), ("empty", ""), ("dot", "."), ("dot_folder", "./x.amc"),
                        ("empty_part", "a//x.amc"), ("nul", "x\0.amc"), ("long_name", "x" * 300 + ".amc")):
        c.append(Case(f"clip_path_{label}", "lossy", _set("clips.0.path", path), "meta: clips[0].path"))
    for label, name in (("absolute", f"{escaped}/x.asf"), ("dotdot", ".."), ("with_folder", "../x.asf"),
                        ("empty", "")):
        c.append(Case(f"skeleton_name_{label}", "lossless", _set("skeletons.0.name", name), "meta: skeletons[0].name"))
    c.append(Case("symlink_in_output_folder", "lossy", _set("clips.0.path", "09/x.amc"), "symbolic link",
                  prepare=_symlink_outside, output=True))
    # 2. Hangs: a lossless stream that claims far more frames than it holds.
    c.append(Case("lossless_claims_1e12_frames", "lossless", _lossless_frames(10**12), "clip/00000", decoded=True))
    c.append(Case("lossless_claims_3e8_frames", "lossless", _lossless_frames(3 * 10**8), "clip/00000", decoded=True))
    # 3. Memory bombs.
    c.append(Case("lossy_1e7_frames", "lossy", _set("clips.0.frames", 10**7), "meta: clips[0].frames"))
    c.append(Case("lossy_frames_beyond_values_limit", "lossy", _set("clips.0.frames", 500_000), "meta: clips[0]"))
    c.append(Case("lossy_stream_shorter_than_its_frames", "lossy", _clip_frames(0, 100_000), "clip/00000",
                  decoded=True))
    c.append(Case("meta_unpacks_to_2GB", "lossy", _stream("meta", lambda: _zstd_bomb(2 << 30)), "meta"))
    c.append(Case("skeletons_unpack_to_300MB", "lossless",
                  _stream("skeletons", lambda: bytes([WHOLE_TEXTS]) + _zstd_bomb(300 << 20)), "skeletons"))
    c.append(Case("meta_fake_content_size", "lossy", _stream("meta", _fake_content_size(1 << 40)), "meta"))
    # 4. Meta of the wrong shape.
    for label, edit, section in (
        ("no_tool", _delete("tool"), "meta: (top level): must contain ['tool'] properties"),
        ("encoding_rot13", _set("clips.0.style.encoding", "rot13"), "meta: clips[0].style.encoding"),
        ("skeleton_99", _set("clips.0.skeleton", 99), "meta: clips[0].skeleton"),
        ("first_frame_string", _set("clips.0.first_frame", "1"), "meta: clips[0].first_frame"),
        ("skeleton_index_float", _set("clips.0.skeleton", 0.0), "meta: clips[0].skeleton"),
        ("overlap_beyond_segments", _both(_set("settings.segment", True), _set("clips.0.segment_overlap", 10**5),
                                          _set("clips.0.segments", [
                                              {"first": 0, "frames": 74, "class": 0, "stream": "clip/00000/000",
                                               "error_cm": 0, "max_error_cm": 0},
                                              {"first": 74, "frames": 74, "class": 0, "stream": "clip/00000/001",
                                               "error_cm": 0, "max_error_cm": 0}])),
         "meta: clips[0].segment_overlap"),
        ("clips_dict", _set("clips", {"0": {}}), "meta: clips"),
        ("no_settings", _delete("settings"), "meta: (top level): must contain ['settings'] properties"),
        ("transform_none", _set("settings.transform", {"id": "none"}), "meta: settings.transform"),
        ("wavelet_unknown", _set("settings.transform", {"id": "dwt", "wavelet": "evil", "level": None}),
         "meta: settings.transform.wavelet"),
        ("knot_spacing_huge", _set("settings.transform", {"id": "poly", "knot_spacing": 1 << 30}),
         "meta: settings.transform"),
        ("representation_unknown", _set("settings.representation", "quaternions"), "meta: settings.representation"),
        ("error_negative", _set("settings.error_cm", -1), "meta: settings.error_cm"),
        ("class_99", _set("clips.0.class", 99), "meta: clips[0].class"),
        ("counts_short", _set("clips.0.counts", [6]), "meta: clips[0].counts"),
        ("counts_huge", _set("clips.0.counts", [7] * 29 + [10**6]), "meta: clips[0].counts"),
        ("bone_with_space", _set("clips.0.bones.1", "lower back"), "meta: clips[0].bones"),
        ("bone_digits", _set("clips.0.bones.1", "17"), "meta: clips[0].bones"),
        ("header_not_a_comment", _set("clips.0.header", ["hello"]), "meta: clips[0].header[0]"),
        ("digits_99", _set("clips.0.style.digits", 99), "meta: clips[0].style.digits"),
        ("newline_tab", _set("clips.0.style.newline", "\t"), "meta: clips[0].style.newline"),
        # written verbatim between each bone's name and its values: blanks or tabs, 1 to 16
        ("name_separator_ideographic_space", _set("clips.0.style.name_separator", "\u3000"),
         "meta: clips[0].style.name_separator"),
        ("name_separator_17_blanks", _set("clips.0.style.name_separator", " " * 17),
         "meta: clips[0].style.name_separator"),
        ("name_separator_with_a_line_end", _set("clips.0.style.name_separator", " \n"),
         "meta: clips[0].style.name_separator"),
        ("unknown_row_field", _set("clips.0.evil", 1), "meta: clips[0]"),
        ("twist_flips_beyond_clip", _set("clips.0.twist_flips", {"rthumb": [0, 10**6]}), "meta: clips[0].twist_flips"),
        ("auto_coder_in_lossy", _set("settings.coefficient_coder", "auto"), "meta: settings.coefficient_coder"),
        ("format_1_coder_in_format_4", _both(_set("settings.coefficient_coder", "zstd"), _stream("priors", None)),
         "meta: settings.coefficient_coder"),
        ("no_axes_from_positions", _delete("settings.axes_from_positions"), "meta: settings.axes_from_positions"),
        ("dead_zone_half", _set("settings.dead_zone", 0.5), "meta: settings.dead_zone"),
        ("segments_without_setting", _set("clips.0.segments", [{"first": 0, "frames": 1, "class": 0, "error_cm": 0,
                                                                "max_error_cm": 0, "stream": "clip/00000/000"}] * 2),
         "meta: clips[0].segments"),
    ):
        c.append(Case(f"meta_{label}", "lossy", edit, section))
    c.append(Case("meta_nested_200000_deep", "lossy", _stream("meta", _meta_stream(b"[" * 200_000 + b"]" * 200_000)),
                  "meta"))
    c.append(Case("meta_nan", "lossy", _stream("meta", _meta_stream(b'{"error_cm": NaN}')), "meta"))
    c.append(Case("meta_not_json", "lossy", _stream("meta", _meta_stream(b"\xff{")), "meta"))
    c.append(Case("meta_is_a_list", "lossy", _stream("meta", _json_stream([])), "meta: (top level)"))
    c.append(Case("meta_not_zstd", "lossy", _stream("meta", b"{}"), "meta"))
    c.append(Case("bone_not_in_skeleton", "lossy", _set("clips.0.bones.1", "tail"), "clip/00000", decoded=True))
    c.append(Case("clip_stream_3_bytes", "lossless", _stream("clip/00000", b"abc"), "clip/00000", decoded=True))
    c.append(Case("class_stream_3_bytes", "lossy", _stream("class/0000", b"abc"), "class/0000", decoded=True))
    c.append(Case("clip_without_root_track", "lossy", _without_root_track, "clip/00000", decoded=True))
    c.append(Case("priors_3_bytes", "lossy", _stream("priors", b"abc"), "priors", decoded=True))
    c.append(Case("class_basis_of_a_million_pose_values", "lossy",
                  _both(_stream("class/0000", _wide_basis), _set("classes.0.components", 1)), "clip/00000",
                  decoded=True))
    c.append(Case("patch_stream_3_bytes", "lossy", _stream("patch/00000", b"abc"), "patch/00000", decoded=True))
    c.append(Case("patch_stream_missing", "lossy", _stream("patch/00000", None), "patch/00000: stream missing"))
    c.append(Case("patches_claimed_beyond_the_clip", "lossy", _set("clips.0.patched_frames", 149),
                  "meta: clips[0].patched_frames"))
    c.append(Case("patches_fewer_than_stored", "lossy", _set("clips.0.patched_frames", BASE_PATCHED - 1), "patch/00000", decoded=True))
    c.append(Case("patched_frame_past_the_end", "lossy", _stream("patch/00000", _patches([147, 150], [0, 0], 1)),
                  "patch/00000", decoded=True))
    c.append(Case("patch_level_41", "lossy", _stream("patch/00000", _patches([3, 4], [0, 41], 1)), "patch/00000",
                  decoded=True))
    c.append(Case("patch_moves_values_past_1e9", "lossy", _stream("patch/00000", _patches([3, 4], [0, 0], 2**61)),
                  "clip/00000", decoded=True))
    # 09_01 (clip 0: 148 frames, 4 foot joints) given one stance, whose stream is at fault
    one_stance = _set("clips.0.planted_stances", 1)
    c.append(Case("plant_stream_3_bytes", "lossy_plant", _both(one_stance, _stream("plant/00000", b"abc")),
                  "plant/00000", decoded=True))
    c.append(Case("plant_stream_missing", "lossy_plant", one_stance, "plant/00000: stream missing"))
    c.append(Case("stances_claimed_beyond_the_clip", "lossy_plant", _set("clips.1.planted_stances", 449),
                  "meta: clips[1].planted_stances"))
    for label, stance in (("stance_past_the_end", (0, 140, 20)), ("stance_of_an_unknown_foot", (9, 0, 5)),
                          ("stance_of_no_frames", (0, 3, 0))):
        c.append(Case(label, "lossy_plant", _both(one_stance, _stream("plant/00000", _stances(stance))),
                      "plant/00000", decoded=True))
    c.append(Case("stances_in_a_lossless_archive", "lossless", _set("clips.0.planted_stances", 1), "meta: clips[0]"))
    c.append(Case("patches_in_a_lossless_archive", "lossless", _set("clips.0.patched_frames", 1), "meta: clips[0]"))
    c.append(Case("repaired_range_of_two_numbers", "lossy", _set("clips.1.repaired.0", [1, 448]),
                  "meta: clips[1].repaired[0]"))
    c.append(Case("repaired_error_negative", "lossy", _set("clips.1.repaired.0", [1, 448, -1]),
                  "meta: clips[1].repaired[0]"))
    c.append(Case("repaired_run_backwards", "lossy", _set("clips.1.repaired.0", [448, 1, 1.0]),
                  "meta: clips[1].repaired[0]"))
    c.append(Case("repaired_run_past_the_clip", "lossy", _set("clips.1.repaired.0", [1, 449, 1.0]),
                  "meta: clips[1].repaired[0]"))
    c.append(Case("contact_error_zero", "lossy", _set("settings.contact_error_cm", 0), "meta: settings.contact_error_cm"))
    # 5. Meta that is well formed but inconsistent.
    c.append(Case("two_clips_one_path", "lossy", _set("clips.1.path", "09_01.amc"), "meta: clips[1].path"))
    c.append(Case("clip_path_is_a_skeleton", "lossy", _set("clips.1.path", "09.asf"), "meta: clips"))
    c.append(Case("file_and_folder", "lossy", _set("clips.1.path", "09_01.amc/x.amc"), "meta: clips"))
    c.append(Case("two_skeletons_one_name", "lossless", _set("skeletons.1.name", "09.asf"), "meta: clips[1].skeleton"))
    c.append(Case("header_with_newline", "lossy", _set("clips.0.header.0", "# a\n1\nroot 0 0 0 0 0 0"),
                  "meta: clips[0].header[0]"))
    c.append(Case("header_with_cr", "lossless", _set("clips.0.header.0", "# a\rb"), "meta: clips[0].header[0]"))
    # a class's counts that are not its rows' (format 7's one class: both clips, 148 + 448 frames, 18 components)
    c.append(Case("class_components_one_fewer", "lossy", _set("classes.0.components", 17), "meta: classes[0].components",
                  decoded=True))
    c.append(Case("class_components_zero", "lossy", _set("classes.0.components", 0), "meta: classes[0].components",
                  decoded=True))
    c.append(Case("class_clips_one_more", "lossy", _set("classes.0.clips", 3), "meta: classes[0].clips"))
    c.append(Case("class_frames_one_fewer", "lossy", _set("classes.0.frames", 595), "meta: classes[0].frames"))
    c.append(Case("class_of_no_clip", "lossy", _class_of_no_clip, "meta: classes[1]"))
    c.append(Case("classes_in_a_lossless_archive", "lossless",
                  _set("classes", [{"name": "pooled", "components": 18, "clips": 2, "frames": 596}]), "meta: classes"))
    # a take cut in two, its segments in two classes: counted with their overlap, meta holds and the
    # copied streams are what a decoder refuses; counted without it, or the row's class not its first
    # segment's, meta is refused
    c.append(Case("segments_in_two_classes", "lossy_bvh", _segmented_09_01(), "clip/00000/000", decoded=True))
    c.append(Case("segments_counted_without_their_overlap", "lossy_bvh", _segmented_09_01(class_frames=(105, 522)),
                  "meta: classes[0].frames"))
    c.append(Case("segmented_take_not_in_its_first_segments_class", "lossy_bvh", _segmented_09_01(row_class=0),
                  "meta: clips[0].class"))
    c.append(Case("skeletons_stream_missing", "lossless", _stream("skeletons", None), "skeletons: stream missing"))
    c.append(Case("clip_stream_missing", "lossless", _stream("clip/00001", None), "clip/00001: stream missing"))
    c.append(Case("priors_missing", "lossy", _stream("priors", None), "priors: stream missing"))
    c.append(Case("skeletons_one_short", "lossless", _stream("skeletons", _skeletons_stream([b"x"])), "skeletons"))
    c.append(Case("skeletons_packed_wrong", "lossless",
                  _stream("skeletons", lambda: bytes([WHOLE_TEXTS]) + entropy.encode_bytes(b"\x02\x05\x05hello",
                                                                                         dictionary("asf.txt"))),
                  "skeletons: data too short"))
    # format 10's skeletons stream: an unknown layout; its numbers cut short, or one too many;
    # a template of a million numbers in 64 bytes (a reader refuses it before decoding any)
    c.append(Case("skeletons_layout_unknown", "lossless", _stream("skeletons", lambda: b"\x07" + _packed_texts([b"x"])),
                  "skeletons: unknown skeletons layout 7"))
    c.append(Case("skeleton_numbers_cut", "lossless", _predicted_skeletons(lambda coded: coded[:-3]), "skeletons: "))
    c.append(Case("skeleton_numbers_one_byte_more", "lossless", _predicted_skeletons(lambda coded: coded + b"\0"),
                  "skeletons: "))
    c.append(Case("skeleton_numbers_a_million", "lossless", _predicted_skeletons(_many_numbers(10**6)),
                  "skeletons: 1,000,000 skeleton numbers (at most 262,144)"))
    c.append(Case("skeleton_numbers_of_zeros", "lossless", _predicted_skeletons(_many_numbers(200_000)), "skeletons: "))
    c.append(Case("skeleton_not_asf", "lossy", _stream("skeletons", _skeletons_stream([b"hello", b"hello"])),
                  "skeletons: skeleton 0", decoded=True))
    # 6. BVH clips (format 8): the format-8 base without its AMC clips, so the BVH clip is clip 0.
    # Its hierarchy's unit: null (not known) only where nothing decodes with it, in a lossless archive.
    c.append(Case("bvh_units_null_in_a_lossy_archive", "lossy_bvh", _set("skeletons.0.units", None),
                  "meta: skeletons[0].units"))
    c.append(Case("bvh_units_null_but_inferred", "lossless_bvh", _set("skeletons.0.units", None),
                  "meta: skeletons[0].units_inferred"))
    bones = _bvh_row("bones")
    for label, edit, section, decoded in (
        ("bvh_bones_swapped", _set("clips.0.bones", [bones[0], bones[2], bones[1], *bones[3:]]), "clip/00000", True),
        ("bvh_bone_dropped", _both(_set("clips.0.bones", bones[:-1]), _set("clips.0.counts", _bvh_row("counts")[:-1])),
         "clip/00000", True),
        ("bvh_angle_unit_rad", _set("clips.0.angle_unit", "rad"), "meta: clips[0]", False),
        ("bvh_path_amc", _set("clips.0.path", "walk.amc"), "meta: clips[0].path", False),
        ("bvh_row_on_an_asf_skeleton", _set("clips.0.skeleton", 1), "meta: clips[0].bvh", False),
        ("bvh_skeleton_of_an_unknown_format", _set("skeletons.0.format", "fbx"), "meta: skeletons[0].format", False),
        ("bvh_skeleton_named_amc", _set("skeletons.0.format", "amc"), "meta: skeletons[0].format", False),
        ("bvh_skeleton_without_its_units", _delete("skeletons.0.units"), "meta: skeletons[0]", False),
        ("bvh_frames_in_other_digits", _set("clips.0.bvh.motion", "MOTION\nFrames: \u0663\u0661\nFrame Time: 0.03\n"),
         "meta: clips[0].bvh.motion", False),
        ("bvh_frame_time_1e999", _set("clips.0.bvh.motion", "MOTION\nFrames: 31\nFrame Time: 1e999\n"),
         "meta: clips[0].bvh.motion", False),
        ("bvh_motion_without_its_line_end", _set("clips.0.bvh.motion", "MOTION\nFrames: 31\nFrame Time: 0.03"),
         "meta: clips[0].bvh.motion", False),
        ("bvh_style_with_a_frame_in_it", _set("clips.0.bvh.style.after", "\n1 2 3\n"), "meta: clips[0].bvh.style",
         False),
        # the style's text fields are written verbatim into each frame line: only the blanks the spec names
        ("bvh_trailing_with_a_line_end", _set("clips.0.bvh.style.trailing", " \n"),
         "meta: clips[0].bvh.style.trailing", False),
        ("bvh_trailing_17_blanks", _set("clips.0.bvh.style.trailing", " " * 17), "meta: clips[0].bvh.style.trailing",
         False),
        ("bvh_trailing_form_feed", _set("clips.0.bvh.style.trailing", "\t\x0c"), "meta: clips[0].bvh.style.trailing",
         False),
        ("bvh_after_unicode_line_separator", _set("clips.0.bvh.style.after", "\u2028"),
         "meta: clips[0].bvh.style.after", False),
        ("bvh_hierarchy_without_its_line_end", _skeleton_0(lambda: _bvh_hierarchy().rstrip()), "skeletons: skeleton 0",
         True),
        ("bvh_hierarchy_1000_deep", _skeleton_0(lambda: _deep_hierarchy(1000)), "skeletons: skeleton 0", True),
        ("bvh_hierarchy_of_60MB", _skeleton_0(lambda: b"HIERARCHY\n" + b"} " * (30 << 20)), "skeletons: skeleton 0",
         True),
        ("bvh_extra_root_nan", _stream("extra_root/00000", encode_channels(np.full((31, 6), np.nan))), "clip/00000",
         True),
        ("bvh_extra_root_5_channels", _stream("extra_root/00000", encode_channels(np.zeros((31, 5)))),
         "extra_root/00000", True),
    ):
        c.append(Case(label, "lossy_bvh", _both(_bvh_only, edit), section, decoded=decoded))
    c.append(Case("bvh_lossless_bones_not_its_joints", "lossless_bvh",
                  _both(_bvh_only, _set("clips.0.bones", [f"j{k}" for k in range(len(_bvh_row("bones", "lossless_bvh")))])),
                  "clip/00000", decoded=True))
    # 9. --model tensor (format 11): a grid place, a model or a path that does not fit.
    for label, edit, section, decoded in (
        ("tensor_at_beyond_its_levels", _set("clips.0.tensor_at", [2]), "meta: clips[0].tensor_at", False),
        ("tensor_at_of_two_modes", _set("clips.0.tensor_at", [0, 0]), "meta: clips[0].tensor_at", False),
        ("tensor_at_in_a_pca_class", _set("clips.2.tensor_at", [0]), "meta: clips[2].tensor_at", False),
        ("tensor_class_without_the_setting", _both(_delete("settings.model"), _delete("settings.modes")),
         "meta: classes[0]", False),
        ("tensor_model_without_its_pattern", _delete("settings.modes"), "meta: settings.modes", False),
        ("tensor_pattern_not_a_pattern", _set("settings.modes", "(?P<subject>[0-9]+"), "meta: settings.modes", False),
        ("tensor_pattern_of_no_group", _set("settings.modes", "[0-9]+_01"), "meta: settings.modes", False),
        ("tensor_pattern_of_nine_groups", _set("settings.modes", "".join(f"(?P<m{k}>x)" for k in range(8))
                                               + "(?P<subject>[0-9]+)"), "meta: settings.modes", False),
        ("tensor_mode_not_in_the_pattern", _set("classes.1.modes", ["actor"]), "meta: classes[1].modes", False),
        ("tensor_mode_twice", _both(_set("classes.1.modes", ["subject", "subject"]),
                                    _set("classes.1.levels", [["09", "64"], ["09", "64"]])),
         "meta: classes[1].modes", False),
        ("tensor_level_twice", _set("classes.1.levels", [["09", "09"]]), "meta: classes[1].levels[0]", False),
        ("tensor_stream_missing", _stream("tensor/0001", None), "tensor/0001", False),
        ("tensor_model_of_no_mode", _stream("tensor/0001", _model_of_no_mode), "tensor/0001", True),
        ("tensor_model_of_another_grid", _stream("tensor/0001", _other_grid_model), "tensor/0001", True),
        ("tensor_model_damaged", _stream("tensor/0001", b"\x01\x05"), "tensor/0001", True),
        ("tensor_model_of_zeros", _stream("tensor/0001", _model_of_zeros), "class 1's model", True),
        ("warp_move_not_a_move", _stream("warp/00000", lambda: entropy.encode_bytes(bytes([3]) * 200)), "warp/00000",
         True),
        ("warp_path_ends_short", _stream("warp/00000", lambda: entropy.encode_bytes(bytes([2]) * 3)), "warp/00000",
         True),
        ("warp_unpacks_to_300MB", _stream("warp/00000", lambda: _zstd_bomb(300 << 20)), "warp/00000", True),
    ):
        c.append(Case(label, "lossy_tensor", edit, section, decoded=decoded))
    return c


def _model_of_no_mode() -> bytes:
    """The format-11 base's tensor model with K set to 0: a model must have a natural mode."""
    with ArchiveReader(BASES["lossy_tensor"]) as reader:
        return bytes([0]) + reader.read("tensor/0001")[1:]


def _model_of_zeros() -> bytes:
    """The format-11 base's tensor model with every number 0: its class's poses decode to bones of
    no direction (the class's basis has no mean of its own)."""
    model = _base_tensor_model()
    return TensorModel(np.zeros_like(model.mean), np.zeros_like(model.core),
                       [np.zeros_like(factor) for factor in model.factors], model.core_step).encode()


def _base_tensor_model() -> TensorModel:
    """The format-11 base's tensor model (class 1)."""
    with ArchiveReader(BASES["lossy_tensor"]) as reader:
        return TensorModel.decode(reader.read("tensor/0001"), (448, 129, 2))  # 64_01's frames, pose values, subjects


def _other_grid_model() -> bytes:
    """The format-11 base's tensor model with a third level on its one mode: not its class's grid."""
    model = _base_tensor_model()
    model.factors[2] = np.vstack([model.factors[2], model.factors[2][:1]])
    return model.encode()


def _bvh_base_meta(base: str) -> dict:
    with ArchiveReader(BASES[base]) as reader:
        return json.loads(entropy.decode_bytes(reader.read("meta"), dictionary=dictionary("meta.json")))


def _bvh_row(field: str, base: str = "lossy_bvh"):
    """A field of the BVH clip's row (clip 2) in a format-8 base."""
    return _bvh_base_meta(base)["clips"][2][field]


def _bvh_only(meta: dict, streams: dict) -> None:
    """A format-8 base with its AMC clips (0 and 1) and their class (1, lossy) left out: its BVH clip,
    clip 2, becomes clip 0."""
    meta["clips"] = meta["clips"][2:]
    meta["classes"] = meta["classes"][:1]
    streams.pop("class/0001", None)
    for kind in ("clip", "patch", "extra_root"):
        for k in (0, 1):
            streams.pop(f"{kind}/{k:05d}", None)
        if f"{kind}/00002" in streams:
            streams[f"{kind}/00000"] = streams.pop(f"{kind}/00002")


def _skeleton_0(text: Callable[[], bytes]) -> Callable[[dict, dict], None]:
    """An edit that replaces skeleton 0 (the BVH hierarchy) with `text`, the ASF skeletons kept."""

    def edit(meta: dict, streams: dict) -> None:
        streams["skeletons"] = _skeletons_stream([text(), *_texts(streams["skeletons"])[1:]])

    return edit


def _bvh_hierarchy() -> bytes:
    """The format-8 lossy base's BVH hierarchy (skeleton 0)."""
    with ArchiveReader(BASES["lossy_bvh"]) as reader:
        return entropy.unpack_blobs(entropy.decode_bytes(reader.read("skeletons"), dictionary=dictionary("asf.txt")))[0]


def _deep_hierarchy(depth: int) -> bytes:
    """A hierarchy of `depth` joints, each inside the one before."""
    joints = "".join(f"{'ROOT' if k == 0 else 'JOINT'} j{k}\n{{\nOFFSET 0 0 1\nCHANNELS 3 Zrotation Xrotation "
                     f"Yrotation\n" for k in range(depth))
    return ("HIERARCHY\n" + joints + "}\n" * depth).encode()


def _fake_content_size(size: int) -> bytes:
    """A tiny zstd frame whose header claims `size` bytes of content (it holds a few)."""
    frame = bytearray(zstandard.ZstdCompressor(write_content_size=False, write_checksum=False).compress(b"{}"))
    # Frame header descriptor: set Frame_Content_Size_flag = 3 (8 bytes), Single_Segment = 0 -> window byte stays.
    descriptor = frame[4]
    frame[4] = (descriptor & 0x3F) | 0xC0
    window_present = not descriptor & 0x20
    insert_at = 5 + (1 if window_present else 0)
    return bytes(frame[:insert_at] + size.to_bytes(8, "little") + frame[insert_at:])


def build(case: Case, archive: Path, base: Path | None = None) -> None:
    """Write the hostile archive of `case` to `archive` through the project's writer, from
    BASES[case.base], or from `base`, an archive this version's compress wrote."""
    with ArchiveReader(base or BASES[case.base]) as reader:
        streams = {name: reader.read(name) for name in reader.names()}
    meta = json.loads(entropy.decode_bytes(streams["meta"], dictionary=dictionary("meta.json")))
    original_meta = streams["meta"]
    if base is None and case.base != "lossy_tensor":  # the bases of formats 7 to 9 hold the packed texts alone
        streams["skeletons"] = bytes([WHOLE_TEXTS]) + streams["skeletons"]
    case.edit(meta, streams)
    if "meta" in streams and streams["meta"] == original_meta:  # the edit changed meta's fields
        streams["meta"] = _json_stream(meta)
    write_archive(archive, streams, tool_version="hostile", overwrite=True, contents=_contents(meta))


def _contents(meta: dict) -> dict | None:
    """The index's clips table as compress writes it, where the (edited) meta still has one."""
    try:
        return contents_of(meta)
    except (KeyError, IndexError, TypeError):
        return None


def run_mcz(*args: str) -> subprocess.CompletedProcess:
    """`mcz ARGS` in a child limited to MEMORY_LIMIT of address space (`limited.run_mcz`)."""
    return limited.run_mcz(*args, memory=MEMORY_LIMIT)


def files_under(root: Path) -> set[str]:
    return {os.path.relpath(os.path.join(folder, name), root)
            for folder, dirs, names in os.walk(root) for name in names + [d for d in dirs
                                                                         if os.path.islink(os.path.join(folder, d))]}


def check(case: Case, watched: Path) -> list[str]:
    """Run the three commands on the case's archive, in a folder of its own under `watched`;
    return what went wrong (empty: refused cleanly, nothing written anywhere under `watched`)."""
    scratch = watched / case.name
    scratch.mkdir()
    archive = scratch / "hostile.mcz"
    build(case, archive)
    out = scratch / "deep" / "er" / "out"
    if case.prepare is not None:
        case.prepare(out)
    before = files_under(watched)
    problems = []
    for command in COMMANDS:
        args = [*command, os.fspath(out)] if command[0] == "decompress" else [*command]
        result = run_mcz(args[0], os.fspath(archive), *args[1:])
        lines = result.stderr.splitlines()
        if result.returncode == 0 and not result.stderr and (
                case.output and command[0] != "decompress" or case.decoded and command[0] == "info"):
            continue  # info lists what meta says and decodes no clip; only decompress sees the output folder
        named = f"mcz: error: {out if case.output else archive}"
        if result.returncode != 1 or result.stdout or len(lines) != 1:
            problems.append(f"{command[0]}: exit {result.returncode}, stdout {result.stdout[:200]!r}, "
                            f"stderr {result.stderr[-600:]!r}")
        elif not lines[0].startswith(named) or case.section not in lines[0]:
            problems.append(f"{command[0]}: {lines[0]!r} does not name {case.section!r}")
    written = files_under(watched) - before
    if written:
        problems.append(f"files written: {sorted(written)}")
    return problems


def main() -> None:
    """Run every case as the test does; print outcome, seconds and the peak memory of the worst child."""
    import tempfile

    peak_case, peak = None, 0
    slowest = (None, 0.0)
    refused = 0
    with tempfile.TemporaryDirectory() as top:
        all_cases = cases(Path(top))
        for case in all_cases:
            started = time.perf_counter()
            problems = check(case, Path(top))
            seconds = time.perf_counter() - started
            rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
            if rss > peak:
                peak_case, peak = case.name, rss
            if seconds > slowest[1]:
                slowest = (case.name, seconds)
            refused += not problems
            print(f"{case.name:40s} {'refused' if not problems else 'FAILED: ' + '; '.join(problems)}  {seconds:.1f} s")
    print(f"{refused} of {len(all_cases)} cases refused cleanly by test, info and decompress; "
          f"slowest {slowest[0]} ({slowest[1]:.1f} s for the three commands); "
          f"largest child {peak / 1024:.0f} MiB ({peak_case})")


if __name__ == "__main__":
    main()
