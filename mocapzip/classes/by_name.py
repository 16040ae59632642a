"""Which clips share a PCA basis: `--classes pooled|single|subject|FILE.csv`.

A class is just a name per clip. Automatic classes (`--classes auto[:K]`, PPCA and
annealing) need the loaded poses: they live in `mocapzip.classes.auto`, dispatched by
`archive.compress`.
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from pathlib import Path, PurePosixPath

from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.text import read_regular_file
from mocapzip.inputs.discover import ClipSource
from mocapzip.limits import MAX_DECODED_STREAM_BYTES, MAX_PATH_BYTES

MAX_TABLE_BYTES = MAX_DECODED_STREAM_BYTES  # refused unread: meta, which names every clip, may not be larger


def class_namer(mode: str) -> Callable[[ClipSource], str]:
    """The function naming a clip's class, decided by its path or table row alone.

    One clip at a time, so `compress` can name each clip as it streams past. Modes that
    look at the motion itself (automatic classes) take the loaded clips and are
    dispatched before this, in `archive.compress`.
    """
    if mode == "single":
        return lambda clip: "all"
    if mode in ("subject", "pooled"):
        # Clips sharing a skeleton file are one subject (CMU: one ASF per subject folder);
        # "pooled" merges the small ones once their frames are known (`pooled_classes`).
        return _subject_name
    path = Path(mode)
    if path.suffix.lower() in (".csv", ".tsv") or (path.exists() and not path.is_dir()):
        table = read_class_table(path)

        def from_table(clip: ClipSource) -> str:
            name = class_in_table(clip, table)
            if name is None:
                raise MocapFormatError(f"clip '{clip.relpath}' has no class in the table", path)
            return name

        return from_table
    raise MocapFormatError(f"unknown --classes value {mode!r}: use pooled, single, subject, auto[:K] or a CSV file")


POOL_FRAMES = 4000  # a subject with fewer frames shares a basis with the other small ones (benchmarks/small_sets.py)


def pooled_classes(frames: dict[str, int], widths: dict[str, int]) -> dict[str, str]:
    """`--classes pooled`: each subject's class, by its frames and pose width. A subject with
    POOL_FRAMES frames or more keeps a basis of its own; the others of one pose width share
    one ("pooled", or "pooled-W" where widths differ), as a basis costs a few KB whoever uses
    it, and for a short subject that is more than what its own basis saves. A pool of one
    keeps the subject's name."""
    small: dict[int, list[str]] = {}
    for name in frames:
        if frames[name] < POOL_FRAMES:
            small.setdefault(widths[name], []).append(name)
    out = {name: name for name in frames}
    for width, names in small.items():
        if len(names) > 1:
            pool = "pooled" if len(set(widths.values())) == 1 else f"pooled-{width}"
            while pool in frames:  # a subject's own name: the pool takes another
                pool += "+"
            out.update(dict.fromkeys(names, pool))
    return out


def _subject_name(clip: ClipSource) -> str:
    if clip.skeleton is not None:
        return clip.skeleton.stem
    parent = PurePosixPath(clip.relpath).parent
    return str(parent) if str(parent) != "." else "all"


def read_class_table(path) -> dict[str, str]:
    """Rows `clip path, class` of a CSV or TSV file; a header naming `file` and `class`
    columns (MANIFEST.tsv) is understood. Rows with an empty class are skipped.

    Fields are clip paths and class names (and notes), so one longer than MAX_PATH_BYTES
    characters is refused, naming the line, as is any CSV error (a field beyond the csv
    module's own limit of 131,072 characters included).
    """
    path = Path(path)
    if not path.exists():
        raise MocapFormatError("class table not found", path)
    lines = read_regular_file(path, MAX_TABLE_BYTES, "a class table").decode("utf-8", errors="replace").splitlines()
    if not lines:
        raise MocapFormatError("class table is empty", path)
    reader = csv.reader(lines, dialect="excel-tab" if "\t" in lines[0] else "excel")
    try:
        rows = [(reader.line_num, _checked_row(row, path, reader.line_num)) for row in reader]
    except csv.Error as exc:
        raise MocapFormatError(f"not a valid CSV table: {exc}", path, reader.line_num) from None
    header = [h.strip().lower() for h in rows[0][1]]
    file_col, class_col, start = 0, 1, 0
    if "class" in header:
        class_col, file_col, start = header.index("class"), header.index("file") if "file" in header else 0, 1
    table = {}
    for lineno, row in rows[start:]:
        if not row or not row[0].strip() or row[0].startswith("#"):
            continue
        if len(row) <= max(file_col, class_col):
            raise MocapFormatError("expected 'clip path, class'", path, lineno)
        if row[class_col].strip():
            table[row[file_col].strip().replace("\\", "/")] = row[class_col].strip()
    return table


def _checked_row(row: list[str], path: Path, lineno: int) -> list[str]:
    """`row`, or MocapFormatError if a field is longer than MAX_PATH_BYTES characters."""
    for field in row:
        if len(field) > MAX_PATH_BYTES:
            raise MocapFormatError(f"a field of {len(field):,} characters, longer than the {MAX_PATH_BYTES:,} "
                                   "a clip path or class name may have", path, lineno)
    return row


def class_in_table(source: ClipSource, table: dict[str, str]) -> str | None:
    """The class of a clip: the row whose path names it, the longest such path winning.

    A row names a clip when it is the clip's stored path, a tail of the clip's file path
    (`cmu/07/07_01.amc` in MANIFEST.tsv names data/cmu/07/07_01.amc), or ends with the
    clip's stored path (a table written from another root).
    """
    full = source.motion.resolve().as_posix()
    best = None
    for key, name in table.items():
        tail = key.lstrip("./")
        if key == source.relpath or full == key or full.endswith("/" + tail) or key.endswith("/" + source.relpath):
            if best is None or len(key) > len(best[0]):
                best = (key, name)
    return best[1] if best else None
