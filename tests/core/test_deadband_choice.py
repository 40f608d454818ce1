"""`jaxfric.motion.deadband_choice` (the default ``deadband="auto"``): the play is applied
when reversals within the noise band come in a run of `CHATTER_RUN`, and then a noisy
standstill keeps its true reversals and does not overflow the memory; a velocity column's
noise at standstill is kept out of the direction (`played_velocity`)."""

import warnings

import numpy as np
import pytest

import jaxfric
from jaxfric import paper
from jaxfric.motion import (
    auto_deadband,
    CHATTER_RUN,
    consistent_velocity,
    deadband_choice,
    play,
    played_velocity,
)

from ..helpers import count_reversals, standstill_motion


def _strokes_in_a_row(x, band):
    """Plain loop: the reversals of ``sign(dx)`` and the longest run of consecutive ones
    whose stroke since the previous reversal point is within `band`."""
    last_d, point, longest, run, count = 0.0, x[0], 0, 0, 0
    for n in range(1, len(x)):
        d = np.sign(x[n] - x[n - 1])
        if d == 0:
            continue
        if last_d != 0 and d != last_d:
            count += 1
            within = abs(x[n - 1] - point) <= band * (1 + 1e-6)
            run = run + 1 if within else 0
            longest = max(longest, run)
            point = x[n - 1]
        last_d = d
    return count, longest


@pytest.mark.parametrize("toggles", [1, 2, CHATTER_RUN - 1, CHATTER_RUN, 9])
def test_the_rule_counts_one_count_toggles_in_a_row(toggles):
    """An encoder that toggles between two counts `toggles` times at the top of a stroke:
    the even number of them are reversals within one count in a row (an odd last toggle
    goes on down); applied from `CHATTER_RUN` in a row on."""
    q = 1e-6
    counts = list(range(0, 30)) + [29 - (k % 2) for k in range(1, toggles + 1)]
    counts += list(range(counts[-1] - 1, -1, -1)) + list(range(1, 30))
    x = q * np.asarray(counts, dtype=float)
    choice = deadband_choice(x)
    count, longest = _strokes_in_a_row(x, choice.estimate)
    assert abs(choice.estimate - q) < 1e-9 * q  # the band: one count
    assert (choice.reversals, choice.longest_run) == (count, longest)
    assert longest == 2 * (toggles // 2)
    assert (choice.deadband is not None) == (longest >= CHATTER_RUN)
    assert auto_deadband(x) == choice.deadband


@pytest.mark.parametrize("quantum", [0.0, 2e-6])
def test_noisy_standstill_default_keeps_the_true_reversals_without_overflow(quantum):
    t, x, x_true = standstill_motion(21, quantum)
    assert count_reversals(x_true) == 3 and count_reversals(x) > 100
    choice = deadband_choice(x)
    assert choice.deadband is not None and choice.longest_run >= 50
    assert choice.within_band > 0.5 * choice.reversals
    assert "within the position noise band" in choice.reason
    assert count_reversals(np.asarray(play(x, choice.deadband))) == 3
    model = paper.two_state(stack_size=8)
    r = jaxfric.simulate(model, t, x, deadband="auto", full_output=True)
    assert int(r.overflow) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", jaxfric.StackOverflowWarning)
        raw = jaxfric.simulate(model, t, x, full_output=True)
    assert int(np.max(np.asarray(raw.parts["depth"]))) > int(np.max(np.asarray(
        r.parts["depth"])))


def test_noisy_velocity_column_at_a_quantised_standstill():
    """The robot's case: an encoder position that stands still (no position step) and a
    velocity column with noise. The direction the models use flips with the noise; the
    decision sees it, and the played velocity keeps the three true reversals."""
    t, x, x_true = standstill_motion(22, quantum=4e-6)
    v = np.gradient(x_true, t) + 1e-3 * np.random.default_rng(3).standard_normal(t.size)
    dt = np.r_[0.0, np.diff(t)]

    def direction_reversals(x, v):
        d = np.sign(np.asarray(consistent_velocity(v, np.r_[0.0, np.diff(x)], dt)))
        last = d[np.maximum.accumulate(np.where(d != 0, np.arange(d.size), 0))]
        return int(np.count_nonzero((last[1:] != last[:-1]) & (last[:-1] != 0)))

    assert direction_reversals(x, v) > 100
    choice = deadband_choice(x, v, t)
    assert choice.deadband is not None and choice.reversals == direction_reversals(x, v)
    p = np.asarray(play(x, choice.deadband))
    assert direction_reversals(p, np.asarray(played_velocity(p, v))) == 3
    model = paper.two_state(stack_size=8)
    r = jaxfric.simulate(model, t, x, v, deadband="auto", full_output=True)
    assert int(r.overflow) == 0


def test_played_velocity_keeps_a_slow_motion_between_counts():
    p = np.array([0.0, 0.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 1.0, 1.0])
    v = np.array([-0.1, 0.1, 0.5, 0.5, -0.2, 0.5, 0.3, -0.4, -0.5, 0.2])
    # before any motion: 0; standing after an up-step: up kept, down zeroed; after the
    # down-step: down kept, up zeroed
    expected = [0.0, 0.0, 0.5, 0.5, 0.0, 0.5, 0.3, 0.0, -0.5, 0.0]
    np.testing.assert_array_equal(np.asarray(played_velocity(p, v)), expected)
