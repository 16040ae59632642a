"""A corpus of bad inputs, generated from real shared files (tests/test_hardening_inputs.py uses it).

Each `Case` is one folder under the corpus root holding what a user might point `mcz` at:
real CMU files (cmu/09: 09.asf, 09_01.amc) damaged in one way. `mcz compress --lossless`
must refuse each (exit 1, one line naming `file`, `line` when there is one, and `problem`).

`build_specials` makes what could hang or exhaust memory if a reader regressed (FIFOs,
/dev/zero, huge files): tests/test_hardening_specials.py runs `mcz` on those in a
subprocess with a timeout and an address-space limit.
"""

from __future__ import annotations

import os
import random
import stat
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mocapzip.limits import MAX_BONES_PER_SKELETON

SUBJECT = Path("cmu") / "09"
ASF_NAME = "09.asf"
AMC_NAME = "09_01.amc"
FOREIGN_AMC = Path("other-vicon-blade") / "walk_200fps" / "walkMoCap2.amc"  # Blade bone names
LARGE_ANGLES = Path("cmu") / "35"  # 35_26.amc has angles beyond 314 (degrees; 314 rad would be 50 turns)


@dataclass
class Case:
    name: str
    inputs: list[str]  # relative to the case folder
    file: str  # the file the message must name (base name)
    problem: str  # a phrase of the message
    line: int | None = None  # the line the message must name
    inspect_warns: bool = False  # `inspect` warns (exit 0) where compress --lossless refuses
    frames: int | None = None  # frames kept when read without --lossless (a truncated copy)


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

    # Truncations (a copy cut short). Inside the last frame: --lossless refuses the file, which
    # it could not give back; without it (and in inspect) that frame is dropped with a warning.
    cut = b"\n".join(amc.lines[: amc.bone(100, b"rhumerus") + 1]) + b"\n"
    amc_case("truncated_mid_frame", cut, "last frame 100 is incomplete", amc.frame(100) + 1,
             inspect_warns=True, frames=99)
    rhumerus = amc.lines[amc.bone(100, b"rhumerus")]
    second_value = rhumerus.index(b" ", rhumerus.index(b" ") + 1) + 1
    cut = b"\n".join(amc.lines[: amc.bone(100, b"rhumerus")]) + b"\n" + rhumerus[: second_value + 2]  # inside the 2nd value
    amc_case("truncated_mid_number", cut, "last frame 100 is incomplete", amc.frame(100) + 1,
             inspect_warns=True, frames=99)
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

    # Numbers no body has (they crashed the codec): refused by the ASF reader, or the AMC
    # reader checking a clip against its skeleton.
    units = next(i for i, line in enumerate(asf_lines) if line.split()[:1] == [b"length"])
    for label, value in (("zero", b"0"), ("tiny", b"1e-300"), ("negative", b"-0.45")):
        damaged = b"\n".join(asf_lines[:units] + [b"  length " + value] + asf_lines[units + 1 :])
        add(Case(f"asf_units_length_{label}", ["."], ASF_NAME, f"units length {value.decode()} is outside [1e-06, 1e+06]",
                 units + 1), {ASF_NAME: damaged, AMC_NAME: amc_bytes})
    femur = asf_lines.index(b"     name lfemur")
    length = next(i for i in range(femur, len(asf_lines)) if asf_lines[i].split()[:1] == [b"length"])
    damaged = b"\n".join(asf_lines[:length] + [b"     length 1e9"] + asf_lines[length + 1 :])
    add(Case("asf_bone_a_million_km_long", ["."], ASF_NAME,
             "bone 'lfemur' is 5.64e+09 cm long (direction x length x 5.64444 cm per unit), longer than the 10000 cm",
             length + 1), {ASF_NAME: damaged, AMC_NAME: amc_bytes})
    degrees = (data / LARGE_ANGLES / "35_26.amc").read_bytes()
    assert degrees.count(b":DEGREES") == 1
    add(Case("radians_header_on_degrees", ["."], "35_26.amc", "angle -323.2 of bone 'rhand' in frame 70 is beyond "
             "314.2 rad (50 turns): the values look like degrees, not the radians this ':RADIANS' line declares",
             degrees.split(b"\n").index(b":DEGREES") + 1),
        {"35.asf": (data / LARGE_ANGLES / "35.asf").read_bytes(), "35_26.amc": degrees.replace(b":DEGREES", b":RADIANS")})

    # Folders and file-system trouble.
    add(Case("folder_without_asf", ["."], AMC_NAME, "no skeleton: no .asf file in its folder", inspect_warns=True),
        {AMC_NAME: amc_bytes})
    # two different skeletons, neither named like the clip (copies of one skeleton count as one)
    add(Case("two_asf_no_option", ["."], AMC_NAME, "ambiguous skeleton: 2 different skeletons", inspect_warns=True),
        {"a.asf": asf_bytes, "b.asf": b"# another skeleton\n" + asf_bytes, AMC_NAME: amc_bytes})

    def unreadable(path: Path) -> None:
        path.write_bytes(amc_bytes)
        path.chmod(0)

    add(Case("unreadable_file", ["."], AMC_NAME, "Permission denied"), {ASF_NAME: asf_bytes, AMC_NAME: unreadable})

    def unreadable_folder(path: Path) -> None:  # a subject folder the user may not list
        path.mkdir()
        (path / ASF_NAME).write_bytes(asf_bytes)
        (path / AMC_NAME).write_bytes(amc_bytes)
        path.chmod(0)

    add(Case("unreadable_folder", ["."], "09", "cannot list this folder, its clips would be left out: Permission denied"),
        {"09": unreadable_folder})
    add(Case("symlink_loop", ["."], "loop.amc", "symbolic link"),
        {ASF_NAME: asf_bytes, "loop.amc": lambda p: p.symlink_to(p.name)})
    add(Case("symlink_loop_named", ["loop.amc"], "loop.amc", "symbolic link"),
        {ASF_NAME: asf_bytes, "loop.amc": lambda p: p.symlink_to(p.name)})
    add(Case("zero_clips", ["."], "zero_clips", "no clips found"), {ASF_NAME: asf_bytes})
    add(Case("zero_clips_dir_loop", ["."], "zero_clips_dir_loop", "no clips found"),
        {ASF_NAME: asf_bytes, "sub": lambda p: p.symlink_to(".", target_is_directory=True)})
    return cases


@dataclass
class Special:
    """A case of `build_specials`: `mcz ARGS` (paths relative to the case folder) must fail with
    one line naming `file` and `problem`; with `skip` also listed as skipped under --skip-bad."""

    name: str
    args: list[str]
    file: str
    problem: str
    line: int | None = None
    skip: str | None = None  # the clip --skip-bad lists (the folder keeps a good clip)


def build_specials(root: Path, data: Path) -> list[Special]:
    """Write the case folders of inputs that are not regular files, or too large, under `root`."""
    asf_bytes = (data / SUBJECT / ASF_NAME).read_bytes()
    amc = data / SUBJECT / AMC_NAME
    fifo = "not a regular file: a named pipe (FIFO)"
    cases: list[Special] = []

    def folder(name: str, files: dict[str, bytes | Callable[[Path], None]]) -> Path:
        where = root / name
        where.mkdir(parents=True)
        for file, content in {ASF_NAME: asf_bytes, AMC_NAME: amc.read_bytes(), **files}.items():
            if callable(content):
                content(where / file)
            else:
                (where / file).write_bytes(content)
        return where

    def sparse(path: Path) -> None:  # the real clip, then zeros that take no disk space
        path.write_bytes(amc.read_bytes())
        os.truncate(path, 200_000_000)

    folder("fifo_amc", {"x.amc": os.mkfifo})
    cases.append(Special("fifo_amc", ["compress", ".", "--lossless"], "x.amc", fifo, skip="x.amc"))
    cases.append(Special("fifo_amc", ["inspect", "."], "x.amc", fifo))
    cases.append(Special("fifo_amc", ["compress", "x.amc", "--lossless"], "x.amc", fifo))
    folder("dev_zero_amc", {"zero.amc": lambda p: p.symlink_to("/dev/zero")})
    cases.append(Special("dev_zero_amc", ["compress", ".", "--lossless"], "zero.amc",
                         "not a regular file: a character device (/dev/zero)", skip="zero.amc"))
    cases.append(Special("dev_zero_amc", ["inspect", "."], "zero.amc", "not a regular file: a character device"))
    folder("fifo_asf", {ASF_NAME: os.mkfifo})
    cases.append(Special("fifo_asf", ["compress", ".", "--lossless"], ASF_NAME, fifo))
    cases.append(Special("fifo_asf", ["inspect", "."], ASF_NAME, fifo))
    folder("fifo_options", {"s.asf": os.mkfifo, "classes.csv": os.mkfifo})
    cases.append(Special("fifo_options", ["compress", AMC_NAME, "--asf", "s.asf", "--lossless"], "s.asf", fifo))
    cases.append(Special("fifo_options", ["inspect", AMC_NAME, "--asf", "s.asf"], "s.asf", fifo))
    cases.append(Special("fifo_options", ["compress", AMC_NAME, "--asf", ASF_NAME, "-c", "classes.csv", "--lossless"],
                         "classes.csv", fifo))

    # Too large: refused by size before a byte is read, or when the frame count passes the limit.
    folder("larger_than_any_clip", {"big.amc": sparse})
    cases.append(Special("larger_than_any_clip", ["compress", ".", "--lossless"], "big.amc",
                         "file of 200,000,000 bytes is larger than the 134,217,728 bytes an AMC file may have",
                         skip="big.amc"))
    frames = 1_048_577  # the root line only: 66 MB, within the size limit
    folder("more_frames_than_any_clip", {AMC_NAME: lambda p: write_long_amc(p, amc, frames, bones=(b"root",))})
    cases.append(Special("more_frames_than_any_clip", ["inspect", "."], AMC_NAME,
                         f"frame {frames} makes the clip too long: more than the 1,048,576 frames a clip may have",
                         line=3 + 2 * frames - 1))

    # Skeletons with long chains of bones (the hierarchy check was cubic in them): up to the limit
    # (test_hardening_specials reads it), and 20,000 bones, refused at the first bone past the limit.
    real_bones = asf_bytes.count(b"  begin\n")
    folder("chain_up_to_the_bone_limit", {ASF_NAME: chain_skeleton(asf_bytes, MAX_BONES_PER_SKELETON - real_bones)})
    folder("chain_of_20000_bones", {ASF_NAME: chain_skeleton(asf_bytes, 20_000)})
    first_too_many = MAX_BONES_PER_SKELETON - real_bones + 1  # chain bones of 7 lines each, after the real ones
    cases.append(Special("chain_of_20000_bones", ["inspect", "."], ASF_NAME,
                         f"more than the {MAX_BONES_PER_SKELETON:,} bones a skeleton may have",
                         line=asf_bytes.split(b":hierarchy\n")[0].count(b"\n") + 7 * first_too_many))
    return cases


def chain_skeleton(asf: bytes, n_bones: int) -> bytes:
    """The real skeleton `asf` (LF) with `n_bones` more bones, without dof, in one chain below rhand."""
    bonedata, hierarchy = asf.split(b":hierarchy\n")
    bones = b"".join(b"  begin\n     id %d\n     name chain%d\n     direction 0 1 0\n     length 0.1\n"
                     b"     axis 0 0 0  XYZ\n  end\n" % (1000 + k, k) for k in range(n_bones))
    links = b"".join(b"    %s chain%d\n" % (b"rhand" if k == 0 else b"chain%d" % (k - 1), k) for k in range(n_bones))
    head, _, tail = hierarchy.rpartition(b"  end")
    return bonedata + bones + b":hierarchy\n" + head + links + b"  end" + tail


def write_long_amc(path: Path, source: Path, n_frames: int, bones: tuple[bytes, ...] | None = None) -> None:
    """An AMC of `n_frames` frames made of the real `source` (LF line ends): its header, then its
    frames over and over, renumbered 1, 2, ...; only the lines of `bones` when given. Written
    in blocks, so a clip beyond the limits never has to fit in memory here."""
    lines = source.read_bytes().split(b"\n")
    first = next(i for i, line in enumerate(lines) if line.strip().isdigit())
    frames, current = [], []
    for line in lines[first + 1 :]:
        if line.strip().isdigit():
            frames.append(b"".join(current))
            current = []
        elif line.strip() and (bones is None or line.split()[0] in bones):
            current.append(line + b"\n")
    frames.append(b"".join(current))
    with open(path, "wb") as out:
        out.write(b"".join(line + b"\n" for line in lines[:first]))
        for start in range(0, n_frames, 10_000):
            block = range(start, min(start + 10_000, n_frames))
            out.write(b"".join(b"%d\n%s" % (k + 1, frames[k % len(frames)]) for k in block))


def is_readable_anyway(path: Path) -> bool:
    """True when permission bits do not stop us (root): the test then simulates the denial."""
    return not (path.stat().st_mode & (stat.S_IRUSR | stat.S_IRGRP | stat.S_IROTH)) and os.access(path, os.R_OK)
