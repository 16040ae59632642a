"""Principal component analysis from streamed statistics.

A motion database can be larger than memory, so the PCA is fitted from
running statistics instead of from the data matrix: `CovarianceAccumulator`
sees the frames batch by batch (or per worker, then merged), and `PcaBasis`
is fitted from its mean and covariance.

Numerical stability: positions are often around 1000 cm with millimetre
motion, so the textbook "sum of squares minus squared sum" loses every
significant digit of the variance.  The accumulator instead keeps the mean
and the scatter about the mean (sum of outer products of centred rows) and
combines batches with Chan et al.'s parallel update:

    n = n_a + n_b,   delta = mean_b - mean_a
    mean    = mean_a + delta * n_b / n
    scatter = scatter_a + scatter_b + outer(delta, delta) * n_a * n_b / n

Each batch's own scatter is computed about its own mean, so no large
offsets are ever squared.
"""

import numpy as np

__all__ = ["CovarianceAccumulator", "PcaBasis"]


class CovarianceAccumulator:
    """Running count, mean and scatter of rows of dimension `dim`."""

    def __init__(self, dim: int):
        if dim < 1:
            raise ValueError(f"dim must be positive, got {dim}")
        self.dim = dim
        self.count = 0
        self._mean = np.zeros(dim)
        self._scatter = np.zeros((dim, dim))

    def add(self, rows) -> None:
        """Add a batch of rows (N x dim, or a single row of length dim)."""
        rows = np.atleast_2d(np.asarray(rows, np.float64))
        if rows.ndim != 2 or rows.shape[1] != self.dim:
            raise ValueError(f"expected rows of length {self.dim}, got shape {rows.shape}")
        if rows.shape[0] == 0:
            return
        mean = rows.mean(axis=0)
        centred = rows - mean
        self._combine(rows.shape[0], mean, centred.T @ centred)

    def merge(self, other: "CovarianceAccumulator") -> None:
        """Add everything `other` has seen (for example from another worker)."""
        if other.dim != self.dim:
            raise ValueError(f"cannot merge dimension {other.dim} into {self.dim}")
        if other.count:
            self._combine(other.count, other._mean, other._scatter)

    def _combine(self, count: int, mean: np.ndarray, scatter: np.ndarray) -> None:
        total = self.count + count
        delta = mean - self._mean
        cross = np.outer(delta, delta) * (self.count * count / total)
        self._scatter = self._scatter + scatter + cross
        self._mean = self._mean + delta * (count / total)
        self.count = total

    @property
    def mean(self) -> np.ndarray:
        self._require_data()
        return self._mean.copy()

    @property
    def covariance(self) -> np.ndarray:
        """Population covariance (scatter / count): eigenvalue * count = residual energy."""
        self._require_data()
        return self._scatter / self.count

    def _require_data(self) -> None:
        if self.count == 0:
            raise ValueError("no rows have been added")


class PcaBasis:
    """Mean, principal directions and their variances, fitted from a `CovarianceAccumulator`.

    `components` is dim x dim with one direction per column, sorted by
    decreasing variance.  Eigenvectors are only defined up to sign, so each
    column is flipped to make its largest-magnitude entry positive: the same
    data then always gives the same basis, and stored bases compare equal.
    """

    def __init__(self, mean, components, variances, count: int):
        self.mean = np.asarray(mean, np.float64)
        self.components = np.asarray(components, np.float64)
        self.variances = np.asarray(variances, np.float64)
        self.count = int(count)

    @classmethod
    def fit(cls, accumulator: CovarianceAccumulator) -> "PcaBasis":
        return cls.from_covariance(accumulator.mean, accumulator.covariance, accumulator.count)

    @classmethod
    def from_covariance(cls, mean, covariance, count: int) -> "PcaBasis":
        """The basis of a mean and covariance however they were summed (`fit`'s, or a weighted
        union of clips' statistics), sorted and signed by the one rule above."""
        variances, components = np.linalg.eigh(covariance)
        order = np.argsort(variances)[::-1]
        variances = np.maximum(variances[order], 0.0)  # rounding can give tiny negatives
        components = components[:, order]
        largest = np.argmax(np.abs(components), axis=0)
        signs = np.sign(components[largest, np.arange(components.shape[1])])
        return cls(mean, components * signs, variances, count)

    def project(self, rows, q: int) -> np.ndarray:
        """Coordinates of the rows (N x dim) on the first q components (N x q)."""
        return (np.asarray(rows, np.float64) - self.mean) @ self.components[:, :q]

    def reconstruct(self, coordinates) -> np.ndarray:
        """Rows (N x dim) from coordinates on the first coordinates.shape[1] components."""
        coordinates = np.asarray(coordinates, np.float64)
        return coordinates @ self.components[:, : coordinates.shape[1]].T + self.mean

    def residual_energy(self, q: int) -> float:
        """Sum of squared reconstruction errors over the fitted rows when keeping q components."""
        return float(self.variances[q:].sum() * self.count)
