"""BVH read and write (formats/bvh.py): every shared BVH file comes back byte for byte, and
damaged ones are refused in one error naming file and line."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mocapzip.formats import bvh as bvh_module
from mocapzip.formats.bvh import (MAX_HIERARCHY_CHARS, NUMBER_STYLES, Bvh, BvhStyle, format_bvh, parse_bvh, read_bvh,
                                  read_hierarchy)
from mocapzip.formats.errors import MocapFormatError


def shared_bvh_files(data):
    return sorted(data.glob("cmu-bvh/*/*.bvh")) + sorted(data.glob("bvh-bandai/*.bvh"))


def test_every_shared_bvh_file_is_written_back_byte_for_byte(shared_data):
    files = shared_bvh_files(shared_data)
    assert len(files) == 178
    styles = set()
    for path in files:
        raw = path.read_bytes()
        bvh = read_bvh(path)
        assert format_bvh(bvh).encode(bvh.encoding) == raw, path
        # and the values alone, in the style found on the first frame, make every frame line again
        assert bvh.style.format(bvh.values) == bvh.frames_text, path
        styles.add(bvh.style)
        assert bvh.values.shape == (bvh.n_frames, sum(len(j.channels) for j in bvh.joints))
    # CMU's conversion prints Python's repr; the studio export C's %g with a blank after each frame
    assert styles == {BvhStyle("repr", " ", "", "\n"), BvhStyle("g6", " ", " ", "\n")}


def test_what_the_two_exporters_hold(shared_data):
    cmu = read_bvh(shared_data / "cmu-bvh" / "10" / "10_01.bvh")
    assert (cmu.joints[0].name, cmu.n_frames, round(cmu.fps, 3)) == ("hip", 802, 120.0)
    assert cmu.joints[0].channels == ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")
    assert {len(j.channels) for j in cmu.joints[1:]} == {3}
    bandai = read_bvh(shared_data / "bvh-bandai" / "dataset-1_bow_active_001.bvh")
    assert [j.name for j in bandai.joints[:2]] == ["joint_Root", "Hips"] and round(bandai.fps, 3) == 30.0
    assert {len(j.channels) for j in bandai.joints} == {6}  # positions and rotations on every joint
    assert bandai.joints[1].parent == 0 and sum(j.end_site is not None for j in bandai.joints) >= 5


def test_a_bvh_built_in_code_is_written_so_that_it_reads_back_the_same(shared_data):
    read = read_bvh(shared_data / "bvh-bandai" / "dataset-1_bow_active_001.bvh")
    with pytest.raises(ValueError, match="read-only"):  # the frame text kept beside them must stay true
        read.values[0, 0] = 1.0
    moved = replace(read, values=read.values + 1.0, frames_text=None)
    assert parse_bvh(format_bvh(moved).encode(), "moved.bvh").values[0, 0] == read.values[0, 0] + 1.0
    shorter = replace(read, values=read.values[:10], frame_time=0.02, frames_text=None)  # Frames and Frame Time follow
    again = parse_bvh(format_bvh(shorter).encode(), "shorter.bvh")
    assert again.n_frames == 10 and again.frame_time == 0.02 and np.array_equal(again.values, read.values[:10])
    built = Bvh(read.joints, read.frame_time, read.values)
    again = parse_bvh(format_bvh(built).encode(), "built.bvh")
    assert np.array_equal(again.values, read.values) and again.frame_time == read.frame_time
    assert [(j.name, j.parent, j.channels) for j in again.joints] == [(j.name, j.parent, j.channels) for j in read.joints]
    assert all(np.array_equal(a.offset, b.offset) for a, b in zip(again.joints, read.joints))


def damaged(data, old: bytes, new: bytes, count: int = 1) -> bytes:
    text = (data / "cmu-bvh" / "10" / "10_03.bvh").read_bytes()
    assert old in text
    return text.replace(old, new, count)


@pytest.mark.parametrize("old, new, message, line", [
    (b"HIERARCHY", b"HIERARCHIE", "expected 'HIERARCHY', got 'HIERARCHIE'", 1),
    (b"Zrotation Xrotation Yrotation", b"Zrotation Xrotation Wrotation", "unknown channel 'Wrotation'", 9),
    (b"CHANNELS 3", b"CHANNELS 7", "CHANNELS count must be 1 to 6, got '7'", 9),
    (b"OFFSET 0 20.6881 -0.73152", b"OFFSET 0 20.6881 nan", "OFFSET is not finite: 'nan'", 8),
    (b"JOINT abdomen", b"JOINT hip", "joint 'hip' appears twice", 6),
    (b"Frames:\t363", b"Frames:\t362", "Frames: says 362, but 363 frame lines follow", 274),
    (b"Frame Time:\t0.00833333", b"Frame Time:\t0", "Frame Time must be from 1e-05 to 1 seconds", 275),
    (b"Frames:\t363", "Frames:\t\u00b2".encode(), "Frames: must be a count", 274),
    (b"CHANNELS 3", "CHANNELS \u00b3".encode(), "CHANNELS count must be 1 to 6", 9),
    (b"MOTION", b"MOTIONS", "no MOTION line: not a BVH file", None),  # as `read_hierarchy` says (inspect, compress)
    (b"End Site", b"End Sight", "expected 'Site', got 'Sight'", 26),
])
def test_a_damaged_file_is_refused_naming_file_and_line(shared_data, old, new, message, line):
    with pytest.raises(MocapFormatError) as caught:
        parse_bvh(damaged(shared_data, old, new), "10_03.bvh")
    assert caught.value.message.startswith(message), caught.value.message
    if line is not None:
        assert caught.value.line == line and caught.value.path == "10_03.bvh"


def test_a_bad_frame_is_named_by_its_line(shared_data):
    text = (shared_data / "cmu-bvh" / "10" / "10_03.bvh").read_bytes()
    lines = text.split(b"\n")
    first = next(i for i, line in enumerate(lines) if line.startswith(b"Frame Time")) + 1
    short = lines.copy()
    short[first + 3] = short[first + 3].rsplit(b" ", 1)[0]
    with pytest.raises(MocapFormatError, match="frame 4 has 131 values, the hierarchy's channels need 132") as caught:
        parse_bvh(b"\n".join(short), "10_03.bvh")
    assert caught.value.line == first + 4
    bad = lines.copy()
    bad[first + 9] = bad[first + 9].replace(b" ", b" 1x2 ", 1).rsplit(b" ", 1)[0]
    with pytest.raises(MocapFormatError, match="not a number: '1x2'") as caught:
        parse_bvh(b"\n".join(bad), "10_03.bvh")
    assert caught.value.line == first + 10
    for word, message in ((b"1_000", "not a number: '1_000'"), (b"inf", "value is not finite: 'inf'"),
                          (b"1e400", "value 1e400 is out of range")):
        bad = lines.copy()
        bad[first + 2] = bad[first + 2].replace(b" ", b" " + word + b" ", 1).rsplit(b" ", 1)[0]
        with pytest.raises(MocapFormatError, match=message) as caught:
            parse_bvh(b"\n".join(bad), "10_03.bvh")
        assert caught.value.line == first + 3


@pytest.mark.parametrize("rel", ["cmu-bvh/10/10_03.bvh", "bvh-bandai/dataset-1_bow_active_001.bvh"])
@pytest.mark.parametrize("ends", [{}, {"final_line_end": False, "after": "\n\n"}])
def test_frames_made_a_few_at_a_time_are_the_same(shared_data, monkeypatch, rel, ends):
    """`BvhStyle.blocks`, as decompress writes a long clip: blocks of 3 frames give the frame
    lines made at once (the file's, in its own style)."""
    read = read_bvh(shared_data / rel)
    style = replace(read.style, **ends)
    whole = style.format(read.values)
    assert whole == read.frames_text or ends
    monkeypatch.setattr(bvh_module, "VALUES_PER_BLOCK", 3 * read.values.shape[1])
    blocks = list(style.blocks(read.values))
    assert len(blocks) == -(-read.n_frames // 3) + 1  # the frames, then what follows them
    assert "".join(blocks) == whole


def test_line_ends_and_styles_a_first_frame_does_not_show(shared_data):
    """CR-only line ends, and a first frame of zeros that %g and repr would both write alike but
    for later frames: the style comes from frames spread over the clip."""
    text = (shared_data / "cmu-bvh" / "10" / "10_03.bvh").read_bytes()
    cr_only = text.replace(b"\r\n", b"\n").replace(b"\n", b"\r")
    bvh = parse_bvh(cr_only, "cr.bvh")
    assert format_bvh(bvh).encode() == cr_only and bvh.style.line_end == "\r"
    assert format_bvh(replace(bvh, frames_text=None)).encode() == cr_only
    shorter = parse_bvh(format_bvh(replace(bvh, values=bvh.values[:5], frame_time=0.01, frames_text=None)).encode())
    assert shorter.n_frames == 5 and shorter.frame_time == 0.01  # before: `Frames:` kept its count after a CR
    head, frames = text.split(b"Frame Time:\t0.00833333\r\n")
    lines = frames.split(b"\n")
    lines[0] = b" ".join([b"0"] * 132)  # a first frame %g writes as it is, and repr does not
    mixed = parse_bvh(head + b"Frame Time:\t0.00833333\r\n" + b"\n".join(lines), "mixed.bvh")
    assert mixed.style.number == "repr"  # as the other frames: nothing written later loses digits
    assert mixed.style.format(mixed.values[1:2]).encode() == lines[1] + b"\n"


def test_the_hierarchy_of_a_file_is_read_no_further_than_a_hierarchy_may_reach(shared_data, tmp_path):
    head = (shared_data / "cmu-bvh/10/10_03.bvh").read_bytes().split(b"MOTION")[0]
    assert read_hierarchy(shared_data / "cmu-bvh/10/10_03.bvh")[0].encode() == head
    path = tmp_path / "endless.bvh"
    path.write_bytes(head + b"#" * (4 * MAX_HIERARCHY_CHARS + (1 << 20)) + b"\nMOTION\n")
    with pytest.raises(MocapFormatError, match=r"endless\.bvh: no MOTION line in its first [0-9,]+ bytes"):
        read_hierarchy(path)


@pytest.mark.parametrize("motion, into, found", [("MOTION extra", 6, False), ("\t" * 100 + "MOTION", 90, True)])
def test_a_motion_line_across_two_read_chunks_is_found_as_parse_bvh_finds_it(
        shared_data, tmp_path, motion, into, found):
    """`read_hierarchy` reads 64 KiB at a time; before, `MOTION` at the end of a chunk was taken for
    the line (`MOTION extra` too), and a line of 100 tabs and `MOTION` across two chunks was missed."""
    text = (shared_data / "cmu-bvh/10/10_03.bvh").read_bytes()
    head, rest = text.split(b"MOTION", 1)
    head += b"\n" * ((1 << 16) - len(head) - into)  # the first chunk ends `into` bytes into the MOTION line
    path = tmp_path / "c.bvh"
    path.write_bytes(head + motion.encode() + rest)
    if found:
        assert read_hierarchy(path)[0].encode() == head == parse_bvh(path.read_bytes()).header.encode()[: len(head)]
    else:
        for read in (lambda: read_hierarchy(path), lambda: parse_bvh(path.read_bytes(), str(path))):
            with pytest.raises(MocapFormatError, match="no MOTION line: not a BVH file"):
                read()


AWKWARD = np.array([[0.0, -0.0, 0.5, 2.5, -1.5, 1e22, 1e23],  # signed zeros, halves, past the exact powers of ten
                    [np.inf, -np.inf, np.nan, 5e-324, 1.7976931348623157e308, 123456.5, 9.9999995],
                    [0.1, -33.333333333333336, 1e-5, 999999.5, 1e15 + 0.3, 2.0**52 + 1, -7.0]])


@pytest.mark.parametrize("number", NUMBER_STYLES)
def test_frame_lines_are_pythons_text_in_every_number_style(number):
    """`BvhStyle.format` writes "g" and "f" numbers in compiled code (`format_rows`), the hard ones
    in Python: its text is Python's `format` of every value, whatever the value."""
    values = np.concatenate([AWKWARD, np.random.default_rng(5).normal(0, 60, (50, 7)).round(4)])
    spec = None if number == "repr" else f".{number[1:]}{number[0]}"
    for style in (BvhStyle(number, " ", "", "\n"), BvhStyle(number, "\t", " ", "\r\n", False, "\n\n")):
        ending = style.trailing + style.line_end
        lines = [style.separator.join(repr(v) if spec is None else format(v, spec) for v in row) + ending
                 for row in values.tolist()]
        expected = "".join(lines)
        expected = expected if style.final_line_end else expected[: -len(style.line_end)]
        assert style.format(values) == expected + style.after
        assert style.format(values[:0]) == style.after
