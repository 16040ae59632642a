"""Stock HDF5 tools read what `mcz compress` writes: `h5ls -r` lists every dataset, `h5dump`
prints the index and its clips table (docs/format.md, "Layout" and "Versions").

The tools are Debian's `hdf5-tools` (HDF5 1.10.8 on Debian 12, older than the HDF5 inside
h5py's wheels): format 12 pins HDF5 1.10's object versions so that they can. CI installs them
(.ci/run); elsewhere, without them, these tests are skipped with that reason.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from mocapzip.formats.mcz import FORMAT_VERSION, ArchiveReader

GOLDEN = Path(__file__).parent / "golden"
NEWEST_GOLDEN = sorted(GOLDEN.glob(f"*_v{FORMAT_VERSION}*.mcz"))

if not (shutil.which("h5ls") and shutil.which("h5dump")):
    if os.environ.get("CI"):  # .ci/run installs them: their absence there is a failure, not a skip
        raise RuntimeError("h5ls/h5dump not found: .ci/run installs Debian's hdf5-tools")
    pytest.skip("stock HDF5 tools (h5ls, h5dump) not installed: apt-get install hdf5-tools", allow_module_level=True)


def tool(*args: str) -> str:
    """A tool's output; it must exit 0 and say nothing of an error (h5dump exits 0 on some)."""
    result = subprocess.run(args, capture_output=True, text=True, errors="replace", timeout=60)
    assert result.returncode == 0, f"{' '.join(args)}: exit {result.returncode}\n{result.stderr}{result.stdout}"
    assert not re.search(r"\*ERROR\*|^h5\w+ error", result.stdout + result.stderr, re.MULTILINE), \
        f"{' '.join(args)}:\n{result.stdout}{result.stderr}"
    return result.stdout


def dumped_index(path: Path) -> str:
    """The index as `h5dump` prints it (`-w 0`: one line), from the attribute or the dataset."""
    out = tool("h5dump", "-w", "0", *(("-d", "index") if _index_is_dataset(path) else ("-a", "index")), str(path))
    line = next(line for line in out.splitlines() if line.lstrip().startswith("(0): "))
    return line.split("(0): ", 1)[1].strip()[1:-1]  # between the quotes h5dump puts around a string


def _index_is_dataset(path: Path) -> bool:
    return re.search(r"^/index\s+Dataset", tool("h5ls", "-r", str(path)), re.MULTILINE) is not None


def assert_listed(path: Path) -> None:
    listing = tool("h5ls", "-r", str(path))
    assert re.search(r"^/payload\s+Dataset \{\d+\}$", listing, re.MULTILINE), listing
    tool("h5dump", "-A", str(path))  # every attribute, and the index dataset's header


@pytest.mark.parametrize("path", NEWEST_GOLDEN, ids=lambda p: p.name)
def test_stock_tools_list_every_newest_golden_archive(path):
    assert_listed(path)
    with ArchiveReader(path) as reader:
        contents = reader.contents
    dumped = dumped_index(path)
    for row in (contents or {}).get("clips", []):
        assert row[0] in dumped  # the clips table, as the tool prints it (non-ASCII as octal escapes)


def test_stock_tools_print_the_index_and_clips_table_of_what_compress_writes(tmp_path, shared_data):
    """Real clips, ASF/AMC and BVH: the index h5dump prints is the one mcz reads, clips table and
    achieved errors included, whichever way the index is stored (attribute or dataset)."""
    from mocapzip.archive import Settings, compress

    clips = [shared_data / "cmu" / "09" / "09_01.amc", shared_data / "bvh-bandai" / "dataset-1_walk-back_normal_001.bvh"]
    for name, inputs in (("one", clips[:1]), ("two", clips)):
        archive = tmp_path / f"{name}.mcz"
        compress(inputs, archive, Settings(error_cm=1.0))
        assert_listed(archive)
        index = json.loads(dumped_index(archive))
        with ArchiveReader(archive) as reader:
            assert index["names"] == reader.names()
            assert index["contents"] == reader.contents
        table = index["contents"]
        assert table["columns"][-3:] == ["mean_error_cm", "p99_error_cm", "max_error_cm"]
        assert [row[0] for row in table["clips"]] == [p.name for p in inputs]
        assert all(0 < row[4] <= row[6] for row in table["clips"])  # lossy: a mean error below the worst
