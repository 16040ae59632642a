"""Text that the tree can hold to itself: package docstrings name their modules, no text cites a
format newer than the writer's, and pyproject.toml names only paths that exist.

A docstring that lists "the" modules of a package but leaves some out, a comment about a
format newer than the one the writer writes, or a dependency's comment pointing at a moved file
all read as true and are not; these checks catch them when the tree changes, not in a review.
"""

import ast
import importlib.util
import os
import re
import subprocess
from pathlib import Path

import pytest

from mocapzip.formats.mcz import FORMAT_VERSION

ROOT = Path(__file__).resolve().parent.parent
PACKAGE_ROOTS = ("mocapzip", "formats", "cli")


def _packages() -> list[Path]:
    return sorted(init.parent for root in PACKAGE_ROOTS for init in (ROOT / root).rglob("__init__.py"))


def _members(package: Path) -> list[str]:
    """The package's modules (each .py but __init__) and sub-packages, by name."""
    modules = [p.stem for p in package.glob("*.py") if p.name != "__init__.py"]
    subpackages = [p.name for p in package.iterdir() if (p / "__init__.py").is_file()]
    return sorted(modules + subpackages)


def _names(docstring: str, member: str) -> bool:
    """Whether `docstring` names `member` as code: `member.py`, `member/`, or `member` (alone or as
    the last part of a dotted name) in backquotes. A bare English word ("search", "settings") is
    not a name."""
    m = re.escape(member)
    return re.search(rf"(?<![\w.]){m}(?:\.py\b|/)|`(?:[\w.]+\.)?{m}`", docstring) is not None


@pytest.mark.parametrize("package", _packages(), ids=lambda p: str(p.relative_to(ROOT)))
def test_each_package_docstring_names_every_module_in_it(package):
    docstring = ast.get_docstring(ast.parse((package / "__init__.py").read_text())) or ""
    missing = [member for member in _members(package) if not _names(docstring, member)]
    assert not missing, f"{package.relative_to(ROOT)}/__init__.py's docstring does not name {missing}"


def test_a_docstring_names_a_module_only_as_code():
    assert _names("the searches (`search`)", "search")
    assert _names("see `mocapzip.ratecontrol.search`", "search")
    assert _names("search.py: the searches", "search")
    assert _names("entropy/   coefficient coders", "entropy")
    assert not _names("the one-dimensional searches it uses", "search")
    assert not _names("a search over steps", "search")
    assert not _names("see `research`", "search")
    assert not _names("see research.py", "search")


# A format cited by number: "format 12", "Format-10", "(format 11)", "formats 1 to 6",
# "formats 7 and 10", "formats 2-4", "format_version >= 7", "FORMAT_VERSION = 12",
# "format version 3". A number is one to three digits not followed by a decimal part or digit
# group ("format 12, 1,861 B" cites 12 only), joined to the next by to, and, or, a comma or a dash.
_NUMBER = r"\d{1,3}(?![\d]|[.,]\d)"
_FORMAT_CITE = re.compile(
    rf"\bformats?(?:[ _-]?version)?s?\s*(?:[<>!=]=?|==|\()?\s*[-]?\s*"
    rf"(?P<numbers>{_NUMBER}(?:\s*(?:,|to|and|or|-|–)\s*{_NUMBER})*)", re.IGNORECASE)
# a golden archive named by its format: lossy_v12.mcz, container_v7_index_dataset.mcz, v6.mcz, lossless_v11
_GOLDEN_CITE = re.compile(r"(?:(?<![^\W_])v(?P<a>\d+)(?:_[a-z_]+)?\.mcz\b|\b(?:lossy|lossless|container)\w*?_v(?P<b>\d+)\b)")


def cited_formats(text: str) -> set[int]:
    """Every format version `text` cites by number."""
    cited = {int(n) for match in _FORMAT_CITE.finditer(text) for n in re.findall(r"\d+", match["numbers"])}
    cited |= {int(match["a"] or match["b"]) for match in _GOLDEN_CITE.finditer(text)}
    return cited


NEXT = FORMAT_VERSION + 1  # the examples name it through {n}, so that this file cites no newer format itself


@pytest.mark.parametrize("text, cited", [
    ("the archive (format {n}).", {NEXT}),
    ("Format {n} on, rows hold", {NEXT}),
    ("format_version {n}", {NEXT}),
    ("if self.format_version >= {n}:", {NEXT}),
    ("FORMAT_VERSION = {n}", {NEXT}),
    ("formats 1 to {n}", {1, NEXT}),
    ("formats 7, 8 and {n}", {7, 8, NEXT}),
    ("formats 2-{n}", {2, NEXT}),
    ("format-{n} layout", {NEXT}),
    ("format version {n}", {NEXT}),
    ("tests/golden/lossy_v{n}.mcz", {NEXT}),
    ('GOLDEN / "container_v{n}_index_dataset.mcz"', {NEXT}),
    ('tmp_path / "v{n}.mcz"', {NEXT}),
    ("lossless_v{n}", {NEXT}),
    ("format 12, 1,861 B larger", {12}),
    ("HDF5 format 1.10", set()),
    ('libver=("v110", "v110")', set()),
    ("coefficient_coder-primed-v2.npz and clip_v1", set()),
    ("{n} formats of 120 frames; 24 cm", set()),
])
def test_cited_formats_finds_each_way_a_format_is_cited(text, cited):
    assert cited_formats(text.format(n=NEXT)) == cited


def _tracked_texts() -> list[Path]:
    listed = subprocess.run(["git", "ls-files", "*.py", "*.md"], cwd=ROOT, capture_output=True, text=True,
                            check=True).stdout.split()
    return [ROOT / name for name in listed if (ROOT / name).is_file()]


def test_no_text_cites_a_format_newer_than_the_writers():
    newer = [f"{path.relative_to(ROOT)}:{number}: format {cited}"
             for path in _tracked_texts()
             for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             for cited in sorted(cited_formats(line)) if cited > FORMAT_VERSION]
    assert not newer, f"FORMAT_VERSION is {FORMAT_VERSION}; cited: {newer}"


def test_pyproject_names_only_paths_that_exist():
    text = (ROOT / "pyproject.toml").read_text()
    # a path: words joined by slashes that end in a file's suffix (mocapzip/parallel.py, docs/cluster.md),
    # in a slash (formats/), or start at a dot (.ci/run); "ASF/AMC" and "formats/cli" are not paths
    slashed = r"(?<![\w./-])(\.[\w-]+(?:/[\w.-]+)+|[\w-]+(?:/[\w-]+)*(?:/[\w-]+\.\w+|/))(?![\w/-])"
    paths = set(re.findall(slashed, text)) | set(re.findall(r'^readme = "([^"]+)"', text, re.MULTILINE))
    assert {"mocapzip/parallel.py", ".ci/run", "formats/", "README.md"} <= paths, "the pattern is broken"
    missing = sorted(p for p in paths if not (ROOT / p).exists())
    assert not missing, f"pyproject.toml names {missing}, which do not exist"


BENCHMARKS = sorted((ROOT / "benchmarks").glob("*.py"))


@pytest.mark.parametrize("path", BENCHMARKS, ids=lambda p: p.name)
def test_every_benchmark_imports(path, monkeypatch):
    """Docs quote numbers from these scripts: a rename in the package must not leave one that no
    longer runs (benchmarks/acl.py once imported a helper the input-format registry removed)."""
    monkeypatch.syspath_prepend(str(path.parent))
    for variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.setenv(variable, os.environ.get(variable, "1"))  # some set them at import
    spec = importlib.util.spec_from_file_location(f"benchmark_{path.stem}", path)
    spec.loader.exec_module(importlib.util.module_from_spec(spec))
