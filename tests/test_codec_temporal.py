"""Tests for mocapzip.codec.temporal, in the style of PyWavelets' own tests."""

import json

import numpy as np
import pytest

from mocapzip.stages import get_stage
from mocapzip.codec.temporal import (DctTransform, DwtTransform, EdgeDctTransform, IdentityTransform, PolyTransform,
                                     gram_polynomials, segment_bounds)

SIZES = [1, 2, 3, 7, 64, 100, 1000, 4097]
DTYPES = [np.float32, np.float64]
WAVELETS = ["haar", "db2", "db4", "sym8", "coif3"]
TOLERANCE = {np.float32: 1e-5, np.float64: 1e-12}


def transforms():
    return ([DctTransform(), IdentityTransform(), PolyTransform(), PolyTransform(knot_spacing=16)]
            + [DwtTransform(name) for name in WAVELETS])


def invertible():
    """With the transforms that are not orthonormal: `dct-edges` at its default and on fewer or more
    columns than a matrix has."""
    return transforms() + [EdgeDctTransform(), EdgeDctTransform(1), EdgeDctTransform(2), EdgeDctTransform(0)]


def curves(n_frames, dtype, n_curves=3, seed=0):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.normal(size=(n_frames, n_curves)), axis=0).astype(dtype)


@pytest.mark.parametrize("transform", invertible(), ids=repr)
@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("n_frames", SIZES)
def test_perfect_reconstruction_with_t_coefficients(transform, dtype, n_frames):
    x = curves(n_frames, dtype)
    coefs = transform.forward(x)
    assert coefs.shape == x.shape
    assert coefs.dtype == dtype
    restored = transform.inverse(coefs, n_frames)
    assert restored.dtype == dtype
    scale = max(1.0, np.abs(x).max())
    np.testing.assert_allclose(restored, x, rtol=0, atol=TOLERANCE[dtype] * scale)


@pytest.mark.parametrize("transform", transforms(), ids=repr)
@pytest.mark.parametrize("n_frames", SIZES)
def test_orthonormal_transforms_preserve_energy(transform, n_frames):
    assert transform.orthonormal
    x = curves(n_frames, np.float64)
    coefs = transform.forward(x)
    assert np.sum(coefs**2) == pytest.approx(np.sum(x**2), rel=1e-10)


@pytest.mark.parametrize("transform", transforms(), ids=repr)
def test_coefficient_error_equals_curve_error(transform):
    """The property quantisation relies on: errors keep their energy through inverse()."""
    x = curves(100, np.float64)
    coefs = transform.forward(x)
    noise = np.random.default_rng(1).normal(scale=0.01, size=coefs.shape)
    error = transform.inverse(coefs + noise, 100) - x
    assert np.sum(error**2) == pytest.approx(np.sum(noise**2), rel=1e-9)


def test_biorthogonal_wavelet_reconstructs_but_is_not_orthonormal():
    transform = DwtTransform("bior2.2")
    assert not transform.orthonormal
    x = curves(100, np.float64)
    np.testing.assert_allclose(transform.inverse(transform.forward(x), 100), x, atol=1e-10)


@pytest.mark.parametrize("level", [0, 1, 4, 30])
@pytest.mark.parametrize("n_frames", [1, 2, 3, 7, 100])
def test_explicit_levels(level, n_frames):
    transform = DwtTransform("db4", level=level)
    x = curves(n_frames, np.float64)
    coefs = transform.forward(x)
    assert coefs.shape == x.shape
    np.testing.assert_allclose(transform.inverse(coefs, n_frames), x, atol=1e-10)
    assert np.sum(coefs**2) == pytest.approx(np.sum(x**2), rel=1e-10)


def test_level_zero_is_identity():
    x = curves(50, np.float64)
    np.testing.assert_array_equal(DwtTransform("db4", level=0).forward(x), x)


def test_smooth_curves_compact_energy():
    """Why these transforms exist: a smooth curve's energy ends up in few coefficients."""
    t = np.linspace(0, 1, 256)[:, None]
    x = np.sin(2 * np.pi * t) + 0.5 * t
    for transform in (DctTransform(), DwtTransform("db4")):
        energy = np.sort(transform.forward(x)[:, 0] ** 2)[::-1]
        assert energy[:16].sum() > 0.999 * energy.sum()


def test_one_dimensional_input():
    x = curves(100, np.float64)[:, 0]
    for transform in invertible():
        coefs = transform.forward(x)
        assert coefs.shape == (100,)
        np.testing.assert_allclose(transform.inverse(coefs, 100), x, atol=1e-10)


def test_inverse_rejects_wrong_length():
    for transform in invertible():
        with pytest.raises(ValueError):
            transform.inverse(np.zeros((10, 2)), 11)


@pytest.mark.parametrize("transform", invertible() + [DwtTransform("sym8", level=3)], ids=repr)
def test_config_round_trip(transform):
    config = json.loads(json.dumps(transform.get_config()))
    rebuilt = get_stage("transform", config)
    assert type(rebuilt) is type(transform)
    assert rebuilt.get_config() == transform.get_config()
    x = curves(100, np.float64)
    np.testing.assert_array_equal(rebuilt.forward(x), transform.forward(x))


def test_invalid_parameters():
    with pytest.raises(ValueError):
        DwtTransform("not-a-wavelet")
    with pytest.raises(ValueError):
        DwtTransform("db4", level=-1)
    for spacing in (0, 513, 1.5, True, "120"):  # 512 bounds a segment's matrix: an archive cannot ask for more
        with pytest.raises(ValueError):
            PolyTransform(knot_spacing=spacing)
    for columns in (-1, 65, 2.0, True, "6"):
        with pytest.raises(ValueError):
            EdgeDctTransform(edge_columns=columns)


@pytest.mark.parametrize("n_points", [1, 2, 5, 64, 181, 768])
def test_gram_polynomials_are_orthonormal_polynomials_by_degree(n_points):
    """Column k is the degree-k polynomial over the points, orthonormal, leading coefficient
    positive: the columns up to k span exactly the polynomials of degree k or less."""
    q = gram_polynomials(n_points)
    np.testing.assert_allclose(q.T @ q, np.eye(n_points), rtol=0, atol=1e-12)
    t = np.linspace(-1.0, 1.0, n_points) if n_points > 1 else np.zeros(1)
    for degree in range(min(n_points, 12)):
        fit = np.polynomial.Polynomial.fit(t, q[:, degree], degree, domain=[-1, 1])
        np.testing.assert_allclose(fit(t), q[:, degree], rtol=0, atol=1e-10)
        if degree:
            assert fit.coef[degree] > 0  # the sign convention a decoder reproduces
            lower = np.polynomial.Polynomial.fit(t, q[:, degree], degree - 1, domain=[-1, 1])
            assert np.abs(lower(t) - q[:, degree]).max() > 1e-3  # of degree k, not less


@pytest.mark.parametrize("n_frames", [1, 59, 60, 61, 179, 180, 1000, 4097])
def test_poly_knots_cover_the_frames_in_near_equal_segments(n_frames):
    bounds = segment_bounds(n_frames, 120)
    lengths = np.diff(bounds)
    assert bounds[0] == 0 and bounds[-1] == n_frames and len(lengths) == max(1, round(n_frames / 120))
    assert lengths.max() - lengths.min() <= 1 and lengths.max() <= 1.5 * 120 + 1


def test_poly_band_is_a_least_squares_polynomial_fit_per_segment():
    """Keeping the first rows (the band) keeps the same low degrees in every segment: the
    decoded curve is each segment's least-squares polynomial of that degree."""
    x = curves(310, np.float64, n_curves=2, seed=3)
    transform = PolyTransform(knot_spacing=100)
    bounds = segment_bounds(310, 100)
    degree = 2
    kept = transform.forward(x)
    kept[(degree + 1) * (len(bounds) - 1):] = 0.0
    smoothed = transform.inverse(kept, 310)
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        t = np.arange(hi - lo)
        for column in range(2):
            fit = np.polynomial.Polynomial.fit(t, x[lo:hi, column], degree)
            np.testing.assert_allclose(smoothed[lo:hi, column], fit(t), rtol=0, atol=1e-9)


@pytest.mark.parametrize("n_frames", SIZES)
@pytest.mark.parametrize("frames", [slice(None), slice(None, None, 8), slice(3, None, 5)])
def test_dct_synthesis_is_the_inverse_of_unit_coefficients(n_frames, frames):
    transform = DctTransform()
    rows = min(n_frames, 40)
    expected = transform.inverse(np.eye(n_frames, rows), n_frames)[frames]
    np.testing.assert_allclose(transform.synthesis(n_frames, rows, frames), expected, rtol=0, atol=1e-14)


def test_poly_takes_integer_curves_as_floats():
    """Integers in (a test's, a user's): the coefficients are floats, not truncated to integers."""
    x = np.arange(30).reshape(10, 3) ** 2
    np.testing.assert_allclose(PolyTransform(knot_spacing=4).forward(x),
                               PolyTransform(knot_spacing=4).forward(x.astype(np.float64)), rtol=0, atol=1e-12)


@pytest.mark.parametrize("n_frames", [3, 7, 64, 100, 1000])
@pytest.mark.parametrize("frames", [slice(None), slice(None, None, 8), slice(3, None, 5)])
def test_dct_edges_synthesis_is_the_inverse_of_unit_coefficients(n_frames, frames):
    transform = EdgeDctTransform(edge_columns=1)
    rows = min(n_frames, 40)
    unit = np.eye(n_frames, rows)
    for edge, column in ((True, 0), (False, 1)):  # column 0 is coded by its ends, column 1 as by the DCT
        coefs = np.zeros((n_frames, 2, rows))
        coefs[:, column] = unit
        expected = np.stack([transform.inverse(coefs[..., r], n_frames)[frames, column] for r in range(rows)], axis=1)
        np.testing.assert_allclose(transform.synthesis(n_frames, rows, frames, edge=edge), expected, rtol=0,
                                   atol=1e-12)


def test_dct_edges_first_rows_are_the_line_through_the_ends():
    x = curves(50, np.float64, n_curves=2)
    coefs = EdgeDctTransform(edge_columns=2).forward(x)
    coefs[2:] = 0
    line = EdgeDctTransform(edge_columns=2).inverse(coefs, 50)
    np.testing.assert_allclose(line[[0, -1]], x[[0, -1]], atol=1e-12)
    np.testing.assert_allclose(np.diff(line, 2, axis=0), 0, atol=1e-12)


def test_what_a_band_leaves_out_piles_up_at_the_dct_s_ends_but_not_at_dct_edges():
    """Why `dct-edges`: a smooth curve whose slope at the ends is not 0, its band cut at 12 of 256
    rows. The DCT's error at the first and last 2 frames is over 6x its mean; coded by its ends,
    the error there is under half the mean, and the whole error smaller."""
    t = np.linspace(0, 1, 256)[:, None]
    x = np.sin(2 * np.pi * 1.3 * t + 0.4) + 0.7 * t
    errors = {}
    for transform in (DctTransform(), EdgeDctTransform(edge_columns=1)):
        coefs = transform.forward(x)
        coefs[12:] = 0
        error = np.abs(transform.inverse(coefs, 256) - x)[:, 0]
        errors[transform.codec_id] = (np.r_[error[:2], error[-2:]].mean() / error.mean(), error.mean())
    assert errors["dct"][0] > 6 and errors["dct-edges"][0] < 0.5
    assert errors["dct-edges"][1] < errors["dct"][1] / 4
