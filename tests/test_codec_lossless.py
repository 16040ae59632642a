"""Tests for mocapzip.codec.lossless: exact round trips of channel matrices from AMC text."""

from pathlib import Path

import numpy as np
import pytest

from mocapzip.codec.lossless import decode_channels, encode_channels

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
REAL_FILE = DATA / "cmu" / "07" / "07_01.amc"


def parse(texts):
    """What an AMC reader does with each token."""
    return np.vectorize(float, otypes=[np.float64])(texts)


def motion_like(rng, n_frames, n_channels):
    """Random-walk channels of very different magnitudes, some crossing zero."""
    steps = rng.normal(size=(n_frames, n_channels)) * np.geomspace(0.001, 2.0, n_channels)
    offsets = rng.choice([0.0, 0.5, 9.9, -37.0, 150.0, 1234.5], size=n_channels)
    return offsets + np.cumsum(steps, axis=0)


def cmu_style(values):
    """%g with 6 significant digits, as CMU and HDM05 files are written."""
    return np.vectorize(lambda v: f"{v:.6g}", otypes=[object])(values)


def fixed_style(values):
    """Six fixed decimals, as Vicon Blade writes (including -0.000000)."""
    return np.vectorize(lambda v: f"{v:.6f}", otypes=[object])(values)


def round_trip(values):
    decoded = decode_channels(encode_channels(values))
    assert decoded.dtype == np.float64
    assert decoded.shape == values.shape
    # Bit for bit: this also keeps -0.0, NaN and every formatting of the values.
    np.testing.assert_array_equal(decoded.view(np.int64), values.view(np.int64))
    return decoded


def add_awkward_channels(rng, values):
    """Columns that exercise every path: constant, duplicate, tiny noise, zeros of both signs."""
    n_frames = values.shape[0]
    tiny = rng.normal(scale=1e-14, size=n_frames)
    tiny[::7] = 0.0
    signed_zeros = np.where(rng.random(n_frames) < 0.5, -0.0, 0.0)
    crossing = np.linspace(-3, 3, n_frames) ** 3
    return np.column_stack(
        [values, np.full(n_frames, 7.12502), values[:, 0], tiny, signed_zeros, crossing]
    )


@pytest.mark.parametrize("n_frames", [1, 2, 3, 50, 400])
def test_cmu_style_text_round_trips(n_frames):
    rng = np.random.default_rng(n_frames)
    texts = cmu_style(add_awkward_channels(rng, motion_like(rng, n_frames, 12)))
    decoded = round_trip(parse(texts))
    assert np.all(parse(cmu_style(decoded)) == parse(texts))


@pytest.mark.parametrize("n_frames", [1, 2, 3, 50, 400])
def test_fixed_decimal_text_round_trips(n_frames):
    rng = np.random.default_rng(100 + n_frames)
    values = add_awkward_channels(rng, motion_like(rng, n_frames, 12))
    texts = fixed_style(values)
    assert "-0.000000" in set(texts.ravel())
    decoded = round_trip(parse(texts))
    assert np.all(np.round(decoded, 6) == np.round(parse(texts), 6))
    assert np.array_equal(fixed_style(decoded), texts)


def test_mixed_precision_and_magnitudes():
    texts = np.array(
        [
            ["3.64024e-015", "-2.01677", "136.231", "0", "1.5e+20", "-0", "0.000001"],
            ["-1.76297e-014", "-2.06376", "99.9999", "0", "1.23457e+06", "-0", "-0.000000"],
            ["1.11071e-014", "9.99999", "100", "1e-300", "-7", "0", "12345.678901"],
            ["-3.59552e-014", "10.0001", "-100.001", "0", "5e-324", "-0", "0.1"],
        ]
    )
    round_trip(parse(texts))


def test_values_that_are_not_short_decimals():
    rng = np.random.default_rng(7)
    values = rng.normal(size=(60, 4)) * 100  # full 17-digit doubles
    values[5, 0] = np.nan
    values[6, 1] = np.inf
    values[7, 2] = -np.inf
    values[:, 3] = np.round(values[:, 3], 3)
    values[10, 3] = 1 / 3  # one stray value in an otherwise decimal channel
    round_trip(values)


def test_empty_shapes():
    round_trip(np.zeros((0, 5)))
    round_trip(np.zeros((10, 0)))
    round_trip(np.zeros((0, 0)))


def test_rejects_non_matrix():
    with pytest.raises(ValueError):
        encode_channels(np.zeros(5))


def test_corrupt_input_raises_value_error():
    rng = np.random.default_rng(8)
    values = parse(cmu_style(add_awkward_channels(rng, motion_like(rng, 30, 3))))
    blob = encode_channels(values)
    for position in range(0, len(blob), 3):
        damaged = blob[:position] + bytes([blob[position] ^ 0x04]) + blob[position + 1 :]
        try:
            decoded = decode_channels(damaged)
        except ValueError:
            continue
        assert np.array_equal(decoded.view(np.int64), values.view(np.int64))
    with pytest.raises(ValueError):
        decode_channels(blob[:-1])
    with pytest.raises(ValueError):
        decode_channels(blob + b"\x00")


def test_smaller_than_text():
    """5000 frames x 62 channels come back exactly in under 30 % of their text."""
    rng = np.random.default_rng(9)
    texts = cmu_style(motion_like(rng, 5000, 62))
    values = parse(texts)
    blob = encode_channels(values)
    decoded = decode_channels(blob)
    np.testing.assert_array_equal(decoded, values)
    text_bytes = sum(len(text) + 1 for text in texts.ravel())
    assert len(blob) < 0.3 * text_bytes


def read_amc_tokens(path):
    """Tiny AMC parser for this test: value tokens of every frame, in file order."""
    frames = []
    for line in path.read_text(encoding="latin-1").splitlines():
        line = line.strip()
        if not line or line[0] in "#:":
            continue
        if line.isdigit():
            frames.append([])
        elif frames:
            frames[-1].extend(line.split()[1:])
    return np.array(frames)


def test_real_cmu_file(shared_data):  # the fixture fails, never skips, when the data is missing
    tokens = read_amc_tokens(REAL_FILE)
    values = parse(tokens)
    blob = encode_channels(values)
    decoded = round_trip(values)
    assert np.all(parse(cmu_style(decoded)) == values)
    # Measured 37.9 kB for this 243 kB file (xz -9: 65.9 kB); guard against regressions.
    assert len(blob) < 0.2 * REAL_FILE.stat().st_size
