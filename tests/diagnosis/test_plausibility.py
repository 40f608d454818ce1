"""The diagnosis's velocity estimates (`fitting._derivatives`) and its plausibility checks
(`fitting._plausibility`)."""

import equinox as eqx
import numpy as np
import pytest

import jaxfric
from fitting._derivatives import describe, estimate_velocity
from fitting._plausibility import plausibility, steady_state


def _motion(n=6000, dt=1e-2, seed=0):
    """Strokes at several speeds, both directions."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    v = np.repeat(rng.choice([-20e-3, -8e-3, -2e-3, 2e-3, 8e-3, 20e-3], n // 200), 200)
    return t, np.cumsum(v) * dt, v


def test_velocity_estimates():
    t = np.linspace(0.0, 1.0, 1001)
    x = np.sin(2 * np.pi * t) * 1e-3
    v_true = 2 * np.pi * np.cos(2 * np.pi * t) * 1e-3
    central = estimate_velocity(t, x)
    backward = estimate_velocity(t, x, "backward")
    smooth = estimate_velocity(t, x, "savgol")
    inner = slice(5, -5)
    assert np.max(np.abs(central - v_true)[inner]) < 1e-4 * np.max(np.abs(v_true))
    assert np.max(np.abs(smooth - v_true)[inner]) < 1e-4 * np.max(np.abs(v_true))
    # The backward difference lags by half a sample: an error of order dt/2 * a.
    assert np.max(np.abs(backward - v_true)[inner]) > 1e-3 * np.max(np.abs(v_true))
    np.testing.assert_array_equal(backward, jaxfric.motion.velocity(t, x))
    assert "zero phase" in describe("central") and "causal" in describe("backward")
    with pytest.raises(ValueError, match="not one of"):
        estimate_velocity(t, x, "forward")
    with pytest.raises(ValueError, match="not a positive number"):
        estimate_velocity(t, x, "central", float("nan"))


def test_steady_state_is_the_models_own_curve_with_its_effects():
    load = jaxfric.effects.PositionLoad(load_1=0.3, load_2=0.0, x_mid=0.0, x_half=1e-3)
    model = jaxfric.paper.two_state() + (jaxfric.effects.Offset(offset=0.5), load)
    speeds = np.array([-5e-3, -1e-3, 1e-3, 5e-3])
    got = steady_state(model, speeds, duration=20.0, at=0.5e-3)  # the load is 0.15 N there
    base = jaxfric.paper.two_state()
    s = base.stribeck
    curve = np.sign(speeds) * (float(s.Fc) + (float(s.Fs) - float(s.Fc)) * np.exp(
        -np.abs(speeds / float(s.Vs)) ** float(s.delta))) + float(base.sigma2) * speeds
    np.testing.assert_allclose(got, curve + 0.5 + 0.15, rtol=1e-6, atol=1e-6 * float(s.Fs))


def test_plausibility_flags_a_friction_curve_that_rises_with_speed():
    t, x, v = _motion(n=3000)
    good = jaxfric.paper.two_state()
    F = np.asarray(jaxfric.simulate(good, t, x, v))
    s = good.stribeck
    rising = eqx.tree_at(lambda m: (m.stribeck.Fs, m.stribeck.Fc), good,
                         (s.Fc, s.Fs))  # Fs and Fc swapped: rises from Fc to Fs
    flags = plausibility(rising, t, x, v, F)
    assert any("rises with speed" in f for f in flags), flags
    assert not any("rises with speed" in f for f in plausibility(good, t, x, v, F))


def test_plausibility_says_when_the_sliding_level_lies_beyond_the_data():
    t, x, v = _motion(n=3000)
    good = jaxfric.paper.two_state()
    F = np.asarray(jaxfric.simulate(good, t, x, v))
    fastest = float(np.max(np.abs(v)))
    assert not any("beyond the data" in f for f in plausibility(good, t, x, v, F))
    # The transition twice as fast as the fastest measured speed: Fc is never reached.
    far = eqx.tree_at(lambda m: m.stribeck.Vs, good, 2.0 * fastest)
    flags = plausibility(far, t, x, v, F)
    assert any("beyond the data" in f and f"{1e3 * fastest:.4g} mm/s" in f
               for f in flags), flags


def test_plausibility_flags_a_lag_that_acts_as_memory():
    t, x, v = _motion(n=3000)
    good = jaxfric.paper.two_state()
    F = np.asarray(jaxfric.simulate(good, t, x, v))
    assert plausibility(good, t, x, v, F) == []
    # The same model with a lag a hundred times slower: seconds of memory on 2 s strokes.
    slow = eqx.tree_at(lambda m: m.C, good, good.C / 300)
    flags = plausibility(slow, t, x, v, F)
    assert any("lag time" in f for f in flags), flags
