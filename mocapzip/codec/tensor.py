"""N-mode SVD of a motion tensor (Krüger et al. 2007, seed 002, section 2, after De Lathauwer et al.).

A class of motions warped to one length is a tensor: frames x DOFs x natural modes (actor,
style, repetition...). Its N-mode SVD is a core tensor and one orthonormal matrix per mode; keeping
the first r_k columns of mode k's matrix (and the matching slices of the core) reduces the model
along that mode alone. HOSVD takes each mode's leading singular vectors of the tensor unfolded
along it; HOOI then refines them in turn, each against the tensor projected on the others, which
never fits worse.
"""

from __future__ import annotations

import numpy as np


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
