"""Tests for mocapzip.codec.entropy.zstd: integer and byte coding with zstd, and corruption handling."""

import numpy as np
import pytest
import scipy.fft

from mocapzip.codec.entropy import zstd as entropy
from mocapzip.codec.entropy.zstd import (
    decode_bytes,
    decode_ints,
    encode_bytes,
    encode_ints,
    encode_sparse,
    pack_blobs,
    unpack_blobs,
)

INT64 = np.iinfo(np.int64)


def sample_arrays():
    rng = np.random.default_rng(0)
    yield np.zeros(0, np.int64)
    yield np.array(7)
    yield np.zeros((4, 5), np.int64)
    yield rng.integers(-1000, 1000, size=(7, 3, 2))
    yield np.array([INT64.min, INT64.max, 0, 1, -1])
    yield np.array([2**64 - 1, 0, 2**63], np.uint64)
    yield rng.integers(-128, 128, size=50).astype(np.int8)
    yield rng.integers(0, 65536, size=(9, 11)).astype(np.uint16)
    yield np.asfortranarray(rng.integers(-5, 5, size=(30, 4)).astype(np.int32))
    yield np.round(rng.laplace(scale=1000.0, size=20_000)).astype(np.int64)


def quantised_dct(rng, nonzero_fraction, n_frames=500, n_curves=20):
    """DCT coefficients of random-walk curves, quantised so about that fraction is non-zero."""
    curves = np.cumsum(rng.normal(size=(n_frames, n_curves)), axis=0)
    coefs = scipy.fft.dct(curves, type=2, norm="ortho", axis=0)
    threshold = np.quantile(np.abs(coefs), 1 - nonzero_fraction)
    return np.rint(coefs / (2 * threshold)).astype(np.int64)


@pytest.mark.parametrize("encode", [encode_ints, encode_sparse])
@pytest.mark.parametrize("array", list(sample_arrays()), ids=lambda a: f"{a.dtype}{a.shape}")
def test_round_trip_keeps_values_shape_and_dtype(encode, array):
    decoded = decode_ints(encode(array))
    assert decoded.dtype == array.dtype
    assert decoded.shape == array.shape
    np.testing.assert_array_equal(decoded, array)


@pytest.mark.parametrize("nonzero_fraction", [0.05, 0.1, 0.2])
def test_sparse_never_larger_than_plain(nonzero_fraction):
    q = quantised_dct(np.random.default_rng(1), nonzero_fraction)
    sparse = encode_sparse(q)
    assert len(sparse) <= len(encode_ints(q))
    np.testing.assert_array_equal(decode_ints(sparse), q)


def test_mostly_zero_data_compresses_well():
    q = quantised_dct(np.random.default_rng(2), 0.05)
    assert len(encode_sparse(q)) < q.size * 0.1  # far below one byte per coefficient


def test_noisy_integers_close_to_their_entropy():
    """Laplace-distributed integers (like prediction residuals) cost little above their entropy."""
    scale = 1000.0
    values = np.round(np.random.default_rng(3).laplace(scale=scale, size=50_000)).astype(np.int64)
    entropy_bits = np.log2(2 * np.e * scale)  # differential entropy of Laplace(scale), quantum 1
    assert len(encode_ints(values)) * 8 / values.size < entropy_bits * 1.03


def test_rejects_non_integer_arrays():
    with pytest.raises(TypeError):
        encode_ints(np.zeros(3))
    with pytest.raises(TypeError):
        encode_sparse(np.array(["a"]))


def test_bytes_round_trip():
    for data in (b"", b"x", bytes(range(256)) * 50):
        assert decode_bytes(encode_bytes(data)) == data


def assert_corruption_detected(decode, blob, expected):
    """Every single-byte change, truncation or extension raises ValueError or decodes correctly."""
    for position in range(len(blob)):
        for flip in (0x01, 0x80):
            damaged = blob[:position] + bytes([blob[position] ^ flip]) + blob[position + 1 :]
            try:
                result = decode(damaged)
            except ValueError:
                continue
            assert np.array_equal(result, expected), f"wrong data after flipping byte {position}"
    for cut in (1, 4, len(blob) // 2, len(blob) - 1):
        with pytest.raises(ValueError):
            decode(blob[:-cut])
    with pytest.raises(ValueError):
        decode(blob + b"\x00")
    with pytest.raises(ValueError):
        decode(b"")


def test_corrupt_bytes_raise_value_error():
    data = bytes(range(200))
    assert_corruption_detected(lambda blob: np.frombuffer(decode_bytes(blob), np.uint8),
                               encode_bytes(data), np.frombuffer(data, np.uint8))


@pytest.mark.parametrize(
    "array",
    [
        np.arange(-20, 20).reshape(8, 5),  # small values: dense byte planes
        np.round(np.random.default_rng(4).laplace(scale=3000.0, size=200)).astype(np.int64),
        quantised_dct(np.random.default_rng(5), 0.05, n_frames=64, n_curves=3),
    ],
    ids=["dense", "noisy", "sparse"],
)
def test_corrupt_ints_raise_value_error(array):
    blob = encode_sparse(array)
    assert_corruption_detected(decode_ints, blob, array)


def test_noisy_data_uses_bit_length_layout_and_checks_its_crc():
    values = np.round(np.random.default_rng(6).laplace(scale=3000.0, size=200)).astype(np.int64)
    blob = encode_ints(values)
    payload, verbatim = entropy._decompress_frame(blob)
    assert payload[0] == entropy._BIT_LENGTH and verbatim
    damaged = blob[:-1] + bytes([blob[-1] ^ 0x10])
    with pytest.raises(ValueError, match="CRC"):
        decode_ints(damaged)


def test_decode_ints_rejects_plain_bytes_blob():
    with pytest.raises(ValueError):
        decode_ints(encode_bytes(b"\x09\x00\x00\x01\x05"))


def test_pack_blobs_round_trip_and_errors():
    blobs = [b"", b"a", b"xyz" * 100, bytes(300)]
    packed = pack_blobs(blobs)
    assert unpack_blobs(packed) == blobs
    assert unpack_blobs(pack_blobs([])) == []
    with pytest.raises(ValueError):
        unpack_blobs(packed[:-1])
    with pytest.raises(ValueError):
        unpack_blobs(packed + b"!")
    with pytest.raises(ValueError):
        unpack_blobs(b"")
