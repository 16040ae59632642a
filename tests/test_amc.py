"""AMC reading and writing on the real data set (../shared/data), plus property tests."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapzip.formats import amc
from mocapzip.formats.amc import (
    MAX_AMC_BYTES,
    MAX_RADIANS,
    AmcStyle,
    Motion,
    _parse_exact,
    _parse_fast,
    amc_blocks,
    format_amc,
    parse_amc,
    read_amc,
    write_amc,
)
from mocapzip.formats.asf import read_asf
from mocapzip.formats.errors import MocapFormatError

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
FOLDERS = ("cmu", "hdm05", "cmu-edited", "other-vicon-blade")
# cmu-edited skeletons named by the data README; 69, 91 and 124 have none here.
EDITED_SKELETONS = {"05": "cmu/05/05.asf", "07": "cmu/07/07.asf"}


def shared_files(suffix: str) -> list[Path]:
    if not DATA.is_dir():
        return []
    return sorted(p for f in FOLDERS for p in (DATA / f).rglob("*") if p.suffix.lower() == suffix)


def skeleton_path(amc: Path) -> Path | None:
    """The ASF that goes with an AMC of the shared data, or None."""
    rel = amc.relative_to(DATA)
    if rel.parts[0] == "cmu-edited":
        named = EDITED_SKELETONS.get(rel.parts[1])
        return DATA / named if named else None
    asfs = sorted(amc.parent.glob("*.asf"))
    return asfs[0] if len(asfs) == 1 else None


def ids(paths):
    return [str(p.relative_to(DATA)) for p in paths]


AMC_FILES = shared_files(".amc")
ASF_FILES = shared_files(".asf")
ALL_FILES = ASF_FILES + AMC_FILES
_SKELETONS: dict[Path, object] = {}


def skeleton_for(amc: Path):
    path = skeleton_path(amc)
    if path is None:
        return None
    if path not in _SKELETONS:
        _SKELETONS[path] = read_asf(path)
    return _SKELETONS[path]


def read_quietly(path, skeleton=None) -> Motion:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_amc(path, skeleton)


def assert_same_to_digits(a: np.ndarray, b: np.ndarray, digits: int = 6) -> None:
    """Equal once both are rounded to `digits` significant digits (half a unit of the last digit)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    assert a.shape == b.shape
    scale = np.where(a == 0, 0.0, 10.0 ** (np.floor(np.log10(np.abs(np.where(a == 0, 1, a)))) - (digits - 1)))
    assert np.all(np.abs(a - b) <= 0.5 * scale * (1 + 1e-9) + 4e-16 * np.abs(a))  # + double rounding


def assert_same_motion(a: Motion, b: Motion) -> None:
    assert a.bones == b.bones
    assert a.counts == b.counts
    assert a.header == b.header
    np.testing.assert_array_equal(a.frame_numbers, b.frame_numbers)
    assert np.array_equal(a.values, b.values)


def test_shared_data_is_there():
    assert DATA.is_dir(), f"real data not found at {DATA}"
    assert len(AMC_FILES) >= 160 and len(ASF_FILES) >= 19


# ------------------------------------------------------------------ every real file parses


@pytest.mark.parametrize("path", ALL_FILES, ids=ids(ALL_FILES))
def test_every_shared_file_parses(path):
    if path.suffix.lower() == ".asf":
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            skel = read_asf(path)
        assert skel.bones and skel.hierarchy
        # Only cmu-edited's ':namespace' line is unusual enough to warn about.
        assert [str(w.message) for w in caught] == (
            [f"{path}:5: unknown ASF section ':namespace' skipped"] if "namespace" in path.name else []
        )
        return
    skeleton = skeleton_for(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        motion = read_amc(path, skeleton)
    assert motion.n_frames > 0
    assert motion.values.shape == (motion.n_frames, sum(motion.counts))
    assert motion.bones[0] == "root" or motion.bones[0].lower().startswith(("root", "hips"))
    assert np.all(np.diff(motion.frame_numbers) == 1)
    assert np.all(np.isfinite(motion.values))
    if path.name == "golf_01.amc":
        assert len(caught) == 1 and "last frame 444 is incomplete" in str(caught[0].message)
        assert motion.dropped_frames == 1
    else:
        assert not caught and motion.dropped_frames == 0
        read_amc(path, skeleton, partial_last_frame="error")  # strict mode (--lossless) takes every complete file
    # far within the limits (formats/amc.py): 13.7 bytes a value at most, no angle near 50 turns
    assert path.stat().st_size <= 14 * motion.values.size < MAX_AMC_BYTES / 25
    assert np.abs(motion.values).max() < MAX_RADIANS * 180 / np.pi / 8


def test_manifest_frame_counts_match():
    """MANIFEST.tsv lists the frames of every AMC; the reader finds the same number."""
    rows = [line.split("\t") for line in (DATA / "MANIFEST.tsv").read_text().splitlines()[1:]]
    frames = {r[0]: int(r[2]) for r in rows if r[0].lower().endswith(".amc") and r[2]}
    checked = 0
    for rel, expected in frames.items():
        path = DATA / rel
        if path.stat().st_size > 800_000:
            continue  # keep the test fast; the parametrised test reads the big ones
        motion = read_quietly(path)
        # golf_01's last frame is cut short and dropped.
        assert motion.n_frames in (expected, expected - 1), rel
        checked += 1
    assert checked > 50


def test_frames_numbered_from_700(tmp_path):
    motion = read_amc(DATA / "cmu-edited/124/124_02_part2_frames700-1319.amc")
    assert motion.frame_numbers[0] == 700 and motion.frame_numbers[-1] == 1319
    out = tmp_path / "part2.amc"
    write_amc(motion, out)
    assert out.read_bytes() == (DATA / "cmu-edited/124/124_02_part2_frames700-1319.amc").read_bytes()


def test_headerless_and_no_final_newline():
    path = DATA / "cmu-edited/07/headerless_walk_1.amc"
    motion = read_amc(path, read_asf(DATA / "cmu/07/07.asf"))
    assert motion.header == [""]
    assert motion.style.final_newline is False
    assert format_amc(motion).encode() == path.read_bytes()
    same = read_amc(DATA / "cmu-edited/07/walk_1_noEOLatEOF.amc")
    np.testing.assert_array_equal(same.values, motion.values)


def test_truncated_last_frame_is_dropped_with_warning():
    path = DATA / "cmu/64/golf_01.amc"
    with pytest.warns(UserWarning, match=r"golf_01\.amc:\d+: last frame 444 is incomplete \(19 of 29 bones"):
        motion = read_amc(path)
    assert motion.n_frames == 443 and motion.frame_numbers[-1] == 443


LOWERBACK_07_01 = [-6.36782, -4.70696, -6.683]  # cmu/07/07_01.amc, line 6


def test_columns_and_angle_unit():
    motion = read_amc(DATA / "cmu/07/07_01.amc")
    cols = motion.columns()
    assert list(cols) == motion.bones
    assert cols["root"] == slice(0, 6)
    assert motion.values[0, cols["lowerback"]].tolist() == LOWERBACK_07_01
    assert motion.angle_unit == "deg"
    assert "lhipjoint" not in motion.bones  # bones without dof never appear


# ------------------------------------------------------------------ fast path == exact path


@pytest.mark.parametrize(
    "rel",
    [
        "cmu/07/07_01.amc",
        "cmu/05/pirouette.amc",
        "hdm05/bk/HDM_bk_sneak2StepsLStart_006_120.AMC",
        "other-vicon-blade/walk_200fps/walkMoCap2.amc",
        "cmu-edited/07/headerless_walk_1.amc",
        "cmu-edited/124/124_02_part2_frames700-1319.amc",
    ],
)
def test_fast_and_exact_paths_agree(rel):
    data = (DATA / rel).read_bytes()
    encoding = "utf-8" if data.isascii() else "latin-1"
    fast = _parse_fast(data, rel, encoding)
    assert fast is not None, "the usual layout must take the fast path"
    exact = _parse_exact(data, rel, encoding)
    assert_same_motion(fast[0], exact[0])
    assert fast[0].style == exact[0].style
    assert fast[1] == exact[1]
    assert np.array_equal(fast[0].values.view(np.uint64), exact[0].values.view(np.uint64))  # -0.0 too


def test_bones_in_varying_order_take_the_exact_path():
    src = (DATA / "cmu/07/07_01.amc").read_bytes().replace(b"\r\n", b"\n")
    lines = src.split(b"\n")
    # Swap two bone lines inside frame 3: columns still follow the first frame's order.
    frame3 = lines.index(b"3")
    lines[frame3 + 1], lines[frame3 + 2] = lines[frame3 + 2], lines[frame3 + 1]
    shuffled = b"\n".join(lines)
    assert _parse_fast(shuffled, None, "utf-8") is None
    motion = parse_amc(shuffled)
    assert_same_motion(motion, parse_amc(src))


def test_comments_and_blank_lines_between_frames():
    src = (DATA / "cmu/07/07_01.amc").read_bytes().replace(b"\r\n", b"\n")
    lines = src.split(b"\n")
    frame3 = lines.index(b"3")
    lines[frame3:frame3] = [b"", b"# a comment", b"   "]
    motion = parse_amc(b"\n".join(lines))
    assert_same_motion(motion, parse_amc(src))


# ------------------------------------------------------------------ write then read


ROUND_TRIP = [
    "cmu/07/07_01.amc",
    "cmu/05/md_02.amc",
    "hdm05/bd/HDM_bd_hopBothLegs1hops_001_120.amc",
    "hdm05/bk/HDM_bk_sneak2StepsLStart_006_120.AMC",
    "cmu-edited/07/headerless_slow_walk_1.amc",
    "cmu-edited/69/headerless_walk_forward_02.amc",
    "other-vicon-blade/walk_200fps/walkMoCap2.amc",
    "other-vicon-blade/trial1_200fps/trial1.amc",
]


@pytest.mark.parametrize("rel", ROUND_TRIP)
def test_write_then_read_keeps_values_header_and_bone_order(rel, tmp_path):
    source = DATA / rel
    motion = read_amc(source)
    out = tmp_path / "out.amc"
    write_amc(motion, out)
    again = read_amc(out)
    assert_same_motion(motion, again)  # the detected number style loses nothing
    assert again.style == motion.style
    # The source layout survives: same header lines, same bone lines in the same order.
    text = out.read_bytes().decode(motion.style.encoding)
    assert text.splitlines()[: len(motion.header)] == motion.header
    first_frame = text.splitlines()[len(motion.header) + 1 : len(motion.header) + 1 + len(motion.bones)]
    assert [line.split()[0] for line in first_frame] == motion.bones
    # With CMU's fixed 6 significant digits the values agree to those 6 digits.
    six = parse_amc(format_amc(motion, digits=6).encode("latin-1"))
    assert six.bones == motion.bones and six.header == motion.header
    assert_same_to_digits(motion.values, six.values, 6)


WRITTEN_BACK = ["cmu/07/07_01.amc", "cmu/05/pirouette.amc", "hdm05/dg/HDM_dg_squat1Reps_025_120.amc",
                "cmu-edited/91/headerless_straight_walk.amc", "cmu-edited/07/headerless_walk_1.amc",
                "other-vicon-blade/walk_200fps/walkMoCapVideo.amc"]


@pytest.mark.parametrize("rel", WRITTEN_BACK)
def test_written_file_is_byte_identical(rel, tmp_path):
    source = DATA / rel
    out = tmp_path / "copy.amc"
    write_amc(read_amc(source), out)
    assert out.read_bytes() == source.read_bytes()


@pytest.mark.parametrize("rel", WRITTEN_BACK)
def test_a_file_made_a_few_frames_at_a_time_is_the_same(rel, monkeypatch):
    """`amc_blocks`, as decompress writes a long clip: blocks of 3 frames give the file's bytes,
    line ends and a missing final newline included."""
    source = DATA / rel
    motion = read_amc(source)
    monkeypatch.setattr(amc, "VALUES_PER_BLOCK", 3 * motion.values.shape[1])
    blocks = list(amc_blocks(motion))
    assert len(blocks) == 1 + -(-motion.n_frames // 3)  # the header, then the frames
    assert "".join(blocks).encode(motion.style.encoding) == source.read_bytes()


def test_fixed_decimals_are_kept():
    """Vicon Blade writes 6 fixed decimals; 6 significant digits would lose 15.287990's last digits."""
    motion = read_amc(DATA / "other-vicon-blade/walk_200fps/walkMoCapVideo.amc")
    assert motion.style.notation == "f" and motion.style.digits == 6
    assert motion.style.name_separator == "  " and motion.style.newline == "\r\n"
    assert motion.values[0, motion.columns()["LeftUpLeg"]][0] == 15.287990
    text = format_amc(motion)
    assert "LeftUpLeg  15.287990 4.497597 0.662860\r\n" in text
    assert "LeftLeg  -1.352469 0.000000 -0.000000\r\n" in text  # -0 stays -0


def test_cmu_style_detected():
    motion = read_amc(DATA / "cmu/02/02_03.amc")  # a CRLF copy
    assert motion.style == AmcStyle(notation="g", digits=6, exponent_digits=3, newline="\r\n")
    assert read_amc(DATA / "cmu/07/07_01.amc").style == AmcStyle(notation="g", digits=6, exponent_digits=3)
    hdm = read_amc(DATA / "hdm05/bd/HDM_bd_squat1Reps_001_120.amc")
    assert hdm.style.newline == "\r\n" and hdm.style.frame_newline == "\n" and hdm.style.encoding == "latin-1"
    assert "f\u00fcr Bonn" in hdm.header[0]


def test_style_serialises():
    style = read_amc(DATA / "other-vicon-blade/walk_200fps/walkMoCap2.amc").style
    assert AmcStyle.from_dict(style.to_dict()) == style
    with pytest.raises(ValueError):
        AmcStyle(notation="x")


def test_format_defaults_for_a_new_motion():
    motion = Motion(["root", "lfemur"], [2, 1], np.array([[1.0, -2.5, 3.14159265], [0.0, 1e-7, 123456789.0]]),
                    np.array([1, 2]), [":DEGREES"])
    assert format_amc(motion) == ":DEGREES\n1\nroot 1 -2.5\nlfemur 3.14159\n2\nroot 0 1e-07\nlfemur 1.23457e+08\n"
    assert format_amc(motion, digits=10).splitlines()[-1] == "lfemur 123456789"
    with pytest.raises(ValueError, match="non-finite"):
        format_amc(Motion(["root"], [1], np.array([[np.nan]]), np.array([1])))


@pytest.mark.parametrize("digits", [3, 6, 9])
def test_format_digits_override(digits):
    motion = read_amc(DATA / "hdm05/bd/HDM_bd_hopBothLegs1hops_001_120.amc")
    again = parse_amc(format_amc(motion, digits).encode("latin-1"))
    assert_same_to_digits(motion.values, again.values, digits)


# ------------------------------------------------------------------ line ending and spacing variants


def _variant(data: bytes, kind: str) -> bytes:
    lf = data.replace(b"\r\n", b"\n")
    if kind == "lf":
        return lf
    if kind == "crlf":
        return lf.replace(b"\n", b"\r\n")
    if kind == "cr":
        return lf.replace(b"\n", b"\r")
    if kind == "mixed":
        lines = lf.split(b"\n")
        return b"".join(line + (b"\r\n" if i % 3 == 0 else b"\n") for i, line in enumerate(lines))
    if kind == "tabs":
        return lf.replace(b" ", b"\t")
    if kind == "spaces":
        return lf.replace(b" ", b"   ").replace(b"\n", b"  \n")
    if kind == "no-final-newline":
        return lf.rstrip(b"\n")
    if kind == "trailing-blank-lines":
        return lf + b"\n\n  \n"
    if kind == "bom":
        return b"\xef\xbb\xbf" + lf
    raise AssertionError(kind)


VARIANTS = ["lf", "crlf", "cr", "mixed", "tabs", "spaces", "no-final-newline", "trailing-blank-lines", "bom"]


@pytest.mark.parametrize("kind", VARIANTS)
def test_line_ending_and_whitespace_variants(kind, tmp_path):
    source = DATA / "cmu/07/07_01.amc"
    reference = read_amc(source)
    path = tmp_path / f"{kind}.amc"
    path.write_bytes(_variant(source.read_bytes(), kind))
    motion = read_amc(path, read_asf(DATA / "cmu/07/07.asf"))
    assert motion.bones == reference.bones and motion.counts == reference.counts
    np.testing.assert_array_equal(motion.values, reference.values)
    np.testing.assert_array_equal(motion.frame_numbers, reference.frame_numbers)
    if kind != "tabs" and kind != "spaces":
        assert [h.strip() for h in motion.header] == reference.header
    # And it writes back to something that reads the same.
    write_amc(motion, tmp_path / "again.amc")
    assert np.array_equal(read_amc(tmp_path / "again.amc").values, motion.values)
    if kind in ("lf", "crlf", "no-final-newline"):
        assert (tmp_path / "again.amc").read_bytes() == path.read_bytes()


# ------------------------------------------------------------------ property tests


values_strategy = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)


@st.composite
def motions(draw):
    n_bones = draw(st.integers(1, 5))
    names = draw(st.lists(st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,8}", fullmatch=True), min_size=n_bones,
                          max_size=n_bones, unique=True))
    counts = draw(st.lists(st.integers(0, 6), min_size=n_bones, max_size=n_bones))
    n_frames = draw(st.integers(1, 6))
    total = sum(counts)
    flat = draw(st.lists(values_strategy, min_size=n_frames * total, max_size=n_frames * total))
    first = draw(st.integers(0, 10_000))
    header = draw(st.sampled_from([[], [":FULLY-SPECIFIED", ":DEGREES"], ["#!OML:ASF x", ":RADIANS"], [""]]))
    values = np.array(flat, dtype=float).reshape(n_frames, total)
    return Motion(names, counts, values, np.arange(first, first + n_frames), header)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(motion=motions(), style=st.builds(
    AmcStyle,
    notation=st.just("g"),
    digits=st.integers(6, 17),
    exponent_digits=st.sampled_from([2, 3]),
    newline=st.sampled_from(["\n", "\r\n"]),
    final_newline=st.booleans(),
))
def test_hypothesis_write_read_round_trip(motion, style):
    text = format_amc(motion, style=style)
    again = parse_amc(text.encode())
    assert again.bones == motion.bones and again.counts == motion.counts and again.header == motion.header
    np.testing.assert_array_equal(again.frame_numbers, motion.frame_numbers)
    assert_same_to_digits(motion.values, again.values, style.digits)
    if style.digits == 17:
        assert np.array_equal(again.values, motion.values)
    # Reading detects a style that writes the same numbers again.
    assert np.array_equal(parse_amc(format_amc(again).encode()).values, again.values)


@settings(max_examples=60, deadline=None)
@given(motion=motions())
def test_hypothesis_six_digit_round_trip(motion):
    again = parse_amc(format_amc(motion, digits=6).encode())
    assert again.bones == motion.bones
    assert_same_to_digits(motion.values, again.values, 6)


def test_parse_amc_accepts_str_and_reports_path():
    motion = parse_amc("1\nroot 1 2 3 4 5 6\n", "memory.amc")
    assert motion.path == "memory.amc" and motion.values.tolist() == [[1, 2, 3, 4, 5, 6]]
    with pytest.raises(MocapFormatError, match=r"^memory\.amc:2: not a number: 'x'$"):
        parse_amc("1\nroot 1 2 x 4 5 6\n", "memory.amc")
