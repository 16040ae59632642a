"""Glitches in the source (`inputs.glitches`): found on the real clip that has one, on hand-made
motions for each kind and each threshold, and reported by `mcz inspect --check` and `compress`."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from mocapzip.cli.main import main
from mocapzip.formats.amc import Motion, read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.inputs import glitches
from mocapzip.inputs.glitches import find_glitches
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel


@pytest.fixture(scope="module")
def cmu01(shared_data):
    skeleton = read_asf(shared_data / "cmu" / "01" / "01.asf")
    return skeleton, SkeletonModel.from_asf(skeleton)


def glitches_of(cmu01, motion: Motion, fps: float = 120.0) -> list:
    skeleton, model = cmu01
    return find_glitches(skeleton, model, motion, forward(model, motion.values, motion).positions, fps)


def test_the_rfemur_flip_of_01_06_is_found(cmu01, shared_data):
    """01_06 turns rfemur ry from about 9 to about 178 degrees for frames 4756-4760 and back."""
    found = glitches_of(cmu01, read_amc(shared_data / "cmu" / "01" / "01_06.amc"))
    flip = [g for g in found if g.bone == "rfemur"]
    assert [(g.kind, g.first, g.last) for g in flip] == [("jump", 4755, 4756), ("limits", 4756, 4760),
                                                         ("jump", 4760, 4761)]
    assert "ry 177.971 outside its limits [-70, 70]" in flip[1].detail
    assert all(g.bone not in ("rtibia",) for g in found if g.kind == "jump")  # the limb below is not named again


@pytest.fixture
def still(cmu01, shared_data) -> Motion:
    """07_01's first 200 frames: a normal walk to break by hand."""
    walk = read_amc(shared_data / "cmu" / "07" / "07_01.amc")
    return Motion(walk.bones, walk.counts, walk.values[:200].copy(), walk.frame_numbers[:200], walk.header, "x.amc")


def column(motion: Motion, bone: str, k: int = 0) -> int:
    return int(np.sum(motion.counts[: motion.bones.index(bone)])) + k


def test_a_normal_walk_has_none(cmu01, still):
    assert glitches_of(cmu01, still) == []


def test_jumps_scale_with_the_frame_rate(cmu01, still):
    """A 40 cm jump of the root in one frame: 48 m/s at 120 Hz, a glitch; 12 m/s at 30 Hz, not."""
    still.values[100:, column(still, "root", 0)] += 40 / (2.54 / 0.45)  # root tx, in CMU units
    found = glitches_of(cmu01, still)
    assert [(g.kind, g.bone, g.first, g.last) for g in found] == [("jump", "root", 100, 101)]
    assert glitches_of(cmu01, still, fps=30.0) == []


def test_limits_count_a_value_at_its_nearest_turn(cmu01, still):
    """rfemur ry's limits are [-70, 70]: 320 degrees is -40 a turn away (inside them); 165 is 95
    beyond, more than the margin."""
    k = column(still, "rfemur", 1)
    still.values[50:53, k] = 320.0
    assert not [g for g in glitches_of(cmu01, still) if g.kind == "limits"]
    still.values[50:53, k] = 70 + glitches.LIMIT_MARGIN_DEG + 5  # 165: beyond by 95
    found = [g for g in glitches_of(cmu01, still) if g.kind == "limits"]
    assert [(g.bone, g.first, g.last) for g in found] == [("rfemur", 51, 53)]


def test_frozen_and_zeroed_runs(cmu01, still):
    start, cols = 20, slice(column(still, "lhumerus"), column(still, "lhumerus") + 3)
    still.values[start:start + glitches.FROZEN_FRAMES, cols] = still.values[start, cols]  # held 30 frames
    still.values[150:152, cols] = 0.0  # zeroed 2 frames
    found = {(g.kind, g.bone, g.first, g.last) for g in glitches_of(cmu01, still)
             if g.kind in ("frozen", "zeroed")}
    assert found == {("frozen", "lhumerus", start + 1, start + glitches.FROZEN_FRAMES), ("zeroed", "lhumerus", 151, 152)}
    still.values[start + glitches.FROZEN_FRAMES - 1, cols] += 1.0  # held one frame less: not reported
    assert not [g for g in glitches_of(cmu01, still) if g.kind == "frozen"]


def test_a_bone_constant_all_along_is_not_frozen(cmu01, still):
    still.values[:, column(still, "lfingers")] = 7.0
    assert glitches_of(cmu01, still) == []


def test_inspect_check_lists_them_and_compress_warns_once(shared_data, tmp_path):
    clip = shared_data / "cmu" / "01" / "01_06.amc"
    result = CliRunner().invoke(main, ["inspect", str(clip), "--check"])
    assert result.exit_code == 0
    lines = result.output.splitlines()
    assert "01_06.amc: frames 4756-4760: rfemur: limits: ry 177.971 outside its limits [-70, 70]" in lines
    assert lines[-1] == f"{len(lines) - 1} glitches in 1 clip of 1"
    report = json.loads(CliRunner().invoke(main, ["inspect", str(clip), "--check", "--json"]).output)
    assert len(report["clips"][0]["glitches"]) == len(lines) - 1
    assert "glitches" not in json.loads(CliRunner().invoke(main, ["inspect", str(clip), "--json"]).output)["clips"][0]
    compressed = CliRunner().invoke(main, ["compress", str(clip), "-o", str(tmp_path / "x.mcz"), "-q"])
    assert compressed.exit_code == 0
    warned = [line for line in compressed.output.splitlines() if "in the source" in line]
    assert warned == [f"mcz: warning: {len(lines) - 1} glitches in the source, in 1 clip (jump 4, limits 3); kept as "
                      "written, the errors are measured against them; `mcz inspect --check` lists them"]


def test_the_mask_covers_a_spike_and_the_limb_below_it(cmu01):
    """`glitch_mask`: a jump or limits glitch frees its bone and every joint below it over its
    frames; held runs (frozen, zeroed) are not repaired."""
    _, model = cmu01
    numbers = np.arange(1, 21)
    found = [glitches.Glitch("limits", "rfemur", 5, 7, ""), glitches.Glitch("frozen", "lhumerus", 1, 20, "")]
    mask = glitches.glitch_mask(model, found, numbers)
    below = {"rfemur", "rtibia", "rfoot", "rtoes"}
    assert {model.names[j] for j in np.flatnonzero(mask.any(axis=0))} == below
    np.testing.assert_array_equal(np.flatnonzero(mask.any(axis=1)), [4, 5, 6])  # frames 5-7
    distances = np.zeros(mask.shape)
    distances[5, model.index["rtoes"]] = 12.34561
    assert glitches.repaired_ranges(mask, distances, numbers) == [[5, 7, 12.346]]
