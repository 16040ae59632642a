"""docs/format.md's worked examples (§13) are test vectors: every block marked `<!-- example: NAME -->`
is checked here with mocapzip. The tiny archive's streams are the bytes shown and decode to the values
shown; each coefficient coder, the rANS residual coder and the lossless coder turn the values shown into
the bytes shown and back.

A zstd frame's bytes are not normative (format.md §1.8), but mocapzip's writer made them: they are
checked both ways too, as the stage fixtures are.
"""

from __future__ import annotations

import hashlib
import json
import re
import struct
import zlib
from pathlib import Path

import h5py
import numpy as np
import pytest

from mocapzip.archive import Archive
from mocapzip.archive.dictionaries import dictionary
from mocapzip.codec.basis import ClassBasis
from mocapzip.codec.entropy.ans import decode_residuals, encode_residuals
from mocapzip.codec.entropy.coefficients import Priors, decode_matrices
from mocapzip.codec.entropy.zstd import decode_bytes, decode_ints, encode_bytes, unpack_blobs
from mocapzip.formats.mcz import ArchiveReader
from mocapzip.stages import get_stage

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "docs" / "format.md"
GOLDEN = ROOT / "tests" / "golden"
EXAMPLE = GOLDEN / "example_v12.mcz"  # written by tests/make_golden_archives.py
CODER_SOURCE = GOLDEN / "lossy_v12.mcz"  # §13.2's matrix and priors come from it
BLOCK = re.compile(r"<!-- example: ([\w-]+) -->\n```\w*\n(.*?)\n```", re.DOTALL)
CHECKED = {  # every example block, by the test that checks it
    "archive-attributes", "archive-index", "archive-streams",  # test_the_container_is_as_shown
    "meta-stream", "meta-json",  # test_meta_is_as_shown
    "skeletons-summary",  # test_skeletons_is_as_shown
    "class-stream", "class-header", "class-mean-ints", "class-offsets", "class-residuals",
    "class-basis-ints",  # test_the_class_stream_is_as_shown
    "clip-stream", "clip-steps", "clip-pose-ints", "amc-text",  # test_the_clip_stream_decodes_to_the_text_shown
    "coder-matrix", "context-stream", "primed-priors", "primed-stream",  # test_each_coefficient_coder_...
    "lossless-values", "lossless-stream", "lossless-section-bytes", "lossless-header",
    "lossless-residuals", "lossless-rans", "lossless-links", "lossless-digits",  # test_the_lossless_...
}


@pytest.fixture(scope="module")
def example() -> dict[str, str]:
    """{name: the text of its block} of every example block in the spec."""
    text = SPEC.read_text(encoding="utf-8")
    blocks = BLOCK.findall(text)
    names = [name for name, _ in blocks]
    assert len(names) == len(set(names)), "an example name is used twice"
    return dict(blocks)


def hex_bytes(text: str) -> bytes:
    return bytes.fromhex(" ".join(text.split()))


def integers(text: str) -> np.ndarray:
    """A block of integers, one matrix row per line (a flat list where the lines are only wrapped)."""
    return np.array([[int(word) for word in line.split()] for line in text.splitlines()], np.int64)


def flat(text: str) -> np.ndarray:
    return np.array(text.split(), np.int64)


@pytest.fixture(scope="module")
def streams() -> dict[str, bytes]:
    with ArchiveReader(EXAMPLE) as archive:
        return {name: archive.read(name) for name in archive.names()}


def test_every_example_block_is_checked(example):
    assert set(example) == CHECKED


def test_the_container_is_as_shown(example):
    with h5py.File(EXAMPLE, "r") as f:
        attributes = {key: f.attrs[key] for key in f.attrs}
        payload = f["payload"][...].tobytes()
    shown = json.loads(example["archive-attributes"])
    assert shown == {"magic": attributes["magic"].decode(), "format_version": int(attributes["format_version"]),
                     "index_crc32": int(attributes["index_crc32"])}
    index = attributes["index"].decode("utf-8")
    assert example["archive-index"] == index
    assert zlib.crc32(index.encode("utf-8")) == shown["index_crc32"]
    rows = [line.split() for line in example["archive-streams"].splitlines()[1:]]
    index = json.loads(index)
    assert [row[0] for row in rows] == index["names"]
    offset = 0
    for (name, start, length, crc), stored_length, stored_crc in zip(rows, index["lengths"], index["crc32"]):
        assert (int(start), int(length), int(crc)) == (offset, stored_length, stored_crc), name
        assert zlib.crc32(payload[offset : offset + stored_length]) == stored_crc, name
        offset += stored_length
    assert offset == len(payload)


def test_meta_is_as_shown(example, streams):
    coded = hex_bytes(example["meta-stream"])
    assert coded == streams["meta"]
    text = json.dumps(json.loads(example["meta-json"]), sort_keys=True).encode()
    assert decode_bytes(coded, dictionary=dictionary("meta.json")) == text
    assert encode_bytes(text, dictionary("meta.json")) == coded


def test_skeletons_is_as_shown(example, streams):
    shown = json.loads(example["skeletons-summary"])
    stream = streams["skeletons"]
    assert stream[0] == shown["layout"] == 1
    assert stream[1] == shown["templates_bytes"] < 0x80  # a one-byte varint
    assert len(stream) == 2 + shown["templates_bytes"] + shown["numbers_bytes"]
    with Archive(EXAMPLE) as archive:
        assert len(archive.meta["skeletons"]) == shown["files"]
        text = archive.skeleton_text(0).encode("latin-1")
    assert (len(text), hashlib.sha256(text).hexdigest()) == (shown["file_bytes"], shown["file_sha256"])


def test_the_class_stream_is_as_shown(example, streams):
    stream = hex_bytes(example["class-stream"])
    assert stream == streams["class/0000"]
    header = json.loads(example["class-header"])
    m, q = struct.unpack_from("<II", stream)
    steps = np.frombuffer(stream, "<f4", q, 8).astype(np.float64)
    assert (m, q, steps.tolist()) == (header["M"], header["Q"], header["steps"])
    matrices = [flat(example[name])[:, None] for name in ("class-mean-ints", "class-offsets", "class-residuals")]
    coder = get_stage("coefficient coder", {"id": "context"})  # class streams are always "context"
    decoded = coder.decode(stream[8 + 4 * q:], [(m, 1), (m, 1), (m, q)])
    for got, shown in zip(decoded, matrices):
        np.testing.assert_array_equal(got, shown)
    assert coder.encode(matrices) == stream[8 + 4 * q:]
    offsets, residuals = matrices[1][:, 0], matrices[2]
    basis_ints = np.zeros_like(residuals)
    for r in range(m):  # format.md §8.4: each row against an earlier one
        basis_ints[r] = residuals[r] + (basis_ints[r - offsets[r]] if offsets[r] else 0)
    np.testing.assert_array_equal(basis_ints[:, 0], flat(example["class-basis-ints"]))
    basis = ClassBasis.decode(stream)
    np.testing.assert_array_equal(basis.mean, matrices[0][:, 0].astype(np.float64) * 0.001)
    np.testing.assert_array_equal(basis.components, basis_ints.astype(np.float64) * steps)


def test_the_clip_stream_decodes_to_the_text_shown(example, streams):
    stream = hex_bytes(example["clip-stream"])
    assert stream == streams["clip/00000"]
    steps = json.loads(example["clip-steps"])
    assert struct.unpack_from("<ff", stream) == (steps["pose_step"], steps["root_step"])
    pose = integers(example["clip-pose-ints"])
    coder = get_stage("coefficient coder", {"id": "context"})
    np.testing.assert_array_equal(coder.decode(stream[8:], [pose.shape])[0], pose)
    assert coder.encode([pose]) == stream[8:]
    with Archive(EXAMPLE) as archive:
        text = archive.file_bytes("motion", 0).decode()
    assert text.startswith(example["amc-text"] + "\n")
    # the value §13.1 works out by hand: frame 1's second root value
    basis = ClassBasis.decode(streams["class/0000"])
    value = float(basis.mean[1] + (float(pose[0, 0]) * steps["pose_step"]) * basis.components[1, 0])
    assert f"= {value!r}`" in SPEC.read_text(encoding="utf-8")
    assert f"root -0.3 {value:.6g} " in text


def test_each_coefficient_coder_codes_the_matrix_to_the_bytes_shown(example):
    matrix = integers(example["coder-matrix"])
    with ArchiveReader(CODER_SOURCE) as archive:
        stored = decode_bytes(archive.read("priors"))
        root = decode_matrices(archive.read("clip/00000")[8:], priors=Priors.decode(stored))[1]
    np.testing.assert_array_equal(matrix, root[:8])  # where §13.2 says it comes from
    context = get_stage("coefficient coder", {"id": "context"})
    stream = hex_bytes(example["context-stream"])
    assert context.encode([matrix]) == stream
    np.testing.assert_array_equal(context.decode(stream, [matrix.shape])[0], matrix)

    content = hex_bytes(example["primed-priors"])
    assert content == bytes([1, 1]) + stored[2 + 389 : 2 + 2 * 389]  # the root-track slot, alone
    priors = Priors.decode(content)
    primed = get_stage("coefficient coder", {"id": "primed"})
    stream = hex_bytes(example["primed-stream"])
    assert primed.encode([matrix], priors) == stream
    np.testing.assert_array_equal(primed.decode(stream, [matrix.shape], priors)[0], matrix)


def test_the_lossless_stream_codes_the_values_to_the_bytes_shown(example):
    values = np.array([[float(word) for word in line.split()] for line in example["lossless-values"].splitlines()])
    coder = get_stage("lossless coder", {"id": "decimal"})
    stream = hex_bytes(example["lossless-stream"])
    assert coder.encode(values) == stream
    decoded = coder.decode(stream)
    np.testing.assert_array_equal(decoded.view(np.int64), values.view(np.int64))  # bit for bit

    sections = unpack_blobs(stream)
    assert [len(section) for section in sections] == flat(example["lossless-section-bytes"]).tolist()
    header = flat(example["lossless-header"])
    np.testing.assert_array_equal(decode_ints(sections[0]), header)
    frames, table = int(header[1]), header[3:].reshape(-1, 4)
    rows = int(np.sum(table[:, 0] == 2))  # the decimal columns
    residuals, rans = integers(example["lossless-residuals"]), hex_bytes(example["lossless-rans"])
    assert sections[1] == b"\x01" + rans
    np.testing.assert_array_equal(decode_residuals(rans, rows, frames), residuals)
    assert encode_residuals(residuals) == rans
    assert decode_ints(sections[2]).size == decode_ints(sections[3]).size == 0  # no exceptions
    assert decode_bytes(sections[4]) == b""  # no zero slot
    np.testing.assert_array_equal(decode_ints(sections[5]), flat(example["lossless-links"]))
    assert sections[6:] == [hex_bytes(example["lossless-digits"])]
