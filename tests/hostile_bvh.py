"""BVH files built from parts, for tests/test_hardening_bvh.py: hierarchy shapes, channel layouts,
frame counts and times, numbers, line ends, encodings and joint names, each at and beyond its limits.

`bvh_text` writes a file from a `Shape`; `REFUSED` holds the files mcz must refuse (one line
naming the file, the line where there is one, and the problem) and `ACCEPTED` those it must take
and give back (the same bytes with --lossless): a `Shape`, or the text of a variation no Shape
says. Synthetic on purpose: each varies one thing from a small valid file, which real clips
cannot do; the real files' round trips are tests/test_bvh*.py.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field

import numpy as np

ROTATIONS = "Zrotation Xrotation Yrotation"
POSITIONS = "Xposition Yposition Zposition"


@dataclass
class Joint:
    name: str
    channels: str = ROTATIONS  # "" writes no CHANNELS line
    children: list[Joint] = field(default_factory=list)
    offset: str = "0 20 0"


@dataclass
class Shape:
    """A whole file: `root` (its channels are the root's), `frames` lines of random values (or of
    `value`), `Frames:` saying `stated` (default: the lines), `Frame Time:` `frame_time`."""
    root: Joint
    frames: int = 3
    stated: int | str | None = None
    frame_time: str = "0.033333"
    line_end: str = "\n"
    value: str | None = None
    seed: int = 1


def chain(names: list[str], channels: str = ROTATIONS) -> list[Joint]:
    """Joints each the child of the one before: the list's first is the top."""
    top = None
    for name in reversed(names):
        top = Joint(name, channels, [top] if top else [])
    return [top] if top else []


def person(*joints: Joint, root_channels: str = f"{POSITIONS} {ROTATIONS}") -> Joint:
    return Joint("Hips", root_channels, list(joints) or chain(["Spine", "Head"]), offset="0 0 0")


def width(joint: Joint) -> int:
    return len(joint.channels.split()) + sum(width(child) for child in joint.children)


def _joint_lines(joint: Joint, depth: int, keyword: str) -> list[str]:
    pad = "  " * depth
    lines = [f"{pad}{keyword} {joint.name}".rstrip(), f"{pad}{{", f"{pad}  OFFSET {joint.offset}"]
    if joint.channels is not None:
        count = len(joint.channels.split())
        lines.append(f"{pad}  CHANNELS {count} {joint.channels}".rstrip())
    for child in joint.children:
        lines += _joint_lines(child, depth + 1, "JOINT")
    if not joint.children:
        lines += [f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0 20 0", f"{pad}  }}"]
    return lines + [f"{pad}}}"]


def bvh_text(shape: Shape) -> str:
    rng = random.Random(shape.seed)
    lines = ["HIERARCHY", *_joint_lines(shape.root, 0, "ROOT"), "MOTION",
             f"Frames: {shape.frames if shape.stated is None else shape.stated}", f"Frame Time: {shape.frame_time}"]
    n = width(shape.root)
    columns = [(rng.uniform(-40, 40), rng.uniform(0, 6.3)) for _ in range(n)]  # smooth, as motion is
    for f in range(shape.frames):
        lines.append(" ".join(shape.value or f"{amplitude * np.sin(0.1 * f + phase):.4f}" for amplitude, phase in columns))
    return shape.line_end.join(lines) + shape.line_end


def motion_line(shape: Shape) -> int:
    """The line number of MOTION in `bvh_text(shape)` (Frames: is the next one)."""
    return bvh_text(shape).split(shape.line_end).index("MOTION") + 1


def wide(n: int) -> Joint:
    """A root with `n` children: a hierarchy's joint count at and past its limit."""
    return person(*(Joint(f"k{i}") for i in range(n)))


@dataclass
class Refused:
    name: str
    text: str | bytes
    problem: str  # a phrase of the message
    line: int | None = None


BASE = Shape(person())
_MOTION = motion_line(BASE)
_SPINE_LINE = 6  # "  JOINT Spine" in bvh_text(BASE)


def _base_with(old: str, new: str, count: int = 1) -> str:
    text = bvh_text(BASE)
    assert old in text, old
    return text.replace(old, new, count)


def _channels_after_the_child() -> tuple[str, int]:
    """BASE with Spine's CHANNELS line moved after its child Head's block; and that line's number."""
    lines = bvh_text(BASE).split("\n")
    channels = lines.pop(_SPINE_LINE + 2)
    close = lines.index("  }")  # Spine's closing brace
    lines.insert(close, channels)
    return "\n".join(lines), close + 1


def _line_ends(hierarchy: str, motion: str, frames: str, last: str) -> str:
    """BASE with these line ends: `hierarchy` up to MOTION, `motion` on its 3 lines, `frames` on the
    frame lines but the last, `last` on that."""
    lines = bvh_text(BASE).split("\n")[:-1]
    ends = [hierarchy] * (_MOTION - 1) + [motion] * 3 + [frames] * (len(lines) - _MOTION - 3) + [last]
    return "".join(line + end for line, end in zip(lines, ends))


_CHANNELS_AFTER = _channels_after_the_child()


def _no_channels(frame_line: str) -> str:
    """BASE without any CHANNELS line, its 3 frames each `frame_line` (a frame of no values)."""
    text = "".join(line for line in bvh_text(BASE).splitlines(keepends=True) if "CHANNELS" not in line)
    return text.split("MOTION")[0] + "MOTION\nFrames: 3\nFrame Time: 0.033333\n" + f"{frame_line}\n" * 3


def _frame_lines(edit) -> str:
    """BASE with its frame lines `edit`ed (a list of lines in, a list out)."""
    head, _, frames = bvh_text(BASE).partition("Frame Time: 0.033333\n")
    return f"{head}Frame Time: 0.033333\n" + "\n".join(edit(frames.splitlines())) + "\n"


def _first_value(token: str) -> str:
    """BASE with the first value of its first frame written as `token`."""
    head, _, frames = bvh_text(BASE).partition("Frame Time: 0.033333\n")
    return f"{head}Frame Time: 0.033333\n{token}{frames[frames.index(' '):]}"


REFUSED = [
    Refused("no_frames", bvh_text(Shape(person(), frames=0)), "no frames: Frames: 0", _MOTION + 1),
    Refused("frames_more_than_lines", bvh_text(Shape(person(), stated=4)), "Frames: says 4, but 3 frame lines follow",
            _MOTION + 1),
    Refused("frames_fewer_than_lines", bvh_text(Shape(person(), stated=2)), "Frames: says 2, but 3 frame lines follow",
            _MOTION + 1),
    Refused("frames_past_the_limit", bvh_text(Shape(person(), stated=10**12)), "Frames: must be a count up to",
            _MOTION + 1),
    Refused("frames_past_the_values_limit", bvh_text(Shape(person(), stated=1 << 20)), "a clip may hold", _MOTION + 1),
    Refused("frames_negative", bvh_text(Shape(person(), stated=-1)), "Frames: must be a count", _MOTION + 1),
    Refused("frames_not_a_count", bvh_text(Shape(person(), stated="3.0")), "Frames: must be a count", _MOTION + 1),
    Refused("frame_time_zero", bvh_text(Shape(person(), frame_time="0")), "Frame Time must be from", _MOTION + 2),
    Refused("frame_time_tiny", bvh_text(Shape(person(), frame_time="1e-300")), "Frame Time must be from", _MOTION + 2),
    Refused("frame_time_negative", bvh_text(Shape(person(), frame_time="-0.03")), "Frame Time must be from",
            _MOTION + 2),
    Refused("frame_time_nan", bvh_text(Shape(person(), frame_time="nan")), "Frame Time is not finite", _MOTION + 2),
    Refused("frame_time_word", bvh_text(Shape(person(), frame_time="fast")), "not a number: 'fast'", _MOTION + 2),
    Refused("value_1e308", bvh_text(Shape(person(), value="1e308")), "value 1e308 is out of range", _MOTION + 3),
    Refused("value_nan", bvh_text(Shape(person(), value="nan")), "value is not finite: 'nan'", _MOTION + 3),
    Refused("value_inf", bvh_text(Shape(person(), value="-inf")), "value is not finite: '-inf'", _MOTION + 3),
    Refused("value_hex", bvh_text(Shape(person(), value="0x10")), "0x10", _MOTION + 3),
    Refused("channels_zero", _base_with("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 0"),
            "CHANNELS count must be 1 to 6", _SPINE_LINE + 3),
    Refused("channels_seven", _base_with("CHANNELS 6", "CHANNELS 7"), "CHANNELS count must be 1 to 6", 5),
    Refused("channels_say_more", _base_with("CHANNELS 3 Z", "CHANNELS 4 Z"), "unknown channel 'JOINT'", 10),
    Refused("channels_say_fewer", _base_with("CHANNELS 3 Z", "CHANNELS 2 Z"), "unexpected 'Yrotation'", 9),
    Refused("channel_unknown", _base_with("Zrotation", "Wrotation"), "unknown channel 'Wrotation'", 5),
    Refused("channel_twice", _base_with("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 3 Zrotation Zrotation "
                                        "Yrotation"), "names a channel twice", 9),
    Refused("joint_twice", bvh_text(Shape(person(Joint("A"), Joint("A")))), "joint 'A' appears twice", 15),
    Refused("joint_without_name", _base_with("JOINT Spine", "JOINT"), "a joint needs a name", 7),
    Refused("joint_named_brace", _base_with("JOINT Spine", "JOINT {"), "a joint needs a name", _SPINE_LINE),
    Refused("joint_name_with_a_space", _base_with("JOINT Spine", "JOINT Sp ine"), "expected '{', got 'ine'",
            _SPINE_LINE),
    Refused("joints_past_the_limit", bvh_text(Shape(wide(1100), frames=1)), "more than 1024 joints"),
    Refused("joints_too_deep", bvh_text(Shape(person(*chain([f"j{i}" for i in range(300)])), frames=1)),
            "joints nested more than 200 deep"),
    Refused("end_site_with_channels", _base_with("End Site\n      {\n", "End Site\n      {\n        CHANNELS 1 Xrotation\n"),
            "expected 'OFFSET', got 'CHANNELS'", 16),
    Refused("offset_nan", _base_with("OFFSET 0 20 0", "OFFSET nan 20 0"), "OFFSET is not finite", 8),
    Refused("offset_1e308", _base_with("OFFSET 0 20 0", "OFFSET 1e308 20 0"), "OFFSET 1e308 is out of range", 8),
    Refused("offset_short", _base_with("OFFSET 0 20 0", "OFFSET 0 20"), "not a number: 'CHANNELS'", 9),
    Refused("unclosed_brace", _base_with("}\nMOTION", "MOTION"), "the hierarchy ends early"),
    Refused("no_motion", bvh_text(BASE).split("MOTION")[0], "MOTION"),
    Refused("no_hierarchy", "MOTION\nFrames: 1\nFrame Time: 0.03\n1 2 3\n", "expected 'HIERARCHY'", 1),
    Refused("braces_only", "HIERARCHY\n" + "{" * 100_000 + "\nMOTION\nFrames: 1\nFrame Time: 0.03\n1\n",
            "expected 'ROOT'", 2),
    Refused("empty", "", ""),
    Refused("nul_byte", _base_with("JOINT Spine", "JOINT Sp\0ine"), "binary data (NUL bytes), not a text BVH file",
            _SPINE_LINE),
    Refused("utf16", "\ufeff" + bvh_text(BASE), "UTF-16 text, not a text BVH file", 1),
    # NULs after the text (as a full disk or a sparse file leaves them), or alone: read as UTF-16 before
    Refused("text_then_nuls", bvh_text(BASE) + "\0" * 100_000, "binary data (NUL bytes), not a text BVH file",
            bvh_text(BASE).count("\n") + 1),
    Refused("nuls_alone", "\0" * 1000, "binary data (NUL bytes), not a text BVH file", 1),
    Refused("trailing_text", bvh_text(BASE) + "hello world\n", "Frames: says 3, but 4 frame lines follow",
            _MOTION + 1),
    # a count of more digits than int() takes (4,300): a traceback in every command
    Refused("frames_with_5000_leading_zeros", bvh_text(Shape(person(), stated="0" * 5000 + "3")),
            "the lines MOTION, Frames: and Frame Time: take more than the 4,096 characters", _MOTION + 1),
    # MOTION is the ASCII word alone on its line, for every command (convert took these, the others did not)
    Refused("motion_with_a_dotless_i", _base_with("MOTION", "MOT\u0131ON"), "no MOTION line: not a BVH file"),
    Refused("motion_after_a_no_break_space", _base_with("MOTION", "\u00a0MOTION"), "no MOTION line: not a BVH file"),
    Refused("motion_and_a_word", _base_with("MOTION", "MOTION extra"), "no MOTION line: not a BVH file"),
    Refused("keyword_with_a_dotless_i", _base_with("JOINT Spine", "JO\u0131NT Spine"),
            "unexpected 'JO\u0131NT' in joint", _SPINE_LINE),  # keywords too are ASCII, any case (`str.upper`: JOINT)
    Refused("no_hierarchy_after_a_byte_order_mark", "\ufeffMOTION\nFrames: 1\nFrame Time: 0.03\n1 2 3\n",
            "expected 'HIERARCHY'", 1),
    Refused("channels_after_a_child_joint", _CHANNELS_AFTER[0], "joint 'Spine' has its CHANNELS after its child joint "
            "'Head'", _CHANNELS_AFTER[1]),
    Refused("cr_cr_lf_line_ends", bvh_text(Shape(person(), line_end="\r\r\n")), "the line ends in CR CR LF",
            2 * _MOTION - 1),  # each CR CR LF ends two lines, as editors count
    Refused("cr_cr_lf_between_frames", _line_ends("\n", "\n", "\r\r\n", "\n"), "the line ends in CR CR LF",
            _MOTION + 3),
    # a hierarchy of no channel: before, "Frames: says 3, but 0 frame lines follow" (its blank frame
    # lines read as blank lines after the last frame), or that the root needs position channels
    Refused("no_channels_and_blank_frames", _no_channels(""), "no joint has a CHANNELS line", 2),
    Refused("no_channels_and_frames_of_blanks", _no_channels("  \t"), "no joint has a CHANNELS line", 2),
    # a number of any length named in its first 40 characters: the line was as long as the number
    # a number of letters other than ASCII digits, quoted as read (each was a '?')
    Refused("value_of_arabic_indic_digits", _first_value("\u0661\u0662"), "not a number: '\u0661\u0662'",
            _MOTION + 3),
    # the fifth hostile pass: numbers Python's float() and int() take but the grammar does not, and
    # lines that repeat, or come where none may
    Refused("value_with_an_underscore", _first_value("1_0"), "not a number: '1_0'", _MOTION + 3),
    Refused("frames_an_arabic_indic_digit", _base_with("Frames: 3", "Frames: \u0663"), "Frames: must be a count",
            _MOTION + 1),
    Refused("frames_and_a_word", _base_with("Frames: 3", "Frames: 3 frames"), "got '3 frames'", _MOTION + 1),
    Refused("frame_time_with_a_comma", _base_with("Frame Time: 0.033333", "Frame Time: 0,033333"),
            "not a number: '0,033333'", _MOTION + 2),
    Refused("frame_time_twice", _base_with("Frame Time: 0.033333", "Frame Time: 0.033333 0.04"),
            "not a number: '0.033333 0.04'", _MOTION + 2),
    Refused("frame_time_just_above_a_second", _base_with("Frame Time: 0.033333", "Frame Time: 1.0000000001"),
            "Frame Time must be from", _MOTION + 2),
    Refused("one_frame_of_one_value_more", _frame_lines(lambda lines: [lines[0], lines[1] + " 1.0", lines[2]]),
            "frame 2 has 13 values, the hierarchy's channels need 12", _MOTION + 4),
    Refused("blank_line_between_frames", _frame_lines(lambda lines: [lines[0], "", *lines[1:]]),
            "Frames: says 3, but 4 frame lines follow", _MOTION + 1),
    Refused("offset_of_four_numbers", _base_with("OFFSET 0 20 0", "OFFSET 0 20 0 5"), "unexpected '5' in joint",
            _SPINE_LINE + 2),
    Refused("channels_twice", _base_with("CHANNELS 3 Zrotation Xrotation Yrotation",
                                         "CHANNELS 3 Zrotation Xrotation Yrotation\n    CHANNELS 1 Xrotation"),
            "joint 'Spine' has a second CHANNELS line", _SPINE_LINE + 4),
    Refused("end_site_twice", _base_with("End Site", "End Site\n      {\n        OFFSET 0 1 0\n      }\n"
                                                     "      End Site"), "joint 'Head' has a second End Site", 18),
    Refused("comment_in_the_hierarchy", _base_with("  JOINT Spine", "# a comment\n  JOINT Spine"), "unexpected '#'",
            _SPINE_LINE),
    Refused("name_with_a_next_line_character", _base_with("JOINT Spine", "JOINT Sp\x85ine"), "expected '{', got 'ine'",
            _SPINE_LINE),  # U+0085 splits words as str.split() does
    # the sixth hostile pass: numbers no BVH writer writes, text in other encodings, a hierarchy cut
    # or closed twice
    Refused("value_in_fortran_notation", _first_value("1d3"), "not a number: '1d3'", _MOTION + 3),
    Refused("value_nan_with_a_payload", _first_value("nan(0x1)"), "not a number: 'nan(0x1)'", _MOTION + 3),
    Refused("value_minus_nan", _first_value("-nan"), "value is not finite: '-nan'", _MOTION + 3),
    Refused("last_value_a_lone_minus", bvh_text(BASE).rstrip("\n").rsplit(" ", 1)[0] + " -\n", "not a number: '-'",
            _MOTION + 5),
    Refused("frame_time_inf", _base_with("Frame Time: 0.033333", "Frame Time: inf"), "Frame Time is not finite",
            _MOTION + 2),
    Refused("frame_time_minus_zero", _base_with("Frame Time: 0.033333", "Frame Time: -0"), "Frame Time must be from",
            _MOTION + 2),
    Refused("frame_time_a_hex_float", _base_with("Frame Time: 0.033333", "Frame Time: 0x1p-5"),
            "not a number: '0x1p-5'", _MOTION + 2),
    Refused("end_site_offset_1e30", _base_with("End Site\n      {\n        OFFSET 0 20 0",
                                               "End Site\n      {\n        OFFSET 0 1e30 0"),
            "End Site OFFSET 1e30 is out of range", 16),
    Refused("utf16_without_a_byte_order_mark", bvh_text(BASE).encode("utf-16-le"), "UTF-16 text, not a text BVH file", 1),
    Refused("root_without_a_name", _base_with("ROOT Hips", "ROOT"), "a joint needs a name", 3),
    Refused("a_brace_closed_twice", _base_with("}\nMOTION", "}\n}\nMOTION"), "expected 'ROOT', got '}'", _MOTION),
    Refused("cut_in_the_hierarchy", bvh_text(BASE)[:bvh_text(BASE).index("JOINT Spine") + 20],
            "no MOTION line: not a BVH file"),
    Refused("offset_of_900_digits", _base_with("OFFSET 0 20 0", "OFFSET 0 " + "9" * 900 + " 0"),
            f"OFFSET {'9' * 40}... is out of range", 8),
]

# Names of every class of character a BVH name (one word) can hold: digits, punctuation, a
# section-like colon, keywords, letters of other scripts, symbols, controls, bidi marks, long.
ODD_NAMES = ["123", ":hierarchy", ":DEGREES", "#x", "JOINT", "End", "ROOT", "OFFSET", "CHANNELS", "MOTION",
             "Frames:", "a}b", "Spïne", "ハンド", "😀", "\u202eabc", "a\x01b", "x" * 5000, "-1e308", "nan"]

ACCEPTED = {
    "one_frame": Shape(person(), frames=1),
    "two_frames": Shape(person(), frames=2),
    "root_alone": Shape(Joint("Hips", f"{POSITIONS} {ROTATIONS}", offset="0 0 0")),
    "one_rotation_channel_each": Shape(person(Joint("Spine", "Zrotation", [Joint("Head", "Xrotation Yrotation")]))),
    "positions_on_every_joint": Shape(person(*chain(["Spine", "Head"], f"{POSITIONS} {ROTATIONS}"))),
    "root_rotations_only": Shape(person(root_channels=ROTATIONS)),
    "zero_offsets": Shape(person(Joint("Spine", offset="0 0 0", children=[Joint("Head", offset="0 0 0")]))),
    "all_zero_values": Shape(person(), value="0"),
    "crlf": Shape(person(), line_end="\r\n"),
    "cr": Shape(person(), line_end="\r"),
    "widest": Shape(wide(1023), frames=2),
    **{f"name_{i:02d}": Shape(person(*chain([name, "Head"]))) for i, name in enumerate(ODD_NAMES)},
    # channel names and keywords in any case: the codec's model read them as the parser does
    "channels_in_upper_case": _base_with(ROTATIONS, ROTATIONS.upper(), 3),
    "channels_in_camel_case": _base_with("Xrotation", "XRotation", 3),
    "all_in_upper_case": bvh_text(BASE).upper(),
    "channels_count_with_4400_leading_zeros": _base_with("CHANNELS 3 Z", "CHANNELS " + "0" * 4400 + "3 Z"),
    # a CR CR LF where a blank line may stand: the hierarchy, after the last frame
    "cr_cr_lf_in_the_hierarchy": _line_ends("\r\r\n", "\r\n", "\r\n", "\r\n"),
    "cr_cr_lf_after_the_last_frame": _line_ends("\n", "\n", "\n", "\r\r\n"),
    # the fifth hostile pass
    "blank_lines_and_blanks_before_the_hierarchy": "\n\n   " + bvh_text(BASE),
    "end_site_in_lower_case": _base_with("End Site", "end site"),
    "crlf_then_lf": bvh_text(BASE).replace("\n", "\r\n", 10),
    "name_with_an_escape_of_a_slash": _base_with("JOINT Spine", "JOINT a%2Fb"),
    "frames_and_frame_time_without_blanks": _base_with("Frames: 3\nFrame Time: 0.033333",
                                                       "Frames:3\nFrame Time:0.033333"),
    "frame_time_of_a_second": _base_with("Frame Time: 0.033333", "Frame Time: 1"),
    # the sixth hostile pass
    "brace_on_the_joint_line": _base_with("JOINT Spine\n  {", "JOINT Spine {"),
    "last_frame_without_a_line_end": bvh_text(BASE).rstrip("\n"),
    "root_channels_interleaved": _base_with("Xposition Yposition Zposition Zrotation Xrotation Yrotation",
                                            "Xposition Zrotation Yposition Xrotation Zposition Yrotation"),
    "offsets_of_1e-200": bvh_text(BASE).replace("OFFSET 0 20 0", "OFFSET 0 1e-200 0"),
    "names_of_one_letter_composed_and_decomposed": Shape(person(Joint("\u00e9a"), Joint("e\u0301a"))),
    "names_of_a_slash_and_its_escape": Shape(person(Joint("a/b"), Joint("a%2Fb"))),
}


# Taken by --lossless, refused by lossy coding (one line, naming the file) for what its model cannot hold.
LOSSY_REFUSES = {"positions_on_every_joint": "lossy coding keeps only the root's position channels",
                 "root_rotations_only": "root joint 'Hips' needs Xposition, Yposition and Zposition",
                 "widest": "more than a lossy archive may hold"}


def accepted_bytes(name: str) -> bytes:
    case = ACCEPTED[name]
    return (case if isinstance(case, str) else bvh_text(case)).encode("utf-8")


def latin1_and_bom() -> dict[str, bytes]:
    """Encodings: Latin-1 (a name's é as one byte) and UTF-8 with a byte-order mark (which the
    archive does not keep: docs/format.md, BVH clips, "Lossless")."""
    shape = Shape(person(*chain(["Spéne", "Head"])))
    return {"latin1": bvh_text(shape).encode("latin-1"), "utf8_bom": b"\xef\xbb\xbf" + bvh_text(BASE).encode()}
