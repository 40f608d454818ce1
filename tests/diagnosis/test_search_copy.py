"""The diagnosis's search copy (`fitting._diagnose._faithful_step`): one sample in k only
where the start model simulated on the copy stays within the force's noise of its
full-rate simulation. On point-to-point moves at 2 ms (moves that start and stop within a
few samples) one sample in 3 changes a GMS start model's simulation by about 1.7 N RMS
against 0.1 N of noise, so the record is searched on every sample; on slow motions the
copy stays."""

import numpy as np
import pytest

import fitting
from fitting import _diagnose
from jaxfric import synthetic


def test_noise_level_is_the_white_noise_of_a_smooth_force_with_steps():
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 10.0, 20_000)
    F = 20.0 * np.sign(np.sin(2 * np.pi * t / 2.0)) + np.sin(t)  # steps at reversals
    assert _diagnose.noise_level(F + 0.1 * rng.standard_normal(t.size)) == pytest.approx(
        0.1, rel=0.05)


def _record(truth, dt, **kw):
    t, x, F = synthetic.measurement(truth, (), dt=dt, noise=0.1, **kw)
    full, _ = _diagnose._record(t, x, F, None, None, None, "central", None)
    return full, fitting.initial_model("gms", t, x, F, full.v, n_elements=20)


def test_point_to_point_moves_at_2_ms_are_searched_on_every_sample():
    full, start = _record("gms_power", 2e-3, motion="point_to_point", duration=30.0)
    k, words = _diagnose._faithful_step(full, start, 3, lambda *_: None)
    assert k == 1 and "not subsampled" in words


def test_a_slow_motion_keeps_its_copy():
    full, start = _record("gms_power", 1e-3)  # the diagnosis motion, 1 ms sampling
    k, words = _diagnose._faithful_step(full, start, 4, lambda *_: None)
    assert k > 1 and "within the force's noise" in words
