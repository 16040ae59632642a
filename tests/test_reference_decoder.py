"""docs/format.md is enough to write a decoder: tests/reference_decoder/, written from it alone and
sharing no code with mocapzip, decodes every golden file, and fresh archives of every representation,
transform and coefficient coder, to the AMC (format 8 on: and BVH) values `mcz decompress` writes.

Lossless clips must agree bit for bit. Lossy clips are compared twice: with the values the package
decodes before it formats them (within float rounding: different but equivalent orders of floating
point operations; for a BVH clip, its model's channel values), and with the AMC or BVH text
`mcz decompress` writes (within one unit of the last digit written, since a value within float
rounding of a rounding boundary may print either way).
"""

from __future__ import annotations

import ast
import math
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import hostile_archives
import reference_decoder
from mocapzip.archive import Archive
from mocapzip.cli.main import main
from mocapzip.formats.amc import read_amc
from mocapzip.formats.bvh import parse_bvh, read_bvh, write_bvh
from mocapzip.formats.mcz import ArchiveError, ArchiveReader
from test_bvh_pipeline import rescaled

GOLDEN = Path(__file__).parent / "golden"
# and the tiny archive docs/format.md §13 shows byte by byte
GOLDEN_FILES = sorted(GOLDEN.glob("lossy_v*.mcz")) + sorted(GOLDEN.glob("lossless_v*.mcz")) + \
    sorted(GOLDEN.glob("example_v*.mcz"))
# decoded angles are degrees (or radians) and lengths cm or ASF units, all within a few thousand:
# float rounding differences stay far below this
FLOAT_ROUNDING = 1e-7

# Fresh archives made by the installed mcz from real clips, one per setting the goldens do not
# hold (they are all `aligned` + `dct`): every representation, every transform, segmented takes
# and classes found from the poses.
FRESH = {
    "channels-identity": ["-r", "channels", "-t", "identity", "-e", "2"],
    "positions-dwt": ["-r", "positions", "-t", "dwt", "-e", "2"],
    "aligned-lossless": ["--lossless"],
    "scaled-dct": ["-r", "scaled", "-e", "1"],
    "normalised-dwt": ["-r", "normalised", "-t", "dwt", "-e", "1"],
    "aligned-poly": ["-t", "poly", "--knot-spacing", "60", "-e", "1"],
    "segmented-auto-classes": ["--segment", "-c", "auto:2", "-e", "1"],
    "max-error": ["-e", "1", "--max-error", "3"],
    "segmented-max-error": ["--segment", "-e", "1", "--max-error", "4"],
    "plant-feet": ["-e", "1", "--plant-feet"],
}
# 02_05 is a boxing take that --segment cuts in four
FRESH_CLIPS = [("09", "09.asf"), ("09", "09_01.amc"), ("09", "09_02.amc"), ("07", "07.asf"), ("07", "07_01.amc"),
               ("02", "02.asf"), ("02", "02_05.amc")]
# BVH clips (format 8 on), the same settings: a CMU conversion (3 rotation channels per joint, the
# root's position channels, several children and End Sites) that --segment cuts in two, and two
# Bandai takes (6 channels on every joint under an extra root, which moves in run_normal only)
FRESH_BVH = {f"bvh-{label}": FRESH[label] for label in ("channels-identity", "positions-dwt", "aligned-lossless",
                                                        "scaled-dct", "normalised-dwt", "segmented-max-error",
                                                        "plant-feet")}
FRESH_BVH_CLIPS = ["cmu-bvh/10/10_01.bvh", "bvh-bandai/dataset-1_run_normal_001.bvh",
                   "bvh-bandai/dataset-1_bow_active_001.bvh"]


def test_reference_decoder_shares_no_code_with_mocapzip():
    """It is independent: no module of it imports mocapzip (or anything but the standard library,
    numpy, scipy, PyWavelets, h5py and zstandard)."""
    allowed = set(sys.stdlib_module_names) | {"numpy", "scipy", "pywt", "h5py", "zstandard", "reference_decoder"}
    package = Path(reference_decoder.__file__).parent
    modules = sorted(package.glob("*.py"))
    assert len(modules) >= 4
    for module in modules:
        for node in ast.walk(ast.parse(module.read_text(), str(module))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [] if node.level else [node.module]
            else:
                continue
            for name in names:
                assert name.split(".")[0] in allowed, f"{module.name} imports {name}"


def compressed(clips: Path, settings: dict, out: Path) -> dict[str, Path]:
    """{label: archive of the folder `clips`, compressed with that label's options}."""
    archives = {}
    for label, options in settings.items():
        archives[label] = out / f"{label}.mcz"
        result = CliRunner().invoke(main, ["compress", str(clips), "-o", str(archives[label]), "-q", *options])
        assert result.exit_code == 0, result.output
    return archives


@pytest.fixture(scope="module")
def fresh_archives(tmp_path_factory, shared_data):
    clips = tmp_path_factory.mktemp("clips")
    for subject, name in FRESH_CLIPS:
        (clips / subject).mkdir(exist_ok=True)
        shutil.copyfile(shared_data / "cmu" / subject / name, clips / subject / name)
    archives = compressed(clips, FRESH, tmp_path_factory.mktemp("fresh"))
    with Archive(archives["segmented-auto-classes"]) as archive:  # the settings did what they are here for
        assert any("segments" in row for row in archive.clips) and len(archive.meta["classes"]) == 2
    for label in ("max-error", "segmented-max-error"):
        with Archive(archives[label]) as archive:
            assert any("patched_frames" in row for row in archive.clips), label
    with Archive(archives["plant-feet"]) as archive:  # 07_01, a walk, has many stances
        assert sum(row.get("planted_stances", 0) for row in archive.clips) >= 10
    return archives


@pytest.fixture(scope="module")
def fresh_bvh_archives(tmp_path_factory, shared_data):
    clips = tmp_path_factory.mktemp("bvh")
    for name in FRESH_BVH_CLIPS:
        (clips / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(shared_data / name, clips / name)
    archives = compressed(clips, FRESH_BVH, tmp_path_factory.mktemp("fresh-bvh"))
    with Archive(archives["bvh-segmented-max-error"]) as archive:  # the clips hold what they are here for
        assert any("segments" in row for row in archive.clips)
        assert any("patched_frames" in row for row in archive.clips)
        assert sorted(row["path"] for row in archive.clips if row["bvh"].get("extra_root")) == [FRESH_BVH_CLIPS[1]]
    with Archive(archives["bvh-plant-feet"]) as archive:  # the lock on BVH models: link joints, identity axes
        assert sum(row.get("planted_stances", 0) for row in archive.clips) >= 2
    return archives


def _unit_of_last_digit(value: float, style: dict) -> float:
    """What one step in the last digit `format_amc` writes is worth for `value` under `style`."""
    if style["notation"] == "f":
        return 10.0 ** -style["digits"]
    magnitude = abs(value)
    exponent = math.floor(math.log10(magnitude)) if magnitude > 0 else 0
    return 10.0 ** (exponent - style["digits"] + 1)


def _bvh_unit_of_last_digit(value: float, number: str) -> float:
    """What one step in the last digit of a BVH frame line's `number` style ("g6" ...) is worth."""
    assert number != "repr", "lossy BVH rows are written with %g"
    magnitude = abs(value)
    exponent = math.floor(math.log10(magnitude)) if magnitude > 0 else 0
    return 10.0 ** (exponent - int(number[1:]) + 1)


def check_bvh_clip(row: dict, ours: np.ndarray, clip: dict, decoded: np.ndarray, written_path: Path,
                   lossless: bool) -> None:
    """A BVH clip: the reference's file values against the file `mcz decompress` wrote (and its text),
    and, lossy, the reference's model channel values against the package's decoded values."""
    written = read_bvh(written_path)
    data = written_path.read_bytes()
    assert ours.shape == written.values.shape, row["path"]
    if lossless:
        for theirs in (written.values, decoded):
            np.testing.assert_array_equal(ours, theirs, err_msg=row["path"])
            assert np.array_equal(np.signbit(ours), np.signbit(theirs)), row["path"]
        assert clip["model_values"] is None and clip["text"] == data, row["path"]
        return
    np.testing.assert_allclose(clip["model_values"], decoded, rtol=0, atol=FLOAT_ROUNDING, err_msg=row["path"])
    number = row["bvh"]["style"]["number"]
    units = np.vectorize(lambda v: _bvh_unit_of_last_digit(v, number))(written.values)
    assert np.all(np.abs(ours - written.values) <= units), row["path"]
    # the reference's text: the same hierarchy and MOTION lines, frame lines that read back as the file's
    header = len(written.header.encode(written.encoding))
    assert clip["text"][:header] == data[:header], row["path"]
    assert np.all(np.abs(parse_bvh(clip["text"]).values - written.values) <= units), row["path"]


def check_against_package(path: Path, tmp_path: Path) -> None:
    bvh_clips = {}
    reference = reference_decoder.decode_archive(path, bvh_clips)
    result = CliRunner().invoke(main, ["decompress", str(path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    with Archive(path) as archive:
        rows = archive.clips
        assert sorted(reference) == sorted(row["path"] for row in rows)
        assert sorted(bvh_clips) == sorted(row["path"] for row in rows if "bvh" in row)
        for index, row in enumerate(rows):
            ours = reference[row["path"]]
            decoded = archive.decode(index).values
            if "bvh" in row:
                check_bvh_clip(row, ours, bvh_clips[row["path"]], decoded, tmp_path / "out" / row["path"],
                               archive.settings.lossless)
                continue
            written = read_amc(tmp_path / "out" / row["path"]).values
            assert ours.shape == decoded.shape == written.shape, row["path"]
            if archive.settings.lossless:
                np.testing.assert_array_equal(ours, written, err_msg=row["path"])
                assert np.array_equal(np.signbit(ours), np.signbit(written)), row["path"]
                continue
            np.testing.assert_allclose(ours, decoded, rtol=0, atol=FLOAT_ROUNDING, err_msg=row["path"])
            units = np.vectorize(lambda v: _unit_of_last_digit(v, row["style"]))(written)
            assert np.all(np.abs(ours - written) <= units), row["path"]


@pytest.mark.parametrize("path", GOLDEN_FILES, ids=lambda p: p.stem)
def test_reference_decoder_decodes_every_golden_file(path, tmp_path):
    check_against_package(path, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("label", sorted(FRESH))
def test_reference_decoder_decodes_fresh_archives(fresh_archives, label, tmp_path):
    check_against_package(fresh_archives[label], tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("label", sorted(FRESH_BVH))
def test_reference_decoder_decodes_fresh_bvh_archives(fresh_bvh_archives, label, tmp_path):
    check_against_package(fresh_bvh_archives[label], tmp_path)


@pytest.mark.parametrize("path", sorted(GOLDEN.glob("container_v*.mcz")), ids=lambda p: p.stem)
def test_reference_container_reads_every_golden_container_as_mocapzip_does(path):
    with ArchiveReader(path) as ours, reference_decoder.Container(path) as theirs:
        assert theirs.names == ours.names() and theirs.format_version == ours.format_version
        assert theirs.tool_version == ours.tool_version
        assert all(theirs.read(name) == ours.read(name) for name in ours.names())


def test_reference_decoder_decodes_a_lossless_bvh_archive_without_units(shared_data, tmp_path):
    """The spec lets a lossless archive hold a BVH hierarchy whose unit compress could not tell
    (`units` null): only lossy decoding needs them. 10_03 rescaled to inches reads as a child in cm."""
    folder = tmp_path / "inches"
    folder.mkdir()
    write_bvh(rescaled(read_bvh(shared_data / "cmu-bvh" / "10" / "10_03.bvh"), 1 / 2.54), folder / "10_03.bvh")
    archive = tmp_path / "inches.mcz"
    result = CliRunner().invoke(main, ["compress", str(folder), "-o", str(archive), "-q", "--lossless"])
    assert result.exit_code == 0, result.output
    with Archive(archive) as opened:
        assert opened.meta["skeletons"][0]["units"] is None
    check_against_package(archive, tmp_path)


def test_both_decoders_refuse_a_degenerate_pose(tmp_path):
    """A tensor model of zeros decodes its class's bones to no direction (§10.8, Degenerate
    poses): before, the two decoders took that rounding noise for directions and wrote angles up to
    6,109 degrees apart. Both refuse the clip now."""

    case = next(c for c in hostile_archives.cases(tmp_path) if c.name == "tensor_model_of_zeros")
    hostile_archives.build(case, tmp_path / "zeros.mcz")
    with Archive(tmp_path / "zeros.mcz") as archive:
        with pytest.raises(ArchiveError, match=r"zeros.mcz: clip/00000 \(09_01.amc\): damaged \(class 1's model and basis "
                                               r"decode to a degenerate pose: bone "):
            archive.decode(0)
    with pytest.raises(ValueError, match="degenerate pose"):
        reference_decoder.decode_archive(tmp_path / "zeros.mcz")
