"""Tests for the context-modelled coefficient coder and the range coder under it."""

import numpy as np
import pytest
import scipy.fft

from mocapzip.codec.entropy.priors import stored_streams
from mocapzip.codec.entropy.coefficients import Priors, decode_matrices, encode_matrices
from mocapzip.codec.entropy.zstd import decode_bytes, encode_sparse
from mocapzip.codec.entropy.rangecoder import Decoder, Encoder, new_models
from mocapzip.codec.clip_stream import CodedClip


def quantised_dct(rng, n_frames, n_curves, step):
    """DCT coefficients of smooth random curves, quantised: sparse, low frequencies first."""
    curves = np.cumsum(np.cumsum(rng.normal(size=(n_frames, n_curves)), axis=0), axis=0)
    return np.rint(scipy.fft.dct(curves, norm="ortho", axis=0) / step).astype(np.int64)


def sample_matrices():
    rng = np.random.default_rng(3)
    yield np.zeros((0, 0), np.int64)
    yield np.zeros((0, 5), np.int64)
    yield np.zeros((7, 0), np.int64)
    yield np.zeros((40, 3), np.int64)
    yield np.array([[1]])
    yield np.array([[-(2**62) + 1, 2**62 - 1, 0], [1, -1, 2**40]])
    yield rng.integers(-3, 4, size=(200, 9)).astype(np.int8)
    yield rng.integers(0, 1000, size=(50, 4)).astype(np.uint16)
    yield quantised_dct(rng, 1, 30, 1.0)
    yield quantised_dct(rng, 700, 40, 50.0)
    yield quantised_dct(rng, 333, 4, 5.0)


@pytest.mark.parametrize("matrix", list(sample_matrices()), ids=lambda m: f"{m.dtype}{m.shape}")
def test_round_trip(matrix):
    (decoded,) = decode_matrices(encode_matrices([matrix]))
    assert decoded.shape == matrix.shape and decoded.dtype == np.int64
    np.testing.assert_array_equal(decoded, matrix)


def test_several_matrices_share_one_stream():
    rng = np.random.default_rng(4)
    matrices = [quantised_dct(rng, 300, 20, 20.0), quantised_dct(rng, 300, 4, 3.0), np.zeros((2, 2), np.int64)]
    for decoded, matrix in zip(decode_matrices(encode_matrices(matrices)), matrices):
        np.testing.assert_array_equal(decoded, matrix)


def test_smaller_than_zstd_on_sparse_spectra():
    """The reason the coder exists: low-frequency structure that zstd's byte view cannot see."""
    q = quantised_dct(np.random.default_rng(5), 1000, 30, 40.0)
    assert 0.01 < np.count_nonzero(q) / q.size < 0.2
    assert len(encode_matrices([q])) < 0.9 * len(encode_sparse(q))


def clip_like_streams(seed, count):
    """(pose, root) matrix pairs of different lengths and steps, as an archive's clips."""
    rng = np.random.default_rng(seed)
    return [[quantised_dct(rng, int(n), 30, 60.0), quantised_dct(rng, int(n), 4, 20.0)]
            for n in rng.integers(100, 600, size=count)]


@pytest.mark.parametrize("matrix", list(sample_matrices()), ids=lambda m: f"{m.dtype}{m.shape}")
def test_round_trip_with_priors(matrix):
    priors = Priors.decode(Priors.train(clip_like_streams(7, 5)).encode())
    (decoded,) = decode_matrices(encode_matrices([matrix], priors), priors=priors)
    np.testing.assert_array_equal(decoded, matrix)


def test_priors_make_short_streams_smaller():
    """Models that start from what many clips taught them skip the learning each clip pays for."""
    priors = Priors.train(clip_like_streams(8, 40))
    held_out = clip_like_streams(9, 20)  # not in the training set
    fresh = sum(len(encode_matrices(matrices)) for matrices in held_out)
    primed = sum(len(encode_matrices(matrices, priors)) for matrices in held_out)
    assert primed < 0.97 * fresh
    for matrices in held_out[:3]:
        for decoded, matrix in zip(decode_matrices(encode_matrices(matrices, priors), priors=priors), matrices):
            np.testing.assert_array_equal(decoded, matrix)


def test_primed_streams_need_their_priors():
    streams = clip_like_streams(10, 3)
    priors = Priors.train(streams)
    blob = encode_matrices(streams[0], priors)
    with pytest.raises(ValueError, match="priors"):
        decode_matrices(blob)
    pose_only = Priors.train([matrices[:1] for matrices in streams])  # no priors for the root matrix
    with pytest.raises(ValueError, match="no priors for coefficient matrix 1"):
        decode_matrices(blob, priors=pose_only)
    table = priors.encode()
    for damaged in (table[:-1], table + b"\x00", b"\x09" + table[1:], b""):
        with pytest.raises(ValueError):
            Priors.decode(damaged)


def test_auto_coder_stores_priors_only_where_they_pay():
    rng = np.random.default_rng(12)
    coded = {f"clip/{i:05d}": CodedClip(0.5, quantised_dct(rng, n, 40, 60.0), 0.5, quantised_dct(rng, n, 4, 20.0))
             for i, n in enumerate(rng.integers(200, 800, size=40))}
    many = {name: clip.payload("context") for name, clip in coded.items()}  # as encode_class holds them
    coder, streams = stored_streams(many, "auto")
    assert coder == "primed" and "priors" in streams
    assert sum(map(len, streams.values())) < sum(map(len, many.values()))
    assert stored_streams(many, "context") == ("context", many)
    priors = Priors.decode(decode_bytes(streams["priors"]))
    for name, coded in coded.items():
        back = CodedClip.from_payload(streams[name], "primed", priors=priors)
        assert np.array_equal(back.pose_ints, coded.pose_ints) and np.array_equal(back.root_ints, coded.root_ints)
    one = dict(list(many.items())[:1])
    assert stored_streams(one, "auto")[0] == "context"  # 400 bytes of priors for one clip do not pay
    assert stored_streams(one, "primed")[0] == "primed"


def test_refuses_values_it_cannot_code():
    with pytest.raises(ValueError, match="2\\*\\*62"):
        encode_matrices([np.array([[2**62]])])
    with pytest.raises(ValueError, match="2-D"):
        encode_matrices([np.zeros(3, np.int64)])


def test_damage_is_detected_not_decoded_silently():
    q = quantised_dct(np.random.default_rng(6), 400, 12, 10.0)
    blob = encode_matrices([q])
    failures = 0
    for cut in range(len(blob)):
        with pytest.raises(ValueError):
            decode_matrices(blob[:cut])
    with pytest.raises(ValueError):
        decode_matrices(blob + b"\x00")
    for position in range(0, len(blob), 3):  # a flipped byte: an error, or (rarely) other values
        damaged = bytearray(blob)
        damaged[position] ^= 0x5A
        try:
            decoded = decode_matrices(bytes(damaged))
        except ValueError:
            failures += 1
            continue
        assert decoded[0].shape != q.shape or not np.array_equal(decoded[0], q)
    # the archive's CRC32 catches what slips through; most damage is caught here already
    assert failures > 0.5 * len(range(0, len(blob), 3))


@pytest.mark.parametrize("seed", range(5))
def test_range_coder_round_trips_modelled_and_direct_bits(seed):
    rng = np.random.default_rng(seed)
    kinds = rng.integers(0, 3, size=5000)
    bits = (rng.random(5000) < np.where(kinds == 0, 0.03, 0.6)).astype(int)
    values = rng.integers(0, 1 << 20, size=5000)
    encoder, models = Encoder(), new_models(3)
    for kind, bit, value in zip(kinds, bits, values):
        if kind == 2:
            encoder.direct(int(value), 20)
        else:
            encoder.bit(models, int(kind), int(bit))
    blob = encoder.finish()
    decoder, models = Decoder(blob), new_models(3)
    for kind, bit, value in zip(kinds, bits, values):
        if kind == 2:
            assert decoder.direct(20) == value
        else:
            assert decoder.bit(models, int(kind)) == bit
    decoder.finish()
