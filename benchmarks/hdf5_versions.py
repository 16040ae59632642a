"""Which HDF5 libraries read which archive format: the table in docs/format_notes.md (§3, "Versions"),
from which docs/format.md's version table (§3.2) takes its column "HDF5 that reads it".

For each h5py release below (each ships its own HDF5 in its wheel), a throwaway venv reads every
golden archive (tests/golden: one or more per format, written by that format's writer) with h5py
alone: the root attributes, the index (attribute or dataset) and the whole payload, as
docs/format_notes.md's "Reading one stream by hand" does. Debian's python3-h5py (HDF5 1.10.8, built
against the system's HDF5) and Debian's stock tools (`h5ls -r`, `h5dump -A`) join the table where
installed (`apt-get install python3-h5py hdf5-tools`). Needs the package registry; never in CI.

    python benchmarks/hdf5_versions.py [--h5py 3.8.0 --h5py 3.11.0 ...] [--venvs DIR]
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

GOLDEN = Path(__file__).resolve().parents[1] / "tests" / "golden"
# The oldest h5py with a wheel for Python 3.11 (the project's floor, h5py>=3.8), one of each HDF5
# minor version after it, and the newest.
H5PY_RELEASES = ("3.8.0", "3.11.0", "3.16.0")

READ_EVERYTHING = r"""
import json, sys, h5py
print("HDF5", h5py.version.hdf5_version)
for path in sys.argv[1:]:
    try:
        with h5py.File(path, "r") as f:
            attrs = {key: f.attrs[key] for key in f.attrs}
            index = attrs.get("index")
            if index is None:
                index = f["index"][...]
            payload = f["payload"][...]
        print("ok", path)
    except Exception as exc:
        print("fail", path, type(exc).__name__, str(exc).splitlines()[0][:80])
"""


def format_of(path: Path) -> int:
    return int(re.search(r"_v(\d+)", path.name).group(1))


def read_with(python: str, archives: list[Path]) -> tuple[str, dict[Path, bool]]:
    out = subprocess.run([python, "-c", READ_EVERYTHING, *map(str, archives)], capture_output=True, text=True,
                         check=True).stdout.splitlines()
    version = out[0].split()[1]
    return version, {Path(line.split()[1]): line.startswith("ok") for line in out[1:]}


def venv_python(venvs: Path, release: str) -> str:
    folder = venvs / f"h5py-{release}"
    python = folder / "bin" / "python"
    if not python.exists():
        subprocess.run([sys.executable, "-m", "venv", str(folder)], check=True)
        before_3_11 = tuple(map(int, release.split(".")[:2])) < (3, 11)
        numpy = "numpy<2" if before_3_11 else "numpy"  # wheels before 3.11 were built against numpy 1
        subprocess.run([str(python), "-m", "pip", "install", "-q", f"h5py=={release}", numpy], check=True)
    return str(python)


def stock_tools(archives: list[Path]) -> tuple[str, dict[Path, bool]] | None:
    if not (shutil.which("h5ls") and shutil.which("h5dump")):
        return None
    version = subprocess.run(["h5ls", "--version"], capture_output=True, text=True).stdout.split()[-1]
    result = {}
    for path in archives:
        listing = subprocess.run(["h5ls", "-r", str(path)], capture_output=True, text=True)
        dump = subprocess.run(["h5dump", "-A", str(path)], capture_output=True, text=True)
        result[path] = (listing.returncode == 0 and "*ERROR*" not in listing.stdout and dump.returncode == 0
                        and "h5dump error" not in dump.stderr)
    return f"h5ls/h5dump {version}", result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--h5py", action="append", help=f"h5py releases (default: {', '.join(H5PY_RELEASES)})")
    parser.add_argument("--venvs", type=Path, help="where the venvs are made and kept (default: a temporary folder)")
    args = parser.parse_args()
    archives = sorted(GOLDEN.glob("*.mcz"), key=lambda p: (format_of(p), p.name))
    with tempfile.TemporaryDirectory() as scratch:
        venvs = args.venvs or Path(scratch)
        columns = []
        for release in args.h5py or H5PY_RELEASES:
            version, result = read_with(venv_python(venvs, release), archives)
            columns.append((f"HDF5 {version} (h5py {release})", result))
        if Path("/usr/bin/python3").exists():
            try:
                version, result = read_with("/usr/bin/python3", archives)
                columns.append((f"HDF5 {version} (Debian python3-h5py)", result))
            except subprocess.CalledProcessError:  # no python3-h5py there
                pass
        tools = stock_tools(archives)
        if tools:
            columns.append(tools)
    by_format = defaultdict(list)
    for path in archives:
        by_format[format_of(path)].append(path)
    print("| format | " + " | ".join(name for name, _ in columns) + " |")
    print("|---:|" + "---|" * len(columns))
    for version, paths in sorted(by_format.items()):
        cells = []
        for _, result in columns:
            failed = [p.name for p in paths if not result[p]]
            cells.append("yes" if not failed else f"**no**: {', '.join(failed)}")
        print(f"| {version} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
