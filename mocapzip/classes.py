"""Which clips share a PCA basis: `--classes single|subject|FILE.csv`.

A class is just a name per clip. Automatic classes (PPCA, annealing) plug in here
later as one more way of producing that mapping.
"""

from __future__ import annotations

import csv
from pathlib import Path, PurePosixPath

from .formats.errors import MocapFormatError
from .inputs import ClipSource


def assign_classes(clips: list[ClipSource], mode: str) -> dict[str, str]:
    """Map each clip's stored path to a class name.

    Takes the clips' sources only: every mode here is decided by paths and tables.
    Modes that look at the motion itself (automatic classes) take the loaded clips
    and are dispatched before this, in `archive.compress`.
    """
    if mode == "single":
        return {c.relpath: "all" for c in clips}
    if mode == "subject":
        # Clips sharing a skeleton file are one subject (CMU: one ASF per subject folder).
        return {c.relpath: _subject_name(c) for c in clips}
    path = Path(mode)
    if path.suffix.lower() in (".csv", ".tsv") or path.is_file():
        return _classes_from_table(clips, path)
    raise MocapFormatError(f"unknown --classes value {mode!r}: use single, subject or a CSV file")


def _subject_name(clip: ClipSource) -> str:
    if clip.asf is not None:
        return clip.asf.stem
    parent = PurePosixPath(clip.relpath).parent
    return str(parent) if str(parent) != "." else "all"


def _classes_from_table(clips: list[ClipSource], path: Path) -> dict[str, str]:
    """CSV or TSV rows `clip path, class`; a clip path matches by its stored path or file name suffix.

    MANIFEST.tsv style files (a header with `file` and `class` columns) work as they are.
    """
    if not path.is_file():
        raise MocapFormatError("class table not found", path)
    text = path.read_text(encoding="utf-8", errors="replace")
    dialect = "excel-tab" if "\t" in text.splitlines()[0] else "excel"
    rows = list(csv.reader(text.splitlines(), dialect=dialect))
    file_col, class_col, start = 0, 1, 0
    header = [h.strip().lower() for h in rows[0]] if rows else []
    if "class" in header:
        class_col = header.index("class")
        file_col = header.index("file") if "file" in header else 0
        start = 1
    table: dict[str, str] = {}
    for lineno, row in enumerate(rows[start:], start=start + 1):
        if not row or not row[0].strip() or row[0].startswith("#"):
            continue
        if len(row) <= max(file_col, class_col):
            raise MocapFormatError("expected 'clip path, class'", path, lineno)
        if row[class_col].strip():
            table[row[file_col].strip().replace("\\", "/")] = row[class_col].strip()
    assigned = {}
    for clip in clips:
        match = [cls for key, cls in table.items() if key == clip.relpath or key.endswith("/" + clip.relpath) or clip.relpath.endswith("/" + key)]
        if not match:
            raise MocapFormatError(f"clip '{clip.relpath}' has no class in the table", path)
        assigned[clip.relpath] = match[0]
    return assigned
