"""Property and fuzz tests (issue 5, item 3).

Round trips: random skeletons and motions through the ASF and AMC writers and readers, the
lossless channel code, and a whole lossless archive. Fuzzing: random bytes and mutated real
files fed to the ASF, AMC and .mcz readers, which may only ever raise MocapFormatError
(ArchiveError for archives). CI runs a bounded number of examples; set MCZ_FUZZ_EXAMPLES
(e.g. 20000) for a longer run.
"""

from __future__ import annotations

import itertools
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapzip.archive import Archive, Settings, compress, decompress, info
from mocapzip.codec.lossless import decode_channels, encode_channels
from mocapzip.formats.amc import AmcStyle, Motion, format_amc, parse_amc, read_amc
from mocapzip.formats.asf import Bone, Skeleton, format_asf, parse_asf, read_asf
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.mcz import ArchiveError

GOLDEN = Path(__file__).parent / "golden"
DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
FUZZ_EXAMPLES = int(os.environ.get("MCZ_FUZZ_EXAMPLES", "0"))


def bounded(examples: int):
    """Hypothesis settings: `examples` in CI, MCZ_FUZZ_EXAMPLES when set; no deadline (shared CI cores)."""
    return settings(max_examples=FUZZ_EXAMPLES or examples, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


# --------------------------------------------------------------------------- random skeletons and motions

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)
unit_range = st.floats(min_value=-1, max_value=1)  # direction components: bones stay within ASF's MAX_BONE_CM
bone_names = st.from_regex(r"[a-z][a-z0-9_]{0,7}", fullmatch=True).filter(lambda name: name != "root")
rotations = st.lists(st.sampled_from(["rx", "ry", "rz"]), unique=True, max_size=3).map(tuple)


@st.composite
def skeletons(draw) -> Skeleton:
    names = draw(st.lists(bone_names, min_size=1, max_size=6, unique=True))
    bones = []
    for i, name in enumerate(names):
        dof = draw(rotations)
        limits = [tuple(sorted(draw(st.tuples(finite, finite)))) for _ in dof] if draw(st.booleans()) else []
        bones.append(Bone(name=name, id=i + 1, direction=np.array(draw(st.tuples(unit_range, unit_range, unit_range))),
                          length=draw(st.floats(0, 100)), axis=np.array(draw(st.tuples(finite, finite, finite))),
                          dof=dof, limits=limits))
    parents = ["root"] + [draw(st.sampled_from(["root", *names[:i]])) for i in range(1, len(names))]
    children: dict[str, list[str]] = {}
    for name, parent in zip(names, parents):
        children.setdefault(parent, []).append(name)
    return Skeleton(name="fuzz", version="1.10", units={"mass": "1.0", "length": "0.45", "angle": "deg"},
                    bones=bones, hierarchy=list(children.items()))


@st.composite
def skeleton_and_motion(draw) -> tuple[Skeleton, Motion]:
    skeleton = draw(skeletons())
    named = ["root", *(b.name for b in skeleton.bones if b.dof)]
    order = draw(st.permutations(named))  # AMC files list bones in their own order
    counts = [len(skeleton.dof_of(name)) for name in order]
    n_frames = draw(st.integers(1, 8))
    flat = draw(st.lists(finite, min_size=n_frames * sum(counts), max_size=n_frames * sum(counts)))
    first = draw(st.integers(0, 5000))
    values = np.array(flat, dtype=float).reshape(n_frames, sum(counts))
    motion = Motion(list(order), counts, values, np.arange(first, first + n_frames), [":FULLY-SPECIFIED", ":DEGREES"])
    return skeleton, motion


@bounded(80)
@given(case=skeleton_and_motion(), newline=st.sampled_from(["\n", "\r\n"]))
def test_asf_and_amc_round_trip_on_random_skeletons(case, newline):
    """Written with 17 digits, every value, bone and frame number reads back exactly, checked against the skeleton."""
    skeleton, motion = case
    text = format_asf(skeleton)
    parsed = parse_asf(text.encode(), "fuzz.asf")
    assert format_asf(parsed) == text
    assert [(b.name, b.dof, b.limits) for b in parsed.bones] == [(b.name, b.dof, b.limits) for b in skeleton.bones]
    amc = format_amc(motion, style=AmcStyle(digits=17, newline=newline))
    again = parse_amc(amc.encode(), "fuzz.amc", skeleton=parsed)
    assert (again.bones, again.counts, again.header) == (motion.bones, motion.counts, motion.header)
    assert np.array_equal(again.frame_numbers, motion.frame_numbers)
    assert np.array_equal(again.values.view(np.int64), motion.values.view(np.int64))


@st.composite
def channel_matrices(draw) -> np.ndarray:
    """Small motions as AMC text gives them (6 significant digits) or arbitrary doubles, -0.0 included."""
    n_frames, n_channels = draw(st.integers(0, 40)), draw(st.integers(0, 6))
    any_double = st.floats(allow_nan=False, allow_infinity=False, width=64)
    element = st.one_of(finite.map(lambda v: float(f"{v:.6g}")), any_double, st.just(-0.0), st.just(0.0))
    flat = draw(st.lists(element, min_size=n_frames * n_channels, max_size=n_frames * n_channels))
    values = np.array(flat, dtype=np.float64).reshape(n_frames, n_channels)
    if n_frames and n_channels > 1 and draw(st.booleans()):
        values[:, 1] = values[:, 0]  # a duplicate column
    return values


@bounded(150)
@given(values=channel_matrices())
def test_lossless_channel_code_round_trips_bit_for_bit(values):
    decoded = decode_channels(encode_channels(values))
    assert decoded.shape == values.shape
    assert np.array_equal(decoded.view(np.int64), values.view(np.int64))


@pytest.fixture(scope="module")
def scratch(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


@bounded(15)
@given(case=skeleton_and_motion())
def test_lossless_archive_gives_every_value_back(scratch, case):
    """mcz compress --lossless then decompress, on random skeletons and motions: exact values."""
    skeleton, motion = case
    folder = scratch / "lossless"  # reused: every file is overwritten by each example
    (folder / "in").mkdir(parents=True, exist_ok=True)
    (folder / "in" / "s.asf").write_text(format_asf(skeleton))
    (folder / "in" / "c.amc").write_text(format_amc(motion, style=AmcStyle(digits=17)))
    compress([folder / "in"], folder / "a.mcz", Settings(lossless=True), force=True)
    decompress(folder / "a.mcz", folder / "out", force=True)
    again = read_amc(folder / "out" / "c.amc", read_asf(folder / "out" / "s.asf"))
    assert again.bones == motion.bones
    assert np.array_equal(again.values.view(np.int64), motion.values.view(np.int64))


# --------------------------------------------------------------------------- fuzzing the readers

TOKENS = [b"begin", b"end", b":hierarchy", b":bonedata", b":root", b"dof", b"limits", b"(", b")", b"root",
          b"nan", b"-inf", b"1e308", b"1e-400", b"0x10", b"\x00", b"\t", b"\r", b"\n", b"\n\n", b"#", b":", b"-",
          b"99999999999999999999", b"\xff\xfe", b"\xef\xbb\xbf", b"lhumerus", b"1", b"2"]


@st.composite
def mutated(draw, original: bytes) -> bytes:
    """`original` after a few random edits: byte flips, cuts, repeated or dropped spans, inserted tokens."""
    data = bytearray(original)
    for _ in range(draw(st.integers(1, 4))):
        size = len(data)
        at = draw(st.integers(0, max(size - 1, 0)))
        span = draw(st.integers(1, 64))
        edit = draw(st.sampled_from(["flip", "truncate", "delete", "repeat", "insert", "random"]))
        if edit == "flip" and size:
            data[at] ^= draw(st.integers(1, 255))
        elif edit == "truncate":
            del data[at:]
        elif edit == "delete":
            del data[at : at + span]
        elif edit == "repeat":
            data[at:at] = data[at : at + span]
        elif edit == "insert":
            data[at:at] = draw(st.sampled_from(TOKENS))
        else:
            data[at : at + span] = draw(st.binary(min_size=1, max_size=span))
    return bytes(data)


def only_format_errors(read, data: bytes, kind: type[Exception] = MocapFormatError) -> None:
    """`read(data)` returns, or raises `kind`; any other exception fails the test."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            read(data)
        except kind:
            pass


def real_text(name: str, frames: int | None = None) -> bytes:
    data = (DATA / "cmu" / "09" / name).read_bytes()
    if frames is None:
        return data
    end = data.index(b"\n%d\n" % (frames + 1))
    return data[: end + 1]


ASF_TEXT = real_text("09.asf")
AMC_TEXT = real_text("09_01.amc", frames=6)  # short: each example parses fast
SKELETON = parse_asf(ASF_TEXT, "09.asf")


@bounded(120)
@given(data=st.one_of(st.binary(max_size=3000), mutated(ASF_TEXT)))
def test_asf_reader_only_raises_format_errors(data):
    only_format_errors(lambda d: parse_asf(d, "fuzz.asf"), data)


@bounded(150)
@given(data=st.one_of(st.binary(max_size=3000), mutated(AMC_TEXT)), checked=st.booleans())
def test_amc_reader_only_raises_format_errors(data, checked):
    only_format_errors(lambda d: parse_amc(d, "fuzz.amc", skeleton=SKELETON if checked else None), data)


LOSSLESS_BLOB = encode_channels(read_amc(DATA / "cmu" / "09" / "09_02.amc").values[:30])


@bounded(120)
@given(blob=st.one_of(st.binary(max_size=500), mutated(LOSSLESS_BLOB)))
def test_lossless_decoder_only_raises_value_error(blob):
    """The documented contract the archive relies on: corrupt channel code is a ValueError."""
    only_format_errors(decode_channels, blob, ValueError)


ARCHIVES = [(GOLDEN / name).read_bytes() for name in ("lossy_v1.mcz", "lossy_v2.mcz", "lossless_v2.mcz")]
_names = itertools.count()


@bounded(100)
@given(data=st.one_of(st.binary(max_size=2000), *(mutated(a) for a in ARCHIVES)))
def test_mcz_reader_only_raises_archive_errors(scratch, data):
    """Opening, `info` and a full `test` (every clip decoded) of a mutated archive raise ArchiveError or nothing."""
    path = scratch / f"{next(_names)}.mcz"
    path.write_bytes(data)

    def open_and_verify(_):
        info(path)
        with Archive(path) as archive:
            archive.verify()

    try:
        only_format_errors(open_and_verify, data, ArchiveError)
    finally:
        path.unlink()
