"""jaxfric.motion: derivatives, reversals and travel since the last reversal, against
plain loops and known signals."""

import numpy as np
import pytest

from jaxfric import motion


def _loop_travel(x):
    """The travel since the last change of direction, sample by sample (the rule of
    docs/algorithm.md section 1: a reversal is the first step against the last motion)."""
    out, anchor, last = np.zeros_like(x), x[0], 0.0
    for n in range(1, x.size):
        d = np.sign(x[n] - x[n - 1])
        if d != 0 and last != 0 and d != last:
            anchor = x[n - 1]
        if d != 0:
            last = d
        out[n] = abs(x[n] - anchor)
    return out


def test_travel_since_reversal_matches_a_loop_with_rests_and_nested_loops():
    rng = np.random.default_rng(3)
    steps = rng.choice([-1.0, 0.0, 1.0], size=400, p=[0.35, 0.2, 0.45]) * 1e-6
    x = np.cumsum(np.r_[0.0, steps])
    np.testing.assert_array_equal(motion.travel_since_reversal(x), _loop_travel(x))
    rev, start = motion.reversals(np.sign(np.r_[0.0, np.diff(x)]))
    assert rev.sum() == np.count_nonzero(np.diff(np.sign(steps[steps != 0])))
    assert np.all(start <= np.arange(x.size))


def test_backward_and_central_velocity():
    t = np.linspace(0.0, 1.0, 101)
    x = 3.0 * t**2
    np.testing.assert_allclose(motion.velocity(t, x)[1:], 3.0 * (t[1:] + t[:-1]))
    assert motion.velocity(t, x)[0] == 0.0
    inner = slice(5, -5)
    np.testing.assert_allclose(motion.velocity(t, x, 0.04)[inner], 6.0 * t[inner], rtol=1e-12)


def test_smooth_derivatives_are_zero_phase_and_smooth_quantisation():
    t = np.arange(0.0, 2.0, 1e-3)
    x_true = 1e-3 * np.sin(2 * np.pi * t)
    x = np.round(x_true / 5e-8) * 5e-8  # a 0.05 um encoder
    v, a = motion.smooth_derivatives(t, x, 0.02)
    v_true = 2 * np.pi * 1e-3 * np.cos(2 * np.pi * t)
    a_true = -((2 * np.pi) ** 2) * 1e-3 * np.sin(2 * np.pi * t)
    inner = slice(50, -50)
    assert np.max(np.abs(v - v_true)[inner]) < 2e-3 * np.max(np.abs(v_true))
    assert np.max(np.abs(a - a_true)[inner]) < 3e-2 * np.max(np.abs(a_true))
    # no lag: the zero crossings of v are where the true ones are, within a sample
    crossings = np.nonzero(np.diff(np.sign(v[inner])))[0]
    true_crossings = np.nonzero(np.diff(np.sign(v_true[inner])))[0]
    np.testing.assert_allclose(crossings, true_crossings, atol=1)


def test_smooth_derivatives_refuse_irregular_sampling():
    t = np.cumsum(np.r_[0.0, np.random.default_rng(0).uniform(0.5e-3, 1.5e-3, 999)])
    with pytest.raises(ValueError, match="uniform sampling"):
        motion.smooth_derivatives(t, np.sin(t), 0.02)


def test_central_difference_is_exactly_zero_at_rest_on_a_jittered_clock():
    """The documented ``(x_{n+1} - x_{n-1}) / (t_{n+1} - t_{n-1})``: exactly 0 where the
    position did not change (`numpy.gradient`'s formula for uneven steps leaves round-off
    there, whose sign a ``sign(v)`` term reads as a direction)."""
    rng = np.random.default_rng(0)
    t = np.arange(200) * 1e-3 + rng.uniform(-1e-4, 1e-4, 200)
    x = np.where(t < 0.1, 0.0, (t - 0.1) ** 2) + 1.234e-3
    v = motion.central_difference(t, x)
    assert np.all(v[1:98] == 0.0)
    np.testing.assert_allclose(v[150], (x[151] - x[149]) / (t[151] - t[149]), rtol=1e-15)
    assert v[0] == (x[1] - x[0]) / (t[1] - t[0]) and v[-1] == (x[-1] - x[-2]) / (t[-1] - t[-2])
