"""Hostile tensor, warp, plant and patch streams (issue 40): archives that use `--model tensor`,
`--plant-feet` and frame patches, each with one of those streams, or the meta that claims it,
changed as an attacker would: cut short or padded, sizes and counts zeroed or huge, shapes that
disagree with their class, NaN and infinite floats, streams copied, swapped, left out or added.

The bases (BASES) are real clips compressed by this version's `compress`, once per test session
(tests/test_hostile_streams.py), and each case is written from its base through the project's own
writer (`hostile_archives.build`), so every checksum is valid and `mcz` has only its own checks
to stand on. A case is either refused in one line naming its section, or, where `may_decode`
says the changed archive can still be one the spec defines, decoded as the reference decoder
decodes it.
"""

from __future__ import annotations

import json

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hostile_archives import _both, _clip_frames, _delete, _fake_content_size, _set, _stream, _zstd_bomb
from mocapzip.codec.entropy import zstd as entropy
from mocapzip.codec.entropy.coefficients import decode_matrices, encode_matrices
from mocapzip.limits import MAX_TENSOR_MODEL_NUMBERS
from test_hardening_streams import zero_matrices_claiming

HDM05_MODES = r"HDM_(?P<actor>[a-z]+)_(?P<motion>[a-zA-Z]+)1Reps"
# name -> (the clips, by folder under the shared data, and compress's options). Clips are stored
# in path order: "plant" holds 07/07_10 (a walk, 301 frames) and 09/09_03 (a run, 128), each with
# stances and patched frames; "tensor" holds HDM05's bd and bk (actors) x elbowToKnee and squat
# (motions), 128, 140, 187 and 181 frames, one class stored as a tensor model of those two modes
# (forced: on four clips the model never pays) under a wavelet transform.
BASES = {
    "plant": ({"07": ["cmu/07/07.asf", "cmu/07/07_10.amc"], "09": ["cmu/09/09.asf", "cmu/09/09_03.amc"]},
              ["-e", "1", "--max-error", "3", "--plant-feet"]),
    "tensor": ({"bd": ["hdm05/bd/HDM_bd.asf", "hdm05/bd/HDM_bd_elbowToKnee1RepsLelbowStart_001_120.amc",
                       "hdm05/bd/HDM_bd_squat1Reps_001_120.amc"],
                "bk": ["hdm05/bk/HDM_bk.asf", "hdm05/bk/HDM_bk_elbowToKnee1RepsLelbowStart_007_120.amc",
                       "hdm05/bk/HDM_bk_squat1Reps_013_120.amc"]},
               ["--model", "tensor", "--modes", HDM05_MODES, "-t", "dwt"]),
}
LONGEST = 2  # the tensor base's longest clip (bk elbowToKnee, 187 frames): the model's timeline
HUGE = 2**62 - 1  # the largest magnitude a matrices stream holds


@dataclass
class Case:
    name: str
    base: str  # a key of BASES
    edit: Callable[[dict, dict], None]  # changes (meta, streams) in place, as hostile_archives.Case's
    section: str  # the part of the archive a refusal must name
    may_decode: bool = False  # the changed archive may be a valid one: then it must decode as the spec says


# --------------------------------------------------------------------------- edits


def _changed(name: str, change: Callable[[bytes], bytes]) -> Callable[[dict, dict], None]:
    """An edit that replaces stream `name` with `change` of its bytes."""

    def edit(meta: dict, streams: dict) -> None:
        streams[name] = change(streams[name])

    return edit


def _copied(source: str, target: str) -> Callable[[dict, dict], None]:
    def edit(meta: dict, streams: dict) -> None:
        streams[target] = streams[source]

    return edit


def _swapped(a: str, b: str) -> Callable[[dict, dict], None]:
    def edit(meta: dict, streams: dict) -> None:
        streams[a], streams[b] = streams[b], streams[a]

    return edit


def _made(name: str, make: Callable[[dict], bytes]) -> Callable[[dict, dict], None]:
    """An edit that writes stream `name` as `make(meta)` makes it, from the (edited) meta's sizes."""

    def edit(meta: dict, streams: dict) -> None:
        streams[name] = make(meta)

    return edit


def _patches(step: float = 1.0, gaps=(), levels=(), value: int = 1, apart: bool = False, columns: int = 0,
             rows: Callable[[int], int] = lambda count: count) -> Callable[[dict], bytes]:
    """Clip 0's patch stream: `step`, then `rows` of its row's patched_frames rows of gaps, levels
    and ints of `value` over its channels (and `columns` more). `gaps` and `levels` come first;
    the other levels are 0, the other gaps 0 (consecutive frames at one level: a run, whose
    stored ints add up) or, `apart`, 1."""

    def make(meta: dict) -> bytes:
        row = meta["clips"][0]
        count = rows(row["patched_frames"])
        head = np.zeros((count, 2), np.int64)
        head[1:, 0] = apart
        head[:len(gaps), 0], head[:len(levels), 1] = gaps, levels
        ints = np.full((count, sum(row["counts"]) + columns), value, np.int64)
        return struct.pack("<f", step) + encode_matrices([head, ints])

    return make


def _stances(*stances: tuple[int, int, int], repeat: int = 1) -> Callable[[dict], bytes]:
    """Clip 0's plant stream of these (foot, gap, frames) rows, `repeat` times over (frames -1:
    the whole clip); its row's planted_stances says how many."""

    def make(meta: dict) -> bytes:
        row = meta["clips"][0]
        rows = [(foot, gap, row["frames"] if frames == -1 else frames) for foot, gap, frames in stances] * repeat
        row["planted_stances"] = len(rows)
        return encode_matrices([np.array(rows, np.int64)])

    return make


def model_parts(blob: bytes) -> tuple[int, list[int], list[int], float, bytes]:
    """A tensor model's header (K, sizes, ranks, core step) and its matrices stream (docs/format.md)."""
    reader = entropy.ByteReader(blob)
    k = reader.take(1)[0]
    sizes = [reader.varint() for _ in range(k + 2)]
    ranks = [reader.varint() for _ in range(k + 2)]
    (step,) = struct.unpack("<f", reader.take(4))
    return k, sizes, ranks, step, reader.take(reader.remaining())


def model_blob(k: int, sizes, ranks, step: float, matrices: bytes | None = None) -> bytes:
    """A tensor model's bytes; `matrices` None: all-zero matrices of the shapes the header declares."""
    head = bytearray([k])
    for value in [*sizes, *ranks]:
        entropy.write_varint(head, value)
    if matrices is None:
        shapes = [(sizes[1], 1), (ranks[0], math.prod(ranks[1:]))] + list(zip(sizes, ranks))
        matrices = zero_matrices_claiming(shapes)
    return bytes(head) + struct.pack("<f", step) + matrices


def _with_matrices(k: int, sizes, ranks, step: float, matrices: bytes, full: bool = False,
                   huge_mean: bool = False) -> bytes:
    """A model of its mean (its first value HUGE, if `huge_mean`), the rest all zero (of full
    ranks, if `full`): every clip predicted as the class's mean pose."""
    ranks = list(sizes) if full else ranks
    shapes = [(sizes[1], 1), (ranks[0], math.prod(ranks[1:]))] + list(zip(sizes, ranks))
    mean = decode_matrices(matrices)[0]
    mean[0] = HUGE if huge_mean else mean[0]
    zeros = [np.zeros(shape, np.int64) for shape in shapes[1:]]
    return model_blob(k, sizes, ranks, step, encode_matrices([mean, *zeros]))


def _model(change: Callable[[int, list, list, float, bytes], bytes]) -> Callable[[dict, dict], None]:
    """An edit of the tensor base's model: `change(K, sizes, ranks, core step, matrices)` makes the new bytes."""
    return _changed("tensor/0000", lambda blob: change(*model_parts(blob)))


def _zero_model(at_most: bool, frames: int = 100_000) -> Callable[[dict, dict], None]:
    """The tensor base's longest clip claims `frames` frames, and its model, all zeros, has every
    size of that class and as many numbers as a reader takes (`at_most`), or one row of U_frames
    more: within each matrix's limits either way."""

    def edit(meta: dict, streams: dict) -> None:
        k, sizes, ranks, step, _ = model_parts(streams["tensor/0000"])
        _clip_frames(LONGEST, frames)(meta, streams)
        sizes[0], ranks[1:] = frames, [1] * (k + 1)
        rest = 2 * sizes[1] + sum(sizes[2:])  # the mean, U_values and each U_k; the core and U_frames: r_0 (1 + L)
        ranks[0] = (MAX_TENSOR_MODEL_NUMBERS - rest) // (1 + frames) + (not at_most)
        streams["tensor/0000"] = model_blob(k, sizes, ranks, step)

    return edit


def _moves(make: Callable[[int, int], bytes]) -> Callable[[dict, dict], None]:
    """Clip 0's warp stream holding `make(L, n)`'s moves (L: the model's frames, n: the clip's)."""

    def edit(meta: dict, streams: dict) -> None:
        streams["warp/00000"] = entropy.encode_bytes(make(meta["clips"][LONGEST]["frames"], meta["clips"][0]["frames"]))

    return edit


def _levels(edit_levels: Callable[[list], None]) -> Callable[[dict, dict], None]:
    def edit(meta: dict, streams: dict) -> None:
        edit_levels(meta["classes"][0]["levels"])

    return edit


# --------------------------------------------------------------------------- cases


def _any_stream(family: str, base: str, name: str, sibling: str, unclaimed: str) -> list[Case]:
    """What is done to every stream alike: bytes cut or added, the stream left out, copied over
    its sibling or to a name nothing claims, swapped with its sibling."""
    return [
        Case(f"{family}_empty", base, _stream(name, b""), name),
        Case(f"{family}_one_byte", base, _changed(name, lambda b: b[:1]), name),
        Case(f"{family}_cut_in_half", base, _changed(name, lambda b: b[: len(b) // 2]), name),
        Case(f"{family}_last_byte_cut", base, _changed(name, lambda b: b[:-1]), name),
        Case(f"{family}_one_byte_more", base, _changed(name, lambda b: b + b"\0"), name),
        Case(f"{family}_flipped_byte", base, _changed(name, lambda b: b[:-2] + bytes([b[-2] ^ 0x55]) + b[-1:]), name,
             may_decode=True),
        Case(f"{family}_missing", base, _stream(name, None), f"{name}: stream missing"),
        Case(f"{family}_copied_to_an_unclaimed_name", base, _copied(name, unclaimed),
             f"{unclaimed}: a stream that no part of meta claims"),
        Case(f"{family}_copied_over_its_sibling", base, _copied(name, sibling), sibling.split("/")[0],
             may_decode=True),
        Case(f"{family}_swapped_with_its_sibling", base, _swapped(name, sibling), sibling.split("/")[0],
             may_decode=True),
    ]


def _patch_cases() -> list[Case]:
    patch = "patch/00000"
    c = _any_stream("patch", "plant", patch, "patch/00001", "patch/00002")
    for label, make, section, may_decode in (
        ("step_nan", _patches(step=math.nan), patch, False),
        ("step_inf", _patches(step=math.inf), patch, False),
        ("step_minus_inf", _patches(step=-math.inf), patch, False),
        ("step_zero", _patches(step=0.0), patch, False),
        ("step_negative", _patches(step=-1.0), patch, False),
        ("step_denormal", _patches(step=1e-45), patch, True),  # a valid step, if a useless one
        ("step_float32_max", _patches(step=3.4e38), "clip/00000", False),  # values past +-1e9
        ("ints_huge", _patches(value=2**61, apart=True), "clip/00000", False),  # values past +-1e9
        ("ints_of_a_run_past_2_62", _patches(value=HUGE), patch, False),  # consecutive rows add up
        ("gap_negative", _patches(gaps=[-1]), patch, False),
        ("gap_past_the_clip", _patches(gaps=[10**6]), patch, False),
        ("gap_ends_past_the_clip", _patches(gaps=[0, 290]), patch, False),  # 07_10: 301 frames
        ("level_41", _patches(levels=[41]), patch, False),
        ("level_negative", _patches(levels=[-1]), patch, False),
        ("one_channel_more", _patches(columns=1), patch, False),
        ("one_frame_more", _patches(rows=lambda count: count + 1), patch, False),
        ("no_frame", _patches(rows=lambda count: 0), patch, False),
        ("values_all_zero", _patches(value=0), patch, True),
    ):
        c.append(Case(f"patch_{label}", "plant", _made(patch, make), section, may_decode))
    shapes_of = lambda shapes: _made(patch, lambda meta: struct.pack("<f", 1.0) + zero_matrices_claiming(shapes))
    c += [
        Case("patch_header_of_2_20_frames", "plant", shapes_of([(1 << 20, 2), (1 << 20, 62)]), patch),
        Case("patch_header_of_one_matrix", "plant", shapes_of([(1, 2)]), patch),
        Case("patch_header_of_three_matrices", "plant", shapes_of([(1, 2), (1, 62), (1, 62)]), patch),
        Case("patched_frames_one_more", "plant", lambda meta, streams: meta["clips"][0].update(
            patched_frames=meta["clips"][0]["patched_frames"] + 1), patch),
        Case("patched_frames_past_the_clip", "plant", _set("clips.0.patched_frames", 302),
             "meta: clips[0].patched_frames"),
        Case("patched_frames_left_out", "plant", _delete("clips.0.patched_frames"),
             f"{patch}: a stream that no part of meta claims"),
        Case("patches_without_a_bound", "plant", _delete("settings.max_error_cm"), "meta: clips[0].patched_frames"),
    ]
    return c


def _plant_cases() -> list[Case]:
    plant = "plant/00000"
    c = _any_stream("plant", "plant", plant, "plant/00001", "plant/00002")
    for label, make, section, may_decode in (
        ("foot_beyond_the_skeleton", _stances((99, 0, 10)), plant, False),
        ("foot_negative", _stances((-1, 0, 10)), plant, False),
        ("feet_decreasing", _stances((1, 0, 10), (0, 0, 10)), plant, False),
        ("gap_negative", _stances((0, -1, 10), (1, 0, 10)), plant, False),
        ("gap_huge", _stances((0, HUGE, 10), (1, 0, 10)), plant, False),
        ("no_frame", _stances((0, 0, 0), (1, 0, 10)), plant, False),
        ("frames_huge", _stances((0, 0, HUGE), (1, 0, 10)), plant, False),
        ("ends_past_the_clip", _stances((0, 0, 200), (0, 50, 200)), plant, False),  # 07_10: 301 frames
        ("whole_clip_on_one_foot", _stances((0, 0, -1), (1, 0, -1)), plant, True),
        ("one_column_more", lambda meta: encode_matrices([np.ones((meta["clips"][0]["planted_stances"], 4),
                                                                 np.int64)]), plant, False),
        ("header_of_2_20_stances", lambda meta: zero_matrices_claiming([(1 << 20, 3)]), plant, False),
        ("header_of_no_matrix", lambda meta: bytes([1, 0]), plant, False),
    ):
        c.append(Case(f"plant_{label}", "plant", _made(plant, make), section, may_decode))
    c += [
        Case("planted_stances_one_more", "plant", lambda meta, streams: meta["clips"][0].update(
            planted_stances=meta["clips"][0]["planted_stances"] + 1), plant),
        Case("planted_stances_as_many_as_frames", "plant", _made(plant, _stances((0, 0, 1), repeat=301)), plant,
             may_decode=True),  # a stance of one frame in each: valid
        Case("planted_stances_as_many_as_frames_of_no_length", "plant", _both(
            _set("clips.0.planted_stances", 301), _stream(plant, lambda: zero_matrices_claiming([(301, 3)]))), plant),
        Case("planted_stances_left_out", "plant", _delete("clips.0.planted_stances"),
             f"{plant}: a stream that no part of meta claims"),
        Case("stances_with_plant_feet_false", "plant", _set("settings.plant_feet", False),
             "meta: clips[0].planted_stances"),
        Case("stances_without_plant_feet", "plant", _delete("settings.plant_feet"), "meta: clips[0].planted_stances"),
    ]
    return c


def _tensor_cases() -> list[Case]:
    model = "tensor/0000"
    c = _any_stream("tensor", "tensor", model, "class/0000", "tensor/0001")
    for label, change, section, may_decode in (
        ("of_no_mode", lambda k, s, r, step, m: model_blob(0, s, r, step, m), model, False),
        ("of_one_mode_fewer", lambda k, s, r, step, m: model_blob(1, s, r, step, m), model, False),
        ("of_nine_modes", lambda k, s, r, step, m: model_blob(9, s, r, step, m), model, False),
        ("frames_one_fewer", lambda k, s, r, step, m: model_blob(k, [s[0] - 1, *s[1:]], r, step, m), model, False),
        ("frames_one_more", lambda k, s, r, step, m: model_blob(k, [s[0] + 1, *s[1:]], r, step, m), model, False),
        ("values_one_more", lambda k, s, r, step, m: model_blob(k, [s[0], s[1] + 1, *s[2:]], r, step, m), model,
         False),
        ("a_third_level", lambda k, s, r, step, m: model_blob(k, [*s[:2], 3, *s[3:]], r, step, m), model, False),
        ("rank_zero", lambda k, s, r, step, m: model_blob(k, s, [0, *r[1:]], step, m), model, False),
        ("rank_above_its_size", lambda k, s, r, step, m: model_blob(k, s, [*r[:2], 3, *r[3:]], step, m), model,
         False),
        ("core_step_nan", lambda k, s, r, step, m: model_blob(k, s, r, math.nan, m), model, False),
        ("core_step_inf", lambda k, s, r, step, m: model_blob(k, s, r, math.inf, m), model, False),
        ("core_step_zero", lambda k, s, r, step, m: model_blob(k, s, r, 0.0, m), model, False),
        ("core_step_negative", lambda k, s, r, step, m: model_blob(k, s, r, -0.5, m), model, False),
        ("core_step_denormal", lambda k, s, r, step, m: model_blob(k, s, r, 1e-45, m), model, True),
        ("core_step_float32_max", lambda k, s, r, step, m: model_blob(k, s, r, 3.4e38, m), "warp/00000", False),
        ("of_its_mean_alone", lambda k, s, r, step, m: _with_matrices(k, s, r, step, m), model, True),
        ("of_full_ranks_and_its_mean_alone", lambda k, s, r, step, m: _with_matrices(k, s, r, step, m, full=True),
         model, True),
        ("of_71M_zero_values", lambda k, s, r, step, m: model_blob(2, [1 << 11, 1 << 14, 2, 4],
                                                                   [1 << 11, 1 << 11, 2, 4], step), model, False),
        ("mean_of_a_huge_int", lambda k, s, r, step, m: _with_matrices(k, s, r, step, m, huge_mean=True),
         "warp/00000", False),  # a pose past MAX_ABS_POSE: no body's
        ("matrices_of_the_mean_alone", lambda k, s, r, step, m: model_blob(k, s, r, step, encode_matrices(
            [np.zeros((s[1], 1), np.int64)])), model, False),
        # every number HUGE at the largest core step: a prediction that overflows to inf (the mean
        # alone is finite); it passed `mcz test` and decoded as the reference decoder does not
        ("whose_products_overflow", lambda k, s, r, step, m: model_blob(k, s, r, 3.4e38, encode_matrices(
            [np.full(shape, HUGE, np.int64) for shape in [(s[1], 1), (r[0], math.prod(r[1:])), *zip(s, r)]])),
         "warp/00000", False),
    ):
        c.append(Case(f"tensor_model_{label}", "tensor", _model(change), section, may_decode))
    c += [
        Case("tensor_model_at_most_the_numbers_a_reader_takes", "tensor", _zero_model(at_most=True), "warp/00000"),
        Case("tensor_model_of_one_number_row_more", "tensor", _zero_model(at_most=False), model),
        Case("tensor_class_of_a_third_actor", "tensor", _levels(lambda levels: levels[0].append("dg")),
             "meta: classes[0].levels"),
        Case("tensor_class_of_one_actor_fewer", "tensor", _levels(lambda levels: levels[0].pop()),
             "meta: classes[0].levels"),
        Case("tensor_two_clips_at_one_place", "tensor", _set("clips.1.tensor_at", [0, 0]), "meta: clips[1].tensor_at"),
        Case("tensor_clips_trade_places", "tensor", _both(_set("clips.0.tensor_at", [0, 1]),
                                                          _set("clips.1.tensor_at", [0, 0])), "clip/0000",
             may_decode=True),
        Case("tensor_class_called_pca", "tensor", _set("classes.0.model", "pca"), "meta: classes[0]"),
        Case("tensor_class_without_levels", "tensor", _delete("classes.0.levels"), "meta: classes[0]"),
        # the fifth hostile pass
        Case("tensor_mode_named_twice", "tensor", _set("classes.0.modes", ["actor", "actor"]),
             "meta: classes[0].modes: a mode named twice"),
        Case("tensor_level_named_twice", "tensor", _levels(lambda levels: levels[0].__setitem__(1, levels[0][0])),
             "meta: classes[0].levels[0]: a level of mode 'actor' named twice"),
        Case("tensor_at_of_floats", "tensor", _set("clips.0.tensor_at", [0.0, 0.0]), "meta: clips[0].tensor_at[0]"),
        Case("tensor_at_of_bools", "tensor", _set("clips.0.tensor_at", [False, False]), "meta: clips[0].tensor_at[0]"),
        Case("tensor_at_2_63", "tensor", _set("clips.0.tensor_at", [2**63, 0]), "meta: clips[0].tensor_at"),
        Case("tensor_at_of_one_mode", "tensor", _set("clips.0.tensor_at", [0]), "meta: clips[0].tensor_at"),
        Case("tensor_modes_not_a_regular_expression", "tensor", _set("settings.modes", "(?P<actor"),
             "meta: settings.modes"),
        Case("tensor_modes_of_no_group", "tensor", _set("settings.modes", "(a+)+$"), "meta: settings.modes"),
        Case("tensor_class_of_no_component", "tensor", _set("classes.0.components", 0), "meta: classes[0].components"),
        Case("tensor_clip_streams_of_two_clips_swapped", "tensor", _swapped("clip/00000", "clip/00002"), "clip/00000"),
        # the sixth hostile pass
        Case("tensor_at_one_level_past_its_mode", "tensor", _set("clips.0.tensor_at", [2, 0]),
             "meta: clips[0].tensor_at: not a place in its class's grid"),
        Case("tensor_class_of_components_true", "tensor", _set("classes.0.components", True),
             "meta: classes[0].components: must be integer"),
        Case("tensor_class_of_2_40_frames", "tensor", _set("classes.0.frames", 2**40), "meta: classes[0].frames"),
        Case("tensor_class_of_a_thousand_levels_more", "tensor",
             _levels(lambda levels: levels[0].extend(f"l{i}" for i in range(1000))), "meta: classes[0].levels"),
        Case("tensor_class_copied_as_a_class_of_no_clip", "tensor",
             lambda meta, streams: meta["classes"].append(json.loads(json.dumps(meta["classes"][0]))),
             "meta: classes[1]: no clip or segment is in this class"),
        Case("tensor_mode_of_no_group_of_the_pattern", "tensor", lambda meta, streams: meta["classes"][0]["modes"]
             .__setitem__(0, "m" * 10_000), "meta: classes[0].modes"),
        Case("tensor_stream_named_up_two_folders", "tensor", _copied("warp/00000", "../../warp"),
             "../../warp: a stream that no part of meta claims"),
    ]
    return c


def _warp_cases() -> list[Case]:
    warp = "warp/00000"
    c = _any_stream("warp", "tensor", warp, "warp/00001", "warp/00004")
    for label, make, may_decode in (
        ("no_move", lambda L, n: b"", False),
        ("move_3", lambda L, n: bytes([3]) * (L + n), False),
        ("move_255", lambda L, n: bytes([2] * (min(L, n) - 2) + [255]), False),
        ("ends_short", lambda L, n: bytes([2]) * (min(L, n) - 2), False),
        ("ends_past_the_model", lambda L, n: bytes([0]) * L + bytes([1]) * (n - 1), False),
        ("one_byte_past_its_limit", lambda L, n: bytes([2]) * (L + n + 1), False),
        ("model_first_then_clip", lambda L, n: bytes([0]) * (L - 1) + bytes([1]) * (n - 1), True),
        ("clip_first_then_model", lambda L, n: bytes([1]) * (n - 1) + bytes([0]) * (L - 1), True),
    ):
        c.append(Case(f"warp_{label}", "tensor", _moves(make), warp, may_decode))
    c += [
        Case("warp_unpacks_to_300MB", "tensor", _stream(warp, lambda: _zstd_bomb(300 << 20)), warp),
        Case("warp_claims_a_terabyte", "tensor", _stream(warp, lambda: _fake_content_size(1 << 40)), warp),
        Case("warp_not_zstd", "tensor", _stream(warp, b"\x02" * 400), warp),
        Case("warp_without_its_place", "tensor", _delete("clips.0.tensor_at"), "meta: clips[0].tensor_at"),
        Case("warp_clip_frames_one_more", "tensor", _clip_frames(0, lambda frames: frames + 1), "clip/00000"),
        Case("warp_of_a_clip_of_other_frames", "tensor", _swapped(warp, "warp/00002"), warp),  # the fifth pass
    ]
    return c


def cases() -> list[Case]:
    """Every hostile stream case, by family."""
    return [*_patch_cases(), *_plant_cases(), *_tensor_cases(), *_warp_cases()]
