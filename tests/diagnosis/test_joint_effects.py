"""The effects of a joint angle (issue 18, item 4): `ripple` (a period that divides a turn,
with harmonics) and `angle_load` (``g_sin sin q + g_cos cos q``). Their terms against NumPy
are in test_effects.py, their C translations in test_export_c.py, the diagnosis naming them
on a foreign truth (slow) in test_diagnosis_foreign.py; here: what the screen searches, and
that a linear file is not searched for them."""

import math

import numpy as np
import pytest

import jaxfric
from fitting._candidates import Data, start_effect
from fitting._diagnose import effect_names
from jaxfric import effects as fx, paper


def _joint(count, seed=0):
    """A joint swinging over 2.4 rad at 0.2..1.5 rad/s (100 Hz), Tustin friction (N m) plus a
    ripple `count` times per turn, written here in NumPy, with noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 30.0, 0.01)
    x = 1.2 * np.sin(2 * np.pi * t / 7.0) + 0.1 * np.sin(2 * np.pi * t / 1.3)
    v = np.gradient(x, t)
    base = np.asarray(jaxfric.simulate(paper.tustin(), t, x, v))
    ripple = 0.6 * np.sin(count * x + 0.2) + 0.3 * np.cos(2 * count * x - 0.4)
    return t, x, v, base + ripple + 0.05 * rng.standard_normal(t.size)


def test_ripple_counts_are_every_integer_up_to_the_limit():
    x = np.linspace(0.0, 2.4, 5000)
    counts = [round(2 * math.pi / float(e.period)) for e in fx.Ripple.grid(None, x, None, None)]
    assert counts[0] == math.ceil(2 * math.pi / 2.4)
    np.testing.assert_array_equal(np.diff(counts), 1)
    assert counts[-1] == fx.RIPPLE_MAX


def test_ripple_start_finds_the_count_per_turn():
    """The diagnosis's start for a ripple (its grid point whose term best regresses the
    residual) has the count per turn and the harmonics' amplitudes."""
    t, x, v, F = _joint(count=37)
    model = paper.tustin()
    resid = F - np.asarray(jaxfric.simulate(model, t, x, v))
    e = start_effect("ripple", Data(t, x, v, F), model, resid)
    assert round(2 * math.pi / float(e.period)) == 37
    amps = np.hypot(np.asarray(e.rip_sin), np.asarray(e.rip_cos))
    np.testing.assert_allclose(amps[:2], [0.6, 0.3], atol=0.03)
    assert amps[2] < 0.03


def test_angle_effects_are_screened_on_rotary_data_only():
    linear = effect_names(None, set(), rotary=False)
    rotary = effect_names(None, set(), rotary=True)
    assert not set(fx.ROTARY_EFFECTS) & set(linear)
    assert set(rotary) == set(fx.EFFECTS) - set(fx.LOAD_EFFECTS)  # no load column here
    assert effect_names(["ripple"], set(), rotary=False) == ["ripple"]  # asked for: screened


def test_ripple_harmonics_are_vectors_of_one_length():
    with pytest.raises(ValueError, match="one entry per harmonic"):
        fx.Ripple(rip_sin=(0.1, 0.2), rip_cos=(0.1,), period=0.1)
    one = fx.Ripple(rip_sin=(0.5,), rip_cos=(0.0,), period=0.1)  # a single harmonic: cogging
    cog = fx.Cogging(cog_sin=0.5, cog_cos=0.0, period=0.1)
    t = np.linspace(0.0, 1.0, 50)
    x = np.sin(3 * t)
    np.testing.assert_allclose(jaxfric.simulate(paper.tustin() + one, t, x),
                               jaxfric.simulate(paper.tustin() + cog, t, x), rtol=0, atol=1e-12)
