"""Old formats stay in one place: `legacy.format_of` is the only code that compares format
versions, and what it says of the newest format is what the rest of the tree reads straight."""

import re
from pathlib import Path

import pytest

from mocapzip.formats.mcz import FORMAT_VERSION
from mocapzip.legacy import Format, format_of

ROOT = Path(__file__).resolve().parent.parent
# a version compared with a number: "format_version >= 7", "version < 10", "FORMAT_VERSION == 12"
_VERSION_TEST = re.compile(r"version\s*(?:[<>]=?|[!=]=)\s*\d", re.IGNORECASE)


def test_the_newest_format_differs_in_nothing():
    """Each field's default is the newest format's: bumping FORMAT_VERSION without giving the
    old version its own values fails here."""
    assert format_of(FORMAT_VERSION) == Format(FORMAT_VERSION)


@pytest.mark.parametrize("version", range(1, FORMAT_VERSION))
def test_each_older_format_differs_in_something(version):
    assert format_of(version) != Format(version)


def test_only_legacy_compares_format_versions():
    sources = [path for top in ("mocapzip", "formats", "cli") for path in (ROOT / top).rglob("*.py")
               if "legacy" not in path.relative_to(ROOT).parts]
    found = [f"{path.relative_to(ROOT)}:{number}: {line.strip()}" for path in sources
             for number, line in enumerate(path.read_text().splitlines(), 1) if _VERSION_TEST.search(line)]
    assert not found, "a format version compared outside mocapzip/legacy:\n" + "\n".join(found)


def test_the_version_test_finds_what_it_should():
    assert _VERSION_TEST.search("if self.format_version >= 10:")
    assert _VERSION_TEST.search("version == 1")
    assert not _VERSION_TEST.search("if self.format_version > FORMAT_VERSION:")
    assert not _VERSION_TEST.search("if layout == 1:")
