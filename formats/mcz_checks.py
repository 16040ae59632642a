"""The checks every layout of the .mcz container shares (`mcz` for formats 7 on,
`mocapzip.legacy.container` for formats 1 to 6): the magic, the spec's JSON, the root's
attributes and datasets, the index's columns, and HDF5's failures turned into `ArchiveError`.
It sits below both, so neither reads the other's internals."""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import h5py
from h5py import h5d, h5t

from mocapzip.formats.errors import ArchiveError

__all__ = ["MAGIC", "dataset_problem", "index_columns", "parse_json", "root_datasets", "section"]

MAGIC = "MCZ mocapzip archive"


def _refuse_constant(name: str):
    raise ValueError(f"{name} is not a JSON number")


def parse_json(data: bytes):
    """JSON as the spec defines it: UTF-8 text (no byte-order mark, which Python's json would skip,
    nor UTF-16, which it would detect), no NaN or Infinity, nor a number that overflows to one
    (1e400), and no key twice in an object (Python keeps the last)."""
    return json.loads(bytes(data).decode("utf-8"), parse_constant=_refuse_constant, parse_float=_finite,
                      object_pairs_hook=_unique_keys)


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text[:20]} is not a finite number")
    return value


def _unique_keys(pairs: list) -> dict:
    doc = {}
    for key, value in pairs:
        if key in doc:
            raise ValueError(f"a key appears twice in an object: {key[:80]!r}")
        doc[key] = value
    return doc


def dataset_problem(ds: h5py.Dataset, file_size: int) -> str | None:
    """What, if anything, makes `ds` other than a 1-D uint8 array stored contiguously in this file."""
    plist, dtype = ds.id.get_create_plist(), ds.id.get_type()
    layout = plist.get_layout()
    if layout == h5d.VIRTUAL:
        return "is a virtual dataset"
    if plist.get_external_count():
        return "is stored in external files"
    if layout != h5d.CONTIGUOUS:  # filters (compression, shuffle, checksums) come with chunks
        return f"is {'chunked' if layout == h5d.CHUNKED else 'compact'}, not contiguous"
    if dtype.get_class() != h5t.INTEGER or dtype.get_size() != 1 or dtype.get_sign() != h5t.SGN_NONE:
        return f"has type {ds.dtype}, not uint8"
    if ds.ndim != 1:
        return f"has shape {ds.shape}, not 1-D"
    if plist.fill_value_defined() != h5d.FILL_VALUE_DEFAULT:
        return "has a fill value"
    if ds.attrs:
        return "has attributes"
    offset = ds.id.get_offset()  # None: no storage allocated
    if ds.shape[0] and (offset is None or offset + ds.shape[0] > file_size):  # also bounds any allocation
        return f"has {ds.shape[0]} bytes, not stored within the file's {file_size}"
    return None


@contextmanager
def section(path: str, part: str) -> Iterator[None]:
    """Turn whatever h5py/HDF5 raises on a damaged file (OSError, KeyError, ValueError, ...) into ArchiveError."""
    try:
        yield
    except ArchiveError:
        raise
    except Exception as exc:
        raise ArchiveError(f"{part}: damaged or unreadable ({type(exc).__name__}: {exc})", path) from exc


def root_datasets(file: h5py.File, path: str, file_size: int, attributes: tuple[str, ...],
                  items: dict[str, Callable]) -> dict[str, h5py.Dataset]:
    """The root's datasets `items` (name -> the check that finds what, if anything, is wrong with
    it), once the root is found to hold nothing the format does not define.

    Checked before any data is read: HDF5 can take a dataset's bytes from other files (external
    storage, virtual datasets, external links), which may be a FIFO or /dev/zero, and decode
    them with filters (plugins); reading relies on `payload` being one contiguous run of this file.
    """
    with section(path, "header"):
        for kind, present, expected in (("attribute", file.attrs, attributes), ("item", file, items)):
            odd = sorted(set(present) ^ set(expected))  # names only: listing no link resolves it
            if odd:
                state = "missing" if odd[0] in expected else "not in the format"
                raise ArchiveError(f"header: root {kind} {odd[0]!r} is {state}", path)
        datasets = {}
        for name, check in items.items():
            link = file.get(name, getlink=True)
            if not isinstance(link, h5py.HardLink):  # resolving a soft or external link could open any file
                raise ArchiveError(f"header: {name} is not a dataset but a link ({type(link).__name__})", path)
            ds = file[name]
            problem = "is not a dataset" if not isinstance(ds, h5py.Dataset) else check(ds, file_size)
            if problem:
                raise ArchiveError(f"header: {name} {problem}", path)
            datasets[name] = ds
    return datasets


def index_columns(doc: dict, keys: tuple[str, ...], path: str) -> list[list]:
    """The index's columns `keys` (names first, crc32 last), once their types are checked (a
    damaged index must not raise TypeError)."""
    columns = [doc[key] for key in keys]
    names, crcs = columns[0], columns[-1]
    if not all(isinstance(column, list) and len(column) == len(names) for column in columns):
        raise ArchiveError(f"index: {', '.join(keys)} must be lists of equal length", path)
    if not all(isinstance(name, str) and name for name in names) or len(set(names)) != len(names):
        raise ArchiveError("index: stream names must be unique non-empty strings", path)
    counts = [n for column in columns[1:-1] for n in column]
    if not all(type(n) is int and n >= 0 for n in counts):
        raise ArchiveError(f"index: {' and '.join(keys[1:-1])} must be non-negative integers", path)
    if not all(type(crc) is int and 0 <= crc < 1 << 32 for crc in crcs):
        raise ArchiveError("index: crc32 values must be integers from 0 to 2**32 - 1", path)
    return columns
