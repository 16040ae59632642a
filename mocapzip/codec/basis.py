"""A class's mean pose and PCA basis as the archive stores them: the `class/NNNN` stream.

Layout (format 3 on; docs/format.md): `u32 M`, `u32 Q`, Q `f32` steps, then one "context"
matrices stream of the mean's integers (M x 1, units of MEAN_STEP_CM), each basis row's
reference offset (M x 1) and the basis integers less their reference row's (M x Q).
Formats 1 and 2's layouts are read by `mocapzip.legacy.streams`.
"""

from __future__ import annotations

import io
import struct
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mocapzip.codec.entropy.coefficients import check_matrix_shape, decode_matrices, encode_matrices, matrix_shapes

MEAN_STEP_CM = 1e-3  # the class mean is kept finely: its error repeats on every frame


@dataclass
class ClassBasis:
    """A class's mean pose and its first Q principal directions, as stored (quantised).

    Each direction j is stored on its own grid, steps[j]. A basis error d moves a pose by
    d times the coefficient, so directions with small coefficients (small variance) can be
    stored coarsely: `steps_for` makes that trade explicit.
    """

    mean: np.ndarray  # (M,)
    components: np.ndarray  # (M, Q)
    steps: np.ndarray  # (Q,) quantiser step of each stored direction

    @staticmethod
    def steps_for(variances: np.ndarray, error_cm: float, precision: float) -> np.ndarray:
        """Basis steps that add about `precision` x error_cm to a pose along each direction."""
        return precision * error_cm / np.sqrt(np.maximum(variances, (precision * error_cm) ** 2))

    @classmethod
    def quantised(cls, mean: np.ndarray, components: np.ndarray, steps: np.ndarray) -> "ClassBasis":
        """Round mean and components to what the archive stores, so encoding sees the decoder's basis."""
        return cls.decode(cls(mean, components, np.asarray(steps, np.float32)).encode())

    def integers(self) -> tuple[np.ndarray, np.ndarray]:
        """(mean integers, basis integers): what every layout stores."""
        ints = np.round(self.components / self.steps.astype("<f4").astype(np.float64)).astype(np.int64)
        return np.round(self.mean / MEAN_STEP_CM).astype(np.int64), ints

    def encode(self) -> bytes:
        """One range-coded stream of three matrices: the mean's integers, each basis row's
        reference row and the basis integers less their reference row's (`_reference_rows`);
        bases are too few to train priors on, so they are always coded "context"."""
        mean_ints, ints = self.integers()
        references = _reference_rows(ints)
        rows = np.arange(len(ints))
        residuals = ints - np.where(references[:, None] >= 0, ints[references], 0)
        offsets = np.where(references >= 0, rows - references, 0)  # 0: no reference
        return self.header() + encode_matrices([mean_ints[:, None], offsets[:, None], residuals])

    def header(self) -> bytes:
        out = io.BytesIO()
        out.write(struct.pack("<II", self.mean.size, self.components.shape[1]))
        out.write(self.steps.astype("<f4").tobytes())
        return out.getvalue()

    @classmethod
    def decode(cls, blob: bytes) -> "ClassBasis":
        """Inverse of `encode`; the declared m x q is checked against the limits before anything is allocated."""
        m, q, steps, pos = read_header(blob)
        expected = [(m, 1), (m, 1), (m, q)]
        stored = matrix_shapes(blob[pos:])  # checked before anything is decoded: a damaged shape must not allocate
        if stored != expected:
            raise ValueError(f"class basis matrices of shapes {stored} for a {m} x {q} basis")
        mean_ints, offsets, residuals = decode_matrices(blob[pos:], expected)
        return cls.from_integers(m, mean_ints, _undo_references(residuals, offsets.ravel()), steps)

    @classmethod
    def from_integers(cls, m: int, mean_ints: np.ndarray, ints: np.ndarray, steps: np.ndarray) -> "ClassBasis":
        """The decoder's basis: exactly `ints * step` per column, the mean in units of MEAN_STEP_CM."""
        q = len(steps)
        mean = mean_ints.reshape(m).astype(np.float64) * MEAN_STEP_CM
        components = ints.reshape(m, q).astype(np.float64) * steps.astype(np.float64)
        return cls(mean, components, steps.copy())

    @property
    def q(self) -> int:
        return self.components.shape[1]

    def project(self, poses: np.ndarray) -> np.ndarray:
        """Least-squares coefficients (the stored basis is only nearly orthonormal)."""
        return (poses - self.mean) @ self._projector

    @cached_property
    def _projector(self) -> np.ndarray:
        return np.linalg.pinv(self.components).T

    def reconstruct(self, coefficients: np.ndarray) -> np.ndarray:
        poses = coefficients @ self.components.T
        poses += self.mean  # in place: `mean + product` made a second array of a long clip's largest size
        return poses


def read_header(blob: bytes) -> tuple[int, int, np.ndarray, int]:
    """(M, Q, steps, offset of what follows) of a class stream of any format, M x Q checked first."""
    m, q = unpack("<II", blob, 0)
    check_matrix_shape(m, q)
    if len(blob) < 8 + 4 * q:
        raise ValueError(f"stream cut short: {q} steps declared")
    return m, q, np.frombuffer(blob, "<f4", q, 8).copy(), 8 + 4 * q


def unpack(layout: str, blob: bytes, offset: int) -> tuple:
    """struct.unpack_from that reports a stream cut short as ValueError, which callers catch."""
    try:
        return struct.unpack_from(layout, blob, offset)
    except struct.error:
        raise ValueError(f"stream cut short: {struct.calcsize(layout)} bytes needed at byte {offset}") from None


def _reference_rows(ints: np.ndarray) -> np.ndarray:
    """For each basis row, the earlier row it is best coded against (-1: none).

    Pose columns come in related groups: a child joint's position and axis move with its
    parent's, so their basis rows are alike, and the difference is smaller to code. Each
    row takes the earlier row that leaves the smallest sum of absolute differences, if
    that beats coding the row as it is.
    """
    references = np.full(len(ints), -1, np.int64)
    for row in range(1, len(ints)):
        costs = np.abs(ints[row] - ints[:row]).sum(axis=1)
        best = int(np.argmin(costs))
        if costs[best] < np.abs(ints[row]).sum():
            references[row] = best
    return references


def _undo_references(residuals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Basis integers from `_reference_rows` residuals and offsets (row - reference, 0: none)."""
    rows = np.arange(len(offsets))
    if np.any((offsets < 0) | (offsets > rows)):
        raise ValueError("class basis refers to a row that does not come before")
    ints = residuals.copy()
    for row in np.flatnonzero(offsets):
        ints[row] += ints[row - offsets[row]]
    return ints
