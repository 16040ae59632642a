"""N-mode SVD (mocapzip.codec.tensor) on tensors whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from mocapzip.codec.tensor import hooi, hosvd, mode_product, project, reconstruct, stored_numbers, unfold


def orthonormal(rng, rows: int, columns: int) -> np.ndarray:
    return np.linalg.qr(rng.normal(size=(rows, columns)))[0]


def low_rank(shape, ranks, seed=0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return reconstruct(rng.normal(size=ranks), [orthonormal(rng, n, r) for n, r in zip(shape, ranks)])


def test_a_mode_product_multiplies_the_unfolding():
    rng = np.random.default_rng(1)
    tensor, matrix = rng.normal(size=(4, 5, 3, 2)), rng.normal(size=(6, 3))
    product = mode_product(tensor, matrix, 2)
    assert product.shape == (4, 5, 6, 2)
    np.testing.assert_allclose(unfold(product, 2), matrix @ unfold(tensor, 2), atol=1e-12)


@pytest.mark.parametrize("method", [hosvd, hooi])
def test_a_tensor_of_those_ranks_is_recovered_exactly(method):
    shape, ranks = (30, 12, 5, 3), (4, 3, 2, 2)
    tensor = low_rank(shape, ranks)
    core, factors = method(tensor, ranks)
    assert core.shape == ranks
    for factor, r in zip(factors, ranks):
        np.testing.assert_allclose(factor.T @ factor, np.eye(r), atol=1e-12)
    np.testing.assert_allclose(reconstruct(core, factors), tensor, atol=1e-10)
    np.testing.assert_allclose(project(tensor, factors), core, atol=1e-12)


def test_full_ranks_keep_everything():
    tensor = np.random.default_rng(2).normal(size=(7, 4, 3))
    np.testing.assert_allclose(reconstruct(*hosvd(tensor, tensor.shape)), tensor, atol=1e-12)


def test_hooi_fits_no_worse_than_hosvd_and_truncation_costs_more_as_ranks_fall():
    tensor = low_rank((40, 15, 6, 3), (6, 5, 4, 3), seed=3) + 0.01 * np.random.default_rng(4).normal(size=(40, 15, 6, 3))
    errors = []
    for ranks in [(6, 5, 4, 3), (5, 4, 3, 2), (3, 3, 2, 2), (1, 1, 1, 1)]:
        by_hosvd = np.linalg.norm(reconstruct(*hosvd(tensor, ranks)) - tensor)
        by_hooi = np.linalg.norm(reconstruct(*hooi(tensor, ranks)) - tensor)
        assert by_hooi <= by_hosvd * (1 + 1e-9)
        errors.append(by_hooi)
    assert errors == sorted(errors)


def test_a_tall_unfolding_still_gives_as_many_vectors_as_asked():
    tensor = np.random.default_rng(5).normal(size=(10, 2, 2))  # mode 0: 10 rows, 4 columns
    core, factors = hosvd(tensor, (6, 2, 2))
    assert factors[0].shape == (10, 6)
    np.testing.assert_allclose(reconstruct(core, factors), tensor, atol=1e-12)


def test_stored_numbers_are_the_core_and_the_factors():
    assert stored_numbers((100, 60, 15, 2), (10, 20, 5, 2)) == 10 * 20 * 5 * 2 + 100 * 10 + 60 * 20 + 15 * 5 + 2 * 2


def test_bad_ranks_are_refused():
    tensor = np.zeros((4, 3, 2))
    for ranks in [(4, 3), (0, 3, 2), (5, 3, 2)]:
        with pytest.raises(ValueError):
            hosvd(tensor, ranks)
