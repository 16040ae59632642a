"""The compiled AMC loops (formats/amc_compiled.py, on formats/numbers_compiled.py) against plain
Python: float() and the number grammar for reading, the `%` operator for writing; on every real
AMC file, on damaged files and on random values. A few real files in the fast tier, all of them
under `slow`."""

from __future__ import annotations

import dataclasses
import math
import random
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hostile_inputs
from mocapzip.formats.amc import AmcStyle, Motion, _number_style, _parse_exact, _parse_fast, format_amc, parse_amc
from mocapzip.formats.amc_compiled import format_frames
from mocapzip.formats.numbers_compiled import STAT_ANY_EXP, STAT_MIN_EXP_DIGITS, scan_tokens
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.text import NUMBER

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
AMC_FILES = sorted(p.relative_to(DATA).as_posix() for p in DATA.rglob("*") if p.suffix.lower() == ".amc")
QUICK = [
    "cmu/07/07_01.amc",
    "cmu/02/02_03.amc",  # CRLF
    "cmu/64/golf_01.amc",  # truncated: the exact path
    "hdm05/bk/HDM_bk_sneak2StepsLStart_006_120.AMC",  # Latin-1 header, LF frame lines
    "other-vicon-blade/walk_200fps/walkMoCap2.amc",  # fixed decimals
    "cmu-edited/124/124_02_part2_frames700-1319.amc",
    "cmu-edited/07/headerless_walk_1.amc",
]
EVERY_FILE = [f if f in QUICK else pytest.param(f, marks=pytest.mark.slow) for f in AMC_FILES]


# --------------------------------------------------------------------------- references in plain Python


def python_words(data: bytes) -> list[bytes]:
    """The value words of an AMC file in file order: every word after a bone name."""
    words, in_frames = [], False
    for line in data.splitlines():
        parts = line.split()
        if len(parts) == 1 and parts[0].isdigit():
            in_frames = True
        elif in_frames and parts:
            words += parts[1:]
    return words


def python_stats(words: list[bytes]) -> np.ndarray:
    """What numbers_compiled counts of valid number words, from their text."""
    sig, decimals, exp_digits, dots = [], [], [], []
    for word in words:
        mantissa, _, exponent = word.lstrip(b"+-").lower().partition(b"e")
        whole, dot, fraction = mantissa.partition(b".")
        sig.append(len((whole + fraction).lstrip(b"0")))
        decimals.append(len(fraction))
        exp_digits.append(len(exponent.lstrip(b"+-")))
        dots.append(bool(dot))
    exps = [e for e in exp_digits if e]
    return np.array([len(words), all(dots), bool(exps), decimals[0], all(d == decimals[0] for d in decimals),
                     max(sig), min(exps, default=0)], dtype=np.int64)


def comparable(stats: np.ndarray) -> list[int]:
    """`stats` with the smallest exponent width dropped where there is no exponent."""
    out = [int(s) for s in stats]
    if not out[STAT_ANY_EXP]:
        out[STAT_MIN_EXP_DIGITS] = 0
    return out


def python_text(motion: Motion, style: AmcStyle) -> str:
    """format_amc's text as Python's `%` operator writes it: the whole frame layout as one format."""
    nl = style.newline
    head = "".join(line + (style.header_newline or nl) for line in motion.header)
    layout = ["%d", style.frame_newline or nl]
    for bone, count in zip(motion.bones, motion.counts):
        layout.append(bone.replace("%", "%%"))
        if count:
            layout.append(style.name_separator + " ".join([style.number_format] * count))
        layout.append(nl)
    rows = np.column_stack([np.asarray(motion.frame_numbers, dtype=float), motion.values])
    text = "".join(layout) * len(rows) % tuple(rows.ravel().tolist())
    if style.notation == "g" and style.exponent_digits != 2:
        text = re.sub(r"(?<=[0-9.])e([+-])([0-9]+)(?![0-9])", lambda m: f"e{m[1]}{m[2].zfill(style.exponent_digits)}", text)
    text = head + text
    return text if style.final_newline or not text.endswith(nl) else text[: -len(nl)]


def same_bits(a, b) -> bool:
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))  # -0.0 too


def encoding_of(data: bytes) -> str:
    return "utf-8" if data.isascii() else "latin-1"


# --------------------------------------------------------------------------- reading: the real data


@pytest.mark.parametrize("rel", EVERY_FILE)
def test_reading_real_files_gives_floats_values_and_style(rel):
    """Values bit for bit as float() of the words, and the number style the words' text gives."""
    data = (DATA / rel).read_bytes()
    fast = _parse_fast(data, rel, encoding_of(data))
    if rel.endswith("golf_01.amc"):
        assert fast is None  # its last frame is cut short
        return
    motion = fast[0]
    words = python_words(data)
    expected = python_stats(words)
    assert same_bits(motion.values.ravel(), [float(w) for w in words])
    assert dataclasses.replace(motion.style, **_number_style(expected)) == motion.style
    values, stats = scan_tokens(np.frombuffer(b" ".join(words), np.uint8), len(words))
    converted = ~np.isnan(values)  # the rest (e.g. CMU's 1.55301e-018: 1e-23 is not exact) went to float()
    assert converted.mean() > 0.999 and same_bits(values[converted], motion.values.ravel()[converted])
    assert comparable(stats) == comparable(expected)
    if rel in QUICK:  # the exact path reads the file the same (its words through scan_tokens)
        exact, first_lines = _parse_exact(data, rel, encoding_of(data))
        assert same_bits(exact.values, motion.values) and exact.style == motion.style and first_lines == fast[1]
        assert np.array_equal(exact.frame_numbers, motion.frame_numbers) and exact.bones == motion.bones


# --------------------------------------------------------------------------- reading: numbers


number_words = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False).flatmap(
        lambda v: st.sampled_from([repr(v), "%.6g" % v, "%.6f" % v, "%.17g" % v, "%e" % v, "%.3E" % v, "%.25f" % v])
    ),
    st.from_regex(r"[+-]?(\d{1,24}\.?\d{0,24}|\.\d{1,24})([eE][+-]?\d{1,4})?", fullmatch=True),
    st.text(alphabet="0123456789.-+eE_xn", min_size=1, max_size=24),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(words=st.lists(number_words, min_size=1, max_size=40))
def test_number_words_convert_as_float_or_are_left_to_it(words):
    raw = [w.encode() for w in words]
    values, stats = scan_tokens(np.frombuffer(b" ".join(raw), np.uint8), len(raw))
    valid = [w for w in raw if NUMBER.match(w)]
    for word, value in zip(raw, values):
        if not NUMBER.match(word):
            assert math.isnan(value), word  # not a number: the caller raises
        elif not math.isnan(value):
            assert same_bits(value, float(word)), word
        else:  # left to float(): only long words, or exponents that may lie beyond 1e22
            assert len(word) > 15 or b"e" in word.lower(), word
    if valid:
        assert comparable(stats) == comparable(python_stats(valid))


def test_cmu_and_blade_words_convert_here():
    words = [b"3.64024e-015", b"-0.000000", b"15.287990", b"0.0030495", b"7.12502", b"-180", b"1e+022", b".5", b"5."]
    values, _ = scan_tokens(np.frombuffer(b" ".join(words), np.uint8), len(words))
    assert same_bits(values, [float(w) for w in words])
    assert math.copysign(1, values[1]) == -1


def test_long_values_in_the_usual_layout_are_read_by_float():
    """A 30-digit value takes the fast path all the same: float() converts just that word."""
    long = b"0.123456789012345678901234567891"
    data = b"1\nroot 1 " + long + b" 3\nlfemur 4\n2\nroot 5 6 7\nlfemur 1e-30\n"
    fast = _parse_fast(data, None, "utf-8")
    assert fast is not None
    assert same_bits(fast[0].values, [[1, float(long), 3, 4], [5, 6, 7, 1e-30]])
    assert fast[0].style.digits == 17  # 30 significant digits: written back with 17


@pytest.mark.parametrize(
    "word, message",
    [(b"1.2.3", r"not a number: '1\.2\.3'"), (b"nan", r"value is not finite: 'nan'"),
     (b"2e9", r"value 2e9 is out of range"), (b"1" * 30, r"value 1{30} is out of range"), (b"1e+", "not a number")],
)
def test_bad_values_leave_the_fast_path_and_are_named_with_their_line(word, message):
    data = b":DEGREES\n1\nroot 1 2 3\nlfemur 4\n2\nroot 5 " + word + b" 7\nlfemur 8\n"
    assert _parse_fast(data, "bad.amc", "utf-8") is None
    with pytest.raises(MocapFormatError, match=r"^bad\.amc:6: " + message):
        parse_amc(data, "bad.amc")


# --------------------------------------------------------------------------- reading: damaged files


def fast_and_exact_agree(data: bytes) -> None:
    """The fast path takes a file only where the exact path reads it to the same motion."""
    encoding = "utf-8" if data.isascii() else "latin-1"
    try:
        exact = _parse_exact(data, "f.amc", encoding, partial_last_frame="error")
    except MocapFormatError as error:
        exact = error
    try:
        fast = _parse_fast(data, "f.amc", encoding)
    except MocapFormatError as error:  # too many frames: raised by both paths, the same
        assert isinstance(exact, MocapFormatError) and str(error) == str(exact)
        return
    if fast is None:
        return
    assert not isinstance(exact, MocapFormatError), f"fast path took what the exact path refuses: {exact}"
    (a, a_lines), (b, b_lines) = fast, exact
    assert (a.bones, a.counts, a.header, a.style, a_lines) == (b.bones, b.counts, b.header, b.style, b_lines)
    assert same_bits(a.values, b.values) and np.array_equal(a.frame_numbers, b.frame_numbers)


@pytest.fixture(scope="module")
def hostile_amcs(tmp_path_factory) -> list[Path]:
    root = tmp_path_factory.mktemp("hostile")
    hostile_inputs.build(root, DATA)
    return sorted(p for p in root.rglob("*") if p.is_file() and p.suffix.lower() == ".amc")


def test_hostile_files_take_the_fast_path_only_where_the_exact_path_agrees(hostile_amcs):
    assert len(hostile_amcs) >= 20
    for path in hostile_amcs:
        if path.stat().st_size < 20_000_000:
            fast_and_exact_agree(path.read_bytes())


PIECES = [b" ", b"\n", b"\r", b"\r\n", b"\t", b"\x0b", b"-", b"+", b".", b"e", b"E-", b"0", b"7", b"x", b"nan", b"#",
          b"1e10", b"0000000000000001", b"123456789012345678", b"1000000001", b"root", b"\xff", b"\x00"]


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_mutated_real_files_take_the_fast_path_only_where_the_exact_path_agrees(seed):
    rng = random.Random(seed)
    source = rng.choice(["cmu/09/09_01.amc", "other-vicon-blade/walk_200fps/walkMoCap2.amc", "cmu/02/02_03.amc"])
    data = bytearray((DATA / source).read_bytes()[:6000])
    for _ in range(rng.randint(1, 3)):
        at = rng.randrange(len(data) + 1)
        if rng.random() < 0.5:
            data[at:at] = rng.choice(PIECES)
        else:
            data[at : at + rng.randint(1, 8)] = rng.choice([b"", *PIECES])
    fast_and_exact_agree(bytes(data))


# --------------------------------------------------------------------------- writing


def written_styles(style: AmcStyle) -> list[AmcStyle]:
    return [style, dataclasses.replace(style, notation="g", digits=6, exponent_digits=3),
            dataclasses.replace(style, notation="f", digits=6), dataclasses.replace(style, notation="g", digits=9, exponent_digits=2)]


@pytest.mark.parametrize("rel", EVERY_FILE)
def test_writing_real_files_gives_pythons_text(rel):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # golf_01.amc: its last frame is cut short and dropped
        motion = parse_amc((DATA / rel).read_bytes(), rel)
    for style in written_styles(motion.style):
        assert format_amc(motion, style=style) == python_text(motion, style), style
    if rel in QUICK:  # 17 digits: every number is left to Python
        style = dataclasses.replace(motion.style, notation="g", digits=17)
        assert format_amc(motion, style=style) == python_text(motion, style)


def halfway_cases() -> list[float]:
    """Values on and next to a rounding half or a power of ten, where digits carry."""
    out = []
    for base in (0.5, 1.5, 2.5, 9.5, 123456.5, 999999.5, 9.999995, 99999.95, 1.0000005, 0.00012345650000000001,
                 1e5, 1e6, 1e-4, 1e-5, 9.9999950000000001e-5, 0.1 + 0.2, 2.0**52, 2.0**53, 4503599627370495.5):
        for scale in (1.0, 10.0, 100.0, 1e-3, 1e3, 1e-7, 1e7):
            x = base * scale
            out += [x, -x, np.nextafter(x, np.inf), np.nextafter(x, -np.inf)]
    return out


EDGES = [0.0, -0.0, 5e-324, 2.2250738585072014e-308, 1e-300, 1e22, 1e23, 1.7976931348623157e308, -1e300]
STYLES = [("g", d, w) for d in (1, 2, 3, 6, 7, 10, 15, 16, 17) for w in (1, 2, 3)] + [("f", d, 2) for d in (0, 1, 3, 6, 17, 25)]


@pytest.mark.parametrize("notation, digits, width", STYLES)
def test_writing_random_values_gives_pythons_text(notation, digits, width):
    rng = np.random.default_rng(digits * 10 + width)
    magnitudes = 10.0 ** rng.uniform(-26, 26, 3000) * rng.choice([-1.0, 1.0], 3000)
    everyday = np.concatenate([rng.normal(0, 100, 2000), np.round(rng.normal(0, 100, 1000), 3), rng.uniform(-1e-5, 1e5, 1000)])
    values = np.concatenate([magnitudes, everyday, halfway_cases(), EDGES]).reshape(-1, 1)
    motion = Motion(["v"], [1], values, np.arange(len(values)), [])
    style = AmcStyle(notation=notation, digits=digits, exponent_digits=width)
    assert format_amc(motion, style=style) == python_text(motion, style)


def test_writing_leaves_only_the_hard_numbers_to_python():
    """Halves, 17 digits and scales beyond 1e22 go to Python; everyday values never do."""
    def left(values, fixed, digits):
        values = np.asarray(values, dtype=np.float64).reshape(-1, 1)
        one = np.array([1], dtype=np.int64)
        newline = np.frombuffer(b"\n", np.uint8)
        _, hard = format_frames(values, np.arange(len(values), dtype=np.float64), np.frombuffer(b"v", np.uint8), one,
                                one, np.frombuffer(b" ", np.uint8), newline, newline, fixed, digits, 2)
        return [item // 2 for _, item in hard.tolist()]  # item: row * 2 + 1 for the row's value
    everyday = np.random.default_rng(0).normal(0, 100, 10_000)
    assert left(everyday, False, 6) == [] and left(everyday, True, 6) == []
    assert left([1.0, 123456.5, 2.0, 1e-30, 0.5], False, 6) == [1, 3]  # a half of the 6th digit, a scale of 1e35
    assert left([0.5, 0.25, 1e17], True, 0) == [0, 2]  # 0.5 is a half; 1e17 is beyond 2**52
    assert left([1.0, 2.0], False, 17) == [0, 1]


@settings(max_examples=100, deadline=None)
@given(values=st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=1, max_size=30),
       notation=st.sampled_from(["g", "f"]), digits=st.integers(0, 17), width=st.integers(1, 4))
def test_hypothesis_writing_gives_pythons_text(values, notation, digits, width):
    style = AmcStyle(notation=notation, digits=max(digits, notation == "g"), exponent_digits=width)
    motion = Motion(["a", "b"], [len(values) - len(values) // 2, len(values) // 2], np.array([values]), np.array([7]), [])
    assert format_amc(motion, style=style) == python_text(motion, style)


def test_writing_frame_numbers_and_bone_names_as_python_did():
    """Frame numbers go through '%d' as floats; names are written as they are, '%' and all,
    and widened where they look like exponents (as the text always was)."""
    values = np.array([[1e-5, 2.0], [-0.0, 1e100]])
    names = ["x1e-5", "f\u00fcr%d"]
    for frames in (np.array([2**62 + 3, -7]), np.array([1.5, -0.5]), np.array([0, 10**9])):
        for style in (AmcStyle(exponent_digits=3), AmcStyle(exponent_digits=1), AmcStyle(notation="f", digits=2)):
            motion = Motion(names, [1, 1], values, frames, ["# h\u00e9ader"])
            assert format_amc(motion, style=style) == python_text(motion, style)
    assert "x1e-005 1e-005\n" in format_amc(Motion(names, [1, 1], values, np.array([1, 2])), style=AmcStyle(exponent_digits=3))
