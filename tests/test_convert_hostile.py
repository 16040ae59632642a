"""`mcz convert` on hostile and generated clips (issue 40): whatever it writes, mcz's own readers
read back to the same joints, names and motion; what they could not, it refuses in one line
naming the clip, and writes nothing (docs/bvh.md, "Converting" and "Names").

Generated BVH hierarchies (tree shapes, channel layouts, names of every kind) go to ASF/AMC and
back, generated ASF skeletons with names a BVH cannot hold to BVH. Joint positions are measured
by kinematics written in the tests (tests/test_bvh_pipeline.py's BVH convention, test_convert.py's
Acclaim kinematics on the reference decoder's ASF reader); names are read back as docs/bvh.md
tells a stranger to: a `bvh-name` record, else each `%XX` decoded."""

from __future__ import annotations

import json
import re
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hostile_inputs import chain_skeleton
from mocapzip import convert as convert_module
from mocapzip.cli.main import main
from mocapzip.convert import ACCLAIM_ORDER, TOLERANCE_CM, bvh_to_amc, convert
from mocapzip.formats.amc import MAX_AMC_BYTES, format_amc, parse_amc, read_amc
from mocapzip.formats.asf import format_asf, parse_asf, read_asf
from mocapzip.formats.bvh import Bvh, BvhJoint, BvhStyle, format_bvh, read_bvh
from mocapzip.limits import MAX_BONES_PER_SKELETON
from mocapzip.motion.bvh_skeleton import bvh_skeleton
from mocapzip.motion.skeleton import SkeletonModel
from test_bvh_pipeline import file_positions
from test_convert import asf_positions, plain_positions, reference_positions

POSITIONS = ("Xposition", "Yposition", "Zposition")
ROTATIONS = ("Xrotation", "Yrotation", "Zrotation")
KEYWORDS = ("HIERARCHY", "ROOT", "JOINT", "End", "Site", "OFFSET", "CHANNELS", "MOTION", "Frames:", "Frame",
            "Time:", "root", "Root", "end", "END", "begin", "Begin", "{x", "x}")
SETTINGS = settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def one_word(name: str) -> bool:
    return bool(name) and not any(c.isspace() for c in name)


# Names a BVH file holds (one word, not a lone brace), of every kind a target may not hold.
BVH_NAMES = st.one_of(
    st.from_regex(r"[A-Za-z_][A-Za-z0-9_.-]{0,8}", fullmatch=True),
    st.from_regex(r"[0-9]{1,4}", fullmatch=True),  # an AMC frame number
    st.sampled_from(["1e5", "-3", "+2.5", ".5", "007", "1.", "-0", "1E-3"]),  # other numbers
    st.from_regex(r"[:#][A-Za-z0-9:#]{0,6}", fullmatch=True),  # an ASF section or a comment
    st.sampled_from([":hierarchy", ":DEGREES", ":bonedata", ":root", "#", ":"]),
    st.sampled_from(KEYWORDS),
    st.from_regex(r"[a-z]{0,3}[{}][a-z{}]{0,3}", fullmatch=True).filter(lambda n: n not in ("{", "}")),
    st.from_regex(r"[a-z]{0,2}%[0-9A-Fa-f%]{0,4}", fullmatch=True),  # escapes, and what only looks like one
    st.sampled_from(["%7B", "%3123", "%72oot", "%", "%25", "50%", "%3Ahierarchy"]),
    st.from_regex(r"[a-z]{0,2}>[a-z>]{0,3}", fullmatch=True),  # a link bone's mark
    st.sampled_from(["~2", "a~2", "x>end", "x>y", "end"]),
    st.text(st.characters(exclude_categories=("Cs", "Cc", "Zs", "Zl", "Zp")), min_size=1, max_size=5),  # unicode
    st.integers(500, 3000).map(lambda n: "ä" * n),  # long
).filter(lambda n: one_word(n) and n not in ("{", "}"))


def values_of(joints, draw, frames: int) -> np.ndarray:
    """Frames of values: the root's positions and every angle random (exact in 3 decimals), the
    other position channels their OFFSET (bones keep their length, as an ASF's do)."""
    columns = []
    for j, joint in enumerate(joints):
        for channel in joint.channels:
            if channel in POSITIONS and j:
                columns.append(np.full(frames, joint.offset[POSITIONS.index(channel)]))
            else:
                bound = 100_000 if channel in POSITIONS else 400_000
                picked = draw(st.lists(st.integers(-bound, bound), min_size=frames, max_size=frames))
                columns.append(np.array(picked) / 1000)
    return np.stack(columns, axis=1) if columns else np.zeros((frames, 0))


def vectors(draw, low: int, high: int) -> np.ndarray:
    return np.array(draw(st.lists(st.integers(low, high), min_size=3, max_size=3))) / 100


def words(values) -> str:
    return " ".join(map(str, values))


@st.composite
def bvh_clips(draw) -> Bvh:
    """A BVH clip of 1 to 7 joints: any tree (joints in file order), the root's position channels and
    any rotations in any order, position channels on joints below the root's children, End Sites
    on leaves or not, 1 to 3 frames."""
    count = draw(st.integers(1, 7))
    chosen = draw(st.lists(BVH_NAMES, min_size=count, max_size=count, unique=True))
    parents, path = [-1], [0]  # path: the joints a next joint may hang from, in file order
    for k in range(1, count):
        path = path[: draw(st.integers(1, len(path)))]
        parents.append(path[-1])
        path.append(k)
    joints = []
    for k, name in enumerate(chosen):
        rotations = list(draw(st.permutations(ROTATIONS)))[: draw(st.integers(0, 3))]
        positions = list(POSITIONS) if k == 0 or (parents[k] > 0 and draw(st.booleans())) else []
        leaf = k not in parents
        end_site = vectors(draw, -3000, 3000) if draw(st.booleans()) and (leaf or draw(st.booleans())) else None
        channels = tuple(draw(st.permutations(positions + rotations)))
        joints.append(BvhJoint(name, parents[k], vectors(draw, -3000, 3000), channels, end_site))
    values = values_of(joints, draw, draw(st.integers(1, 3)))
    return Bvh(joints, 1 / 30, values, style=BvhStyle("repr"))


def recorded_names(asf: Path) -> dict[str, str]:
    """The ASF's `bvh-name <bone> <JSON string>` lines (docs/bvh.md, "Names")."""
    lines = (line.split(None, 2) for line in read_asf(asf).documentation)
    return {words[1]: json.loads(words[2]) for words in lines if words[0] == "bvh-name"}


def unescaped(name: str) -> str:
    """Each `%XX` of `name` decoded (docs/bvh.md, "Names")."""
    return re.sub(rb"%([0-9A-F]{2})", lambda m: bytes([int(m[1], 16)]), name.encode()).decode(errors="replace")


def model_of_shape(joints):
    """The codec's model of a hierarchy's shape (its joints named j0, j1, ...: names that clash with
    nothing), and each model joint's BVH point by the hierarchy's own names."""
    model = bvh_skeleton([BvhJoint(f"j{k}", j.parent, j.offset, j.channels, j.end_site) for k, j in enumerate(joints)],
                         "cm").model
    named = {f"j{k}": joint.name for k, joint in enumerate(joints)}
    points = [named[p] if p in named else f"{named[p.split()[0]]} End Site" for p in model.points]
    return model, points


def check_bvh_round_trip(bvh: Bvh, folder: Path, encoding: str = "utf-8") -> None:
    """BVH -> ASF/AMC -> BVH: each file as mcz reads it has the source's joint positions, and its
    names are the source's, or recorded (ASF), or given back (BVH)."""
    (folder / "in").mkdir()
    (folder / "in" / "clip.bvh").write_bytes(format_bvh(bvh).encode(encoding))
    source = read_bvh(folder / "in" / "clip.bvh")
    assert [j.name for j in source.joints] == [j.name for j in bvh.joints]  # the input is what was made
    expected = file_positions(source)

    convert([folder / "in"], folder / "amc", units="cm")
    asf, amc = folder / "amc" / "clip.asf", folder / "amc" / "clip.amc"
    skeleton = read_asf(asf)
    SkeletonModel.from_asf(skeleton)  # mcz models it
    parse_amc(amc.read_bytes(), str(amc), skeleton, partial_last_frame="error")
    names, got = reference_positions(asf, amc)
    model, points = model_of_shape(source.joints)
    assert len(names) == len(points)
    for j, point in enumerate(points):
        assert np.abs(got[:, j] - expected[point]).max() < TOLERANCE_CM, point
    for dof in (tuple(c.lower() for c in skeleton.root_order), *(bone.dof for bone in skeleton.bones)):
        assert list(dof) == sorted(dof, key=ACCLAIM_ORDER.index)  # `tx ty tz rx ry rz`, or some of them
    plain_names, plain = plain_positions(asf, amc)  # a reader that turns x, y, z whatever the dof order
    assert plain_names == names and np.abs(plain - got).max() < TOLERANCE_CM
    recorded = recorded_names(asf)
    assert recorded.get("root", "root") == source.joints[0].name
    for bone, shape_name in zip(skeleton.bones, model.names[1:]):
        if ">" not in shape_name:  # a joint's own bone, not a link: its name, decoded, or recorded
            name = source.joints[int(shape_name[1:])].name
            assert recorded[bone.name] == name if bone.name in recorded else bone.name in (name, unescaped(name))

    convert([folder / "amc"], folder / "bvh")
    back = read_bvh(folder / "bvh" / "clip.bvh")
    back_positions = file_positions(back)
    assert back.joints[0].name == source.joints[0].name
    for joint in source.joints:  # each joint with a bone of its own comes back by its name, where it was
        if any(c in ROTATIONS for c in joint.channels) or joint.parent < 0:
            assert np.abs(back_positions[joint.name] - expected[joint.name]).max() < TOLERANCE_CM


@SETTINGS
@given(bvh_clips())
def test_generated_bvh_clips_go_to_asf_amc_and_back_with_their_joints_and_names(bvh):
    with tempfile.TemporaryDirectory() as folder:
        check_bvh_round_trip(bvh, Path(folder))


def a_clip_with(name: str) -> Bvh:
    """A hip, a child named `name` with an End Site, and a second child (so a link bone too)."""
    turns, leg = ("Zrotation", "Xrotation", "Yrotation"), np.array([0, -40.0, 0])
    joints = [BvhJoint("hip", -1, np.zeros(3), POSITIONS + turns),
              BvhJoint(name, 0, np.array([10.0, 0, 0]), turns, leg),
              BvhJoint("other", 0, np.array([-10.0, 0, 0]), turns, leg)]
    values = np.array([[1.5, 90, -2, 10, 20, 30, -45, 30, 60, 5, 6, 7],
                       [2, 91, -3, 11, 21, 31, 50, -35, 170, 8, 9, 10]])
    return Bvh(joints, 1 / 30, values, style=BvhStyle("repr"))


@pytest.mark.parametrize("name, encoding", [("123", "utf-8"), (":hierarchy", "utf-8"), (":DEGREES", "utf-8"),
                                            ("#x", "utf-8"), ("root", "utf-8"), ("end", "utf-8"), ("x>end", "utf-8"),
                                            ("1e5", "utf-8"), ("Ärm", "latin-1"), ("%3123", "utf-8")])
def test_the_names_that_made_convert_write_what_mcz_misreads_come_back(tmp_path, name, encoding):
    check_bvh_round_trip(a_clip_with(name), tmp_path, encoding)


# Names an ASF/AMC holds (mcz's readers and the reference decoder's), of every kind a BVH may not.
ASF_NAMES = st.one_of(
    st.from_regex(r"[A-Za-z_][A-Za-z0-9_.-]{0,8}", fullmatch=True),
    st.sampled_from(["{", "}", "{}", "a{b", "x}", "JOINT", "End", "Site", "ROOT", "OFFSET", "CHANNELS", "MOTION",
                     "HIERARCHY", "%7B", "%4AOINT", "%", "%25", "50%", "a>b", "b>end", "~2", "{~2"]),
    st.from_regex(r"[a-z]{0,2}[{}%>][a-zA-Z0-9{}%>]{0,4}", fullmatch=True),
    st.text(st.characters(exclude_categories=("Cs", "Cc", "Zs", "Zl", "Zp")), min_size=1, max_size=5),
    st.integers(500, 3000).map(lambda n: "\u8155" * n),
).filter(lambda n: one_word(n) and n[0] not in ":#" and n.lower() not in ("root", "begin", "end")
         and not re.fullmatch(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?", n, re.ASCII))


# Names mcz's ASF and AMC readers read, but not every reader (the reference decoder ends a hierarchy
# at a line led by `end`): an ASF/AMC to BVH and back gives them back as they were.
ASF_READ_NAMES = st.one_of(
    ASF_NAMES,
    st.sampled_from(["End", "end", "END", "begin", "Begin", "ROOT", "Root", "%45nd", "%65nd", "%2545nd", "%52OOT",
                     "%72oot", "a>b", "x>end", "a%3Eb", "１２３", "١٢٣", "²", "x²"]),
)


@st.composite
def asf_amc_clips(draw, bone_names=ASF_NAMES) -> tuple[str, str, list[str]]:
    """(ASF text, AMC text, bone names): 1 to 6 bones in any tree below the root, each with any
    direction, length, axis and any subset of rx ry rz in any order; 1 to 3 frames of angles."""
    count = draw(st.integers(1, 6))
    names = draw(st.lists(bone_names, min_size=count, max_size=count, unique=True))
    parents = [draw(st.integers(-1, k - 1)) for k in range(count)]  # -1: the root
    dofs = [list(draw(st.permutations(("rx", "ry", "rz"))))[: draw(st.integers(0, 3))] for _ in names]
    bones = "".join(f"  begin\n    id {k + 1}\n    name {name}\n"
                    f"    direction {words(vectors(draw, -100, 100) + 0.01)}\n"
                    f"    length {draw(st.integers(1, 4000)) / 100}\n    axis {words(vectors(draw, -9000, 9000))} XYZ\n"
                    + (f"    dof {' '.join(dofs[k])}\n" if dofs[k] else "") + "  end\n" for k, name in enumerate(names))
    children = {p: [names[k] for k in range(count) if parents[k] == p] for p in range(-1, count)}
    hierarchy = "".join(f"    {'root' if p < 0 else names[p]} {' '.join(kids)}\n"
                        for p, kids in children.items() if kids)
    asf = (":version 1.10\n:name generated\n:units\n  mass 1.0\n  length 1\n  angle deg\n:root\n"
           "  order TX TY TZ RX RY RZ\n  axis XYZ\n  position 0 0 0\n  orientation 0 0 0\n"
           f":bonedata\n{bones}:hierarchy\n  begin\n{hierarchy}  end\n")

    def numbers(count: int, bound: int) -> str:
        return words(v / 1000 for v in draw(st.lists(st.integers(-bound, bound), min_size=count, max_size=count)))

    frames = "".join(f"{f}\nroot {numbers(3, 50_000)} {numbers(3, 400_000)}\n"
                     + "".join(f"{name} {numbers(len(dofs[k]), 400_000)}\n" for k, name in enumerate(names) if dofs[k])
                     for f in range(1, draw(st.integers(1, 3)) + 1))
    return asf, ":FULLY-SPECIFIED\n:DEGREES\n" + frames, names


@SETTINGS
@given(asf_amc_clips())
def test_generated_asf_amc_clips_go_to_bvh_with_their_joints_and_names(clip):
    asf_text, amc_text, bone_names = clip
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        (folder / "in").mkdir()
        asf, amc = folder / "in" / "clip.asf", folder / "in" / "clip.amc"
        asf.write_text(asf_text, encoding="utf-8")
        amc.write_text(amc_text, encoding="utf-8")
        assert [b.name for b in read_asf(asf).bones] == bone_names  # the input is what was made
        names, expected = reference_positions(asf, amc)

        convert([folder / "in"], folder / "bvh")
        bvh = read_bvh(folder / "bvh" / "clip.bvh")
        model = SkeletonModel.from_asf(read_asf(asf))
        assert list(model.names) == names and len(bvh.joints) == len(names)
        got = file_positions(bvh)
        for j, (joint, name) in enumerate(zip(bvh.joints, names)):
            assert name in (joint.name, unescaped(joint.name)), (joint.name, name)  # no two escape alike
            first_child = next((joint_k.name for joint_k in bvh.joints if joint_k.parent == j), None)
            point = joint.name if j == 0 else first_child or f"{joint.name} End Site"
            assert np.abs(got[point] - expected[:, j]).max() < TOLERANCE_CM, name


def asf_positions_by_name(asf: Path, amc: Path) -> dict[str, np.ndarray]:
    """{joint: (frames, 3) cm} of an ASF/AMC pair as mcz reads it (the root and each bone's end)."""
    names, positions = asf_positions(read_asf(asf), read_amc(amc, read_asf(asf)))
    return dict(zip(names, np.moveaxis(positions, 1, 0)))


def check_asf_amc_round_trip(folder: Path, asf: str, stem: str) -> None:
    """ASF/AMC (`folder/in/<asf>`, `<stem>.amc`) -> BVH -> ASF/AMC: each bone comes back by its own
    name, its end where it was."""
    convert([folder / "in"], folder / "bvh")
    convert([folder / "bvh"], folder / "back", units="cm")  # the lengths ASF/AMC to BVH writes
    before = asf_positions_by_name(folder / "in" / asf, folder / "in" / f"{stem}.amc")
    after = asf_positions_by_name(folder / "back" / f"{stem}.asf", folder / "back" / f"{stem}.amc")
    for name, positions in before.items():
        assert name in after, (name, sorted(after))
        assert np.linalg.norm(after[name] - positions, axis=-1).max() < TOLERANCE_CM, name


@SETTINGS
@given(asf_amc_clips(ASF_READ_NAMES))
def test_generated_asf_amc_clips_go_to_bvh_and_back_with_their_names(clip):
    asf_text, amc_text, bone_names = clip
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        (folder / "in").mkdir()
        (folder / "in" / "clip.asf").write_text(asf_text, encoding="utf-8")
        (folder / "in" / "clip.amc").write_text(amc_text, encoding="utf-8")
        assert [b.name for b in read_asf(folder / "in" / "clip.asf").bones] == bone_names
        check_asf_amc_round_trip(folder, "clip.asf", "clip")


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.text(st.characters(exclude_categories=("Cs",)), min_size=1, max_size=6),
                 st.from_regex(r"[+-]?[0-9\uff10-\uff19\u0660-\u0669\u00b2\u00b3.eE]{1,5}", fullmatch=True)))
def test_a_name_convert_writes_as_it_is_is_a_bone_line_of_the_amc(name):
    """Convert and the AMC reader agree on what a frame's number is: a line of ASCII digits, while
    `１２３`, `١٢٣` and `²` are bone names (docs/bvh.md, "Names")."""
    if convert_module._asf_reads(name):
        motion = parse_amc(f"1\nroot 0 0 0 0 0 0\n{name} 1.5\n".encode(), partial_last_frame="error")
        assert (motion.bones, motion.n_frames) == (["root", name], 1)


def renamed(text: bytes, names: dict[str, str], lead: bytes = b"") -> bytes:
    """`text` with each word `lead` + a key of `names` (a whole word) named the key's value."""
    for old, new in names.items():
        text = re.sub(rb"(?<!\S)(" + lead + rb")" + re.escape(old.encode()) + rb"(?!\S)",
                      lambda m: m[1] + new.encode(), text)
    return text


# Bones of the same file whose names a BVH cannot hold, or hold only escaped, or which are escapes;
# names of Unicode digits, which an AMC line does not take for a frame's number.
RENAMES = [{"lfemur": "End", "rfemur": "%45nd"}, {"lfemur": "{", "rfemur": "%7B"}, {"lfemur": "%7B"},
           {"lowerback": "ROOT", "upperback": "end", "thorax": "a>b", "lhumerus": "begin", "rhumerus": "50%"},
           {"lfemur": "１２３", "rfemur": "١٢٣", "lhumerus": "²", "rhumerus": "x٣"}]


@pytest.mark.parametrize("names", RENAMES, ids=lambda names: " ".join(names.values()))
def test_cmu_bones_go_to_bvh_and_back_with_their_names(shared_data, tmp_path, names):
    """A name is escaped only where both formats cannot hold it as it is, and no two alike: the
    left femur named `End` and the right `%45nd` were a BVH's `%45nd` and `%45nd~2`, and the ASF
    they came back to had `%45nd` on the left femur."""
    (tmp_path / "in").mkdir()
    for name in ("01.asf", "01_01.amc"):
        (tmp_path / "in" / name).write_bytes(renamed((shared_data / "cmu/01" / name).read_bytes(), names))
    assert set(names.values()) <= {b.name for b in read_asf(tmp_path / "in" / "01.asf").bones}
    check_asf_amc_round_trip(tmp_path, "01.asf", "01_01")


@pytest.mark.parametrize("names", [{"lThigh": "End", "rThigh": "%45nd", "lShldr": "ROOT", "rShldr": "Site"},
                                   {"lThigh": "１２３", "rThigh": "١٢٣", "neck": "²", "lShldr": "%7B", "rShldr": "a>b"}],
                         ids=lambda names: " ".join(names.values()))
def test_cmu_bvh_joints_go_to_asf_amc_and_back_with_their_names(shared_data, tmp_path, names):
    """mcz reads a BVH joint named `End` or `ROOT`; the ASF records what it cannot hold as it is."""
    (tmp_path / "in").mkdir()
    text = renamed((shared_data / "cmu-bvh/10/10_03.bvh").read_bytes(), names, lead=b"JOINT ")
    (tmp_path / "in" / "10_03.bvh").write_bytes(text)
    source = read_bvh(tmp_path / "in" / "10_03.bvh")
    assert set(names.values()) <= {j.name for j in source.joints}
    convert([tmp_path / "in"], tmp_path / "amc")
    _, got = reference_positions(tmp_path / "amc" / "10_03.asf", tmp_path / "amc" / "10_03.amc")
    expected = file_positions(source)
    points = bvh_skeleton(source.joints, None).model.points
    for j, point in enumerate(points):
        assert np.abs(got[:, j] - expected[point]).max() < TOLERANCE_CM, point
    convert([tmp_path / "amc"], tmp_path / "back")
    back = read_bvh(tmp_path / "back" / "10_03.bvh")
    back_positions = file_positions(back)
    for joint in source.joints:  # every joint has rotations: each comes back by its name, where it was
        assert np.abs(back_positions[joint.name] - expected[joint.name]).max() < TOLERANCE_CM, joint.name


@pytest.mark.parametrize("value", ["angles", "root", "all"])
def test_large_values_keep_their_joints_through_the_amc(tmp_path, value):
    """An AMC written with 6 significant digits moved joints: angles unwrapped to 12,345.678
    degrees by 0.044 cm, a root 1,234,567.891 cm from the origin by 2.1 cm, every value
    123,456,789.123 by 328 cm. It is written with 17 where 6 would move a joint."""
    clip = a_clip_with("x")
    values = clip.values.copy()
    if value == "angles":
        values[:, 3:] += 12345.678
    elif value == "root":
        values[:, :3] += 1234567.891
    else:
        values[:] = [[123456789.123], [123456789.456]]
    check_bvh_round_trip(replace(clip, values=values), tmp_path)


def test_files_that_would_move_a_joint_are_never_written(tmp_path, monkeypatch):
    """The read-back check on its own, with 6 digits only: a root 1,234,567.891 cm from the origin
    would be read back 5 cm from where it is."""
    monkeypatch.setattr(convert_module, "AMC_DIGITS", (6,))
    clip = a_clip_with("x")
    values = clip.values.copy()
    values[:, :3] += 1234567.891
    (tmp_path / "far.bvh").write_bytes(format_bvh(replace(clip, values=values)).encode())
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "far.bvh"), "-o", str(tmp_path / "out"), "--units",
                                       "cm"])
    assert result.exit_code == 1 and not (tmp_path / "out").exists()
    assert re.fullmatch(re.escape(f"mcz: error: {tmp_path / 'far.bvh'}: cannot be converted: mcz would read a joint "
                                  "back ") + r"[\d.]+ cm from where the clip has it \(more than 0\.005 cm\)\n",
                        result.stderr), result.stderr


def test_an_ordinary_clip_keeps_six_digits(shared_data, tmp_path):
    """More digits only where they are needed: CMU's BVH converts with %.6g."""
    result = CliRunner().invoke(main, ["convert", str(shared_data / "cmu-bvh/10/10_03.bvh"), "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert read_amc(tmp_path / "10_03.amc").style.digits == 6  # the most significant digits of a value


def test_a_chain_kilometres_long_keeps_its_end_through_the_bvh(tmp_path):
    """A BVH angle in 6 decimals is up to 5e-7 degrees off: at the end of a chain of 80 bones of
    90 m (the longest a bone may be is 100 m) that moved the tip by 0.041 cm. Its clip is written
    with Python's repr."""
    (tmp_path / "in").mkdir()
    rng, count = np.random.default_rng(1), 80
    bone = "  begin\n    name b{}\n    direction 0 1 0\n    length 9000\n    axis 0 0 0 XYZ\n    dof rx ry rz\n  end\n"
    asf = (":units\n  length cm\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n  axis XYZ\n  position 0 0 0\n"
           "  orientation 0 0 0\n:bonedata\n" + "".join(bone.format(k) for k in range(count))
           + ":hierarchy\n  begin\n    root b0\n" + "".join(f"    b{k} b{k + 1}\n" for k in range(count - 1))
           + "  end\n")
    amc = "".join(f"{f}\nroot 1 2 3 4 5 6\n" + "".join(f"b{k} {words(np.round(rng.uniform(-3, 3, 3), 10))}\n"
                                                       for k in range(count)) for f in range(1, 4))
    (tmp_path / "in" / "far.asf").write_text(asf)
    (tmp_path / "in" / "far.amc").write_text(":FULLY-SPECIFIED\n:DEGREES\n" + amc)
    _, expected = reference_positions(tmp_path / "in" / "far.asf", tmp_path / "in" / "far.amc")
    convert([tmp_path / "in"], tmp_path / "bvh")
    got = file_positions(read_bvh(tmp_path / "bvh" / "far.bvh"))
    points = ["root", *(f"b{k}" for k in range(1, count)), f"b{count - 1} End Site"]
    for j, point in enumerate(points):
        assert np.linalg.norm(got[point] - expected[:, j], axis=-1).max() < TOLERANCE_CM, point


def test_names_no_file_could_hold_are_escaped_and_recorded():
    """A Bvh made in code may name its joints anything: empty, with blanks or line breaks."""
    odd = ["", "a b", "line\nbreak", "tab\there", "\u2028"]
    clip = a_clip_with("x")
    joints = clip.joints + [BvhJoint(name, 1, np.array([0, 1.0, 0]), ("Zrotation",)) for name in odd]
    values = np.concatenate([clip.values, np.full((2, len(odd)), 12.5)], axis=1)
    skeleton, motion = bvh_to_amc(Bvh(joints, 1 / 30, values), "cm")
    read = parse_asf(format_asf(skeleton).encode())
    assert parse_amc(format_amc(motion).encode(), skeleton=read, partial_last_frame="error").bones == motion.bones
    recorded = {words[1]: json.loads(words[2]) for words in (line.split(None, 2) for line in read.documentation)
                if words[0] == "bvh-name"}
    assert sorted(recorded[b.name] for b in read.bones if b.name in recorded) == sorted(odd)


def test_a_root_with_1023_children_is_refused_in_one_line_and_nothing_is_written(tmp_path):
    """Its link bones would make an ASF of 2,046 bones, more than a skeleton may have."""
    joints = [BvhJoint("hip", -1, np.zeros(3), POSITIONS)]
    joints += [BvhJoint(f"j{k}", 0, np.array([0, 10.0, 0]), ("Zrotation",), np.array([0, 10.0, 0]))
               for k in range(MAX_BONES_PER_SKELETON - 1)]
    (tmp_path / "many.bvh").write_bytes(format_bvh(Bvh(joints, 1 / 30, np.zeros((2, len(joints) + 2)))).encode())
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "many.bvh"), "-o", str(tmp_path / "out"), "--units",
                                       "cm"])
    assert result.exit_code == 1 and not (tmp_path / "out").exists()
    refusal = re.escape(f"mcz: error: {tmp_path / 'many.bvh'}: cannot be converted: mcz would refuse the files it "
                        "becomes (many.asf:") + r"\d+: more than the 1,024 bones a skeleton may have\)\n"
    assert re.fullmatch(refusal, result.stderr), result.stderr


def star_asf(bones: int) -> str:
    """An ASF whose root has `bones` children, none with a dof."""
    bonedata = "".join(f"  begin\n    name b{k}\n    direction 0 1 0\n    length 1\n    axis 0 0 0 XYZ\n  end\n"
                       for k in range(bones))
    return (":units\n  length 1\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n  axis XYZ\n  position 0 0 0\n"
            f"  orientation 0 0 0\n:bonedata\n{bonedata}:hierarchy\n  begin\n    root "
            + " ".join(f"b{k}" for k in range(bones)) + "\n  end\n")


@pytest.mark.parametrize("what", ["joints", "depth"])
def test_an_asf_whose_bvh_would_pass_a_limit_is_refused_in_one_line(shared_data, tmp_path, what):
    """1,024 bones (the most an ASF may have) are 1,025 BVH joints with the root; a chain of 201
    more bones below CMU's hand nests deeper than the 200 levels a BVH may."""
    (tmp_path / "in").mkdir()
    if what == "joints":
        (tmp_path / "in" / "star.asf").write_text(star_asf(MAX_BONES_PER_SKELETON))
        (tmp_path / "in" / "star.amc").write_text("1\nroot 0 0 0 0 0 0\n2\nroot 1 2 3 4 5 6\n")
        clip, refusal = "star.amc", "more than 1024 joints)"
    else:
        asf = (shared_data / "cmu/09/09.asf").read_bytes().replace(b"\r\n", b"\n")
        (tmp_path / "in" / "09.asf").write_bytes(chain_skeleton(asf, 201))
        (tmp_path / "in" / "09_01.amc").write_bytes((shared_data / "cmu/09/09_01.amc").read_bytes())
        clip, refusal = "09_01.amc", "joints nested more than 200 deep"
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "in"), "-o", str(tmp_path / "out")])
    assert result.exit_code == 1 and not (tmp_path / "out").exists()
    assert result.stderr.startswith(f"mcz: error: {tmp_path / 'in' / clip}: cannot be converted: mcz would refuse")
    assert refusal in result.stderr and result.stderr.count("\n") == 1


def test_names_that_would_make_an_amc_too_large_are_refused_before_it_is_made(tmp_path):
    """Long names, repeated in every AMC frame: 2 of 400,000 characters in 170 frames of a BVH under
    1 MB would take 136 MB of AMC (the reader takes 128 MiB)."""
    joints = [BvhJoint("hip", -1, np.zeros(3), POSITIONS + ("Zrotation",), None)]
    joints += [BvhJoint(c * 400_000, 0, np.array([0, 10.0, 0]), ("Zrotation",), np.array([0, 10.0, 0])) for c in "ab"]
    (tmp_path / "long.bvh").write_bytes(format_bvh(Bvh(joints, 1 / 30, np.zeros((170, 6)))).encode())
    assert (tmp_path / "long.bvh").stat().st_size < 1 << 20
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "long.bvh"), "-o", str(tmp_path / "out"), "--units",
                                       "cm"])
    assert result.exit_code == 1 and not (tmp_path / "out").exists()
    assert result.stderr == (f"mcz: error: {tmp_path / 'long.bvh'}: cannot be converted: its joint names alone would "
                             f"take 136,001,190 bytes of its AMC file, which may have {MAX_AMC_BYTES:,}\n")


@pytest.mark.parametrize("name, why", [("#x", "clip.amc would not read back as its frames"),
                                       ("123", "mcz would refuse the files it becomes (clip.amc:")])
def test_a_file_mcz_would_misread_or_refuse_is_never_written(tmp_path, monkeypatch, name, why):
    """The read-back check on its own, with names left unescaped: an AMC line of a leaf `#x` is a
    comment (the clip would lose the bone), `123 ...` no bone line."""
    monkeypatch.setattr(convert_module, "_escaped", lambda name, holds, special: name)
    (tmp_path / "clip.bvh").write_bytes(format_bvh(a_clip_with(name)).encode())
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "clip.bvh"), "-o", str(tmp_path / "out"), "--units",
                                       "cm"])
    assert result.exit_code == 1 and not (tmp_path / "out").exists()
    assert result.stderr.startswith(f"mcz: error: {tmp_path / 'clip.bvh'}: cannot be converted: {why}")
    assert result.stderr.count("\n") == 1


def test_file_names_with_a_line_break_or_no_utf8_name_an_asf_on_one_line(shared_data, tmp_path):
    """The ASF's `:name` is the BVH file's stem, which a line break would end early."""
    folder = tmp_path / "in"
    folder.mkdir()
    for name in ("a\nb.bvh", b"c\xff.bvh".decode("utf-8", "surrogateescape")):
        (folder / name).symlink_to(shared_data / "cmu-bvh/10/10_03.bvh")
    result = CliRunner().invoke(main, ["convert", str(folder), "-o", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    assert sorted(read_asf(path).name for path in (tmp_path / "out").glob("*.asf")) == ["a b", "c\ufffd"]


@pytest.mark.parametrize("clip", ["bvh", "amc"])
def test_a_symbolic_link_in_the_output_folder_never_takes_a_file_outside_it(shared_data, tmp_path, clip):
    """Before: `convert in -o out`, where out/sub was a link to a folder elsewhere, wrote in/sub's
    clips there (decompress refused the same link). Now refused in one line, nothing written."""
    (tmp_path / "in" / "sub").mkdir(parents=True)
    if clip == "bvh":
        (tmp_path / "in" / "sub" / "c.bvh").write_bytes(format_bvh(a_clip_with("x")).encode())
        first = "c.amc"
    else:
        for name in ("09.asf", "09_01.amc"):
            (tmp_path / "in" / "sub" / name).symlink_to(shared_data / "cmu" / "09" / name)
        first = "09_01.bvh"
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "sub").symlink_to(tmp_path / "elsewhere", target_is_directory=True)
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "in"), "-o", str(tmp_path / "out"), "--units", "cm"])
    assert result.exit_code == 1 and list((tmp_path / "elsewhere").iterdir()) == []
    assert result.stderr == (f"mcz: error: {tmp_path / 'out' / 'sub' / first}: its folder leads outside the output "
                             "folder through a symbolic link; refusing to write it\n")


@pytest.mark.parametrize("root", ["Hips", "%3Aodd", ":odd"])
def test_a_hierarchy_mcz_cannot_model_is_refused_naming_the_files_joints(tmp_path, root):
    """Convert models the hierarchy under the joints' ASF names (`root` for the root): a root
    without position channels was refused as "root joint 'root' needs ...", a joint the file
    does not have."""
    joints = [BvhJoint(root, -1, np.zeros(3), ROTATIONS), BvhJoint("Spine", 0, np.array([0, 20.0, 0]), ROTATIONS,
                                                                    np.array([0, 20.0, 0]))]
    (tmp_path / "c.bvh").write_bytes(format_bvh(Bvh(joints, 1 / 30, np.zeros((2, 6)))).encode())
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "c.bvh"), "-o", str(tmp_path / "out"), "--units",
                                       "cm"])
    assert result.exit_code == 1 and not (tmp_path / "out").exists()
    assert result.stderr == (f"mcz: error: {tmp_path / 'c.bvh'}: root joint '{root}' needs Xposition, Yposition and "
                             "Zposition\n"), result.stderr
