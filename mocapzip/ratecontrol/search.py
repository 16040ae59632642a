"""Root finding for error targets (thesis section 3.2.3), always erring towards less error."""

from __future__ import annotations

import math
from typing import Callable


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
                          lo: int, hi: int, scale: float = 1.0) -> tuple[int, float]:
    """`smallest_count`, guided by a cheap `proxy` of the error: each guess is the smallest count
    whose proxy, times the ratio error / proxy last measured, meets the target, kept inside the
    bracket the true scores so far allow. A right guess costs two scores (the count and the one
    below it). Returns (count, the ratio last measured)."""
    passed, failed = None, None  # smallest count known to meet the target, largest known to miss it

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
            return passed, scale
        if failed == hi:
            return hi, scale
        if proxy(count) > 0 and error > 0:
            scale = error / proxy(count)
        count = guess()


def largest_step(error_at: Callable[[float], float], target: float, lo: float, hi: float,
                 rel_tol: float = 0.02, max_iter: int = 30, guess: float | None = None) -> tuple[float, float]:
    """Largest quantiser step in [lo, hi] whose error is <= target, by bisection in log space.

    Returns (step, error). The lower bracket always meets the target, so the answer
    errs towards less error; if even `lo` misses, `lo` is returned with its error
    and the caller decides what to do. A `guess` inside [lo, hi] first narrows the
    bracket by doubling or halving from it: fewer scores when the guess is close.
    """
    scores: dict[float, float] = {}

    def score(step: float) -> float:
        if step not in scores:
            scores[step] = error_at(step)
        return scores[step]

    if guess is not None and lo < guess < hi:
        if score(guess) <= target:
            lo = guess
            while lo * 2 < hi and score(lo * 2) <= target:
                lo *= 2
            hi = min(hi, lo * 2)
        else:
            hi = guess
            while hi / 2 > lo and score(hi / 2) > target:
                hi /= 2
            lo = max(lo, hi / 2)
    err_lo = score(lo)
    if err_lo > target:
        return lo, err_lo
    err_hi = score(hi)
    if err_hi <= target:
        return hi, err_hi
    for _ in range(max_iter):
        if hi / lo <= 1 + rel_tol:
            break
        mid = math.sqrt(lo * hi)
        err = score(mid)
        if err <= target:
            lo, err_lo = mid, err
        else:
            hi = mid
    return lo, err_lo
