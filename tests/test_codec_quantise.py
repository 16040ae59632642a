"""Tests for mocapzip.codec.quantise and the stage registry's handling of it."""

import json

import numpy as np
import pytest

from mocapzip.stages import get_stage
from mocapzip.codec.quantise import UniformQuantiser

# Relative slack for float rounding exactly at bin edges.
EPS = 1e-12


@pytest.mark.parametrize("dead_zone", [0.0, 0.2, 0.49])
@pytest.mark.parametrize("step", [1e-4, 0.1, 3.0])
@pytest.mark.parametrize("shape", [(0,), (1,), (1000,), (40, 7)])
def test_quantise_is_the_documented_formula(shape, step, dead_zone):
    """The compiled quantiser gives exactly sign(x) * max(floor(|x| / step + 0.5 - dead_zone), 0),
    bin edges and signed zeros included."""
    rng = np.random.default_rng(len(shape))
    x = rng.normal(scale=50 * step, size=shape)
    k = np.arange(x.size) % 40 - 20
    edges = np.sign(k) * (np.abs(k) + 0.5 + dead_zone) * step  # values at the thresholds, both signs
    x = np.where(rng.random(shape) < 0.3, edges.reshape(shape), x)
    x.reshape(-1)[:2] = [0.0, -0.0] if x.size >= 2 else x.reshape(-1)[:2]
    expected = (np.sign(x) * np.maximum(np.floor(np.abs(x) / step + 0.5 - dead_zone), 0.0)).astype(np.int64)
    ints = UniformQuantiser(step, dead_zone).quantise(x)
    assert ints.shape == x.shape and ints.dtype == np.int64
    np.testing.assert_array_equal(ints, expected)
    np.testing.assert_array_equal(UniformQuantiser(step, dead_zone).quantise(x.T), expected.T)  # any layout


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, 1e300])
def test_quantise_refuses_what_it_cannot_represent(bad):
    with pytest.raises(ValueError, match="not finite or too large"):
        UniformQuantiser(0.1).quantise(np.array([1.0, bad]))


@pytest.mark.parametrize("step", [1e-4, 0.1, 3.0])
def test_error_bound_without_dead_zone(step):
    x = np.random.default_rng(0).normal(scale=100 * step, size=10_000)
    quantiser = UniformQuantiser(step)
    q = quantiser.quantise(x)
    assert q.dtype == np.int64
    assert np.all(np.abs(x - quantiser.dequantise(q)) <= step / 2 * (1 + EPS))


@pytest.mark.parametrize("dead_zone", [0.1, 0.3, 0.49])
def test_dead_zone(dead_zone):
    step = 0.5
    x = np.random.default_rng(1).normal(scale=2.0, size=10_000)
    quantiser = UniformQuantiser(step, dead_zone)
    q = quantiser.quantise(x)
    assert np.all(q[np.abs(x) < (0.5 + dead_zone) * step * (1 - EPS)] == 0)
    assert np.all(q[np.abs(x) >= (0.5 + dead_zone) * step * (1 + EPS)] != 0)
    assert np.all(np.abs(x - quantiser.dequantise(q)) <= (0.5 + dead_zone) * step * (1 + EPS))
    # A dead zone only ever moves values towards zero.
    assert np.all(np.abs(q) <= np.abs(UniformQuantiser(step).quantise(x)))


@pytest.mark.parametrize("dead_zone", [0.0, 0.25])
def test_zero_stays_zero_and_sign_is_symmetric(dead_zone):
    quantiser = UniformQuantiser(0.1, dead_zone)
    np.testing.assert_array_equal(quantiser.quantise(np.array([0.0, -0.0])), [0, 0])
    assert np.all(quantiser.dequantise(np.zeros(3, np.int64)) == 0)
    x = np.random.default_rng(2).normal(size=1000)
    np.testing.assert_array_equal(quantiser.quantise(-x), -quantiser.quantise(x))


def test_rounds_to_nearest_multiple():
    quantiser = UniformQuantiser(0.5)
    np.testing.assert_array_equal(
        quantiser.quantise([0.2, 0.3, 0.74, 0.76, -0.3, -1.26]), [0, 1, 1, 2, -1, -3]
    )


def test_config_round_trip_through_registry():
    quantiser = UniformQuantiser(0.05, dead_zone=0.2)
    config = json.loads(json.dumps(quantiser.get_config()))
    assert config == {"id": "uniform", "step": 0.05, "dead_zone": 0.2}
    rebuilt = get_stage("quantiser", config)
    assert isinstance(rebuilt, UniformQuantiser)
    assert (rebuilt.step, rebuilt.dead_zone) == (0.05, 0.2)
    assert UniformQuantiser.from_config(config).get_config() == config


def test_registry_errors():
    with pytest.raises(ValueError, match="unknown quantiser id"):
        get_stage("quantiser", {"id": "no-such-stage"})
    with pytest.raises(ValueError, match="no 'id'"):
        get_stage("quantiser", {"step": 1.0})
    with pytest.raises(ValueError, match="bad config"):
        get_stage("quantiser", {"id": "uniform", "stepp": 1.0})


@pytest.mark.parametrize(
    "step, dead_zone", [(0.0, 0.0), (-1.0, 0.0), (np.inf, 0.0), (1.0, 0.5), (1.0, -0.1)]
)
def test_invalid_parameters(step, dead_zone):
    with pytest.raises(ValueError):
        UniformQuantiser(step, dead_zone)


def test_rejects_values_that_do_not_fit():
    quantiser = UniformQuantiser(1e-9)
    for bad in ([np.nan], [np.inf], [1e12]):
        with pytest.raises(ValueError):
            quantiser.quantise(np.array(bad))

