"""A corpus of bad inputs, generated from real shared files (tests/test_hardening_inputs.py uses it).

Each `Case` is one folder under the corpus root holding what a user might point `mcz` at:
real CMU files (cmu/09: 09.asf, 09_01.amc) damaged in one way. `expect` says what `mcz`
must do: "error" (exit 1, one line naming `file`, `line` when there is one, and `problem`)
or "warning" (accepted: the damaged part is dropped, as documented in formats/amc.py).
"""

from __future__ import annotations

import os
import random
import stat
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

SUBJECT = Path("cmu") / "09"
ASF_NAME = "09.asf"
AMC_NAME = "09_01.amc"
FOREIGN_AMC = Path("other-vicon-blade") / "walk_200fps" / "walkMoCap2.amc"  # Blade bone names


@dataclass
class Case:
    name: str
    inputs: list[str]  # relative to the case folder
    file: str  # the file the message must name (base name)
    problem: str  # a phrase of the message
    line: int | None = None  # the line the message must name
    expect: str = "error"  # or "warning": accepted, with `problem` in a warning line
    frames: int | None = None  # frames kept, for accepted cases
    inspect_warns: bool = False  # `inspect` needs no skeleton: it warns (exit 0) where compress refuses


class Amc:
    """The lines of the real AMC (LF line ends) with helpers that find a frame's lines."""

    def __init__(self, data: bytes):
        assert b"\r" not in data and data.endswith(b"\n")
        self.lines = data[:-1].split(b"\n")

    def frame(self, number: int) -> int:
        return self.lines.index(b"%d" % number)

    def bone(self, number: int, name: bytes) -> int:
        start = self.frame(number)
        return next(i for i in range(start + 1, len(self.lines)) if self.lines[i].split()[0] == name)

    def with_line(self, index: int, text: bytes) -> bytes:
        lines = list(self.lines)
        lines[index] = text
        return b"\n".join(lines) + b"\n"

    def with_value(self, number: int, name: bytes, value: bytes) -> tuple[bytes, int]:
        """The file with the first value of bone `name` in frame `number` replaced; and its 1-based line."""
        i = self.bone(number, name)
        words = self.lines[i].split()
        return self.with_line(i, b" ".join([words[0], value, *words[2:]])), i + 1


def build(root: Path, data: Path) -> list[Case]:
    """Write every case folder under `root` from the shared files in `data`; return the cases."""
    asf_bytes = (data / SUBJECT / ASF_NAME).read_bytes()
    amc_bytes = (data / SUBJECT / AMC_NAME).read_bytes()
    amc = Amc(amc_bytes)
    cases: list[Case] = []

    def add(case: Case, files: dict[str, bytes | Callable[[Path], None]]) -> None:
        folder = root / case.name
        folder.mkdir(parents=True)
        for name, content in files.items():
            if callable(content):
                content(folder / name)
            else:
                (folder / name).write_bytes(content)
        cases.append(case)

    def amc_case(name: str, content: bytes, problem: str, line: int | None, **kw) -> None:
        add(Case(name, ["."], AMC_NAME, problem, line, **kw), {ASF_NAME: asf_bytes, AMC_NAME: content})

    # Truncations (a copy cut short). Inside the last frame: that frame is dropped with a warning.
    cut = b"\n".join(amc.lines[: amc.bone(100, b"rhumerus") + 1]) + b"\n"
    amc_case("truncated_mid_frame", cut, "last frame 100 is incomplete", amc.frame(100) + 1,
             expect="warning", frames=99)
    rhumerus = amc.lines[amc.bone(100, b"rhumerus")]
    second_value = rhumerus.index(b" ", rhumerus.index(b" ") + 1) + 1
    cut = b"\n".join(amc.lines[: amc.bone(100, b"rhumerus")]) + b"\n" + rhumerus[: second_value + 2]  # inside the 2nd value
    amc_case("truncated_mid_number", cut, "last frame 100 is incomplete", amc.frame(100) + 1,
             expect="warning", frames=99)
    cut = b"\n".join(amc.lines[: amc.frame(100)]) + b"\n10"  # "100" cut to "10"
    amc_case("truncated_mid_frame_number", cut, "frame number 10 out of order (after 99)", amc.frame(100) + 1)

    # Damaged frames.
    foreign = (data / FOREIGN_AMC).read_bytes()
    first_bone_line = next(i for i, text in enumerate(foreign.split(b"\n")) if text.strip() == b"1") + 3
    add(Case("amc_for_another_skeleton", ["."], "walkMoCap2.amc", "is not in the skeleton", first_bone_line),
        {ASF_NAME: asf_bytes, "walkMoCap2.amc": foreign})
    i = amc.bone(1, b"lhand")
    amc_case("unknown_bone", amc.with_line(i, amc.lines[i].replace(b"lhand", b"lhnad")),
             "bone 'lhnad' is not in the skeleton", i + 1)
    i = amc.bone(50, b"lhand")
    amc_case("unknown_bone_later", amc.with_line(i, amc.lines[i].replace(b"lhand", b"lhnad")),
             "bone 'lhnad' is not among the first frame's bones", i + 1)
    i = amc.bone(40, b"rradius")
    amc_case("duplicate_bone", amc.with_line(i, amc.lines[i] + b"\n" + amc.lines[i]),
             "bone 'rradius' appears twice in frame 40", i + 2)
    i = amc.bone(40, b"rhumerus")
    amc_case("too_few_values", amc.with_line(i, amc.lines[i][: amc.lines[i].rindex(b" ")]),
             "bone 'rhumerus' has 2 values, expected 3", i + 1)
    amc_case("too_many_values", amc.with_line(i, amc.lines[i] + b" 1.5"),
             "bone 'rhumerus' has 4 values, expected 3", i + 1)
    i = amc.frame(41)
    amc_case("duplicate_frame_number", amc.with_line(i, b"40"), "duplicate frame number 40", i + 1)
    amc_case("decreasing_frame_number", amc.with_line(i, b"39"), "frame number 39 out of order (after 40)", i + 1)
    i = amc.frame(60)
    amc_case("missing_bone_mid_file", amc.with_line(i + 2, b"#"), "truncated frame 60: 28 of 29 bones", i + 31)
    for label, token, problem in (("nan", b"nan", "is not finite: 'nan'"), ("inf", b"-inf", "is not finite: '-inf'"),
                                  ("1e308", b"1e308", "1e308 is out of range")):
        content, line = amc.with_value(60, b"lfemur", token)
        amc_case(f"value_{label}", content, problem, line)

    # Not AMC text at all.
    rng = random.Random(5)
    garbage = rng.randbytes(4096).replace(b"\r", b"\n")
    amc_case("binary_garbage", garbage, "binary data (NUL bytes)", garbage[: garbage.index(0)].count(b"\n") + 1)
    no_nul = bytes(b if b not in b"\x00\n\r" else 0x80 for b in rng.randbytes(4096))
    amc_case("binary_without_nul", no_nul, "expected a frame number", 1)
    amc_case("empty_file", b"", "empty file", 1)
    amc_case("blank_file", b"\n \n\t\n", "empty file", 1)
    amc_case("utf16_with_bom", amc_bytes.decode().encode("utf-16"), "UTF-16 text", 1)
    amc_case("utf16_without_bom", amc_bytes.decode().encode("utf-16-le"), "UTF-16 text", 1)
    asf_lines = asf_bytes.split(b"\n")
    cut_asf = b"\n".join(asf_lines[: asf_lines.index(b":hierarchy")])
    add(Case("asf_truncated", ["."], ASF_NAME, "no ':hierarchy' section", asf_lines.index(b":hierarchy")),
        {ASF_NAME: cut_asf, AMC_NAME: amc_bytes})

    # Folders and file-system trouble.
    add(Case("folder_without_asf", ["."], AMC_NAME, "no skeleton: no .asf file in its folder", inspect_warns=True),
        {AMC_NAME: amc_bytes})
    add(Case("two_asf_no_option", ["."], AMC_NAME, "ambiguous skeleton: 2 .asf files", inspect_warns=True),
        {ASF_NAME: asf_bytes, "09b.asf": asf_bytes, AMC_NAME: amc_bytes})

    def unreadable(path: Path) -> None:
        path.write_bytes(amc_bytes)
        path.chmod(0)

    add(Case("unreadable_file", ["."], AMC_NAME, "Permission denied"), {ASF_NAME: asf_bytes, AMC_NAME: unreadable})
    add(Case("symlink_loop", ["."], "loop.amc", "symbolic link"),
        {ASF_NAME: asf_bytes, "loop.amc": lambda p: p.symlink_to(p.name)})
    add(Case("symlink_loop_named", ["loop.amc"], "loop.amc", "symbolic link"),
        {ASF_NAME: asf_bytes, "loop.amc": lambda p: p.symlink_to(p.name)})
    add(Case("zero_clips", ["."], "zero_clips", "no AMC clips found"), {ASF_NAME: asf_bytes})
    add(Case("zero_clips_dir_loop", ["."], "zero_clips_dir_loop", "no AMC clips found"),
        {ASF_NAME: asf_bytes, "sub": lambda p: p.symlink_to(".", target_is_directory=True)})
    return cases


def is_readable_anyway(path: Path) -> bool:
    """True when permission bits do not stop us (root): the test then simulates the denial."""
    return not (path.stat().st_mode & (stat.S_IRUSR | stat.S_IRGRP | stat.S_IROTH)) and os.access(path, os.R_OK)
