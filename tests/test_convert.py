"""`mcz convert` (mocapzip/convert.py): ASF/AMC to BVH and back, joint positions kept within
TOLERANCE_CM, on real clips of every exporter in the shared data. Positions are measured with
Acclaim kinematics written here on the reference decoder's ASF reader (no mocapzip code), by a
plain reader written here that assumes what common readers do (`plain_positions`: dofs turned x,
y, z), and with BVH kinematics written in tests/test_bvh_pipeline.py from the BVH convention."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mocapzip.cli.main import main
from mocapzip.convert import TOLERANCE_CM, amc_to_bvh, bvh_to_amc, convert
from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.formats.bvh import read_bvh, write_bvh
from mocapzip.formats.errors import MocapFormatError
from mocapzip.motion.bvh_skeleton import bvh_skeleton
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel
from reference_decoder.geometry import Skeleton, asf_lines, euler
from test_bvh_pipeline import _rotation, file_positions

AMC_CLIPS = [("cmu/09/09.asf", "cmu/09/09_01.amc", 120.0),  # CMU: length 0.45 (inches / 0.45), 120 fps stated nowhere
             ("hdm05/bd/HDM_bd.asf", "hdm05/bd/HDM_bd_depositFloorR_001_120.amc", 120.0),
             ("other-vicon-blade/walk_200fps/walkMoCapVideo.asf",  # Vicon Blade: 200 fps in the AMC header
              "other-vicon-blade/walk_200fps/walkMoCapVideo.amc", 200.0)]
BVH_CLIPS = ["cmu-bvh/10/10_03.bvh", "bvh-bandai/dataset-1_bow_active_001.bvh"]


def asf_positions(skeleton, motion) -> tuple[tuple[str, ...], np.ndarray]:
    model = SkeletonModel.from_asf(skeleton)
    return model.names, forward(model, motion.values, motion).positions


def reference_positions(asf: Path, amc: Path) -> tuple[list[str], np.ndarray]:
    """(joint names, (frames, joints, 3) cm) of an ASF/AMC pair, read by the reference decoder's
    ASF reader (tests/reference_decoder: written from docs/format.md, no mocapzip code) and the
    AMC lines and Acclaim kinematics (R_j = C_j^T M_j C_j R_parent, T_j = T_parent + V_j R_j) here."""
    sk = Skeleton(asf.read_bytes().decode("latin-1"), False)
    frames: list[dict[str, list[float]]] = []
    for line in asf_lines(amc.read_bytes().decode("latin-1")):  # decoded as the ASF (§5): names may be UTF-8
        words = line.split()
        if words[0][0] == ":":
            continue
        if len(words) == 1 and words[0].isdigit():
            frames.append({})
        else:
            frames[-1][words[0]] = [float(w) for w in words[1:]]
    unit = 1.0 if sk.radians else np.pi / 180
    rotations, positions = [], []
    for j, name in enumerate(sk.names):
        values = np.array([frame.get(name, [0.0] * len(sk.channels[j])) for frame in frames])
        angles = [values[:, k] * unit for k, c in enumerate(sk.channels[j]) if c[0] == "r"]
        m = euler(np.stack(angles, axis=-1), sk.axes[j]) if angles else np.eye(3)[None]
        parent = sk.parent[j]
        r = sk.C[j].T @ m @ sk.C[j] @ (rotations[parent] if parent >= 0 else np.eye(3))
        rotations.append(np.broadcast_to(r, (len(frames), 3, 3)))
        if parent < 0:
            t = np.zeros((len(frames), 3))
            for k, c in enumerate(sk.channels[j]):
                if c[0] == "t":
                    t[:, "xyz".index(c[1])] = values[:, k] * sk.cm_per_unit
        else:
            t = positions[parent] + np.einsum("i,fij->fj", sk.V[j], rotations[j])
        positions.append(t)
    return sk.names, np.stack(positions, axis=1)


def plain_positions(asf: Path, amc: Path) -> tuple[list[str], np.ndarray]:
    """(joint names, (frames, joints, 3) cm) of an ASF/AMC pair as a plain reader takes it (as common
    Python readers of CMU's files do): `:units length` a number, file units per inch; a line's angles
    taken by their dof names and turned x first, then y, then z, whatever order the dof line gives;
    R_j = R_parent C_j M_j C_j^-1, T_j = T_parent + R_j V_j in column vectors."""
    sections, bones, children = {}, {}, {}
    for line in asf.read_bytes().decode("utf-8").split("\n"):
        words = line.split()
        if words and words[0][0] == ":":
            section = sections.setdefault(words[0], [])
        elif words and words[0][0] != "#":
            section.append(words)
    cm = 2.54 / float(dict(sections[":units"])["length"])
    for words in sections[":bonedata"]:
        if words[0] == "begin":
            bone = {}
        elif words[0] == "name":
            bones[words[1]] = bone
        bone[words[0]] = words[1:]
    for words in sections[":hierarchy"][1:-1]:
        children[words[0]] = words[1:]
    frames = []
    for line in amc.read_bytes().decode("utf-8").split("\n"):
        words = line.split()
        if len(words) == 1 and words[0].isdigit():
            frames.append({})
        elif words and words[0][0] not in ":#":
            frames[-1][words[0]] = np.array(words[1:], dtype=float)

    def turn(angles) -> np.ndarray:  # (frames, 3) radians about x, y, z; x turns first
        return _rotation(2, angles[:, 2]) @ _rotation(1, angles[:, 1]) @ _rotation(0, angles[:, 0])

    def values(name: str, dof: list[str]) -> tuple[np.ndarray, np.ndarray]:  # (angles in radians, translation in cm)
        columns = np.array([frame[name] if dof else [] for frame in frames]).reshape(len(frames), len(dof))
        by_dof = {d.lower(): columns[:, k] for k, d in enumerate(dof)}
        return (np.radians(np.stack([by_dof.get("r" + a, np.zeros(len(frames))) for a in "xyz"], axis=1)),
                np.stack([by_dof.get("t" + a, np.zeros(len(frames))) * cm for a in "xyz"], axis=1))

    names, rotations, positions = ["root"], [], []
    angles, translation = values("root", dict((w[0], w[1:]) for w in sections[":root"])["order"])
    rotations.append(turn(angles))
    positions.append(translation)
    stack = [(child, 0) for child in reversed(children.get("root", []))]
    while stack:  # depth first, children in file order
        name, parent = stack.pop()
        bone = bones[name]
        c = turn(np.radians(np.array([bone["axis"][:3]], dtype=float)))
        assert bone["axis"][3] == "XYZ"
        rotations.append(rotations[parent] @ c @ turn(values(name, bone.get("dof", []))[0]) @ np.swapaxes(c, 1, 2))
        vector = np.array(bone["direction"], dtype=float) * float(bone["length"][0]) * cm
        positions.append(positions[parent] + rotations[-1] @ vector)
        names.append(name)
        stack.extend((child, len(names) - 1) for child in reversed(children.get(name, [])))
    return names, np.stack(positions, axis=1)


@pytest.mark.parametrize("asf, amc, fps", AMC_CLIPS, ids=lambda v: str(v).split("/")[0])
def test_amc_to_bvh_puts_every_joint_where_it_was(shared_data, tmp_path, asf, amc, fps):
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(shared_data / amc), "--asf", str(shared_data / asf), "-o", str(out)])
    assert result.exit_code == 0, result.output
    skeleton = read_asf(shared_data / asf)
    names, expected = asf_positions(skeleton, read_amc(shared_data / amc, skeleton))
    reference_names, reference = reference_positions(shared_data / asf, shared_data / amc)
    assert list(names) == reference_names and np.abs(reference - expected).max() < 1e-9  # two readers agree
    written = read_bvh(out / (amc.rsplit("/", 1)[1][:-4] + ".bvh"))
    assert written.fps == fps and written.n_frames == len(expected)
    got = file_positions(written)  # {joint or "<joint> End Site": cm (the BVH is in cm)}
    model = SkeletonModel.from_asf(skeleton)
    for j, name in enumerate(names):  # an ASF joint is the end of its bone: its first child's start, or an End Site
        children = [model.names[k] for k in range(model.n_joints) if model.parents[k] == j]
        point = name if j == 0 else children[0] if children else f"{name} End Site"
        assert np.abs(got[point] - expected[:, j]).max() < TOLERANCE_CM, (amc, name)


@pytest.mark.parametrize("path", BVH_CLIPS, ids=lambda p: p.split("/")[0])
def test_bvh_to_amc_puts_every_joint_where_it_was(shared_data, tmp_path, path):
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(shared_data / path), "-o", str(out)])
    assert result.exit_code == 0, result.output
    stem = path.rsplit("/", 1)[1][:-4]
    assert sorted(p.name for p in out.iterdir()) == [f"{stem}.amc", f"{stem}.asf"]
    source = read_bvh(shared_data / path)
    skeleton = read_asf(out / f"{stem}.asf")
    assert skeleton.frame_rate == source.fps and skeleton.length_scale == 2.54  # lengths in cm
    names, got = reference_positions(out / f"{stem}.asf", out / f"{stem}.amc")  # read by a reader not ours
    expected = file_positions(source)
    points = bvh_skeleton(source.joints, None).model.points  # which BVH point each ASF joint is
    assert len(points) == len(names)
    for j, point in enumerate(points):
        assert np.abs(got[:, j] - expected[point]).max() < TOLERANCE_CM, (path, point)


def test_the_plain_reader_reads_cmus_files_as_mcz_does(shared_data):
    """`plain_positions` is right where CMU's files are: bone axes, dofs `rx rz`, `ry`, ..., `length 0.45`."""
    names, plain = plain_positions(shared_data / AMC_CLIPS[0][0], shared_data / AMC_CLIPS[0][1])
    skeleton = read_asf(shared_data / AMC_CLIPS[0][0])
    mcz_names, positions = asf_positions(skeleton, read_amc(shared_data / AMC_CLIPS[0][1], skeleton))
    assert names == list(mcz_names) and np.abs(plain - positions).max() < 1e-9


@pytest.mark.parametrize("path", BVH_CLIPS, ids=lambda p: p.split("/")[0])
def test_bvh_to_amc_writes_what_a_plain_reader_reads(shared_data, tmp_path, path):
    """Lengths in cm as a number (`length 2.54`: file units per inch), dofs `rx ry rz` as CMU's:
    a reader that assumes them puts every joint where mcz does and where the BVH has it. With
    `length cm` and the BVH's turn order (`ry rx rz`) it could not read the units, and read with
    them it put Bandai's joints 19 cm off on average, CMU BVH's 4.5."""
    assert convert([shared_data / path], tmp_path)["clips"] == 1
    stem = path.rsplit("/", 1)[1][:-4]
    asf, amc = tmp_path / f"{stem}.asf", tmp_path / f"{stem}.amc"
    skeleton = read_asf(asf)
    assert skeleton.units["length"] == "2.54" and skeleton.cm_per_unit == 1.0
    assert skeleton.root_order == ("TX", "TY", "TZ", "RX", "RY", "RZ")
    assert {bone.dof for bone in skeleton.bones} == {(), ("rx", "ry", "rz")}  # link bones turn with their joint
    names, plain = plain_positions(asf, amc)
    mcz_names, positions = asf_positions(skeleton, read_amc(amc, skeleton))
    assert names == list(mcz_names) and np.abs(plain - positions).max() < TOLERANCE_CM
    source = read_bvh(shared_data / path)
    expected = file_positions(source)
    for j, point in enumerate(bvh_skeleton(source.joints, None).model.points):
        assert np.abs(plain[:, j] - expected[point]).max() < TOLERANCE_CM, (path, point)


def test_bvh_to_amc_angles_change_from_frame_to_frame_no_more_than_the_bvhs(shared_data, tmp_path):
    """Bandai's shoulders turn about y by about 90 degrees, the gimbal lock of `rx ry rz` about the
    BVH's axes: written so, this clip's angles jumped by 90 degrees in a frame where the BVH's move
    21 at most. Each bone keeps the BVH's angles in a frame of its own (its `axis`)."""
    path = shared_data / "bvh-bandai/dataset-1_byebye_giant_001.bvh"
    assert convert([path], tmp_path)["clips"] == 1
    skeleton = read_asf(tmp_path / f"{path.stem}.asf")
    motion = read_amc(tmp_path / f"{path.stem}.amc", skeleton)
    source = read_bvh(path)

    def largest_step(angles: np.ndarray) -> float:  # degrees, modulo 360
        return float(np.abs((np.diff(angles, axis=0) + 180) % 360 - 180).max())

    bones = [c[0] == "r" and bone != "root" for bone in motion.bones for c in skeleton.dof_of(bone)]
    root = bvh_skeleton(source.joints, None).model.names[0]  # Hips, below an extra root that stands still
    joints = [c.endswith("rotation") and joint.name != root for joint in source.joints for c in joint.channels]
    assert largest_step(motion.values[:, bones]) <= largest_step(source.values[:, joints]) < 25


def test_amc_to_bvh_and_back_keeps_the_joints(shared_data, tmp_path):
    skeleton = read_asf(shared_data / "cmu/09/09.asf")
    motion = read_amc(shared_data / "cmu/09/09_01.amc", skeleton)
    bvh = amc_to_bvh(skeleton, motion, 120.0)
    back_skeleton, back_motion = bvh_to_amc(replace(bvh, path=str(tmp_path / "09_01.bvh")), "cm")
    _, before = asf_positions(skeleton, motion)
    _, after = asf_positions(back_skeleton, back_motion)
    # in memory, nothing printed: every joint of the source is, exactly, one of the round trip's
    for j in range(before.shape[1]):
        assert np.min(np.abs(after - before[:, j : j + 1]).max(axis=(0, 2))) < 1e-9


def test_a_bvh_whose_extra_root_moves_is_refused(shared_data, tmp_path):
    path = shared_data / "bvh-bandai/dataset-1_walk-back_normal_001.bvh"
    with pytest.raises(MocapFormatError, match="its extra root 'joint_Root' moves: an ASF skeleton has one root"):
        bvh_to_amc(read_bvh(path))
    result = CliRunner().invoke(main, ["convert", str(path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 1 and "its extra root 'joint_Root' moves" in result.stderr


def test_a_bvh_in_millimetres_comes_out_in_cm_at_the_same_places(shared_data, tmp_path):
    source = read_bvh(shared_data / BVH_CLIPS[0])
    lengths = np.array([c.endswith("position") for j in source.joints for c in j.channels])
    in_mm = replace(source, joints=[replace(j, offset=j.offset * 10,
                                            end_site=None if j.end_site is None else j.end_site * 10)
                                    for j in source.joints],
                    values=np.where(lengths, source.values * 10, source.values), header=None, frames_text=None)
    (tmp_path / "in").mkdir()
    write_bvh(in_mm, tmp_path / "in" / "mm.bvh")
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "in"), "-o", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    names, got = reference_positions(tmp_path / "out" / "mm.asf", tmp_path / "out" / "mm.amc")
    expected = file_positions(source)  # the cm original
    for j, point in enumerate(bvh_skeleton(source.joints, None).model.points):
        assert np.abs(got[:, j] - expected[point]).max() < TOLERANCE_CM, point


def test_convert_never_writes_over_an_input_and_writes_nothing_unless_every_clip_converts(shared_data, tmp_path):
    folder = tmp_path / "clips"
    folder.mkdir()
    (folder / "10_03.bvh").write_bytes((shared_data / BVH_CLIPS[0]).read_bytes())
    (folder / "09.asf").write_bytes((shared_data / "cmu/09/09.asf").read_bytes())
    (folder / "10_03.amc").write_bytes((shared_data / "cmu/09/09_01.amc").read_bytes())  # what 10_03.bvh would become
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    result = CliRunner().invoke(main, ["convert", str(folder), "-o", str(folder), "-f"])
    assert result.exit_code == 1 and "is an input: convert never writes over one" in result.stderr
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    # a clip that cannot be converted stops the run before any file is written ...
    moving = shared_data / "bvh-bandai/dataset-1_walk-back_normal_001.bvh"  # its extra root moves
    inputs = [str(shared_data / BVH_CLIPS[1]), str(moving)]
    result = CliRunner().invoke(main, ["convert", *inputs, "-o", str(tmp_path / "out")])
    assert result.exit_code == 1 and not (tmp_path / "out").exists()
    # ... or, with --skip-bad, is left out and named
    result = CliRunner().invoke(main, ["convert", *inputs, "-o", str(tmp_path / "out"), "--skip-bad"])
    assert result.exit_code == 0 and "skipped dataset-1_walk-back_normal_001.bvh" in result.stderr
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["dataset-1_bow_active_001.amc",
                                                                    "dataset-1_bow_active_001.asf"]


def test_names_with_dots_keep_them_and_two_clips_never_share_a_file(shared_data, tmp_path):
    folder = tmp_path / "takes"
    folder.mkdir()
    for name in ("Take 02.55.01.bvh", "Take 02.55.02.bvh"):
        (folder / name).symlink_to(shared_data / BVH_CLIPS[0])
    result = CliRunner().invoke(main, ["convert", str(folder), "-o", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "Take 02.55.01.amc", "Take 02.55.01.asf", "Take 02.55.02.amc", "Take 02.55.02.asf"]
    (folder / "Take 02.55.01.BVH").symlink_to(shared_data / BVH_CLIPS[1])  # would be written where .bvh's is
    result = CliRunner().invoke(main, ["convert", str(folder), "-o", str(tmp_path / "out2")])
    assert result.exit_code == 1 and "two clips would be written to Take 02.55.01.amc" in result.stderr
    assert not (tmp_path / "out2").exists()


def test_a_joint_named_root_that_is_not_the_root_is_escaped_and_named_again_on_the_way_back(shared_data, tmp_path):
    text = (shared_data / BVH_CLIPS[0]).read_bytes().replace(b"JOINT abdomen", b"JOINT root", 1)
    (tmp_path / "x.bvh").write_bytes(text)
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "x.bvh"), "-o", str(tmp_path / "amc")])
    assert result.exit_code == 0, result.output
    skeleton = read_asf(tmp_path / "amc" / "x.asf")  # ASF keeps `root` for its root (docs/bvh.md, "Names")
    assert "%72oot" in [b.name for b in skeleton.bones] and "root" not in [b.name for b in skeleton.bones]
    assert {'bvh-name root "hip"', 'bvh-name %72oot "root"'} <= set(skeleton.documentation)
    source = read_bvh(tmp_path / "x.bvh")
    names, got = reference_positions(tmp_path / "amc" / "x.asf", tmp_path / "amc" / "x.amc")
    expected = file_positions(source)
    for j, point in enumerate(bvh_skeleton(source.joints, None).model.points):
        assert np.abs(got[:, j] - expected[point]).max() < TOLERANCE_CM, point
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "amc"), "-o", str(tmp_path / "bvh")])
    assert result.exit_code == 0, result.output
    back = read_bvh(tmp_path / "bvh" / "x.bvh")
    assert back.joints[0].name == "hip" and "root" in [j.name for j in back.joints]
    assert np.abs(file_positions(back)["root"] - expected["root"]).max() < TOLERANCE_CM
