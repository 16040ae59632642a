"""Tests for mocapzip.codec.pca: streamed covariance and the PCA basis fitted from it."""

import numpy as np
import pytest

from mocapzip.codec.pca import CovarianceAccumulator, PcaBasis


def correlated_rows(rng, n=300, dim=6, offset=0.0):
    """Rows with distinct variances along random directions (so the basis is well defined)."""
    directions, _ = np.linalg.qr(rng.normal(size=(dim, dim)))
    scales = np.geomspace(10.0, 0.1, dim)
    return offset + rng.normal(size=(n, dim)) * scales @ directions.T


def fitted(rows):
    accumulator = CovarianceAccumulator(rows.shape[1])
    accumulator.add(rows)
    return accumulator, PcaBasis.fit(accumulator)


def test_matches_numpy_svd():
    rows = correlated_rows(np.random.default_rng(0))
    _, basis = fitted(rows)

    centred = rows - rows.mean(axis=0)
    _, singular_values, vt = np.linalg.svd(centred, full_matrices=False)
    np.testing.assert_allclose(basis.mean, rows.mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(basis.variances, singular_values**2 / len(rows), rtol=1e-10)
    expected = vt.T * np.sign(vt.T[np.argmax(np.abs(vt.T), axis=0), np.arange(vt.shape[0])])
    np.testing.assert_allclose(basis.components, expected, atol=1e-9)


def test_covariance_is_population_covariance():
    rows = correlated_rows(np.random.default_rng(1))
    accumulator, _ = fitted(rows)
    np.testing.assert_allclose(accumulator.covariance, np.cov(rows.T, bias=True), rtol=1e-10)
    assert accumulator.count == len(rows)


def test_merge_equals_single_accumulator():
    rows = correlated_rows(np.random.default_rng(2), n=500)
    whole, _ = fitted(rows)
    first = CovarianceAccumulator(rows.shape[1])
    second = CovarianceAccumulator(rows.shape[1])
    first.add(rows[:123])
    second.add(rows[123:400])
    second.add(rows[400:])
    first.merge(second)
    assert first.count == whole.count
    np.testing.assert_allclose(first.mean, whole.mean, rtol=1e-12)
    np.testing.assert_allclose(first.covariance, whole.covariance, rtol=1e-10, atol=1e-12)


def test_merge_with_empty_accumulators():
    rows = correlated_rows(np.random.default_rng(3), n=50)
    accumulator, _ = fitted(rows)
    empty = CovarianceAccumulator(rows.shape[1])
    accumulator.merge(empty)
    empty.merge(accumulator)
    np.testing.assert_allclose(empty.covariance, accumulator.covariance, rtol=1e-12)


def test_stable_with_large_offset():
    """Positions near 1e4 with variances near 1e-6 keep their precision."""
    rng = np.random.default_rng(4)
    small = correlated_rows(rng, n=1000, dim=4) * 1e-4
    rows = 1e4 + small
    accumulator = CovarianceAccumulator(4)
    for batch in np.array_split(rows, 7):
        accumulator.add(batch)
    reference = np.cov((rows - 1e4).T, bias=True)
    np.testing.assert_allclose(accumulator.covariance, reference, rtol=1e-6)

    # The textbook formula E[x x^T] - mean mean^T loses these digits entirely.
    naive = rows.T @ rows / len(rows) - np.outer(rows.mean(axis=0), rows.mean(axis=0))
    assert np.abs(naive - reference).max() > 1e-3 * np.abs(reference).max()


def test_full_projection_reconstructs_exactly():
    rows = correlated_rows(np.random.default_rng(5))
    _, basis = fitted(rows)
    coordinates = basis.project(rows, rows.shape[1])
    assert coordinates.shape == rows.shape
    np.testing.assert_allclose(basis.reconstruct(coordinates), rows, atol=1e-10)


@pytest.mark.parametrize("q", [0, 1, 3, 6])
def test_residual_energy_is_squared_reconstruction_error(q):
    rows = correlated_rows(np.random.default_rng(6))
    _, basis = fitted(rows)
    error = rows - basis.reconstruct(basis.project(rows, q))
    assert basis.residual_energy(q) == pytest.approx(np.sum(error**2), rel=1e-9, abs=1e-9)


def test_sorted_and_sign_convention():
    rows = correlated_rows(np.random.default_rng(7))
    _, basis = fitted(rows)
    assert np.all(np.diff(basis.variances) <= 0)
    columns = np.arange(basis.components.shape[1])
    largest = basis.components[np.argmax(np.abs(basis.components), axis=0), columns]
    assert np.all(largest > 0)
    # Same statistics, same basis: flipping the data does not flip the components.
    _, flipped = fitted(-rows)
    np.testing.assert_allclose(np.abs(flipped.components), np.abs(basis.components), atol=1e-9)
    assert np.all(flipped.components[np.argmax(np.abs(flipped.components), axis=0), columns] > 0)


def test_invalid_use():
    accumulator = CovarianceAccumulator(3)
    with pytest.raises(ValueError):
        accumulator.mean
    with pytest.raises(ValueError):
        accumulator.add(np.zeros((4, 2)))
    with pytest.raises(ValueError):
        accumulator.merge(CovarianceAccumulator(2))
    with pytest.raises(ValueError):
        CovarianceAccumulator(0)
