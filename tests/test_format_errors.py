"""Malformed ASF/AMC input: every fault is a MocapFormatError naming file, line and what was wrong.

Bad files are made in tmp_path from real files of ../shared/data (a value replaced, a line
deleted, ...), so the surrounding content is realistic and the line numbers are known.
"""

from __future__ import annotations

import functools
import pickle
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapzip.formats import amc as amc_module
from mocapzip.formats.amc import MAX_RADIANS, parse_amc, read_amc
from mocapzip.formats.asf import MAX_BONE_CM, parse_asf, read_asf
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.text import MAX_ABS_VALUE

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
AMC = DATA / "cmu" / "07" / "07_01.amc"  # LF, 3 header lines, frames of 29 bone lines
ASF = DATA / "cmu" / "07" / "07.asf"


# ------------------------------------------------------------------ helpers


def amc_lines() -> list[str]:
    return AMC.read_bytes().decode().replace("\r\n", "\n").split("\n")


def bone_index(lines: list[str], frame: int, bone: str) -> int:
    """0-based index of `bone`'s line in frame `frame` (line number = index + 1)."""
    start = lines.index(str(frame))
    for i in range(start + 1, start + 40):
        if lines[i].split()[0] == bone:
            return i
    raise AssertionError((frame, bone))


def write(tmp_path: Path, lines: list[str], name: str = "bad.amc") -> Path:
    path = tmp_path / name
    path.write_text("\n".join(lines))
    return path


def raises(path: Path, message: str, line: int | None, reader=read_amc, *args):
    """Assert the reader raises MocapFormatError with this message (regex) at this line."""
    with pytest.raises(MocapFormatError) as info:
        reader(path, *args)
    err = info.value
    assert err.path == str(path)
    assert err.line == line, str(err)
    assert re.fullmatch(message, err.message), err.message
    expected = f"{path}:{line}: {err.message}" if line is not None else f"{path}: {err.message}"
    assert str(err) == expected
    return err


# ------------------------------------------------------------------ the exception itself


def test_error_string_and_pickling():
    err = MocapFormatError("not a number: 'x'", "a/b.amc", 12)
    assert str(err) == "a/b.amc:12: not a number: 'x'"
    assert (err.message, err.path, err.line) == ("not a number: 'x'", "a/b.amc", 12)
    again = pickle.loads(pickle.dumps(err))
    assert (again.message, again.path, again.line) == (err.message, err.path, err.line)
    assert str(MocapFormatError("empty file", Path("c.asf"))) == "c.asf: empty file"
    assert str(MocapFormatError("plain")) == "plain"
    assert isinstance(err, Exception) and not isinstance(err, ValueError)


# ------------------------------------------------------------------ AMC: values


@pytest.mark.parametrize(
    "token, message",
    [
        ("abc", r"not a number: 'abc'"),
        ("1.2.3", r"not a number: '1\.2\.3'"),
        ("2_5", r"not a number: '2_5'"),
        ("0x1A", r"not a number: '0x1A'"),
        ("1e", r"not a number: '1e'"),
        ("--1", r"not a number: '--1'"),
        ("nan", r"value is not finite: 'nan'"),
        ("NaN", r"value is not finite: 'NaN'"),
        ("inf", r"value is not finite: 'inf'"),
        ("-Infinity", r"value is not finite: '-Infinity'"),
        ("1e308", r"value 1e308 is out of range \(\|v\| > 1e\+09\)"),
        ("-2.5e9", r"value -2\.5e9 is out of range \(\|v\| > 1e\+09\)"),
        ("1e999", r"value 1e999 is out of range \(\|v\| > 1e\+09\)"),
    ],
)
def test_bad_value(tmp_path, token, message):
    lines = amc_lines()
    i = bone_index(lines, 120, "lfemur")
    words = lines[i].split()
    words[2] = token
    lines[i] = " ".join(words)
    raises(write(tmp_path, lines), message, i + 1)


def test_bad_value_in_first_line_of_first_frame(tmp_path):
    lines = amc_lines()
    i = bone_index(lines, 1, "root")
    lines[i] = lines[i].replace(lines[i].split()[1], "abc", 1)
    raises(write(tmp_path, lines), r"not a number: 'abc'", i + 1)


def test_magnitude_bound_is_inclusive(tmp_path):
    lines = amc_lines()
    i = bone_index(lines, 3, "rtibia")
    lines[i] = f"rtibia {MAX_ABS_VALUE:.0f}"
    assert read_amc(write(tmp_path, lines)).values.max() == MAX_ABS_VALUE


def test_wrong_number_of_values(tmp_path):
    lines = amc_lines()
    i = bone_index(lines, 40, "rtibia")
    lines[i] += " 1.5"
    raises(write(tmp_path, lines), r"bone 'rtibia' has 2 values, expected 1", i + 1)


def test_missing_value(tmp_path):
    lines = amc_lines()
    i = bone_index(lines, 40, "root")
    lines[i] = lines[i].rsplit(" ", 1)[0]
    raises(write(tmp_path, lines), r"bone 'root' has 5 values, expected 6", i + 1)


def test_wrong_number_of_values_for_the_skeleton(tmp_path):
    lines = amc_lines()
    # Consistently 2 values for lowerback everywhere: only the skeleton can tell.
    for k, line in enumerate(lines):
        if line.startswith("lowerback "):
            lines[k] = line.rsplit(" ", 1)[0]
    path = write(tmp_path, lines)
    assert read_amc(path).counts[1] == 2
    raises(path, r"bone 'lowerback' has 2 values, the skeleton .*07\.asf gives it 3 dof \(rx ry rz\)", 6,
           read_amc, read_asf(ASF))


def test_bone_not_in_skeleton(tmp_path):
    lines = [line.replace("upperneck ", "neck2 ", 1) for line in amc_lines()]
    path = write(tmp_path, lines)
    assert "neck2" in read_amc(path).bones  # fine without a skeleton
    raises(path, r"bone 'neck2' is not in the skeleton .*07\.asf", bone_index(lines, 1, "neck2") + 1,
           read_amc, read_asf(ASF))


def test_bone_not_in_first_frame(tmp_path):
    lines = amc_lines()
    i = bone_index(lines, 77, "head")
    lines[i] = lines[i].replace("head", "haed")
    raises(write(tmp_path, lines), r"bone 'haed' is not among the first frame's bones", i + 1)


def test_duplicate_bone_in_frame(tmp_path):
    lines = amc_lines()
    first = bone_index(lines, 8, "thorax")
    i = bone_index(lines, 8, "lclavicle")
    lines[i] = lines[first]
    raises(write(tmp_path, lines), rf"bone 'thorax' appears twice in frame 8 \(first at line {first + 1}\)", i + 1)


def test_duplicate_bone_in_first_frame(tmp_path):
    lines = amc_lines()
    i = bone_index(lines, 1, "head")
    lines.insert(i + 1, lines[i])
    raises(write(tmp_path, lines), rf"bone 'head' appears twice in frame 1 \(first at line {i + 1}\)", i + 2)


# ------------------------------------------------------------------ AMC: frames


def test_truncated_frame_in_the_middle(tmp_path):
    lines = amc_lines()
    frame_line = lines.index("100") + 1
    del lines[bone_index(lines, 100, "lfoot")]
    next_frame = lines.index("101") + 1
    raises(
        write(tmp_path, lines),
        rf"truncated frame 100: 28 of 29 bones, missing 'lfoot' \(frame starts at line {frame_line}\)",
        next_frame,
    )


def test_truncated_frame_missing_several_bones(tmp_path):
    lines = amc_lines()
    start = lines.index("5")
    del lines[start + 20 : start + 30]
    raises(
        write(tmp_path, lines),
        rf"truncated frame 5: 19 of 29 bones, missing 'lfingers', 'lthumb', 'rfemur', 'rtibia', 'rfoot', \.\.\. "
        rf"\(frame starts at line {start + 1}\)",
        start + 21,
    )


@pytest.mark.parametrize("cut", ["lines", "mid-line"])
def test_truncated_last_frame_is_dropped_with_a_warning(tmp_path, cut):
    lines = [line for line in amc_lines() if line]
    last = lines.index("316")
    if cut == "lines":
        lines = lines[: last + 12]
    else:
        lines = lines[: last + 12] + [lines[last + 12].rsplit(" ", 1)[0]]
    path = write(tmp_path, lines)
    with pytest.warns(UserWarning, match=rf"bad\.amc:{last + 1}: last frame 316 is incomplete \((11|12) of 29 bones"):
        motion = read_amc(path)
    assert motion.n_frames == 315 and motion.dropped_frames == 1
    np.testing.assert_array_equal(motion.values, read_amc(AMC).values[:315])
    assert read_amc(AMC).dropped_frames == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # strict mode refuses without a warning
        raises(path, r"last frame 316 is incomplete \((11|12) of 29 bones, the file ends at line \d+\): "
               r"--lossless cannot keep a partial frame", last + 1, functools.partial(read_amc, partial_last_frame="error"))
    with pytest.raises(MocapFormatError, match="cannot keep a partial frame"):
        parse_amc(path.read_bytes(), partial_last_frame="error")


def test_partial_last_frame_mode_is_checked():
    with pytest.raises(ValueError, match="partial_last_frame"):
        parse_amc(AMC.read_bytes(), partial_last_frame="keep")


# ------------------------------------------------------------------ AMC: size limits
# The limits are made small here (monkeypatch) so the files stay small; both readers are
# tried: the vectorised one on the file as it is, the line-by-line one with a comment added
# after the last frame (which the vectorised reader leaves to it).


def limited(monkeypatch, **limits):
    for name, value in limits.items():
        monkeypatch.setattr(amc_module, name, value)


@pytest.mark.parametrize("exact", [False, True], ids=["fast", "exact"])
def test_more_frames_than_a_clip_may_have(tmp_path, monkeypatch, exact):
    limited(monkeypatch, MAX_FRAMES_PER_CLIP=200)
    lines = amc_lines() + (["# comment"] if exact else [])
    raises(write(tmp_path, lines), r"frame 201 makes the clip too long: more than the 200 frames a clip may have",
           lines.index("201") + 1)
    limited(monkeypatch, MAX_FRAMES_PER_CLIP=316)  # the clip's own length is fine
    assert read_amc(write(tmp_path, lines)).n_frames == 316


@pytest.mark.parametrize("exact", [False, True], ids=["fast", "exact"])
def test_more_values_than_a_clip_may_have(tmp_path, monkeypatch, exact):
    limited(monkeypatch, MAX_VALUES_PER_CLIP=62 * 100 + 61)  # room for 100 frames of 62 values
    lines = amc_lines() + (["# comment"] if exact else [])
    raises(write(tmp_path, lines), r"frame 101 makes the clip too long: more than the 6,261 values a clip may have "
           r"\(62 per frame\)", lines.index("101") + 1)


def test_more_values_per_frame_than_a_frame_may_have(tmp_path, monkeypatch):
    limited(monkeypatch, MAX_VALUES_PER_FRAME=61)
    raises(write(tmp_path, amc_lines()), r"frame 1 has 62 values, more than the 61 a frame may have", 4)


def test_file_larger_than_a_clip_may_be_is_refused_unread(tmp_path, monkeypatch):
    path = write(tmp_path, amc_lines())
    limited(monkeypatch, MAX_AMC_BYTES=path.stat().st_size - 1)
    raises(path, rf"file of {path.stat().st_size:,} bytes is larger than the {path.stat().st_size - 1:,} bytes an AMC "
           r"file may have \(16 bytes for each of the 8,388,608 values a clip may hold\)", None)
    with pytest.raises(MocapFormatError, match="is larger than"):
        parse_amc(path.read_bytes())


# ------------------------------------------------------------------ AMC: angles in radians


def test_degrees_under_a_radians_header(tmp_path):
    lines = amc_lines()
    assert lines[2] == ":DEGREES"
    lines[2] = ":RADIANS"
    i = bone_index(lines, 40, "lfemur")
    lines[i] = "lfemur 320 0 0"
    raises(write(tmp_path, lines), r"angle 320 of bone 'lfemur' in frame 40 is beyond 314\.2 rad \(50 turns\): the "
           r"values look like degrees, not the radians this ':RADIANS' line declares", 3, read_amc, read_asf(ASF))
    lines[i] = f"lfemur {MAX_RADIANS} 0 0"  # the bound itself is an angle
    assert read_amc(write(tmp_path, lines), read_asf(ASF)).values.max() == MAX_RADIANS
    lines[bone_index(lines, 1, "root")] = "root 1000 2000 3000 0 0 0"  # translations are no angles
    read_amc(write(tmp_path, lines), read_asf(ASF))


def test_degrees_under_a_radians_skeleton(tmp_path):
    asf = asf_lines()
    asf[asf_index(asf, "angle deg")] = "  angle rad"
    skeleton = read_asf(write_asf_lines(tmp_path, asf))
    lines = amc_lines()
    del lines[2]  # no :DEGREES: the skeleton's unit applies
    i = bone_index(lines, 7, "rtibia")
    lines[i] = "rtibia -400"
    raises(write(tmp_path, lines), rf"angle -400 of bone 'rtibia' in frame 7 is beyond 314\.2 rad \(50 turns\): the "
           rf"values look like degrees, not the radians the skeleton {re.escape(str(tmp_path))}/bad\.asf declares "
           r"\('angle rad'\)", None, read_amc, skeleton)
    assert read_amc(write(tmp_path, [":DEGREES"] + lines), skeleton).values.min() == -400  # the AMC's unit wins


@pytest.mark.parametrize(
    "number, message",
    [
        ("49", r"duplicate frame number 49"),
        ("12", r"frame number 12 out of order \(after 49\)"),
        ("51", r"frame numbers jump from 49 to 51 \(frames must be consecutive\)"),
    ],
)
def test_bad_frame_number(tmp_path, number, message):
    lines = amc_lines()
    i = lines.index("50")
    lines[i] = number
    raises(write(tmp_path, lines), message, i + 1)


def test_frame_number_out_of_range(tmp_path):
    lines = amc_lines()
    i = lines.index("1")
    lines[i] = "1" + "0" * 5000
    raises(write(tmp_path, lines), r"frame number 1" + "0" * 39 + r"\.\.\. is out of range \(> 1000000000\)", i + 1)


def test_frames_may_start_anywhere(tmp_path):
    lines = amc_lines()
    n = 0
    for k, line in enumerate(lines):
        if line.isdigit():
            lines[k] = str(int(line) + 9999)
            n += 1
    motion = read_amc(write(tmp_path, lines))
    assert motion.frame_numbers[0] == 10000 and motion.n_frames == n


@pytest.mark.parametrize("line_end", ["\n", "\r"])  # the compiled path, and the exact one
def test_a_frame_number_of_more_digits_than_int_takes_is_read_by_its_value(tmp_path, line_end):
    """int() refuses a word of more than 4,300 digits, leading zeros too: before, the exact path
    raised its ValueError (a traceback in every command)."""
    lines = amc_lines()
    i = lines.index("50")
    lines[i] = "0" * 5000 + "50"
    path = tmp_path / "long.amc"
    path.write_text(line_end.join(lines))
    assert read_amc(path).frame_numbers[49] == 50


def test_frame_without_bones(tmp_path):
    raises(write(tmp_path, [":DEGREES", "1", "2", "root 1 2 3 4 5 6"]), r"frame 1 has no bone lines", 2)


def test_bone_line_before_first_frame(tmp_path):
    lines = amc_lines()
    lines.insert(3, "root 1 2 3 4 5 6")
    raises(write(tmp_path, lines), r"expected a frame number, got 'root 1 2 3 4 5 6' \(a bone line before the first frame number\)", 4)


def test_line_of_numbers_instead_of_bone(tmp_path):
    lines = amc_lines()
    i = bone_index(lines, 9, "rhand")
    lines[i] = "12 13"
    raises(write(tmp_path, lines), r"expected a bone name or a frame number, got '12 13'", i + 1)


# ------------------------------------------------------------------ AMC and ASF: whole-file faults


@pytest.mark.parametrize("reader, suffix", [(read_amc, ".amc"), (read_asf, ".asf")])
@pytest.mark.parametrize(
    "content, message, line",
    [
        (b"", r"empty file", 1),
        (b" \r\n\n\t\n", r"empty file", 1),
        ("kind:utf16", r"UTF-16 text, not an ASCII Acclaim file", 1),
        ("kind:utf16-nobom", r"UTF-16 text, not an ASCII Acclaim file", 1),
        ("kind:utf16-be", r"UTF-16 text, not an ASCII Acclaim file", 1),
        (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(range(256)), r"binary data \(NUL bytes\), not an ASCII Acclaim file", 3),
    ],
)
def test_unreadable_content(tmp_path, reader, suffix, content, message, line):
    source = (AMC if suffix == ".amc" else ASF).read_text()
    if content == "kind:utf16":
        content = source.encode("utf-16")
    elif content == "kind:utf16-nobom":
        content = source.encode("utf-16-le")
    elif content == "kind:utf16-be":
        content = source.encode("utf-16-be")
    path = tmp_path / f"bad{suffix}"
    path.write_bytes(content)
    raises(path, message, line, reader)


def test_amc_header_only(tmp_path):
    raises(write(tmp_path, amc_lines()[:3] + [""]), r"no frames: the file has header lines only", 3)


def test_not_an_amc_file(tmp_path):
    path = tmp_path / "bad.amc"
    path.write_bytes(ASF.read_bytes())
    with pytest.raises(MocapFormatError, match=r"bad\.amc:\d+: expected a frame number"):
        read_amc(path)


# ------------------------------------------------------------------ ASF


def asf_lines() -> list[str]:
    return ASF.read_text().replace("\r\n", "\n").split("\n")


def asf_index(lines: list[str], text: str, start: int = 0) -> int:
    return next(i for i in range(start, len(lines)) if lines[i].strip() == text)


def write_asf_lines(tmp_path, lines):
    path = tmp_path / "bad.asf"
    path.write_text("\n".join(lines))
    return path


def test_an_asf_bone_id_of_more_digits_than_int_takes_is_read_by_its_value(tmp_path):
    """Before: the ValueError of int(), which refuses more than 4,300 digits, leading zeros too."""
    lines = asf_lines()
    i = next(k for k, line in enumerate(lines) if line.split() == ["id", "2"])
    for sign, value in (("", 2), ("-", -2)):
        lines[i] = f"    id {sign}{'0' * 5000}2"
        assert read_asf(write_asf_lines(tmp_path, lines)).bone("lfemur").id == value


def test_asf_bone_without_end(tmp_path):
    lines = asf_lines()
    begin = asf_index(lines, "name ltibia") - 2
    end = asf_index(lines, "end", begin)
    del lines[end]
    next_begin = asf_index(lines, "begin", begin + 1)
    raises(write_asf_lines(tmp_path, lines),
           rf"'begin' inside bone 'ltibia' \(begin at line {begin + 1}; missing 'end'\)", next_begin + 1, read_asf)


def test_asf_last_bone_without_end(tmp_path):
    lines = asf_lines()
    h = asf_index(lines, ":hierarchy")
    del lines[h - 1]
    raises(write_asf_lines(tmp_path, lines), r"bone 'rthumb' \(begin at line \d+\) has no 'end' before ':hierarchy'", h, read_asf)


def test_asf_hierarchy_without_end(tmp_path):
    lines = [line for line in asf_lines() if line.strip()]
    assert lines[-1].strip() == "end"
    del lines[-1]
    raises(write_asf_lines(tmp_path, lines), r"file ends inside ':hierarchy' \(begin at line \d+; missing 'end'\)",
           len(lines), read_asf)


def test_asf_unknown_bone_in_hierarchy(tmp_path):
    lines = asf_lines()
    i = asf_index(lines, "lfemur ltibia")
    lines[i] = "    lfemur ltibiaa"
    raises(write_asf_lines(tmp_path, lines), r"hierarchy names unknown bone 'ltibiaa'", i + 1, read_asf)


def test_asf_unknown_parent_in_hierarchy(tmp_path):
    lines = asf_lines()
    i = asf_index(lines, "lfemur ltibia")
    lines[i] = "    lfemr ltibia"
    raises(write_asf_lines(tmp_path, lines), r"hierarchy names unknown bone 'lfemr'", i + 1, read_asf)


def test_asf_cycle(tmp_path):
    lines = asf_lines()
    i = asf_index(lines, "lhipjoint lfemur")
    lines[i] = "    ltibia lfemur"  # lfemur -> ltibia -> lfemur, cut off from root
    raises(write_asf_lines(tmp_path, lines), r"cycle in ':hierarchy': lfemur <- ltibia <- lfemur", i + 1, read_asf)


def test_asf_cycle_at_the_end_of_a_long_chain(tmp_path):
    """The cycle check walks each bone once: 990 bones in a chain, the last two in a loop."""
    lines = asf_lines()
    h = asf_index(lines, ":hierarchy")
    n = 990
    lines[h:h] = [f"  begin\n     name c{k}\n     direction 0 1 0\n     length 0.1\n     axis 0 0 0  XYZ\n  end"
                  for k in range(n)]
    lines.insert(-2, "    rhand c0\n" + "\n".join(f"    c{k} c{k + 1}" for k in range(n - 2)))
    lines.insert(-2, f"    c{n - 1} c{n - 1}")  # c19999's parent is itself, so the chain never gets back to root
    path = write_asf_lines(tmp_path, lines)
    last_line = path.read_text().split("\n").index(f"    c{n - 1} c{n - 1}") + 1
    raises(path, rf"cycle in ':hierarchy': c{n - 1} <- c{n - 1}", last_line, read_asf)


@pytest.mark.parametrize("value", ["0", "-0.45", "1e-300", "9.9e-7", "1.1e6"])
def test_asf_units_length_out_of_range(tmp_path, value):
    lines = asf_lines()
    i = asf_index(lines, "length 0.45")
    lines[i] = f"  length {value}"
    raises(write_asf_lines(tmp_path, lines),
           rf"units length {re.escape(value)} is outside \[1e-06, 1e\+06\] \(file lengths are inches x this factor\)",
           i + 1, read_asf)


def test_asf_units_length_bounds_are_inclusive(tmp_path):
    lines = asf_lines()
    i = asf_index(lines, "length 0.45")
    lines[i] = "  length 1e6"
    assert read_asf(write_asf_lines(tmp_path, lines)).length_scale == 1e6
    lines[i] = "  length 1e-6"  # allowed, but it makes every bone kilometres long
    raises(write_asf_lines(tmp_path, lines), r"bone 'lhipjoint' is .* cm long .*", asf_index(lines, "length 2.68184") + 1,
           read_asf)


def test_asf_bone_longer_than_a_bone_may_be(tmp_path):
    lines = asf_lines()
    i = asf_index(lines, "length 6.92462", asf_index(lines, "name lfemur"))  # 39 cm
    cm_per_unit = 2.54 / 0.45
    lines[i] = f"     length {0.999 * MAX_BONE_CM / cm_per_unit}"  # just within the bound: fine
    assert read_asf(write_asf_lines(tmp_path, lines)).bone("lfemur").length * cm_per_unit == pytest.approx(0.999 * MAX_BONE_CM)
    lines[i] = "     length 1e9"
    raises(write_asf_lines(tmp_path, lines), r"bone 'lfemur' is 5\.64e\+09 cm long \(direction x length x 5\.64444 cm "
           r"per unit\), longer than the 10000 cm a bone may be", i + 1, read_asf)
    lines[i] = "     length 6.92462"
    j = asf_index(lines, "direction 0.34202 -0.939693 0", asf_index(lines, "name lfemur"))
    lines[j] = "     direction 1e4 0 0"  # the bone vector is direction x length
    raises(write_asf_lines(tmp_path, lines), r"bone 'lfemur' is 3\.91e\+05 cm long .*", i + 1, read_asf)


def test_asf_root_as_child(tmp_path):
    lines = asf_lines()
    i = asf_index(lines, "lfoot ltoes")
    lines[i] = "    lfoot ltoes root"
    raises(write_asf_lines(tmp_path, lines), r"'root' cannot be a child \(of 'lfoot'\): cycle in ':hierarchy'", i + 1, read_asf)


def test_asf_two_parents(tmp_path):
    lines = asf_lines()
    first = asf_index(lines, "lfoot ltoes")
    i = asf_index(lines, "rfoot rtoes")
    lines[i] = "    rfoot rtoes ltoes"
    raises(write_asf_lines(tmp_path, lines),
           rf"bone 'ltoes' has two parents in ':hierarchy', 'lfoot' \(line {first + 1}\) and 'rfoot'", i + 1, read_asf)


def test_asf_bone_missing_from_hierarchy(tmp_path):
    lines = asf_lines()
    lines[asf_index(lines, "lfoot ltoes")] = "    lfoot"
    name_line = asf_index(lines, "name ltoes") + 1
    raises(write_asf_lines(tmp_path, lines), r"bone 'ltoes' is not in ':hierarchy'", name_line, read_asf)


def test_asf_duplicate_bone(tmp_path):
    lines = asf_lines()
    first = asf_index(lines, "name ltoes")
    i = asf_index(lines, "name rtoes")
    lines[i] = "     name ltoes"
    raises(write_asf_lines(tmp_path, lines), rf"duplicate bone 'ltoes' \(first at line {first + 1}\)", i + 1, read_asf)


@pytest.mark.parametrize(
    "old, new, message",
    [
        ("length 6.92462", "length abc", r"not a number: 'abc'"),
        ("length 6.92462", "length 7.1578 2", r"length needs 1 number, got 2"),
        ("length 6.92462", "length nan", r"value is not finite: 'nan'"),
        ("length 6.92462", "length 1e308", r"value 1e308 is out of range \(\|v\| > 1e\+09\)"),
        ("direction 0.34202 -0.939693 0", "direction 0.34202 -0.939693", r"direction needs 3 numbers, got 2"),
        ("axis 0 0 20  XYZ", "axis 0 0 20 XYW", r"axis order must be an order of X, Y, Z, got 'XYW'"),
        ("dof rx ry rz", "dof rx rw rz", r"unknown dof 'rw' in bone 'lfemur' \(expected rx ry rz tx ty tz l\)"),
        ("dof rx ry rz", "dof rx rx rz", r"bone 'lfemur' names a dof twice"),
        ("dof rx ry rz", "dof rx ry", r"bone 'lfemur' has 2 dof but 3 limits"),
        ("limits (-160.0 20.0)", "limits (-160.0 20.0", r"limits need '\(min max\)' pairs, got '\(-160\.0 20\.0'"),
        ("limits (-160.0 20.0)", "limits (-160.0 x)", r"not a number: 'x'"),
        ("limits (-160.0 20.0)", "limits (20.0 -160.0)", r"limit minimum 20\.0 is above maximum -160\.0"),
        ("id 2", "id two", r"bone id must be an integer, got 'two'"),
        ("name lfemur", "name lfemur thigh", r"bone name must be one word, got 'lfemur thigh'"),
    ],
)
def test_asf_bad_bone_line(tmp_path, old, new, message):
    lines = asf_lines()
    i = next(k for k, line in enumerate(lines) if line.strip() == old and k > asf_index(lines, "name lfemur") - 3)
    lines[i] = "    " + new
    # the limits/dof mismatch is reported at the bone's 'end'
    line = asf_index(lines, "end", i) + 1 if "limits" in message and "dof but" in message else i + 1
    raises(write_asf_lines(tmp_path, lines), message, line, read_asf)


@pytest.mark.parametrize(
    "old, new, message",
    [
        ("order TX TY TZ RX RY RZ", "order TX TY TZ RX RY RW", r"unknown root channel 'RW' \(expected TX TY TZ RX RY RZ\)"),
        ("axis XYZ", "axis XY", r"root axis must be an order of X, Y, Z, got 'XY'"),
        ("position 0 0 0", "position 0 0", r"root position needs 3 numbers, got 2"),
        ("angle deg", "angle grad", r"angle unit must be 'deg' or 'rad', got 'grad'"),
        ("length 0.45", "length 0,45", r"not a number: '0,45'"),
        (":units", ":units metric", r"unexpected text after ':units': 'metric'"),
    ],
)
def test_asf_bad_header_line(tmp_path, old, new, message):
    lines = asf_lines()
    i = next(k for k, line in enumerate(lines) if line.strip() == old)
    lines[i] = ("" if new.startswith(":") else "   ") + new
    raises(write_asf_lines(tmp_path, lines), message, i + 1, read_asf)


def test_asf_missing_section(tmp_path):
    lines = asf_lines()
    cut = asf_index(lines, ":hierarchy")
    lines = lines[:cut]
    raises(write_asf_lines(tmp_path, lines), r"not a complete ASF file: no ':hierarchy' section", len(lines), read_asf)


def test_asf_text_before_first_section(tmp_path):
    lines = ["Acclaim skeleton"] + asf_lines()
    raises(write_asf_lines(tmp_path, lines), r"expected a ':section' or '#' comment, got 'Acclaim skeleton'", 1, read_asf)


def test_asf_unknown_section_is_skipped_with_a_warning(tmp_path):
    lines = asf_lines()
    i = asf_index(lines, ":units")
    lines[i:i] = [":skin", "  whatever.obj", "  more stuff"]
    path = write_asf_lines(tmp_path, lines)
    with pytest.warns(UserWarning, match=rf"bad\.asf:{i + 1}: unknown ASF section ':skin' skipped"):
        skel = read_asf(path)
    assert len(skel.bones) == 30


def test_amc_file_given_to_the_asf_reader(tmp_path):
    path = tmp_path / "bad.asf"
    path.write_bytes(AMC.read_bytes())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        raises(path, r"not a complete ASF file: no ':root' section", len(amc_lines()), read_asf)
    assert [str(w.message) for w in caught] == [
        f"{path}:2: unknown ASF section ':fully-specified' skipped",
        f"{path}:3: unknown ASF section ':degrees' skipped",
    ]


# ------------------------------------------------------------------ never a bare exception


SMALL_AMC = "\n".join(amc_lines()[: 3 + 30 * 4]).encode() if AMC.exists() else b""
SMALL_ASF = ASF.read_bytes() if ASF.exists() else b""


def _mutate(data: bytes, edits) -> bytes:
    out = bytearray(data)
    for kind, pos, byte in edits:
        if not out:
            break
        pos %= len(out)
        if kind == 0:
            out[pos] = byte
        elif kind == 1:
            del out[pos : pos + 1 + byte % 40]
        else:
            out[pos:pos] = bytes([byte]) * (1 + byte % 3)
    return bytes(out)


edits = st.lists(st.tuples(st.integers(0, 2), st.integers(0, 1 << 20), st.integers(0, 255)), min_size=1, max_size=6)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(edits=edits)
def test_damaged_amc_raises_only_mocap_format_error(edits):
    data = _mutate(SMALL_AMC, edits)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            motion = parse_amc(data, "fuzz.amc")
        except MocapFormatError as err:
            assert err.path == "fuzz.amc" and str(err).startswith("fuzz.amc:")
            return
    assert np.all(np.isfinite(motion.values)) and np.all(np.abs(motion.values) <= MAX_ABS_VALUE)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(edits=edits)
def test_damaged_asf_raises_only_mocap_format_error(edits):
    data = _mutate(SMALL_ASF, edits)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            parse_asf(data, "fuzz.asf")
        except MocapFormatError as err:
            assert err.path == "fuzz.asf" and str(err).startswith("fuzz.asf:")
