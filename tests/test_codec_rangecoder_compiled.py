"""The compiled (numba) coefficient coder at its edges: the errors it reports through status
codes, its output buffer growing, and inputs it must refuse because compiled code does not
check array bounds."""

import numpy as np
import pytest

from mocapzip.codec.entropy.coefficients import Priors, decode_matrices, encode_matrices
from mocapzip.codec.entropy.zstd import write_varint


def stream(shapes, payload: bytes) -> bytes:
    """A version-1 matrices stream: header for `shapes`, then `payload` as the range-coded bytes."""
    header = bytearray([1, len(shapes)])
    for rows, columns in shapes:
        write_varint(header, rows)
        write_varint(header, columns)
    return bytes(header) + payload


def test_damaged_streams_raise_what_they_always_raised():
    matrix = np.zeros((10, 2), np.int64)
    matrix[9, 0], matrix[3, 1] = 7, -2
    blob = encode_matrices([matrix])
    payload = blob[len(stream([(10, 2)], b"")):]
    cases = {
        "range-coded stream ends early": blob[:-1],
        "1 unexpected bytes after the range-coded stream": blob + b"\x00",
        "range-coded stream shorter than its 4-byte minimum": stream([(10, 2)], payload[:3]),
        "column 0 ends at row 10 of 5": stream([(5, 2)], payload),  # the header understates the rows
        # FF FF FF FF: the code starts at the top of the range and every bit decodes as 1
        "column 0 ends at row 9223372036854775807 of 5": stream([(5, 3)], b"\xff" * 4 + bytes(40)),
        "range-coded stream is inconsistent at its end": stream([(0, 0)], b"\xff" * 4),
    }
    for message, damaged in cases.items():
        with pytest.raises(ValueError) as caught:
            decode_matrices(damaged)
        assert str(caught.value) == message


def test_output_buffer_grows_with_large_magnitudes():
    """Dense values near 2**62 code about 16 bytes each: many times the first buffer."""
    rng = np.random.default_rng(1)
    matrix = rng.integers(-(2**62) + 1, 2**62, size=(700, 5), dtype=np.int64)
    blob = encode_matrices([matrix, matrix[:3]])
    assert len(blob) > 8 * matrix.size
    decoded = decode_matrices(blob)
    np.testing.assert_array_equal(decoded[0], matrix)
    np.testing.assert_array_equal(decoded[1], matrix[:3])


def test_training_refuses_what_encoding_refuses():
    """Magnitudes index models by their bit length: past 2**62 they would index past the end."""
    with pytest.raises(ValueError, match="2\\*\\*62"):
        Priors.train([[np.array([[2**62]])]])
    with pytest.raises(ValueError, match="2-D"):
        Priors.train([[np.zeros(3, np.int64)]])
