"""Dynamic time warping of two motions, plain and multiscale (Krüger et al. 2007, seed 002,
section 3.2, after Zinke and Mayer 2006): which frames of one correspond to which of the other.

Both motions are sequences of feature vectors, (frames, K, 3) as `physics.physics_features`
gives them. Two frames cost the mean over the K features of (1 - cos(angle between them)) / 2,
in [0, 1], and 0 for a feature that is zero in either frame (the seed's local cost). A warping
path runs from (0, 0) to (n - 1, m - 1) in steps of (1, 0), (0, 1) or (1, 1), and DTW finds
the one of least total cost by dynamic programming.

Plain DTW fills all n x m cells. The multiscale search does it at the coarsest level only: it
averages the features over windows of 2, 4, ... frames, down to about 4 Hz; aligns there; then
at each finer level fills only the cells near the coarser path, projected and widened by
MULTISCALE_RADIUS cells. A path is computed over cells of a *band*: for each row i, the
columns [lo[i], hi[i]).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

COARSEST_HZ = 4.0  # the multiscale search starts at about this many feature frames per second
MULTISCALE_RADIUS = 2  # cells each side of the projected coarse path, searched at the finer level


@dataclass(frozen=True)
class Warping:
    """A warping path and what finding it took."""

    path: np.ndarray  # (L, 2) int: (frame of the first motion, frame of the second), both non-decreasing
    cost: float  # the path's total cost
    cells: int  # cells of the cost matrix filled, over every level: the work done

    def carried(self, values: np.ndarray, onto: int) -> np.ndarray:
        """`values` (one row per frame of the other motion) carried onto the frames of motion `onto`
        (0: the first, 1: the second): each frame gets the mean of the rows of the frames matched to it."""
        to, came = self.path[:, onto], self.path[:, 1 - onto]
        counts = np.bincount(to)
        rows = np.asarray(values, np.float64)[came]
        sums = np.zeros((len(counts), *rows.shape[1:]))
        np.add.at(sums, to, rows)
        return sums / counts.reshape(-1, *[1] * (rows.ndim - 1))


def dtw(first: np.ndarray, second: np.ndarray) -> Warping:
    """Plain DTW over the full cost matrix."""
    return Warping(*_plain(_checked(first), _checked(second)))


def multiscale_dtw(first: np.ndarray, second: np.ndarray, fps: float) -> Warping:
    """DTW coarse to fine: levels of 2^k-frame means, k from `levels(fps)` - 1 down to 0."""
    return Warping(*_multiscale(_checked(first), _checked(second), levels(fps), MULTISCALE_RADIUS))


def levels(fps: float) -> int:
    """Resolution levels from `fps` down to about COARSEST_HZ (6 at 120 Hz: 3.75 Hz at the coarsest)."""
    return max(1, round(math.log2(max(fps / COARSEST_HZ, 1.0))) + 1)


def _checked(features) -> np.ndarray:
    features = np.ascontiguousarray(features, dtype=np.float64)
    if features.ndim != 3 or features.shape[2] != 3 or not len(features):
        raise ValueError(f"features must be (frames >= 1, K, 3), got {features.shape}")
    if not np.isfinite(features).all():
        raise ValueError("features must be finite (a NaN or an infinity has no direction to compare)")
    return features


@njit(cache=True)
def _plain(a, b):
    n, m = a.shape[0], b.shape[0]
    return _dtw_band(_unit(a), _unit(b), np.zeros(n, np.int64), np.full(n, m, np.int64))


@njit(cache=True)
def _multiscale(a, b, n_levels, radius):
    """The coarse-to-fine search of `multiscale_dtw`: (path, cost, cells filled over every level)."""
    pyramid_a = [a]
    pyramid_b = [b]
    for _ in range(n_levels - 1):
        if min(pyramid_a[-1].shape[0], pyramid_b[-1].shape[0]) < 2:
            break
        pyramid_a.append(_halved(pyramid_a[-1]))
        pyramid_b.append(_halved(pyramid_b[-1]))
    path, cost, cells = _plain(pyramid_a[-1], pyramid_b[-1])
    for level in range(len(pyramid_a) - 2, -1, -1):
        fine_a, fine_b = pyramid_a[level], pyramid_b[level]
        lo, hi = _projected_band(path, fine_a.shape[0], fine_b.shape[0], radius)
        path, cost, filled = _dtw_band(_unit(fine_a), _unit(fine_b), lo, hi)
        cells += filled
    return path, cost, cells


@njit(cache=True)
def _halved(x):
    """Means of consecutive pairs of frames (a last odd frame alone): the next coarser level."""
    n = x.shape[0]
    out = np.empty(((n + 1) // 2, x.shape[1], 3))
    for i in range(n // 2):
        out[i] = 0.5 * (x[2 * i] + x[2 * i + 1])
    if n % 2:
        out[n // 2] = x[n - 1]
    return out


@njit(cache=True)
def _projected_band(path, n, m, radius):
    """The band at the finer level (n x m): each coarse cell (i, j) covers rows 2i, 2i + 1 and
    columns 2j, 2j + 1; every row's span widened by `radius` cells each side."""
    lo = np.full(n, m, np.int64)
    hi = np.zeros(n, np.int64)
    for c in range(path.shape[0]):
        for row in range(2 * path[c, 0], min(2 * path[c, 0] + 2, n)):
            lo[row] = min(lo[row], 2 * path[c, 1])
            hi[row] = max(hi[row], min(2 * path[c, 1] + 2, m))
    for row in range(n):
        lo[row] = max(lo[row] - radius, 0)
        hi[row] = min(hi[row] + radius, m)
    return lo, hi


@njit(cache=True)
def _unit(x):
    """Each feature vector scaled to length 1 (0 stays 0): the cost is then a mean of dot products."""
    out = np.zeros_like(x)
    for i in range(x.shape[0]):
        for f in range(x.shape[1]):
            norm = math.sqrt(x[i, f, 0] ** 2 + x[i, f, 1] ** 2 + x[i, f, 2] ** 2)
            if norm > 0:
                for c in range(3):
                    out[i, f, c] = x[i, f, c] / norm
    return out


@njit(cache=True)
def _dtw_band(a, b, lo, hi):
    """(path, cost, cells) of least-cost DTW over the band's cells (row i: columns lo[i] to hi[i] - 1)."""
    n = a.shape[0]
    k = a.shape[1]
    start = np.zeros(n + 1, np.int64)
    for i in range(n):
        start[i + 1] = start[i] + hi[i] - lo[i]
    total = np.full(start[n], np.inf)
    for i in range(n):
        for j in range(lo[i], hi[i]):
            c = 0.0
            for f in range(k):
                dot = a[i, f, 0] * b[j, f, 0] + a[i, f, 1] * b[j, f, 1] + a[i, f, 2] * b[j, f, 2]
                zero = (a[i, f, 0] == 0.0 and a[i, f, 1] == 0.0 and a[i, f, 2] == 0.0) or \
                       (b[j, f, 0] == 0.0 and b[j, f, 1] == 0.0 and b[j, f, 2] == 0.0)
                c += 0.0 if zero else 0.5 * (1.0 - dot)
            c /= k
            if i == 0 and j == 0:
                best = 0.0
            else:
                best = np.inf
                if j > lo[i]:
                    best = total[start[i] + j - 1 - lo[i]]
                if i > 0:
                    if lo[i - 1] <= j < hi[i - 1]:
                        best = min(best, total[start[i - 1] + j - lo[i - 1]])
                    if lo[i - 1] <= j - 1 < hi[i - 1]:
                        best = min(best, total[start[i - 1] + j - 1 - lo[i - 1]])
            total[start[i] + j - lo[i]] = c + best
    m_last = hi[n - 1] - 1
    # back from the last cell: the cheapest predecessor, diagonal first on ties
    path = np.empty((n + m_last + 1, 2), np.int64)
    i, j, length = n - 1, m_last, 0
    while True:
        path[length, 0] = i
        path[length, 1] = j
        length += 1
        if i == 0 and j == 0:
            break
        best, bi, bj = np.inf, -1, -1
        if i > 0 and lo[i - 1] <= j - 1 < hi[i - 1] and total[start[i - 1] + j - 1 - lo[i - 1]] < best:
            best, bi, bj = total[start[i - 1] + j - 1 - lo[i - 1]], i - 1, j - 1
        if i > 0 and lo[i - 1] <= j < hi[i - 1] and total[start[i - 1] + j - lo[i - 1]] < best:
            best, bi, bj = total[start[i - 1] + j - lo[i - 1]], i - 1, j
        if j > lo[i] and total[start[i] + j - 1 - lo[i]] < best:
            best, bi, bj = total[start[i] + j - 1 - lo[i]], i, j - 1
        if bi < 0:
            raise ValueError("no warping path through the band")
        i, j = bi, bj
    return path[:length][::-1].copy(), total[start[n - 1] + m_last - lo[n - 1]], start[n]


# ------------------------------------------------------------------------ a path as stored

_MOVES = np.array([[1, 0], [0, 1], [1, 1]])  # move codes 0, 1, 2: along the first motion, the second, or both


def path_moves(path: np.ndarray) -> bytes:
    """The moves of a path from (0, 0), one byte each (0: the first motion's next frame, 1: the
    second's, 2: both): what `--model tensor` stores of a clip's warping (`warp/NNNNN`, zstd)."""
    path = np.asarray(path, np.int64)
    steps = np.diff(path, axis=0)
    if len(path) == 0 or path[0].any() or not np.isin(steps, (0, 1)).all() or (steps.sum(axis=1) == 0).any():
        raise ValueError("not a warping path from (0, 0) in steps of (1, 0), (0, 1) or (1, 1)")
    return _MOVE_OF_STEP[steps[:, 0], steps[:, 1]].astype(np.uint8).tobytes()


_MOVE_OF_STEP = np.array([[-1, 1], [0, 2]])  # [first's step, second's step] -> move (`_MOVES` inverted)


def path_of_moves(moves: bytes, first_frames: int, second_frames: int) -> np.ndarray:
    """Inverse of `path_moves`, checked to end at (first_frames - 1, second_frames - 1)."""
    codes = np.frombuffer(moves, np.uint8)
    if np.any(codes > 2):
        raise ValueError(f"warping move {int(codes.max())}: moves are 0, 1 or 2")
    path = np.zeros((len(codes) + 1, 2), np.int64)
    np.cumsum(_MOVES[codes], axis=0, out=path[1:])
    if tuple(path[-1]) != (first_frames - 1, second_frames - 1):
        raise ValueError(f"a warping path that ends at {tuple(int(v) for v in path[-1])}, not at "
                         f"({first_frames - 1}, {second_frames - 1})")
    return path
