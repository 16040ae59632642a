"""Root finding for error targets (thesis section 3.2.3), always erring towards less error."""

from __future__ import annotations

import math
from typing import Callable

import numpy as np


def smallest_count(error_at: Callable[[int], float], target: float, lo: int, hi: int) -> int:
    """Smallest count n in [lo, hi] with error_at(n) <= target, assuming error falls as n grows.

    Bisection over a discrete count (PCA components). Returns hi when even hi misses
    the target: the caller keeps everything rather than exceed the budget.
    """
    if error_at(lo) <= target:
        return lo
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if error_at(mid) <= target:
            hi = mid
        else:
            lo = mid
    return hi


def smallest_count_guided(error_at: Callable[[int], float], proxy: Callable[[int], float], target: float,
                          lo: int, hi: int) -> int:
    """`smallest_count`, guided by a cheap `proxy` of the error: each guess is the smallest count
    whose proxy, times the ratio error / proxy last measured, meets the target, kept inside the
    bracket the true scores so far allow. A right guess costs two scores (the count and the one
    below it)."""
    passed, failed = None, None  # smallest count known to meet the target, largest known to miss it
    scale = 1.0

    def guess() -> int:
        count = smallest_count(lambda n: scale * proxy(n), target, lo, hi)
        low = lo if failed is None else failed + 1
        high = hi if passed is None else passed - 1
        return min(max(count, low), high)

    count = guess()
    while True:
        error = error_at(count)
        if error <= target:
            passed = count
        else:
            failed = count
        if passed is not None and (passed == lo or failed == passed - 1):
            return passed
        if failed == hi:
            return hi
        if proxy(count) > 0 and error > 0:
            scale = error / proxy(count)
        count = guess()


def largest_step(error_at: Callable[[float], float], target: float, lo: float, hi: float,
                 rel_tol: float = 0.02, max_iter: int = 30, guess: float | None = None,
                 close: float = 0.0) -> tuple[float, float]:
    """Largest quantiser step in [lo, hi] whose error is <= target, to a factor 1 + rel_tol,
    or the first step found whose error is within `close` (a share) under the target.

    Returns (step, error). The lower bracket always meets the target, so the answer
    errs towards less error; if even `lo` misses, `lo` is returned with its error
    and the caller decides what to do. `guess`, a step inside [lo, hi], is tried first.

    A quantiser adds noise of variance about proportional to step squared to the error
    that remains at the finest step, so each round fits error^2 = a + b step^2 to the
    scores nearest the target on either side, scores just below the step where the fit
    meets the target, then one tolerance above what passed (or below what failed): a good
    fit closes the bracket in two scores, where bisection in log space needs about a dozen.
    A round that does not halve the bracket (in log space) is followed by a bisection.
    """
    scores: dict[float, float] = {}

    def score(step: float) -> float:
        if step not in scores:
            scores[step] = error_at(step)
        return scores[step]

    err_lo = score(lo)
    if err_lo > target:
        return lo, err_lo
    top = hi  # not scored until a round asks for it
    width = 1 + rel_tol
    step = guess if guess is not None and lo < guess < hi else None
    for _ in range(max_iter):
        if hi / lo <= width:
            break
        before = hi / lo
        fitted = step is None
        if fitted:
            step = _where_fit_meets(scores, lo, hi, target)
        trials = [min(max(step / math.sqrt(width), lo * width**0.25), hi / width**0.25) if hi != top else step]
        if fitted:  # a fit is close: one tolerance past the first score, towards the other end
            trials.append(None)
        for trial in trials:
            if trial is None:
                trial = lo * width if lo == trials[0] else hi / width
            if not lo < trial <= hi or (trial == hi and hi != top) or (trial == top and top in scores):
                continue
            if score(trial) <= target:
                lo, err_lo = trial, score(trial)
            else:
                hi = trial
        if lo == top or err_lo >= (1 - close) * target:
            return lo, err_lo
        narrowed = hi != top and math.log(hi / lo) <= 0.5 * math.log(before)
        step = None if narrowed or hi == top or not fitted else math.sqrt(lo * hi)
    return lo, err_lo


def _where_fit_meets(scores: dict[float, float], lo: float, hi: float, target: float) -> float:
    """The step in (lo, hi) where error^2 = a + b step^2, fitted to the scores just below and
    (if any) just above the target, meets it; the middle in log space if the fit fails."""
    below = max((s for s in scores if scores[s] <= target), default=None)
    above = min((s for s in scores if scores[s] > target), default=None)
    points = [s for s in (below, above) if s is not None]
    if len(points) < 2:  # only passing scores: fit through the finest one (the error's floor)
        points = sorted(s for s in scores if scores[s] <= target)[:1] + points
    (s0, e0), (s1, e1) = [(s, scores[s]) for s in points[:1] + points[-1:]]
    if s1 > s0 and e1 > e0:
        slope = (e1 * e1 - e0 * e0) / (s1 * s1 - s0 * s0)
        squared = s0 * s0 + (target * target - e0 * e0) / slope
        if squared > 0 and lo < math.sqrt(squared) < hi:
            return math.sqrt(squared)
        if squared > 0 and math.sqrt(squared) >= hi:
            return hi
    return math.sqrt(lo * hi)


def largest_step_power_law(error_at: Callable[[float], float], target: float, lo: float, hi: float, start: float,
                           log_tol: float) -> float:
    """Largest step in [lo, hi] whose error is <= target, to within `log_tol` in log step, for an
    error with no floor that grows about like a power of the step (quantisation error alone).

    Regula falsi on log error against log step (Illinois variant, the bracket always holding a
    step that meets the target and one that does not) takes a handful of scores where plain
    bisection takes 16. `start`, a step that meets the target, is the bracket's lower end (kept
    in [lo, hi]); `hi` is returned if it meets the target, `lo` if the target is not positive,
    and the lower end if it misses after all.
    """
    if target <= 0:
        return lo

    def excess(log_step: float) -> float:  # log(error / target): <= 0 meets the target
        return float(np.log(max(error_at(float(np.exp(log_step))), 1e-300) / target))

    top = np.log(hi)
    f_top = excess(top)
    if f_top <= 0:
        return hi
    bottom = float(np.clip(np.log(start), np.log(lo), top))
    f_bottom = excess(bottom)
    if f_bottom > 0:
        return float(np.exp(bottom))
    kept = 0  # which end the last trials kept: halve its value when kept twice (Illinois)
    while top - bottom > log_tol:
        x = bottom - f_bottom * (top - bottom) / (f_top - f_bottom)
        x = min(max(x, bottom + 0.01 * (top - bottom)), top - 0.01 * (top - bottom))
        f = excess(x)
        if f <= 0:
            bottom, f_bottom = x, f
            f_top = f_top / 2 if kept == 1 else f_top
            kept = 1
        else:
            top, f_top = x, f
            f_bottom = f_bottom / 2 if kept == -1 else f_bottom
            kept = -1
    return float(np.exp(bottom))
