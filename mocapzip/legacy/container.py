"""Formats 1 to 6's container, read only: five root attributes (`magic`, `format_version`,
`tool_version`, `index_crc32`, and `header_crc32` over the first four) and the index as a zstd
frame of JSON (`names`, `offsets`, `lengths`, `crc32`) in a uint8 dataset beside `payload`.
Format 7 made the index readable JSON holding the tool name (`formats.mcz`). The checks that
both layouts share are the container's own (`formats.mcz`), which calls `read_index` for
an archive whose `legacy.Format.container` is 1.
"""

from __future__ import annotations

import itertools
import zlib

import h5py
import zstandard

from mocapzip.formats import mcz

ROOT_ATTRIBUTES = ("magic", "format_version", "tool_version", "index_crc32", "header_crc32")
INDEX_KEYS = ("names", "offsets", "lengths", "crc32")


def header_crc(format_version: int, tool_version: str, index_crc32: int) -> int:
    """The CRC32 over the header attributes (format 7 keeps tool_version in the index)."""
    return zlib.crc32(f"{mcz.MAGIC}\n{format_version}\n{tool_version}\n{index_crc32}".encode())


def read_index(reader: mcz.ArchiveReader, file_size: int) -> tuple[h5py.Dataset, list[str], list[int], list[int]]:
    """The payload dataset and the stream names, lengths and CRC32s of `reader`'s archive, once
    its root is found to hold what this layout defines, its header CRC and its index checked.
    Sets `reader.tool_version`."""
    datasets = reader._datasets(file_size, ROOT_ATTRIBUTES, {"index": mcz._dataset_problem,
                                                             "payload": mcz._dataset_problem})
    index_ds, f = datasets["index"], reader._file
    with mcz._section(reader.path, "header"):
        tool_version, index_crc32, stored_header_crc = (f.attrs[key] for key in ROOT_ATTRIBUTES[2:])
        if not isinstance(tool_version, bytes):
            raise reader._error(f"header: tool_version is {type(tool_version).__name__}, not a string")
        reader.tool_version = tool_version.decode()
        if header_crc(reader.format_version, reader.tool_version, index_crc32) != stored_header_crc:
            raise reader._error("header: CRC32 mismatch in the root attributes")
    with mcz._section(reader.path, "index"):
        limit = mcz.MAX_INDEX_BYTES
        if index_ds.shape[0] > limit:
            raise reader._error(f"index: {index_ds.shape[0]} bytes stored, more than the limit of {limit}")
        index = index_ds[:].tobytes()
        if zlib.crc32(index) != index_crc32:
            raise reader._error("index: CRC32 mismatch")
        size = zstandard.frame_content_size(index)  # checked before anything is decompressed
        if size < 0:
            raise reader._error("index: the zstd frame does not state its size")
        if size > limit:
            raise reader._error(f"index: unpacks to {size} bytes, more than the limit of {limit}")
        doc = mcz.parse_json(zstandard.ZstdDecompressor().decompress(index, allow_extra_data=False))
    if not isinstance(doc, dict) or sorted(doc) != sorted(INDEX_KEYS):
        raise reader._error(f"index: not a JSON object with exactly the keys {', '.join(INDEX_KEYS)}")
    names, offsets, lengths, crcs = reader._index_columns(doc, INDEX_KEYS)
    if [0, *itertools.accumulate(lengths)][:-1] != offsets:
        raise reader._error("index: streams are not stored back to back")
    return datasets["payload"], names, lengths, crcs
