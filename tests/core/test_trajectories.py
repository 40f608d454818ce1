"""The motion families of `jaxfric.trajectories`: finite, within their stated travel and speed,
reproducible, varied by a generator, and with the features each is named for."""

import numpy as np
import pytest

from jaxfric import trajectories


T = np.arange(0.0, 20.0, 1e-3)


@pytest.mark.parametrize("name", sorted(trajectories.FAMILIES))
def test_family_is_finite_reproducible_and_varied(name):
    f = trajectories.FAMILIES[name]
    x = f(T)
    assert x.shape == T.shape and np.all(np.isfinite(x))
    np.testing.assert_array_equal(x, f(T))
    a = f(T, np.random.default_rng(3))
    b = f(T, np.random.default_rng(4))
    assert not np.allclose(a, b)
    v = np.gradient(x, T)
    assert np.max(np.abs(v)) < 0.1  # m/s: machine-like speeds
    assert np.sum(np.diff(np.sign(v[np.abs(v) > 1e-6])) != 0) >= 2  # reverses


def test_point_to_point_stands_still_and_accelerates_hard():
    x = trajectories.point_to_point(T)
    v = np.gradient(x, T)
    assert np.mean(np.abs(v) < 1e-9) > 0.2  # dwells
    assert np.max(np.abs(v)) <= 20e-3 * (1 + 1e-9)
    assert np.max(np.abs(np.gradient(v, T))) > 0.3  # m/s^2: 0.02 s ramps
    assert np.max(np.abs(x)) <= 5e-3 * (1 + 1e-9)


def test_jerk_limited_acceleration_is_continuous():
    x = trajectories.jerk_limited(T)
    a = np.gradient(np.gradient(x, T), T)
    jumps_smooth = np.max(np.abs(np.diff(a)))
    a_trap = np.gradient(np.gradient(trajectories.point_to_point(T), T), T)
    assert jumps_smooth < 0.1 * np.max(np.abs(np.diff(a_trap)))


def test_sine_sweep_gets_faster():
    x = trajectories.sine_sweep(T)
    crossings = np.flatnonzero(np.diff(np.sign(x)) != 0)
    assert np.sum(crossings < T.size // 2) < np.sum(crossings >= T.size // 2)


def test_jittered_clock_increases_and_stays_near_nominal():
    rng = np.random.default_rng(0)
    tj = trajectories.jittered_clock(T, rng, 0.2)
    assert np.all(np.diff(tj) > 0)
    assert np.max(np.abs(tj - T)) <= 0.2e-3 * (1 + 1e-9)
    with pytest.raises(ValueError, match="jitter"):
        trajectories.jittered_clock(T, rng, 0.6)


def test_bad_time_is_refused():
    with pytest.raises(ValueError, match="increasing"):
        trajectories.sine_strokes(np.array([0.0, 0.0, 1.0]))
