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
