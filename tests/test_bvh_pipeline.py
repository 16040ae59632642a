"""BVH clips through the whole pipeline (compress, decompress, info, inspect, the API), on the
shared BVH files: CMU's conversion (hip root, 3 channels per joint) and Bandai Namco's export
(6 channels on every joint, an extra root above the hips).

Joint positions are checked with forward kinematics written here from the BVH convention (column
vectors, v' = R1 R2 R3 v for CHANNELS R1 R2 R3, position channels in place of the OFFSET), and
with an independent BVH library from PyPI (`bvhio`), never with mocapzip's own kinematics alone.
"""

from __future__ import annotations

import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import mocapzip
from mocapzip.archive import info as archive_info
from mocapzip.cli.main import main
from mocapzip.formats.bvh import read_bvh, split_header
from mocapzip.formats.errors import MocapFormatError
from mocapzip.motion.bvh_skeleton import bvh_skeleton
from mocapzip.motion.kinematics import forward

SOME_BANDAI = ["dataset-1_walk-back_normal_001.bvh",  # its extra root moves: root motion on joint_Root
               "dataset-1_bow_active_001.bvh", "dataset-1_dash_proud_001.bvh"]


def file_positions(bvh) -> dict[str, np.ndarray]:
    """{joint or "<joint> End Site": (frames, 3) world position in file units}, by the BVH convention."""
    frames = bvh.n_frames
    columns = iter(range(bvh.values.shape[1]))
    world, at, out = {}, {}, {}
    for j, joint in enumerate(bvh.joints):
        offset = np.repeat(np.asarray(joint.offset, dtype=np.float64)[None], frames, axis=0)
        turn = np.repeat(np.eye(3)[None], frames, axis=0)
        for channel in joint.channels:
            value = bvh.values[:, next(columns)]
            axis = "XYZ".index(channel[0])
            if channel.endswith("position"):
                offset[:, axis] = value
            else:
                turn = turn @ _rotation(axis, np.radians(value))
        if joint.parent < 0:
            at[j], world[j] = offset, turn
        else:
            at[j] = at[joint.parent] + np.einsum("fij,fj->fi", world[joint.parent], offset)
            world[j] = world[joint.parent] @ turn
        out[joint.name] = at[j]
        if joint.end_site is not None:
            out[f"{joint.name} End Site"] = at[j] + np.einsum("fij,j->fi", world[j], joint.end_site)
    return out


def _rotation(axis: int, angle: np.ndarray) -> np.ndarray:
    """Column-vector rotations about one axis, (frames, 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    b, d = (axis + 1) % 3, (axis + 2) % 3
    out = np.zeros((len(angle), 3, 3))
    out[:, axis, axis] = 1.0
    out[:, b, b] = out[:, d, d] = c
    out[:, b, d], out[:, d, b] = -s, s
    return out


def errors_cm(source, decoded, cm_per_unit: float = 1.0) -> np.ndarray:
    """(frames, points) distances in cm between two BVH clips' joints and End Sites (an extra root's
    included: it is a joint of the file)."""
    a, b = file_positions(source), file_positions(decoded)
    assert a.keys() == b.keys()
    return np.stack([np.linalg.norm(a[k] - b[k], axis=1) for k in a], axis=1) * cm_per_unit


def shared_bvh_files(data: Path) -> list[Path]:
    return sorted(data.glob("cmu-bvh/*/*.bvh")) + sorted(data.glob("bvh-bandai/*.bvh"))


def linked(folder: Path, *files: Path) -> Path:
    """A folder of symbolic links to shared files: a set to compress, the data never copied."""
    folder.mkdir(parents=True, exist_ok=True)
    for file in files:
        (folder / file.name).symlink_to(file)
    return folder


def test_the_codecs_model_puts_every_joint_and_end_site_where_the_file_does(shared_data):
    for path in shared_bvh_files(shared_data):
        bvh = read_bvh(path)
        skeleton = bvh_skeleton(bvh.joints, None, path)
        motion = skeleton.motion(bvh, lossless=False)
        got = forward(skeleton.model, motion.values, motion).positions
        if len(skeleton.above):  # the model hangs below an extra root (Bandai's joint_Root): put that at rest
            values = np.array(bvh.values)
            values[:, skeleton.above] = 0.0
            bvh = replace(bvh, values=values, frames_text=None)
        expected = file_positions(bvh)
        assert set(skeleton.model.points) == set(expected) - ({bvh.joints[0].name} if len(skeleton.above) else set())
        for k, name in enumerate(skeleton.model.points):
            # Bandai writes each joint's position channels, equal to its OFFSET to 1e-5 cm: the model uses the OFFSET
            assert np.abs(got[:, k] - expected[name]).max() < 1e-4, (path, name)
        # and the package's own positions of the file, which follow every channel, are this test's
        assert np.abs(mocapzip.bvh_joint_positions(bvh) - np.stack(list(expected.values()), axis=1)).max() < 1e-9


def test_another_bvh_library_puts_the_joints_where_we_do(shared_data):
    bvhio = pytest.importorskip("bvhio")  # a test dependency (pyproject [test]); the package never needs it
    for path in [shared_data / "cmu-bvh/10/10_03.bvh", *(shared_data / "bvh-bandai" / n for n in SOME_BANDAI)]:
        ours = file_positions(read_bvh(path))
        root = bvhio.readAsHierarchy(os.fspath(path))
        joints = [joint for joint, _, _ in root.layout()]
        for frame in (0, 17, read_bvh(path).n_frames - 1):
            root.loadPose(frame)
            theirs = np.array([joint.PositionWorld for joint in joints], dtype=np.float64)
            assert np.abs(theirs - np.array([ours[j.Name][frame] for j in joints])).max() < 1e-3, (path, frame)


def test_lossy_bvh_comes_back_within_the_bounds_and_as_bvh(shared_data, tmp_path):
    bandai = shared_data / "bvh-bandai"
    inputs = linked(tmp_path / "in", shared_data / "cmu-bvh/10/10_03.bvh", *(bandai / n for n in SOME_BANDAI))
    summary = mocapzip.compress(inputs, tmp_path / "db.mcz", error=1.0, max_error=5.0)
    assert summary["clips"] == 4
    mocapzip.decompress(tmp_path / "db.mcz", tmp_path / "out")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(p.name for p in inputs.iterdir())
    with mocapzip.open(tmp_path / "db.mcz") as archive:
        for clip in archive:
            source, written = read_bvh(inputs / clip.path), read_bvh(tmp_path / "out" / clip.path)
            assert clip.format == "bvh" and clip.fps == source.fps == written.fps
            hierarchy = split_header(source.header)[0].encode()
            assert (tmp_path / "out" / clip.path).read_bytes().startswith(hierarchy)  # as it was, line ends too
            distances = errors_cm(source, written)
            points = distances.shape[1] - (clip.path in SOME_BANDAI)  # the extra root is exact
            # the archive's mean is over the body's points; the extra root adds an exact one here
            assert distances.sum() / (distances.shape[0] * points) <= clip.error.mean_cm + 1e-3 <= 1.0 + 1e-3
            assert distances.max() <= clip.error.max_cm + 1e-3 <= 5.0 + 1e-3
            assert np.allclose(clip.positions(), mocapzip.bvh_joint_positions(written))
            with pytest.raises(AttributeError, match="is a BVH clip: it has no motion"):
                clip.motion
        walk_back = archive["dataset-1_walk-back_normal_001.bvh"]
        # its root motion is on the extra root, which comes back exactly
        assert np.array_equal(walk_back.channels[:, :6], read_bvh(inputs / walk_back.path).values[:, :6])
        assert np.ptp(walk_back.channels[:, 2]) > 50


@pytest.mark.slow
def test_every_shared_bvh_clip_comes_back_within_1_cm(shared_data, tmp_path):
    for folder in ("cmu-bvh", "bvh-bandai"):
        archive = tmp_path / f"{folder}.mcz"
        summary = mocapzip.compress(shared_data / folder, archive, error=1.0, jobs=2)
        mocapzip.decompress(archive, tmp_path / folder)
        written = sorted((tmp_path / folder).rglob("*.bvh"))
        assert len(written) == summary["clips"] == {"cmu-bvh": 4, "bvh-bandai": 174}[folder]
        for path in written:
            distances = errors_cm(read_bvh(shared_data / folder / path.relative_to(tmp_path / folder)), read_bvh(path))
            assert distances.mean() <= 1.0 and distances.max() <= 10.0 + 1e-3, path


def test_lossless_bvh_keeps_every_byte(shared_data, tmp_path):
    bandai = shared_data / "bvh-bandai"
    inputs = [shared_data / "cmu-bvh/10/10_03.bvh", *(bandai / n for n in SOME_BANDAI)]  # CMU's: mixed CRLF/LF
    mocapzip.compress(inputs, tmp_path / "db.mcz", lossless=True)
    mocapzip.decompress(tmp_path / "db.mcz", tmp_path / "out")
    for path in inputs:
        assert (tmp_path / "out" / path.name).read_bytes() == path.read_bytes(), path


@pytest.mark.slow
def test_lossless_keeps_every_byte_of_every_shared_bvh_file(shared_data, tmp_path):
    files = shared_bvh_files(shared_data)
    mocapzip.compress([shared_data / "cmu-bvh", shared_data / "bvh-bandai"], tmp_path / "db.mcz", lossless=True,
                      jobs=2)
    mocapzip.decompress(tmp_path / "db.mcz", tmp_path / "out")
    written = sorted((tmp_path / "out").rglob("*.bvh"))
    assert len(written) == len(files) == 178
    for path in files:
        relative = path.relative_to(shared_data / path.relative_to(shared_data).parts[0])
        assert (tmp_path / "out" / relative).read_bytes() == path.read_bytes(), path


def test_bvh_and_asf_amc_in_one_folder(shared_data, tmp_path):
    inputs = linked(tmp_path / "mixed", shared_data / "cmu/09/09.asf", shared_data / "cmu/09/09_01.amc",
                    shared_data / "cmu-bvh/10/10_03.bvh")
    result = CliRunner().invoke(main, ["compress", str(inputs), "-o", str(tmp_path / "db.mcz"), "-q"])
    assert result.exit_code == 0, result.output
    info = CliRunner().invoke(main, ["info", str(tmp_path / "db.mcz")])
    assert "skeletons: 1 ASF skeleton, 1 BVH hierarchy (units: cm, inferred from the skeleton)" in info.output
    assert re.search(r"10_03\.bvh +363 ", info.output) and re.search(r"09_01\.amc +148 ", info.output)
    CliRunner().invoke(main, ["decompress", str(tmp_path / "db.mcz"), "-o", str(tmp_path / "out")])
    # the ASF is written beside its AMC; a BVH file holds its own skeleton
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["09.asf", "09_01.amc", "10_03.bvh"]
    inspected = CliRunner().invoke(main, ["inspect", str(inputs)])
    assert inspected.exit_code == 0 and "2 skeletons" in inspected.output


def rescaled(bvh, factor: float):
    """`bvh` with every length (OFFSETs, End Sites, position channels) times `factor`: the same
    motion in another unit."""
    joints = [replace(j, offset=j.offset * factor, end_site=None if j.end_site is None else j.end_site * factor)
              for j in bvh.joints]
    lengths = np.array([c.endswith("position") for j in bvh.joints for c in j.channels])
    values = np.where(lengths, bvh.values * factor, bvh.values)
    return replace(bvh, joints=joints, values=values, header=None, frames_text=None)


@pytest.mark.parametrize("unit, factor, inferred", [("m", 0.01, True), ("mm", 10.0, True), ("in", 1 / 2.54, False)])
def test_the_unit_of_lengths_is_inferred_or_given(shared_data, tmp_path, unit, factor, inferred):
    source = read_bvh(shared_data / "cmu-bvh/10/10_03.bvh")
    path = tmp_path / "in" / "10_03.bvh"
    path.parent.mkdir()
    mocapzip.write_bvh(rescaled(source, factor), path)
    archive = tmp_path / "db.mcz"
    if not inferred:  # a human in inches is a child's size in cm: mcz asks
        with pytest.raises(MocapFormatError, match=r"cannot tell the unit of its OFFSETs .*give it \(--units cm\|mm\|m\|in\)"):
            mocapzip.compress(path.parent, archive)
    mocapzip.compress(path.parent, archive, units=None if inferred else unit)
    with mocapzip.open(archive) as opened:
        clip = opened[0]
        assert clip.error.mean_cm <= 1.0
        # positions in cm whatever the file's unit: the same as the source's, within the error
        distances = np.linalg.norm(clip.positions() - mocapzip.bvh_joint_positions(source), axis=-1)
        assert distances.mean() <= clip.error.mean_cm + 1e-3
    (skeleton,) = archive_info(archive)["bvh_skeletons"]
    assert (skeleton["units"], skeleton["units_inferred"]) == (unit, inferred)


def test_position_channels_that_move_are_kept_by_lossless_only(shared_data, tmp_path):
    source = read_bvh(shared_data / "bvh-bandai/dataset-1_bow_active_001.bvh")
    column = next(k for k, (j, c) in enumerate(source.columns()) if source.joints[j].name == "Spine"
                  and c == "Xposition")
    values = np.array(source.values)
    values[40:60, column] += 3.0  # the spine stretches by 3 cm: no skeleton of fixed bones can say that
    path = tmp_path / "in" / "stretch.bvh"
    path.parent.mkdir()
    mocapzip.write_bvh(replace(source, values=values, frames_text=None), path)
    with pytest.raises(MocapFormatError, match=r"stretch\.bvh: joint 'Spine' Xposition moves 3 cm from its "
                                               r"OFFSET; .*use --lossless"):
        mocapzip.compress(path, tmp_path / "lossy.mcz")
    mocapzip.compress(path, tmp_path / "lossless.mcz", lossless=True)
    with mocapzip.open(tmp_path / "lossless.mcz") as archive:
        assert np.array_equal(archive[0].channels, values)


def test_bvh_frame_rates_are_kept_and_fps_overrides_them(shared_data, tmp_path):
    inputs = [shared_data / "bvh-bandai" / SOME_BANDAI[1], shared_data / "cmu-bvh/10/10_03.bvh"]
    mocapzip.compress(inputs, tmp_path / "own.mcz")
    mocapzip.compress(inputs, tmp_path / "given.mcz", fps=60)
    with mocapzip.open(tmp_path / "own.mcz") as own, mocapzip.open(tmp_path / "given.mcz") as given:
        assert [c.fps for c in own] == [120.0, 30.0] and [c.fps for c in given] == [60.0, 60.0]
        assert [c.path for c in own] == ["10_03.bvh", SOME_BANDAI[1]]


def test_a_bvh_file_without_motion_or_with_two_roots_is_refused_in_one_line(shared_data, tmp_path):
    text = (shared_data / "bvh-bandai" / SOME_BANDAI[1]).read_text()
    hierarchy = text.split("MOTION")[0]
    cases = {"no_motion.bvh": hierarchy,
             "two_roots.bvh": hierarchy.replace("HIERARCHY", "HIERARCHY\nROOT other\n{\n OFFSET 0 0 0\n}", 1)
             + "MOTION\nFrames: 1\nFrame Time: 0.1\n" + " ".join(["0"] * 132) + "\n"}
    for name, content in cases.items():
        (tmp_path / name).write_text(content)
        result = CliRunner().invoke(main, ["compress", str(tmp_path / name), "-o", str(tmp_path / "db.mcz")])
        assert result.exit_code == 1 and not (tmp_path / "db.mcz").exists(), name
        (line,) = result.stderr.splitlines()
        assert line.startswith(f"mcz: error: {tmp_path / name}") and ("MOTION" in line or "ROOT" in line), line


def test_bvh_joint_names_of_a_skeleton(shared_data):
    bvh = read_bvh(shared_data / "bvh-bandai" / SOME_BANDAI[0])
    names = mocapzip.bvh_point_names(bvh)
    assert names[:3] == ("joint_Root", "Hips", "Spine") and names.index("Head End Site") == names.index("Head") + 1
    assert len(names) == len(bvh.joints) + sum(j.end_site is not None for j in bvh.joints)
    assert names == tuple(file_positions(bvh))
