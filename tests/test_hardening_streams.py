"""Hostile codec streams (issue 13): every CRC and checksum valid, only the declared sizes lie.

Each stream is built with the project's own encoders, then its header is rewritten to claim
what an attacker would: 10**12 frames, ten million zero frames, gigabytes of zstd output.
Decoding must refuse it with a ValueError, quickly and without allocating what it claims, so
each one is decoded in a child process limited to 1 GiB of address space and 60 seconds: a
hang, a MemoryError or a kill fails the test.
"""

from __future__ import annotations

import io
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest
import zstandard

from mocapzip.codec.entropy import ans
from mocapzip.codec.entropy import zstd as entropy
from mocapzip.codec.entropy.coefficients import encode_matrices
from mocapzip.codec.entropy.zstd import write_varint
from mocapzip.codec.lossless import encode_channels
from mocapzip.legacy import streams as legacy
from mocapzip.codec.basis import ClassBasis
from mocapzip.codec.clip_stream import CodedClip
from mocapzip.limits import MAX_DECODED_STREAM_BYTES, MAX_FRAMES_PER_CLIP

CHILD = """
import pathlib, resource, sys
resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))
blob = pathlib.Path(sys.argv[1]).read_bytes()
try:
    {call}
except ValueError as error:
    print(f"ValueError: {{error}}")
else:
    print("decoded")
"""


def refused_in_child(tmp_path, call: str, blob: bytes, message: str) -> None:
    """Run `call` on `blob` in a child with 1 GiB of address space: it must raise a ValueError
    whose message holds `message`."""
    path = tmp_path / "hostile.bin"
    path.write_bytes(blob)
    child = subprocess.run([sys.executable, "-c", CHILD.format(call=call), str(path)],
                           capture_output=True, text=True, timeout=60)
    assert child.returncode == 0, f"exit {child.returncode}: {child.stderr[-2000:]}"
    assert child.stdout.startswith("ValueError: "), child.stdout
    assert message in child.stdout, child.stdout


# --------------------------------------------------------------------------- lossless clips


def lossless_claiming(frames: int) -> bytes:
    """A 3-frame synthetic clip's lossless stream rewritten to claim `frames` frames, its rANS
    stream holding one state per lane of that shape (so a decoder that believes it starts decoding)."""
    values = np.round(np.cumsum(np.random.default_rng(13).normal(size=(3, 2)), axis=0), 4)
    sections = entropy.unpack_blobs(encode_channels(values))
    meta = entropy.decode_ints(sections[0])
    meta[1] = frames
    rows = int(np.sum(meta[3::4] == 2))  # decimal channels: the residual matrix's rows
    parts = entropy.unpack_blobs(sections[1][5:])  # after the coder tag and the CRC
    parts[1] = np.full(ans._Layout(rows, frames).n_lanes, ans._STATE_LOW, "<u4").tobytes()
    body = entropy.pack_blobs(parts)
    sections[0] = entropy.encode_ints(meta)
    sections[1] = sections[1][:1] + zlib.crc32(body).to_bytes(4, "little") + body
    return entropy.pack_blobs(sections)


@pytest.mark.parametrize("frames", [10**12, 3 * 10**8])
def test_lossless_clip_claiming_too_many_frames(tmp_path, frames):
    blob = lossless_claiming(frames)
    assert len(blob) < 300
    refused_in_child(tmp_path, "from mocapzip.codec.lossless import decode_channels; decode_channels(blob)",
                     blob, f"stream declares {frames} frames (at most {MAX_FRAMES_PER_CLIP})")


def test_lossless_clip_claiming_more_frames_than_its_bytes_hold(tmp_path):
    """Within the limits, but a rANS stream of a few hundred bytes cannot hold two channels of a million frames."""
    refused_in_child(tmp_path, "from mocapzip.codec.lossless import decode_channels; decode_channels(blob)",
                     lossless_claiming(MAX_FRAMES_PER_CLIP), "cannot hold 2 x 1048576 values")


def test_residual_stream_refuses_shapes_beyond_the_limits(tmp_path):
    blob = ans.encode_residuals(np.arange(6).reshape(2, 3))
    refused_in_child(tmp_path, "from mocapzip.codec.entropy.ans import decode_residuals; decode_residuals(blob, 2, 10**12)",
                     blob, "stream declares 1000000000000 residual steps")


# --------------------------------------------------------------------------- lossy clips and bases


def matrix_header(version: int, shapes) -> bytes:
    header = bytearray([version, len(shapes)])
    for rows, columns in shapes:
        write_varint(header, rows)
        write_varint(header, columns)
    return bytes(header)


def zero_matrices_claiming(shapes) -> bytes:
    """encode_matrices of one-row zero matrices, its header rewritten to claim `shapes`: a zero
    column codes only its end, so the coded bits are valid for any row count."""
    stream = encode_matrices([np.zeros((1, columns), np.int64) for _, columns in shapes])
    real = matrix_header(stream[0], [(1, columns) for _, columns in shapes])
    assert stream.startswith(real)
    return matrix_header(stream[0], shapes) + stream[len(real):]


def zero_ints_claiming(shape) -> bytes:
    """An entropy.encode_ints stream of zeros claiming `shape`: dense planes of width 0 hold any count."""
    header = bytearray([entropy._DENSE, 3, 0, len(shape)])  # int64, C order
    for size in shape:
        write_varint(header, size)
    return entropy.encode_bytes(bytes(header) + b"\x00")


def with_length(blob: bytes) -> bytes:
    return struct.pack("<I", len(blob)) + blob


TEN_MILLION = 10**7


def test_lossy_clip_claiming_ten_million_zero_frames(tmp_path):
    shapes = [(TEN_MILLION, 3), (TEN_MILLION, 4)]
    payload = struct.pack("<ff", 1.0, 0.2) + zero_matrices_claiming(shapes)
    assert len(payload) < 40
    refused_in_child(tmp_path, f"from mocapzip.codec.clip_stream import CodedClip; "
                               f"CodedClip.from_payload(blob, 'context', {shapes})",
                     payload, f"stream declares {TEN_MILLION} matrix rows")


def test_zstd_lossy_clip_claiming_ten_million_zero_frames(tmp_path):
    np.testing.assert_array_equal(entropy.decode_ints(zero_ints_claiming((5, 3))), np.zeros((5, 3)))
    payload = struct.pack("<ddB", 1.0, 0.2, 1) + with_length(zero_ints_claiming((TEN_MILLION, 3)))
    refused_in_child(tmp_path, "from mocapzip.legacy.streams import clip_v1; clip_v1(blob)",
                     payload, f"stream declares {TEN_MILLION} array values along one axis")


@pytest.mark.parametrize("coder", ["context", "zstd"])
def test_class_basis_claiming_ten_million_pose_values(tmp_path, coder):
    m, q = TEN_MILLION, 3
    head = struct.pack("<II", m, q) + np.ones(q, "<f4").tobytes()
    if coder == "context":
        body = zero_matrices_claiming([(m, 1), (m, 1), (m, q)])
    else:
        body = with_length(zero_ints_claiming((m,))) + with_length(zero_ints_claiming((m, q)))
    decoder = "from mocapzip.codec.basis import ClassBasis; ClassBasis.decode(blob)" if coder == "context" \
        else "from mocapzip.legacy.streams import class_v1; class_v1(blob)"
    refused_in_child(tmp_path, decoder, head + body, f"stream declares {m} matrix rows")


@pytest.mark.parametrize("decode", [
    lambda blob: CodedClip.from_payload(blob, "context"),
    legacy.clip_v1,
    ClassBasis.decode,
    legacy.class_v1,
    legacy.class_v2,
], ids=["clip-context", "clip-format-1", "basis", "basis-format-1", "basis-format-2"])
def test_lossy_streams_cut_short_raise_value_error(decode):
    with pytest.raises(ValueError, match="cut short"):
        decode(b"\x01\x00\x00")


# --------------------------------------------------------------------------- zstd output


def zstd_frame(chunk: bytes, repeats: int, declared: int) -> bytes:
    """A zstd frame of `chunk` repeated, written in steps (never held whole); its header
    declares `declared` bytes (-1: no content size)."""
    out = io.BytesIO()
    with zstandard.ZstdCompressor(level=1).stream_writer(out, size=declared, closefd=False) as writer:
        for _ in range(repeats):
            writer.write(chunk)
    return out.getvalue()


@pytest.fixture(scope="module")
def two_gib_frames() -> dict[str, bytes]:
    """2 GiB of zeros, a few dozen kilobytes each: with its true size declared, with none, and
    with its header's 4-byte size rewritten to 1000."""
    zeros = bytes(1 << 20)
    declared, undeclared = zstd_frame(zeros, 1 << 11, 1 << 31), zstd_frame(zeros, 1 << 11, -1)
    assert zstandard.frame_content_size(declared) == 1 << 31 and declared[4] == 0x80  # 4-byte size at byte 6
    understated = declared[:6] + (1000).to_bytes(4, "little") + declared[10:]
    return {"declared": declared, "undeclared": undeclared, "understated": understated}


@pytest.mark.parametrize("kind, message", [
    ("declared", f"unpacks to {1 << 31} bytes, more than the limit of {MAX_DECODED_STREAM_BYTES}"),
    ("undeclared", f"unpacks to more than the limit of {MAX_DECODED_STREAM_BYTES} bytes"),
    ("understated", "corrupt zstd data"),  # zstd notices output past the declared 1000 bytes
])
def test_zstd_stream_unpacking_to_gigabytes(tmp_path, two_gib_frames, kind, message):
    blob = two_gib_frames[kind]
    assert len(blob) < 100_000
    refused_in_child(tmp_path, "from mocapzip.codec.entropy.zstd import decode_bytes; decode_bytes(blob)",
                     blob, message)


def test_integer_stream_unpacking_past_what_its_values_need(tmp_path, two_gib_frames):
    refused_in_child(tmp_path, "from mocapzip.codec.entropy.zstd import decode_ints; decode_ints(blob)",
                     two_gib_frames["undeclared"], "unpacks to more than the limit of")


@pytest.mark.parametrize("declared", [100, -1])
def test_decode_bytes_limit_is_exact(declared):
    blob = zstd_frame(b"x" * 100, 1, declared)
    assert entropy.decode_bytes(blob, limit=100) == b"x" * 100
    with pytest.raises(ValueError, match="more than the limit of 99"):
        entropy.decode_bytes(blob, limit=99)


def test_blob_count_beyond_the_bytes_is_refused():
    header = bytearray()
    write_varint(header, 10**18)
    with pytest.raises(ValueError, match="declares 1000000000000000000 blobs"):
        entropy.unpack_blobs(bytes(header) + b"\x00")
