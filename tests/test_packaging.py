"""The package list in pyproject.toml names every package in the tree, so the wheel holds them all.

formats/ and cli/ install as mocapzip.formats and mocapzip.cli (package-dir), which setuptools'
automatic discovery cannot rename; the list is therefore explicit and held to the tree here, and
.ci/run checks the built wheel itself against the tree.
"""

from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib", reason="tomllib is in the standard library from Python 3.11")

ROOT = Path(__file__).resolve().parent.parent


def _tree_packages():
    roots = {"mocapzip": ROOT / "mocapzip", "mocapzip.formats": ROOT / "formats", "mocapzip.cli": ROOT / "cli"}
    found = set()
    for name, folder in roots.items():
        for init in folder.rglob("__init__.py"):
            parts = init.parent.relative_to(folder).parts
            found.add(".".join((name, *parts)))
    return found


def test_pyproject_lists_every_package_in_the_tree():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    assert listed == _tree_packages()
    assert config["package-dir"] == {"mocapzip": "mocapzip", "mocapzip.formats": "formats", "mocapzip.cli": "cli"}
