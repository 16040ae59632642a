"""PPCA segmentation of a long take (Barbic et al. 2004, as used by Hou et al. section VI-B2).

A take is cut where the distribution of its poses changes. Growing a window of the
first k frames of the current segment, a PPCA model (`ppca.PpcaModel`: components
holding `variance_share` of the variance, rho the mean of the rest) is fitted to it and
the mean Mahalanobis distance (thesis eq. 3.12) of the next `horizon` frames is taken:

    H(k) = mean_{f = k .. k + horizon} d(x_f | model of frames 0 .. k)

While the take continues one behaviour, H(k) stays flat or falls; when a new
behaviour starts just after k, H rises, and once the window has swallowed it H falls
again. A cut is made at the peak of H when H has risen by more than `rise` standard
deviations of its own history and then fallen back by half of that rise (Barbic et
al.: a peak of H). After a cut the search restarts on the remaining frames. Segments
shorter than `min_frames` are never made.

    segment_take(poses) -> [0, c1, c2, ..., n_frames]   (cut frames, first and last included)

How a cut take is coded and joined again (`mcz compress --segment`): `codec.segments`.
"""

from __future__ import annotations

import numpy as np

from mocapzip.codec.pca import CovarianceAccumulator
from mocapzip.classes.ppca import PpcaModel

MIN_FRAMES = 240  # 2 s at 120 Hz: shorter segments cost more in headers than they save
HORIZON = 120  # frames scored after the window (1 s at 120 Hz)
STEP = 10  # window growth per evaluation
RISE = 3.0  # a peak must rise this many standard deviations above H's history
VARIANCE_SHARE = 0.9  # Barbic et al. keep 90 % of the variance for the window model


def distance_curve(poses: np.ndarray, start: int, stop: int, min_frames: int = MIN_FRAMES,
                   horizon: int = HORIZON, step: int = STEP, variance_share: float = VARIANCE_SHARE):
    """(window ends k, H(k)) for the segment starting at `start` (k from start + min_frames).

    The window's statistics grow incrementally (`CovarianceAccumulator`), so each k costs one
    eigendecomposition, not a pass over the window.
    """
    accumulator = CovarianceAccumulator(poses.shape[1])
    accumulator.add(poses[start : start + min_frames])
    ends, values = [], []
    k = start + min_frames
    while k + horizon <= stop:
        model = PpcaModel.from_accumulator(accumulator, variance_share)
        values.append(float(model.distance(poses[k : k + horizon]).mean()))
        ends.append(k)
        accumulator.add(poses[k : k + step])
        k += step
    return np.array(ends, int), np.array(values)


def _first_peak(ends: np.ndarray, values: np.ndarray, rise: float, lag: int) -> int | None:
    """The window end at the first qualifying peak of H, or None.

    H is compared in log (it spans orders of magnitude) with its own history up to `lag`
    evaluations earlier (a change takes a horizon to ramp H up, and the ramp must not
    count as history): baseline its median, spread its median absolute deviation.
    """
    logs = np.log(np.maximum(values, 1e-12))
    for i in range(lag + 3, len(logs)):
        history = logs[: i - lag]
        baseline = float(np.median(history))
        spread = max(1.4826 * float(np.median(np.abs(history - baseline))), 0.1)
        if logs[i] - baseline < rise * spread:
            continue
        top = i  # a rise: follow it to its top, then require a fall by half of the rise
        for j in range(i + 1, len(logs)):
            if logs[j] > logs[top]:
                top = j
            elif logs[top] - logs[j] >= 0.5 * (logs[top] - baseline):
                return int(ends[top])
        return None
    return None


def segment_take(poses: np.ndarray, min_frames: int = MIN_FRAMES, horizon: int = HORIZON, step: int = STEP,
                 rise: float = RISE, variance_share: float = VARIANCE_SHARE) -> list[int]:
    """Cut frames of one take: [0, c1, ..., n_frames], every segment at least `min_frames` long."""
    poses = np.asarray(poses, np.float64)
    n = len(poses)
    cuts, start = [0], 0
    while n - start >= 2 * min_frames:
        ends, values = distance_curve(poses, start, n, min_frames, horizon, step, variance_share)
        peak = _first_peak(ends, values, rise, max(1, horizon // step))
        if peak is None or n - peak < min_frames:
            break
        cuts.append(peak)
        start = peak
    cuts.append(n)
    return cuts
