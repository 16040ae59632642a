"""BVH files at and beyond their limits through every command that reads them (issue 40, item 1).

The files are made by tests/hostile_bvh.py, one variation of a small valid file each. A refused
file: `compress` (lossy and --lossless), `inspect --check` and `convert` each say ONE line naming
the file (and its line, where there is one) and the problem, exit 1, and leave nothing behind.
An accepted one: --lossless gives the same bytes back; lossy gives the same joints and frames,
within the error it reports. Hypothesis then draws whole files (tree shapes, channel layouts,
names, numbers, line ends) for the same round trips.
"""

from __future__ import annotations

import math
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hostile_bvh
import limited
from hostile_bvh import ACCEPTED, POSITIONS, REFUSED, ROTATIONS, Joint, Shape, bvh_text, person
from mocapzip import api
from mocapzip.archive import Archive
from mocapzip.cli.main import main
from mocapzip.formats.bvh import read_bvh
from mocapzip.formats.errors import MocapFormatError
from mocapzip.motion.bvh_skeleton import file_positions, point_names

COMMANDS = {  # each reads BVH its own way: lossy and lossless coding, the glitch check, conversion
    "compress": ["compress", "in", "-o", "out/db.mcz", "--units", "cm", "-j", "1", "-q"],
    "compress --lossless": ["compress", "in", "-o", "out/db.mcz", "--lossless", "-j", "1", "-q"],
    "inspect --check": ["inspect", "in", "--check", "--units", "cm"],
    "convert": ["convert", "in", "-o", "out/converted", "--units", "cm"],
}
# What tries the reader's limits on size or depth runs in a child under the hostile suites' limits.
IN_A_LIMITED_CHILD = {"frames_past_the_limit", "frames_past_the_values_limit", "joints_past_the_limit",
                      "joints_too_deep", "braces_only"}


def run(folder: Path, args: list[str]):
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        return CliRunner().invoke(main, args)
    finally:
        os.chdir(cwd)


def file_bytes(case) -> bytes:
    if case.name == "utf16":
        return case.text.encode("utf-16-le")  # after its byte-order mark, from the text
    return case.text.encode("utf-8") if isinstance(case.text, str) else case.text


def refusal_problem(case, command: str, exit_code: int, stdout: str, stderr: str, left: list[str]) -> str | None:
    lines = stderr.splitlines()
    where = "in/c.bvh" + (f":{case.line}" if case.line is not None else "")
    if exit_code != 1 or len(lines) != 1 or stdout.strip():
        return f"{command}: exit {exit_code}, stdout {stdout[-300:]!r}, stderr {stderr[-600:]!r}"
    if not lines[0].startswith("mcz: error: in/c.bvh") or case.problem not in lines[0]:
        return f"{command}: {lines[0]!r} should name in/c.bvh and say {case.problem!r}"
    if case.line is not None and command != "compress" and not lines[0].startswith(f"mcz: error: {where}: "):
        return f"{command}: {lines[0]!r} should name {where}"
    if left:
        return f"{command} left {left}"
    return None


@pytest.mark.parametrize("case", [c for c in REFUSED if c.name not in IN_A_LIMITED_CHILD], ids=lambda c: c.name)
def test_a_bad_bvh_file_is_refused_in_one_line_by_every_command(case, tmp_path):
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "c.bvh").write_bytes(file_bytes(case))
    problems = []
    for command, args in COMMANDS.items():
        (tmp_path / "out").mkdir()
        result = run(tmp_path, args)
        problem = refusal_problem(case, command, result.exit_code, result.stdout, result.stderr,
                                  os.listdir(tmp_path / "out"))
        if problem:
            problems.append(problem)
        shutil.rmtree(tmp_path / "out")
    assert problems == []


@pytest.mark.parametrize("name", sorted(IN_A_LIMITED_CHILD))
def test_a_bvh_file_past_a_size_limit_is_refused_within_the_memory_and_time_limits(name, tmp_path):
    case = next(c for c in REFUSED if c.name == name)
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "c.bvh").write_bytes(file_bytes(case))
    for command in ("compress", "compress --lossless", "convert"):
        (tmp_path / "out").mkdir()
        result = limited.run_mcz(*COMMANDS[command], cwd=tmp_path, memory=1 << 30)
        assert refusal_problem(case, command, result.returncode, result.stdout, result.stderr,
                               os.listdir(tmp_path / "out")) is None
        (tmp_path / "out").rmdir()


def round_trip(folder: Path, data: bytes, lossy_refuses: str | None = None) -> None:
    """--lossless gives `data` back (less a UTF-8 byte-order mark); lossy gives its frames and
    joints within the reported max error, or refuses with `lossy_refuses`."""
    source = folder / "in" / "c.bvh"
    source.parent.mkdir(parents=True, exist_ok=True)
    source.write_bytes(data)
    lossless, lossy = folder / "lossless.mcz", folder / "lossy.mcz"
    api.compress(source.parent, lossless, lossless=True, jobs=1)
    api.decompress(lossless, folder / "back", jobs=1)
    assert (folder / "back" / "c.bvh").read_bytes() == data.removeprefix(b"\xef\xbb\xbf")
    original = read_bvh(source)
    if lossy_refuses is not None:
        with pytest.raises(MocapFormatError, match=re.escape(lossy_refuses)):
            api.compress(source.parent, lossy, error=1.0, units="cm", jobs=1)
        assert not lossy.exists()
        return
    api.compress(source.parent, lossy, error=1.0, units="cm", jobs=1)
    api.decompress(lossy, folder / "lossy_back", jobs=1)
    decoded = read_bvh(folder / "lossy_back" / "c.bvh")
    assert decoded.n_frames == original.n_frames
    assert [j.name for j in decoded.joints] == [j.name for j in original.joints]
    with api.open(lossy) as archive:
        worst = archive["c.bvh"].error.max_cm
    names = point_names(original.joints)
    moved = np.linalg.norm(file_positions(decoded, "cm") - file_positions(original, "cm"), axis=-1)
    assert moved.shape[1] == len(names) and moved.max() <= worst + 1e-3


@pytest.mark.parametrize("name", sorted(ACCEPTED))
def test_a_degenerate_or_odd_bvh_file_round_trips(name, tmp_path):
    round_trip(tmp_path, hostile_bvh.accepted_bytes(name), hostile_bvh.LOSSY_REFUSES.get(name))


@pytest.mark.parametrize("name", ["latin1", "utf8_bom"])
def test_bvh_encodings_round_trip(name, tmp_path):
    round_trip(tmp_path, hostile_bvh.latin1_and_bom()[name])


def test_inspect_check_names_why_a_hierarchy_has_no_model(tmp_path):
    """Before: `inspect --check` of a BVH whose unit cannot be told said '12 channels, the skeleton has 0'."""
    (tmp_path / "in").mkdir()
    small = bvh_text(Shape(person(Joint("Spine", offset="0 1 0", children=[Joint("Head", offset="0 1 0")]))))
    (tmp_path / "in" / "c.bvh").write_text(small)
    result = run(tmp_path, ["inspect", "in", "--check"])
    assert result.exit_code == 1 and "cannot tell the unit" in result.stderr and "--units" in result.stderr


# --------------------------------------------------------------------------- drawn files

NAME = st.text(alphabet=st.characters(blacklist_categories=("Zs", "Zl", "Zp", "Cc", "Cs"),
                                      blacklist_characters="{}"), min_size=1, max_size=12) \
    | st.sampled_from(["123", ":hierarchy", ":DEGREES", "#", "JOINT", "End", "MOTION", "CHANNELS"])
ROTATION_LAYOUT = st.permutations(ROTATIONS.split()).flatmap(lambda r: st.integers(1, 3).map(lambda k: " ".join(r[:k])))


@st.composite
def drawn_shapes(draw) -> Shape:
    names = draw(st.lists(NAME, min_size=1, max_size=6, unique=True).filter(lambda n: "Hips" not in n))
    joints = [Joint(name, draw(ROTATION_LAYOUT), offset=f"0 {draw(st.integers(5, 40))} 0") for name in names]
    for k, joint in enumerate(joints[1:], start=1):  # each joint below one drawn before it: any tree shape
        joints[draw(st.integers(0, k - 1))].children.append(joint)
    root = person(joints[0], root_channels=f"{POSITIONS} {' '.join(draw(st.permutations(ROTATIONS.split())))}")
    return Shape(root, frames=draw(st.integers(1, 5)), line_end=draw(st.sampled_from(["\n", "\r\n", "\r"])),
                 seed=draw(st.integers(0, 1000)))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                 HealthCheck.too_slow])
@given(shape=drawn_shapes())
def test_drawn_bvh_files_round_trip(shape, tmp_path_factory):
    round_trip(tmp_path_factory.mktemp("drawn"), bvh_text(shape).encode("utf-8"))


# --------------------------------------------------------------------------- values lossy coding cannot hold

HUGE_VALUES = {  # each read by every reader; their numbers as written are too coarse or too near the limit
    "root_at_1e8_6_digits": ("123456789.123", "45.5"),  # written back as 1.23457e+08: a metre's precision
    "every_value_near_1e8": ("98765432.123", "98765432.123"),
}


@pytest.mark.parametrize("name", sorted(HUGE_VALUES))
def test_values_lossy_coding_cannot_hold_are_refused_in_one_line(name, tmp_path):
    """Before: a traceback from the rate control. --lossless keeps them exactly."""
    position, angle = HUGE_VALUES[name]
    shape = Shape(person(Joint("Spine", offset="0 50 0", children=[Joint("Head", offset="0 60 0")])), frames=3)
    text = bvh_text(shape).split("\n")
    start = text.index("MOTION") + 3
    for f in range(start, start + 3):
        text[f] = " ".join([position] * 3 + [angle] * 9)
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "c.bvh").write_text("\n".join(text))
    (tmp_path / "out").mkdir()
    result = run(tmp_path, COMMANDS["compress"])
    lines = result.stderr.splitlines()
    assert result.exit_code == 1 and len(lines) == 1 and lines[0].startswith("mcz: error: in/c.bvh: "), result.output
    assert "--lossless" in lines[0] and os.listdir(tmp_path / "out") == []
    assert run(tmp_path, COMMANDS["compress --lossless"]).exit_code == 0
    assert run(tmp_path, ["decompress", "out/db.mcz", "-o", "back"]).exit_code == 0
    assert (tmp_path / "back" / "c.bvh").read_bytes() == (tmp_path / "in" / "c.bvh").read_bytes()


def root_at_the_limit(amc) -> str:
    """The AMC text of `amc` with its root's x swaying from 1e9 - 4 to 1e9, the most a file may hold."""
    lines = Path(amc).read_text().splitlines()
    for frame, k in enumerate([k for k, line in enumerate(lines) if line.startswith("root ")]):
        lines[k] = " ".join(["root", f"{1e9 - 2 * (1 + math.cos(frame / 8)):.4f}", *lines[k].split()[2:]])
    return "\n".join(lines) + "\n"


def test_an_amc_root_at_the_value_limit_is_refused_lossy(shared_data, tmp_path):
    """Before: exit 0, and an archive that `mcz test` and `decompress` called damaged: a real clip
    whose root stands at x = 1e9, the most a file may hold, decoded a hair past it. (Since format
    13 a root that stands still there comes back exactly, its line through the ends being all it
    needs: the root here sways by a few cm up to the limit, and its quantisation noise passes it.)"""
    (tmp_path / "in").mkdir()
    shutil.copy(shared_data / "cmu" / "09" / "09.asf", tmp_path / "in")
    (tmp_path / "in" / "09_01.amc").write_text(root_at_the_limit(shared_data / "cmu" / "09" / "09_01.amc"))
    (tmp_path / "out").mkdir()
    result = run(tmp_path, ["compress", "in", "-o", "out/db.mcz", "-j", "1", "-q"])
    assert result.exit_code == 1 and result.stderr.startswith("mcz: error: in/09_01.amc: its decoded values would pass")
    assert os.listdir(tmp_path / "out") == []


def test_a_glitch_at_an_end_site_is_repaired(tmp_path):
    """Before: --repair-glitches of a BVH whose End Site jumps (its joint turned half a turn for one
    frame at 120 Hz: 40 cm in a frame) ended in a traceback, `KeyError: 'Head End Site'`: a jump
    names the point that jumps, and the repair looked it up among the joints' names."""
    text = bvh_text(Shape(person(), frames=120, frame_time="0.008333")).split("\n")
    values = text[text.index("MOTION") + 6].split()  # frame 4 (frames count from 1)
    values[9] = f"{float(values[9]) + 180:.4f}"  # Head's Zrotation
    text[text.index("MOTION") + 6] = " ".join(values)
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "c.bvh").write_text("\n".join(text))
    (tmp_path / "out").mkdir()
    result = run(tmp_path, [*COMMANDS["compress"], "--repair-glitches"])
    assert result.exit_code == 0, result.output
    with Archive(tmp_path / "out" / "db.mcz") as archive:
        assert [r[:2] for r in archive.clips[0]["repaired"]] == [[3, 5]]  # the jumps into and out of frame 4
