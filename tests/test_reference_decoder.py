"""docs/format.md is enough to write a decoder: tests/reference_decoder/, written from it alone and
sharing no code with mocapzip, decodes every golden file, and fresh archives of every representation,
transform and coefficient coder, to the AMC values `mcz decompress` writes.

Lossless clips must agree bit for bit. Lossy clips are compared twice: with the values the package
decodes before it formats them (within float rounding: different but equivalent orders of floating
point operations), and with the AMC text `mcz decompress` writes (within one unit of the last digit
written, since a value within float rounding of a rounding boundary may print either way).
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

import reference_decoder
from mocapzip.archive import Archive
from mocapzip.cli.main import main
from mocapzip.formats.amc import read_amc
from mocapzip.formats.mcz import ArchiveReader

GOLDEN = Path(__file__).parent / "golden"
GOLDEN_FILES = sorted(GOLDEN.glob("lossy_v*.mcz")) + sorted(GOLDEN.glob("lossless_v*.mcz"))
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
    "segmented-auto-classes": ["--segment", "-c", "auto:2", "-e", "1"],
    "max-error": ["-e", "1", "--max-error", "3"],
    "segmented-max-error": ["--segment", "-e", "1", "--max-error", "4"],
}
# 02_05 is a boxing take that --segment cuts in four
FRESH_CLIPS = [("09", "09.asf"), ("09", "09_01.amc"), ("09", "09_02.amc"), ("07", "07.asf"), ("07", "07_01.amc"),
               ("02", "02.asf"), ("02", "02_05.amc")]


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


@pytest.fixture(scope="module")
def fresh_archives(tmp_path_factory, shared_data):
    clips = tmp_path_factory.mktemp("clips")
    for subject, name in FRESH_CLIPS:
        (clips / subject).mkdir(exist_ok=True)
        shutil.copyfile(shared_data / "cmu" / subject / name, clips / subject / name)
    out = tmp_path_factory.mktemp("fresh")
    archives = {}
    for label, options in FRESH.items():
        archives[label] = out / f"{label}.mcz"
        result = CliRunner().invoke(main, ["compress", str(clips), "-o", str(archives[label]), "-q", *options])
        assert result.exit_code == 0, result.output
    with Archive(archives["segmented-auto-classes"]) as archive:  # the settings did what they are here for
        assert any("segments" in row for row in archive.clips) and len(archive.meta["classes"]) == 2
    for label in ("max-error", "segmented-max-error"):
        with Archive(archives[label]) as archive:
            assert any("patched_frames" in row for row in archive.clips), label
    return archives


def _unit_of_last_digit(value: float, style: dict) -> float:
    """What one step in the last digit `format_amc` writes is worth for `value` under `style`."""
    if style["notation"] == "f":
        return 10.0 ** -style["digits"]
    magnitude = abs(value)
    exponent = math.floor(math.log10(magnitude)) if magnitude > 0 else 0
    return 10.0 ** (exponent - style["digits"] + 1)


def check_against_package(path: Path, tmp_path: Path) -> None:
    reference = reference_decoder.decode_archive(path)
    result = CliRunner().invoke(main, ["decompress", str(path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    with Archive(path) as archive:
        rows = archive.clips
        assert sorted(reference) == sorted(row["path"] for row in rows)
        for index, row in enumerate(rows):
            ours = reference[row["path"]]
            decoded = archive.decode(index).values
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


@pytest.mark.parametrize("path", sorted(GOLDEN.glob("container_v*.mcz")), ids=lambda p: p.stem)
def test_reference_container_reads_every_golden_container_as_mocapzip_does(path):
    with ArchiveReader(path) as ours, reference_decoder.Container(path) as theirs:
        assert theirs.names == ours.names() and theirs.format_version == ours.format_version
        assert theirs.tool_version == ours.tool_version
        assert all(theirs.read(name) == ours.read(name) for name in ours.names())
