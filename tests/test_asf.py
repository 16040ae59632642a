"""ASF reading and writing on the real data set (../shared/data)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from mocapzip.formats.asf import (
    MAX_BONE_CM,
    UNITS_LENGTH_RANGE,
    Bone,
    Skeleton,
    format_asf,
    parse_asf,
    read_asf,
    write_asf,
)

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
ASF_FILES = sorted(
    p for f in ("cmu", "hdm05", "cmu-edited", "other-vicon-blade") for p in (DATA / f).rglob("*.asf")
) if DATA.is_dir() else []
CMU07 = DATA / "cmu" / "07" / "07.asf"


def read_quietly(path) -> Skeleton:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_asf(path)


def assert_same_skeleton(a: Skeleton, b: Skeleton) -> None:
    """Every field equal (numbers exactly)."""
    for name in ("name", "version", "units", "documentation", "root_order", "root_axis", "hierarchy", "comments"):
        assert getattr(a, name) == getattr(b, name), name
    np.testing.assert_array_equal(a.root_position, b.root_position)
    np.testing.assert_array_equal(a.root_orientation, b.root_orientation)
    assert [bone.name for bone in a.bones] == [bone.name for bone in b.bones]
    for x, y in zip(a.bones, b.bones):
        assert (x.id, x.length, x.axis_order, x.dof, x.limits, x.extra) == (y.id, y.length, y.axis_order, y.dof, y.limits, y.extra), x.name
        np.testing.assert_array_equal(x.direction, y.direction)
        np.testing.assert_array_equal(x.axis, y.axis)


@pytest.mark.parametrize("path", ASF_FILES, ids=[str(p.relative_to(DATA)) for p in ASF_FILES])
def test_write_then_read_keeps_every_field(path, tmp_path):
    skel = read_quietly(path)
    out = tmp_path / "out.asf"
    write_asf(skel, out)
    again = read_asf(out)  # no warning: unknown sections are not written back
    assert_same_skeleton(skel, again)
    assert format_asf(again) == format_asf(skel)


@pytest.mark.parametrize("path", ASF_FILES, ids=[str(p.relative_to(DATA)) for p in ASF_FILES])
def test_real_skeletons_are_far_within_the_bounds(path):
    """The bounds that refuse impossible skeletons leave real ones a wide margin."""
    skel = read_quietly(path)
    low, high = UNITS_LENGTH_RANGE
    assert low * 1e4 < skel.length_scale < high / 1e4  # 0.45 (CMU, HDM05) or 1 (Blade)
    assert max(np.linalg.norm(b.direction) * b.length * skel.cm_per_unit for b in skel.bones) < MAX_BONE_CM / 100
    assert skel.dof_map() == {name: skel.dof_of(name) for name in ["root", *(b.name for b in skel.bones)]}


def test_cmu_skeleton_content():
    skel = read_asf(CMU07)
    assert skel.version == "1.10" and skel.name == "VICON"
    assert skel.units == {"mass": "1.0", "length": "0.45", "angle": "deg"}
    assert skel.angle_unit == "deg" and skel.cm_per_unit == pytest.approx(2.54 / 0.45)
    assert skel.documentation[0].startswith(".ast/.asf automatically generated")
    assert skel.comments[0] == "# AST/ASF file generated using VICON BodyLanguage"
    assert skel.root_order == ("TX", "TY", "TZ", "RX", "RY", "RZ") and skel.root_axis == "XYZ"
    assert len(skel.bones) == 30
    lfemur = skel.bone("lfemur")
    assert lfemur.id == 2 and lfemur.dof == ("rx", "ry", "rz")
    assert lfemur.limits == [(-160.0, 20.0), (-70.0, 70.0), (-60.0, 70.0)]
    assert lfemur.axis.tolist() == [0, 0, 20] and lfemur.axis_order == "XYZ"
    assert skel.bone("lhipjoint").dof == ()
    assert skel.parents()["lfemur"] == "lhipjoint" and skel.parents()["lhipjoint"] == "root"
    assert skel.dof_of("root") == ("tx", "ty", "tz", "rx", "ry", "rz")
    assert skel.dof_of("lfoot") == ("rx", "rz")
    with pytest.raises(KeyError):
        skel.bone("nope")


def test_blade_skeleton_content():
    skel = read_asf(DATA / "other-vicon-blade/walk_200fps/walkMoCapVideo.asf")
    assert skel.name == "HOM" and skel.root_axis == "XYZ"  # written 'axis xyz'
    assert skel.comments[0] == "# File created by Blade"
    assert skel.bone("LeftUpLeg").length == 19.141694
    assert skel.bone("LeftUpLeg_dum").dof == ()


def test_unknown_section_warns_with_file_and_line():
    path = DATA / "cmu-edited/05/moderndance_namespace.asf"
    with pytest.warns(UserWarning, match=r"moderndance_namespace\.asf:5: unknown ASF section ':namespace' skipped"):
        skel = read_asf(path)
    assert skel.name == "Modern Dance"
    assert [b.name for b in skel.bones] == [b.name for b in read_asf(DATA / "cmu/05/05.asf").bones]


def _variant(data: bytes, kind: str) -> bytes:
    lf = data.replace(b"\r\n", b"\n")
    return {
        "lf": lambda: lf,
        "crlf": lambda: lf.replace(b"\n", b"\r\n"),
        "cr": lambda: lf.replace(b"\n", b"\r"),
        "mixed": lambda: b"".join(line + (b"\r\n" if i % 2 else b"\n") for i, line in enumerate(lf.split(b"\n"))),
        "tabs": lambda: lf.replace(b" ", b"\t"),
        "no-final-newline": lambda: lf.rstrip(b"\n"),
        "bom": lambda: b"\xef\xbb\xbf" + lf,
        "comments": lambda: lf.replace(b"  begin\n", b"  # a bone follows\n  begin\n").replace(b":hierarchy\n", b"# tree\n:hierarchy\n"),
    }[kind]()


@pytest.mark.parametrize("kind", ["lf", "crlf", "cr", "mixed", "tabs", "no-final-newline", "bom", "comments"])
def test_line_ending_and_whitespace_variants(kind, tmp_path):
    path = tmp_path / f"{kind}.asf"
    path.write_bytes(_variant(CMU07.read_bytes(), kind))
    skel = read_asf(path)
    if kind == "tabs":  # free text keeps its (now tab) separators
        skel.documentation = [line.replace("\t", " ") for line in skel.documentation]
        skel.comments = [line.replace("\t", " ") for line in skel.comments]
    assert_same_skeleton(read_asf(CMU07), skel)


SMALL = """\
# a hand-made skeleton
:version 1.10
:name tiny
:units
  mass 1.0
  length 1.0
  angle rad
:documentation
  radians, a free dof order, infinite limits
:root
  order RX RY RZ TX TY TZ
  axis ZYX
  position 0 1 2
  orientation 0.1 -0.2 0.3
:bonedata
  begin
    id 1
    name spine
    direction 0 1 0
    length 2.5
    axis 0 0 1.5 ZXY
    dof rz tx rx
    limits (-inf inf)
           (-1.0e1 10)
           (-3.14159 3.14159)
    bodymass 3.2
  end
  begin
    id 2
    name head
    direction 0 1 0
    length 1
    axis 0 0 0 XYZ
    dof ry
    limits (-inf 0)
  end
  begin
    name tail
    direction 0 -1 0
    length 0.5
    axis 0 0 0 XYZ
  end
:hierarchy
  begin
    root spine tail
    spine head
  end
"""


def test_hand_made_features(tmp_path):
    skel = parse_asf(SMALL.encode(), "tiny.asf")
    assert skel.angle_unit == "rad" and skel.units["angle"] == "rad"
    assert skel.root_order == ("RX", "RY", "RZ", "TX", "TY", "TZ") and skel.root_axis == "ZYX"
    assert skel.root_orientation.tolist() == [0.1, -0.2, 0.3]
    spine = skel.bone("spine")
    assert spine.dof == ("rz", "tx", "rx") and spine.axis_order == "ZXY"
    assert spine.limits == [(-math.inf, math.inf), (-10.0, 10.0), (-3.14159, 3.14159)]
    assert spine.extra == ["bodymass 3.2"]
    assert skel.bone("head").limits == [(-math.inf, 0.0)]
    assert skel.bone("tail").id is None and skel.bone("tail").dof == ()
    assert skel.dof_of("root") == ("rx", "ry", "rz", "tx", "ty", "tz")
    assert skel.parents() == {"spine": "root", "tail": "root", "head": "spine"}
    out = tmp_path / "tiny.asf"
    write_asf(skel, out)
    assert "limits (-inf inf)" in out.read_text()
    assert_same_skeleton(skel, read_asf(out))


def test_parse_accepts_str():
    skel = parse_asf(CMU07.read_text())
    assert len(skel.bones) == 30 and skel.path is None


def test_format_of_constructed_skeleton():
    skel = Skeleton(name="x", units={"angle": "deg"}, bones=[Bone("a", dof=("rx",), limits=[(-1.5, 2.0)])],
                    hierarchy=[("root", ["a"])])
    text = format_asf(skel)
    assert_same_skeleton(skel, parse_asf(text.encode()))
    assert "    limits (-1.5 2)" in text
