"""N-mode SVD of a motion tensor (Krüger et al. 2007, seed 002, section 2, after De Lathauwer et al.).

A class of motions warped to one length is a tensor: frames x DOFs x natural modes (actor,
style, repetition...). Its N-mode SVD is a core tensor and one orthonormal matrix per mode; keeping
the first r_k columns of mode k's matrix (and the matching slices of the core) reduces the model
along that mode alone. HOSVD takes each mode's leading singular vectors of the tensor unfolded
along it; HOOI then refines them in turn, each against the tensor projected on the others, which
never fits worse.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np

from mocapzip.codec.entropy.coefficients import check_matrix_shape, decode_matrices, encode_matrices
from mocapzip.codec.entropy.zstd import ByteReader, write_varint
from mocapzip.limits import MAX_TENSOR_MODEL_NUMBERS
from mocapzip.motion.timewarp import Warping


def unfold(tensor: np.ndarray, mode: int) -> np.ndarray:
    """(I_mode, product of the other sizes): the mode's fibres as columns."""
    return np.moveaxis(tensor, mode, 0).reshape(tensor.shape[mode], -1)


def mode_product(tensor: np.ndarray, matrix: np.ndarray, mode: int) -> np.ndarray:
    """tensor x_mode matrix: every mode-`mode` fibre multiplied by `matrix` (J x I_mode)."""
    return np.moveaxis(np.tensordot(matrix, tensor, axes=(1, mode)), 0, mode)


def hosvd(tensor: np.ndarray, ranks) -> tuple[np.ndarray, list[np.ndarray]]:
    """(core, factors): factor k is the first ranks[k] left singular vectors of the mode-k unfolding,
    and core = tensor x_1 U_1^T ... x_N U_N^T."""
    _check_ranks(tensor, ranks)
    factors = [_leading(unfold(tensor, k), r) for k, r in enumerate(ranks)]
    return project(tensor, factors), factors


def hooi(tensor: np.ndarray, ranks, iterations: int = 10, tolerance: float = 1e-10) -> tuple[np.ndarray, list[np.ndarray]]:
    """`hosvd` refined by higher-order orthogonal iteration: each factor in turn becomes the leading
    singular vectors of the tensor projected on all the other factors. Stops after `iterations`
    sweeps, or when a sweep improves the core's norm (the fit) by less than `tolerance`, relative."""
    core, factors = hosvd(tensor, ranks)
    fit = np.linalg.norm(core)
    for _ in range(iterations):
        for k, r in enumerate(ranks):
            others = tensor
            for j, factor in enumerate(factors):
                if j != k:
                    others = mode_product(others, factor.T, j)
            factors[k] = _leading(unfold(others, k), r)
        core = project(tensor, factors)
        previous, fit = fit, np.linalg.norm(core)
        if fit - previous <= tolerance * max(previous, 1e-300):
            break
    return core, factors


def project(tensor: np.ndarray, factors: list[np.ndarray]) -> np.ndarray:
    """The core of `tensor` for orthonormal `factors`: tensor x_k U_k^T for every mode k."""
    for k, factor in enumerate(factors):
        tensor = mode_product(tensor, factor.T, k)
    return tensor


def reconstruct(core: np.ndarray, factors: list[np.ndarray]) -> np.ndarray:
    """core x_1 U_1 ... x_N U_N: the tensor the model stands for."""
    for k, factor in enumerate(factors):
        core = mode_product(core, factor, k)
    return core


def stored_numbers(shape, ranks) -> int:
    """Numbers a model of these ranks stores: the core and every factor."""
    return int(np.prod(ranks)) + sum(size * r for size, r in zip(shape, ranks))


def _leading(matrix: np.ndarray, count: int) -> np.ndarray:
    """The first `count` left singular vectors (all of U where the matrix has fewer columns than that)."""
    return np.linalg.svd(matrix, full_matrices=count > min(matrix.shape))[0][:, :count]


def _check_ranks(tensor: np.ndarray, ranks) -> None:
    if len(ranks) != tensor.ndim or any(not 1 <= r <= n for r, n in zip(ranks, tensor.shape)):
        raise ValueError(f"ranks {tuple(ranks)} for a tensor of shape {tensor.shape}: one per mode, 1 to its size")


# ------------------------------------------------------------------------ the stored model

FACTOR_STEP = 2.0 ** -9  # factors are orthonormal: entries within [-1, 1], stored to about 1/500
MEAN_STEP_CM = 1e-3  # as a class basis's mean (`codec.basis.MEAN_STEP_CM`)


@dataclass
class TensorModel:
    """A class's motions warped to one length, as `--model tensor` stores them (`tensor/NNNN`):
    their mean pose, and the N-mode SVD of the rest, frames x pose values x natural modes.

    It predicts each clip (`warped`, then put back on the clip's own timeline by its warping
    path); the clip's stream codes only what the prediction misses, so a model that predicts
    badly costs bytes, never error.
    """

    mean: np.ndarray  # (M,) weighted pose
    core: np.ndarray  # (r_frames, r_values, r_1 ... r_K)
    factors: list[np.ndarray]  # (L, r_frames), (M, r_values), then (levels_k, r_k) per natural mode
    core_step: float

    @classmethod
    def quantised(cls, mean: np.ndarray, core: np.ndarray, factors: list[np.ndarray], core_step: float) -> "TensorModel":
        """The model as the archive stores it, so that the encoder predicts what the decoder will."""
        model = cls(mean, core, factors, float(np.float32(core_step)))
        return cls.decode(model.encode(), model.shape)

    @property
    def shape(self) -> tuple[int, ...]:
        """(L, M, levels_1 .. levels_K): the class's warped tensor, which the model reduces."""
        return tuple(factor.shape[0] for factor in self.factors)

    def warped(self, at: tuple[int, ...]) -> np.ndarray:
        """(L, M): the prediction of the clip at levels `at` of the natural modes, on the warped timeline.
        The core is reduced along the natural modes (last first), then U_frames @ G @ U_values^T + mean."""
        if len(at) != len(self.factors) - 2:
            raise ValueError(f"{len(at)} levels for {len(self.factors) - 2} natural modes")
        reduced = self.core
        for k in range(len(at) - 1, -1, -1):
            reduced = reduced @ self.factors[2 + k][at[k]]
        return self.factors[0] @ reduced @ self.factors[1].T + self.mean

    def encode(self) -> bytes:
        """u8 K, varints L, M, levels_1..K, then r_frames, r_values, r_1..K, f32 core step, then one
        matrices stream: the mean (M x 1, MEAN_STEP_CM), the core (r_frames x the rest, C order)
        and each factor (FACTOR_STEP)."""
        header = bytearray([len(self.factors) - 2])
        for size in [factor.shape[0] for factor in self.factors] + list(self.core.shape):
            write_varint(header, size)
        header += struct.pack("<f", self.core_step)
        core = np.round(self.core / np.float64(self.core_step)).astype(np.int64)
        matrices = [np.round(self.mean / MEAN_STEP_CM).astype(np.int64)[:, None], core.reshape(core.shape[0], -1)]
        matrices += [np.round(factor / FACTOR_STEP).astype(np.int64) for factor in self.factors]
        return bytes(header) + encode_matrices(matrices)

    @classmethod
    def decode(cls, blob: bytes, shape: tuple[int, ...]) -> "TensorModel":
        """Inverse of `encode`, for a class of `shape` (`TensorModel.shape`: its longest clip's
        frames, its basis's pose values, its grid's levels, as meta and the class stream say).
        The blob may come from anyone: its sizes must be `shape`, and its ranks and all it stores
        within the limits (`check_model_sizes`), before anything is decoded."""
        reader = ByteReader(bytes(blob))
        modes = reader.take(1)[0]
        if modes != len(shape) - 2:
            raise ValueError(f"{modes} natural modes, its class has {len(shape) - 2}")
        sizes = [reader.varint() for _ in range(modes + 2)]
        ranks = [reader.varint() for _ in range(modes + 2)]
        (core_step,) = struct.unpack("<f", reader.take(4))
        if sizes != list(shape):
            raise ValueError(f"sizes {sizes}, where its class has {list(shape)} (frames of its longest clip, "
                             "pose values, each mode's levels)")
        if not (np.isfinite(core_step) and core_step > 0):
            raise ValueError(f"core step {core_step}: not a model")
        check_model_sizes(sizes, ranks)
        shapes = [(sizes[1], 1), (ranks[0], math.prod(ranks[1:]))] + list(zip(sizes, ranks))
        mean, core, *factors = decode_matrices(reader.take(reader.remaining()), shapes)
        if len(factors) != len(sizes):
            raise ValueError(f"{len(factors) + 2} matrices in a tensor model, expected {len(sizes) + 2}")
        return cls(mean[:, 0] * MEAN_STEP_CM, core.reshape(ranks).astype(np.float64) * np.float64(core_step),
                   [factor.astype(np.float64) * FACTOR_STEP for factor in factors], float(core_step))


def check_model_sizes(sizes, ranks) -> None:
    """ValueError unless a model of these sizes and ranks is one a reader takes: each rank 1 to its
    size, each matrix it stores and the prediction it makes (L x M) within the matrix limits, and
    all it stores within MAX_TENSOR_MODEL_NUMBERS (Python ints: no overflow)."""
    if any(not 1 <= r <= n for r, n in zip(ranks, sizes)):
        raise ValueError(f"ranks {ranks} for sizes {sizes}: not a model")
    check_matrix_shape(sizes[0], sizes[1])  # the prediction it makes: bounded before it is made
    for rows, columns in zip(sizes, ranks):  # each factor, then the core
        check_matrix_shape(rows, columns)
    check_matrix_shape(ranks[0], math.prod(ranks[1:]))
    numbers = sizes[1] + stored_numbers(sizes, ranks)  # the mean, the core and the factors
    if numbers > MAX_TENSOR_MODEL_NUMBERS:
        raise ValueError(f"a model of {numbers:,} numbers, more than the "
                         f"{MAX_TENSOR_MODEL_NUMBERS:,} a reader takes")


def prediction(model: TensorModel, at: tuple[int, ...], path: np.ndarray) -> np.ndarray:
    """(F, M): the model's clip at levels `at`, each frame of the clip the mean of the reference
    frames its warping path matches to it (`Warping.carried`): what the decoder adds to its poses."""
    return Warping(path, 0.0, 0).carried(model.warped(at), onto=1)
