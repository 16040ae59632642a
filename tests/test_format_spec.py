"""docs/format.md states what the code holds, where the two could drift apart: the meta schema
(rendered in full from `archive.meta.SCHEMA`), the version table (one row per format, against
`mocapzip.legacy.format_of`) and the fixed files of the format (against the package's copies).

When the schema changes, `python tests/test_format_spec.py` writes its new rendering into
docs/format.md.
"""

from __future__ import annotations

import hashlib
import json
import re
import sys
from pathlib import Path

from mocapzip.archive.dictionaries import SHA256, dictionary
from mocapzip.archive.meta import SCHEMA
from mocapzip.archive.skeletons import template_dictionary
from mocapzip.formats.mcz import FORMAT_VERSION
from mocapzip.legacy import FIELDS_ADDED_IN, format_of

SPEC = Path(__file__).resolve().parents[1] / "docs" / "format.md"
SCHEMA_BLOCK = re.compile(r"(<!-- schema: [^\n]*-->\n```json\n)(.*?)(\n```)", re.DOTALL)
WIDTH = 100  # the widest line a rendering aims for


def rendered(value, indent: int = 0, used: int = 0) -> str:
    """`value` as JSON that reads well in a page: on one line where that fits in WIDTH, else one
    member per line (a list of plain values wrapped to WIDTH). Parsing it gives `value` back."""
    line = json.dumps(value)
    if not isinstance(value, (dict, list)) or indent + used + len(line) <= WIDTH:
        return line
    pad = " " * (indent + 2)
    if isinstance(value, dict):
        members = [f"{pad}{json.dumps(key)}: {rendered(item, indent + 2, len(json.dumps(key)) + 2)}"
                   for key, item in value.items()]
        return "{\n" + ",\n".join(members) + "\n" + " " * indent + "}"
    if any(isinstance(item, (dict, list)) for item in value):
        return "[\n" + ",\n".join(pad + rendered(item, indent + 2) for item in value) + "\n" + " " * indent + "]"
    lines, current = [], ""
    for item in map(json.dumps, value):
        if current and len(pad) + len(current) + len(item) + 2 > WIDTH:
            lines.append(current + ",")
            current = ""
        current = f"{current}, {item}" if current else item
    return "[\n" + "\n".join(pad + line for line in [*lines, current]) + "\n" + " " * indent + "]"


def test_rendering_gives_the_value_back_and_keeps_lines_short():
    text = rendered(SCHEMA)
    assert json.loads(text) == SCHEMA
    assert max(map(len, text.splitlines())) <= WIDTH + 30  # a long pattern or key may pass WIDTH a little


def test_the_spec_holds_the_meta_schema_exactly():
    match = SCHEMA_BLOCK.search(SPEC.read_text(encoding="utf-8"))
    assert match, "docs/format.md has no schema block"
    assert match[2] == rendered(SCHEMA), "docs/format.md's meta schema is not SCHEMA's: run python tests/test_format_spec.py"


def _table(text: str, header_start: str) -> list[list[str]]:
    """The rows of the markdown table whose header line starts with `header_start`, as cells."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(header_start))
    rows = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        rows.append([cell.strip() for cell in line.strip().strip("|").split("|")])
    return rows


def _code(cell: str) -> list[str]:
    return re.findall(r"`([^`]+)`", cell)


def test_the_version_table_has_one_row_per_format_as_legacy_says():
    rows = _table(SPEC.read_text(encoding="utf-8"), "| F | container")
    assert [int(row[0]) for row in rows] == list(range(1, FORMAT_VERSION + 1))
    for row in rows:
        version, container, contents, meta, skeletons, class_stream, clip_stream, coders, _, fields = row[:10]
        old = format_of(int(version))
        assert container.split(",")[0] == f"F{old.container}", version
        assert contents == (f"{old.contents_columns} columns" if old.index_contents else "—"), version
        assert ("`meta.json`" in meta) == old.stream_dictionaries, version
        assert skeletons.startswith(f"F{old.skeletons}:"), version
        assert class_stream.startswith(f"F{old.class_stream}:"), version
        assert clip_stream.startswith(f"F{old.clip_stream}:"), version
        assert tuple(_code(coders)) == old.coders, version
        added = {f"{part}.{name}" if part == "settings" else f"{part}[].{name}"
                 for part, name in FIELDS_ADDED_IN.get(int(version), ())}
        assert {name for name in _code(fields) if "." in name} == added, version


def test_the_dictionary_table_names_every_file_the_package_ships():
    rows = _table(SPEC.read_text(encoding="utf-8"), "| file | bytes | SHA-256")
    listed = {_code(row[0])[0]: (int(row[1].replace(",", "")), _code(row[2])[0]) for row in rows}
    assert listed == {name: (len(dictionary(name)), sha) for name, sha in SHA256.items()}
    for name in listed:
        assert hashlib.sha256(dictionary(name)).hexdigest() == SHA256[name]


def test_the_templated_dictionary_is_the_one_the_spec_states():
    text = SPEC.read_text(encoding="utf-8")
    derived = template_dictionary()
    assert f"{len(derived):,} bytes" in text
    assert hashlib.sha256(derived).hexdigest() in text


if __name__ == "__main__":
    spec = SPEC.read_text(encoding="utf-8")
    if not SCHEMA_BLOCK.search(spec):
        sys.exit("docs/format.md has no schema block")
    SPEC.write_text(SCHEMA_BLOCK.sub(lambda m: m[1] + rendered(SCHEMA) + m[3], spec, count=1), encoding="utf-8")
    print("wrote the meta schema into docs/format.md")
