"""The error-target root finders err towards less error and find the boundary."""

import math

import numpy as np
import pytest

from mocapzip.codec.quantise import UniformQuantiser
from mocapzip.ratecontrol.search import largest_step, largest_step_power_law, smallest_count, smallest_count_guided


@pytest.mark.parametrize("target", [0.05, 0.3, 1.0, 7.0])
def test_smallest_count_is_minimal_and_meets_target(target):
    error = lambda n: 10.0 / (n + 1)  # noqa: E731 - a falling error curve
    n = smallest_count(error, target, 0, 500)
    assert error(n) <= target
    assert n == 0 or error(n - 1) > target


def test_smallest_count_returns_hi_when_unreachable():
    assert smallest_count(lambda n: 1.0, 0.5, 0, 20) == 20


@pytest.mark.parametrize("target", [0.01, 0.2, 0.9])
def test_largest_step_meets_target_within_tolerance(target):
    error = lambda step: step ** 1.5  # noqa: E731 - a rising error curve
    step, err = largest_step(error, target, 1e-6, 10.0, rel_tol=0.01)
    assert err == error(step) and err <= target
    assert error(step * 1.02) > target  # no much larger step would do


def test_largest_step_reports_when_even_the_smallest_step_misses():
    step, err = largest_step(lambda s: 5.0, 1.0, 1e-3, 1.0)
    assert step == 1e-3 and err == 5.0


@pytest.mark.parametrize("guess", [1e-5, 0.003, 0.1, 0.5, 3.0, 9.9])
@pytest.mark.parametrize("target", [0.01, 0.2, 0.9])
def test_a_guess_changes_the_cost_not_the_answer(guess, target):
    calls = []

    def error(step):
        calls.append(step)
        return step ** 1.5

    step, err = largest_step(error, target, 1e-6, 10.0, rel_tol=0.01, guess=guess)
    assert len(set(calls)) == len(calls)  # each step scored once
    assert err == error(step) and err <= target
    assert error(step * 1.02) > target


def quantiser_like(floor: float, gain: float, wobble: float = 0.0):
    """Error of a quantiser step: what the finest step leaves, plus noise growing with the step,
    and (wobble) the few-per-cent ups and downs real codings show between nearby steps."""
    return lambda step: math.sqrt(floor**2 + (gain * step) ** 2) * (1 + wobble * math.sin(300 * math.log(step)))


@pytest.mark.parametrize("floor, gain", [(0.0, 0.07), (0.6, 0.06), (0.95, 0.01), (0.2, 3.0)])
def test_a_quantiser_like_curve_is_solved_in_a_few_scores(floor, gain):
    """The fit error^2 = a + b step^2 lands next to the answer: far fewer scores than bisecting
    1e-4..1e3 to 0.3 % (about 13)."""
    error, calls = quantiser_like(floor, gain), []
    step, err = largest_step(lambda s: calls.append(s) or error(s), 1.0, 1e-4, 1e3, rel_tol=0.003)
    assert err == error(step) <= 1.0 < error(step * 1.003 ** 2)
    assert len(calls) <= 7, calls


@pytest.mark.parametrize("guess", [0.5, 3.0, 15.0, 200.0])
def test_a_wobbling_curve_still_gives_a_step_within_the_target(guess):
    error, calls = quantiser_like(0.7, 0.05, wobble=0.02), []
    step, err = largest_step(lambda s: calls.append(s) or error(s), 1.0, 1e-4, 1e3, rel_tol=0.003,
                             guess=guess, close=0.01)
    assert err == error(step) <= 1.0
    assert len(calls) == len(set(calls)) <= 14


@pytest.mark.parametrize("guess", [None, 3.0, 15.0])
def test_close_stops_at_the_first_step_within_it(guess):
    error = quantiser_like(0.6, 0.06)
    counts = {}
    for close in (0.0, 0.05):
        calls = []
        step, err = largest_step(lambda s: calls.append(s) or error(s), 1.0, 1e-4, 1e3, rel_tol=0.003,
                                 guess=guess, close=close)
        counts[close] = len(calls)
    assert 0.95 <= err <= 1.0
    assert counts[0.05] <= counts[0.0]


def test_a_close_guess_needs_fewer_scores():
    counts = {}
    for name, guess in (("none", None), ("close", 0.33)):
        calls = []
        largest_step(lambda s: calls.append(s) or s, 0.3, 1e-4, 1e3, guess=guess)
        counts[name] = len(calls)
    assert counts["close"] < counts["none"]


def test_a_power_law_step_is_the_one_a_fine_bisection_finds():
    """A quantiser's error on random curves (no floor): regula falsi finds, to its log tolerance,
    the step a fine bisection finds, in fewer scores than bisecting 1e-4..1e3 to 1 % (16)."""
    rng = np.random.default_rng(6)
    curves = np.cumsum(rng.normal(size=(400, 8)), axis=0) * np.linspace(4, 0.2, 8)
    gains = rng.uniform(0.5, 3.0, 8)

    def error(step):
        q = UniformQuantiser(step, 0.2)
        return float((((curves - q.dequantise(q.quantise(curves))) ** 2).sum(axis=0) * gains).sum())

    for target in (0.5, 40.0, 4000.0):
        calls = []
        step = largest_step_power_law(lambda s: calls.append(s) or error(s), target, 1e-4, 1e3, 1e-4, 0.01)
        lo, hi = np.log(1e-4), np.log(1e3)
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if error(np.exp(mid)) <= target else (lo, mid)
        assert error(step) <= target and step == pytest.approx(np.exp(lo), rel=0.03)
        assert len(calls) < 16, (target, len(calls))


def test_a_power_law_search_at_its_ends():
    assert largest_step_power_law(lambda s: s * s, 0.0, 1e-4, 1e3, 1e-2, 0.01) == 1e-4  # no budget: the finest
    assert largest_step_power_law(lambda s: s * s, 1e7, 1e-4, 1e3, 1e-2, 0.01) == 1e3  # all within: the coarsest


@pytest.mark.parametrize("bias", [0.5, 0.9, 1.0, 1.3, 3.0])
@pytest.mark.parametrize("target", [0.05, 0.3, 1.0, 7.0])
def test_a_guided_count_is_the_smallest_whatever_the_proxy(bias, target):
    """The proxy only guides: a biased one costs scores, never the answer."""
    error = lambda n: 10.0 / (n + 1)  # noqa: E731 - a falling error curve
    proxy = lambda n: bias * 10.0 / (n + 2)  # noqa: E731 - a different shape as well as a bias
    assert smallest_count_guided(error, proxy, target, 0, 500) == smallest_count(error, target, 0, 500)


def test_an_exact_proxy_costs_two_scores():
    calls = []

    def error(n):
        calls.append(n)
        return 10.0 / (n + 1)

    assert smallest_count_guided(error, lambda k: 10.0 / (k + 1), 0.3, 0, 500) == 33 and sorted(calls) == [32, 33]


def test_a_guided_count_returns_hi_when_unreachable():
    assert smallest_count_guided(lambda n: 1.0, lambda n: 0.1, 0.5, 0, 20) == 20
