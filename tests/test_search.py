"""The error-target root finders err towards less error and find the boundary."""

import pytest

from mocapzip.ratecontrol.search import largest_step, smallest_count


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


def test_a_close_guess_needs_fewer_scores():
    counts = {}
    for name, guess in (("none", None), ("close", 0.33)):
        calls = []
        largest_step(lambda s: calls.append(s) or s, 0.3, 1e-4, 1e3, guess=guess)
        counts[name] = len(calls)
    assert counts["close"] < counts["none"]
