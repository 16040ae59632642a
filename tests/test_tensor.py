"""N-mode SVD (mocapzip.codec.tensor) on tensors whose answer is known."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from mocapzip.codec import tensor as tensor_codec
from mocapzip.codec.tensor import (TensorModel, hooi, hosvd, mode_product, prediction, project, reconstruct,
                                   stored_numbers, unfold)


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


# ------------------------------------------------------------------------ the stored model (--model tensor)

def stored_model(shape=(40, 9, 3, 2), ranks=(6, 4, 3, 2), core_step=0.01, seed=6) -> tuple[np.ndarray, TensorModel]:
    tensor = low_rank(shape, ranks, seed)
    mean = np.random.default_rng(seed).normal(size=shape[1]) * 10
    return tensor, TensorModel.quantised(mean, *hooi(tensor, ranks), core_step)


def test_a_stored_model_decodes_to_itself_and_predicts_each_place_of_its_grid():
    tensor, model = stored_model()
    again = TensorModel.decode(model.encode(), model.shape)
    assert again.encode() == model.encode()
    for a in range(3):
        for b in range(2):
            predicted = model.warped((a, b))
            np.testing.assert_array_equal(predicted, again.warped((a, b)))
            # quantised to steps of 0.01 (core) and 2^-9 (factors): close to the tensor's slice, not equal
            np.testing.assert_allclose(predicted, tensor[:, :, a, b] + model.mean, atol=0.05)
            assert not np.array_equal(predicted, tensor[:, :, a, b] + model.mean)


def test_the_prediction_follows_the_spec_order_of_products():
    """docs/format.md, `tensor/NNNN`: the core reduced along the last mode first, then U_frames @ G @ U_values^T."""
    _, model = stored_model()
    g = np.tensordot(np.tensordot(model.core, model.factors[3][1], axes=(3, 0)), model.factors[2][2], axes=(2, 0))
    np.testing.assert_allclose(model.warped((2, 1)), model.factors[0] @ g @ model.factors[1].T + model.mean,
                               atol=1e-9)


def test_a_prediction_is_carried_back_along_the_path():
    _, model = stored_model()
    warped = model.warped((0, 0))
    path = np.array([[0, 0], [1, 0], [2, 1]] + [[i, i - 1] for i in range(3, 40)])  # frames 0 and 1 onto clip frame 0
    clip = prediction(model, (0, 0), path)
    assert clip.shape == (39, 9)
    np.testing.assert_allclose(clip[0], (warped[0] + warped[1]) / 2)
    np.testing.assert_array_equal(clip[5], warped[6])


@pytest.mark.parametrize("damage", [
    lambda b: bytes([9]) + b[1:],  # 9 natural modes, where its class has 2 (and at most 8 are allowed)
    lambda b: bytes([3]) + b[1:],  # one more mode than its class has, and than the stream holds
    lambda b: b[:-3],  # cut short
])
def test_a_damaged_model_is_refused(damage):
    model = stored_model()[1]
    with pytest.raises((ValueError, EOFError)):
        TensorModel.decode(damage(model.encode()), model.shape)


def test_ranks_above_their_size_or_a_bad_step_are_refused_before_decoding():
    _, model = stored_model()
    blob = bytearray(model.encode())
    blob[5] = 50  # r_frames (after K and the four one-byte sizes 40, 9, 3, 2): above L = 40
    with pytest.raises(ValueError, match="not a model"):
        TensorModel.decode(bytes(blob), model.shape)
    blob = bytearray(model.encode())
    blob[9:13] = struct.pack("<f", -1.0)  # the core step
    with pytest.raises(ValueError, match="not a model"):
        TensorModel.decode(bytes(blob), model.shape)


@pytest.mark.parametrize("shape", [(41, 9, 3, 2), (40, 8, 3, 2), (40, 9, 2, 2), (40, 9, 3), (40, 9, 3, 2, 2)],
                         ids=["frames", "pose-values", "levels", "a-mode-fewer", "a-mode-more"])
def test_a_model_is_refused_unless_its_sizes_are_its_classs(shape):
    """A class's frames, pose values and levels are known (meta, the class stream) before its model is decoded."""
    _, model = stored_model()
    with pytest.raises(ValueError, match="its class has"):
        TensorModel.decode(model.encode(), shape)


def test_a_model_storing_more_numbers_than_a_reader_takes_is_refused_before_decoding(monkeypatch):
    """Each matrix within the matrix limits is not enough: together they are bounded too."""
    _, model = stored_model()  # 9 (mean) + 6*4*3*2 (core) + 40*6 + 9*4 + 3*3 + 2*2 (factors) = 442 numbers
    monkeypatch.setattr(tensor_codec, "MAX_TENSOR_MODEL_NUMBERS", 442)
    assert TensorModel.decode(model.encode(), model.shape).encode() == model.encode()
    monkeypatch.setattr(tensor_codec, "MAX_TENSOR_MODEL_NUMBERS", 441)
    with pytest.raises(ValueError, match="a model of 442 numbers, more than the 441 a reader takes"):
        TensorModel.decode(model.encode(), model.shape)
