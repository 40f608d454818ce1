"""`jaxfric.synthetic`'s foreign truth with true stiction, its motion families and its
jittered clock (the data of the diagnosis's slow tests and bench)."""

import numpy as np
import pytest

from jaxfric import synthetic, trajectories


def test_stiction_breaks_away_above_the_sliding_curve_and_drops():
    t = np.arange(0.0, 4.0, 2e-4)
    x = trajectories.point_to_point(t, np.random.default_rng(0))
    v = np.gradient(x, t)
    v = np.where(np.abs(v) < 1e-7, 0.0, v)
    f = synthetic.stiction_force(t, x, v)
    assert np.max(np.abs(f)) > 26.0  # the breakaway (27 N), above the curve's 24 N peak
    jumps = np.abs(np.diff(f))
    assert jumps.max() > 2.0  # the slip: a drop to the sliding curve in one step
    sliding = np.abs(v) > 5e-3
    level = np.abs(f[sliding]) - 60.0 * np.abs(v[sliding])
    assert np.all(level < 24.01) and np.all(level > 19.99)  # on the Stribeck curve


def test_measurement_takes_a_motion_family_and_a_jittered_clock():
    t, _, _ = synthetic.measurement("stiction", (), dt=2e-3, motion="jerk_limited",
                                    duration=4.0, jitter=0.1)
    assert t.size == 2000 and np.all(np.diff(t) > 0)
    steps = np.diff(t)
    # each sample up to 0.1 dt early or late: intervals of 0.8..1.2 dt
    assert steps.min() == pytest.approx(1.6e-3) and steps.max() == pytest.approx(2.4e-3)
    plain = synthetic.measurement("gms_power", (), dt=1e-2)
    again = synthetic.measurement("gms_power", (), dt=1e-2, jitter=0.0)
    for a, b in zip(plain, again):
        np.testing.assert_array_equal(a, b)  # jitter 0 is the uniform clock, unchanged


def test_hidden_effects_on_a_motion_that_never_slides_fast_are_finite():
    """A slow sine sweep never exceeds 5 mm/s: the hidden effects scale with the level of
    its fastest samples instead (was NaN: the median of no samples)."""
    *_, F = synthetic.measurement("stiction", ("cogging",), noise=0.03, dt=0.01,
                                    motion="sine_sweep", duration=30, seed=0)
    assert np.all(np.isfinite(F))


DWELLS = {"noise": 0.0, "dt": 1e-2, "seed": 3, "motion": "point_to_point", "duration": 30.0,
          "jitter": 0.1}


def _dwells(hidden):
    """``(F, F0, still)``: the stiction file with `hidden`, without it, and its dwells."""
    _, x, F = synthetic.measurement("stiction", hidden, **DWELLS)
    _, _, F0 = synthetic.measurement("stiction", (), **DWELLS)
    still = np.r_[False, (x[2:] == x[1:-1]) & (x[1:-1] == x[:-2]), False]
    assert still.sum() > 300  # the dwells
    return F, F0, still


@pytest.mark.parametrize("hidden", ["stribeck", "friction_lag"])
def test_hidden_effects_with_a_direction_are_zero_at_rest(hidden):
    """A dwell is at rest: a hidden effect with ``sign(v)`` adds nothing there, not even
    with the sign of the fine grid's round-off velocity (up to a hump's full 2 N on a
    point-to-point record's dwells, if it did)."""
    F, F0, still = _dwells((hidden,))
    np.testing.assert_array_equal(F[still], F0[still])


def test_the_hidden_asymmetry_holds_at_rest_what_it_raised_while_moving():
    """A direction-dependent friction level scales the force wherever it points toward +x,
    at rest too: a stop holds the force it had, so no force changes while nothing moves."""
    F, F0, still = _dwells(("asymmetry",))
    np.testing.assert_allclose(F[still], F0[still] + 0.06 * np.maximum(F0[still], 0.0),
                               rtol=1e-12, atol=1e-12)
    assert np.sum(F0[still] > 1.0) > 100  # dwells that hold a force toward +x
