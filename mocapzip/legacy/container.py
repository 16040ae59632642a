"""Formats 1 to 6's container, read only: five root attributes (`magic`, `format_version`,
`tool_version`, `index_crc32`, and `header_crc32` over the first four) and the index as a zstd
frame of JSON (`names`, `offsets`, `lengths`, `crc32`) in a uint8 dataset beside `payload`.
Format 7 made the index readable JSON holding the tool name (`formats.mcz`). The checks that
both layouts share are in `formats.mcz_checks`; `formats.mcz` calls `read_index` for an
archive whose `legacy.Format.container` is 1.
"""

from __future__ import annotations

import itertools
import zlib

import h5py
import zstandard

from mocapzip.formats.errors import ArchiveError
from mocapzip.formats.mcz_checks import MAGIC, dataset_problem, index_columns, parse_json, root_datasets, section

ROOT_ATTRIBUTES = ("magic", "format_version", "tool_version", "index_crc32", "header_crc32")
INDEX_KEYS = ("names", "offsets", "lengths", "crc32")


def header_crc(format_version: int, tool_version: str, index_crc32: int) -> int:
    """The CRC32 over the header attributes (format 7 keeps tool_version in the index)."""
    return zlib.crc32(f"{MAGIC}\n{format_version}\n{tool_version}\n{index_crc32}".encode())


def read_index(f: h5py.File, path: str, format_version: int, file_size: int,
               limit: int) -> tuple[h5py.Dataset, list[str], list[int], list[int], str]:
    """The payload dataset, the stream names, lengths and CRC32s, and the tool version of the
    archive `f` (at `path`), once its root is found to hold what this layout defines, its header
    CRC and its index (stored and unpacked, at most `limit` bytes) checked."""
    datasets = root_datasets(f, path, file_size, ROOT_ATTRIBUTES, {"index": dataset_problem,
                                                                    "payload": dataset_problem})
    index_ds = datasets["index"]
    with section(path, "header"):
        tool_version, index_crc32, stored_header_crc = (f.attrs[key] for key in ROOT_ATTRIBUTES[2:])
        if not isinstance(tool_version, bytes):
            raise ArchiveError(f"header: tool_version is {type(tool_version).__name__}, not a string", path)
        tool_version = tool_version.decode()
        if header_crc(format_version, tool_version, index_crc32) != stored_header_crc:
            raise ArchiveError("header: CRC32 mismatch in the root attributes", path)
    with section(path, "index"):
        if index_ds.shape[0] > limit:
            raise ArchiveError(f"index: {index_ds.shape[0]} bytes stored, more than the limit of {limit}", path)
        index = index_ds[:].tobytes()
        if zlib.crc32(index) != index_crc32:
            raise ArchiveError("index: CRC32 mismatch", path)
        size = zstandard.frame_content_size(index)  # checked before anything is decompressed
        if size < 0:
            raise ArchiveError("index: the zstd frame does not state its size", path)
        if size > limit:
            raise ArchiveError(f"index: unpacks to {size} bytes, more than the limit of {limit}", path)
        doc = parse_json(zstandard.ZstdDecompressor().decompress(index, allow_extra_data=False))
    if not isinstance(doc, dict) or sorted(doc) != sorted(INDEX_KEYS):
        raise ArchiveError(f"index: not a JSON object with exactly the keys {', '.join(INDEX_KEYS)}", path)
    names, offsets, lengths, crcs = index_columns(doc, INDEX_KEYS, path)
    if [0, *itertools.accumulate(lengths)][:-1] != offsets:
        raise ArchiveError("index: streams are not stored back to back", path)
    return datasets["payload"], names, lengths, crcs, tool_version
