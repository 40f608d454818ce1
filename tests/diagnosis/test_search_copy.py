"""The diagnosis's search copy (`fitting._diagnose._search_copy`): about `search_samples`
samples evenly in time, as many where the base model's states change, and every change of
the direction of motion with the sample before it, doubled until the base model simulated
on the copy is within the force's noise of its full-rate simulation. A copy of one sample
in k of the same size is not: it misses the reversal points and charges the lag's
forcing after each reversal and start over a long step (measured here: 0.4 N against
0.1 N of noise on point-to-point moves at 2 ms, 0.1 N on the 1 ms diagnosis motion, 1 N
against 0.25 N on the EMPS record)."""

import pathlib

import numpy as np
import pytest

import fitting
from fitting import _diagnose
from fitting._candidates import Data
from jaxfric import synthetic
from jaxfric.motion import make_motion


DATA = pathlib.Path(__file__).resolve().parents[3] / "shared" / "data"


def _quiet(*_):
    return None


def test_noise_level_is_the_white_noise_of_a_smooth_force_with_steps():
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 10.0, 20_000)
    F = 20.0 * np.sign(np.sin(2 * np.pi * t / 2.0)) + np.sin(t)  # steps at reversals
    assert _diagnose.noise_level(F + 0.1 * rng.standard_normal(t.size)) == pytest.approx(
        0.1, rel=0.05)


def _record(truth, family, dt, **kw):
    t, x, F = synthetic.measurement(truth, (), dt=dt, noise=0.1, **kw)
    full, _ = _diagnose._record(t, x, F, None, None, None, "central", None)
    extra = {"n_elements": 20} if family == "gms" else {}
    return full, fitting.initial_model(family, t, x, F, full.v, **extra)


def _uniform_error(full: Data, model, size: int) -> float:
    """The RMS change of `model`'s simulation on one sample in k, a copy of about `size`."""
    copy, idx = full.every(max(2, full.t.size // size))
    return float(np.sqrt(np.mean((copy.simulate(model) - full.simulate(model)[idx]) ** 2)))


@pytest.mark.parametrize(("truth", "family", "dt", "kw"), [
    ("two_state_power", "two-state", 2e-3, {"motion": "point_to_point", "duration": 30.0}),
    ("gms_power", "gms", 1e-3, {}),
])
def test_the_copy_is_faithful_where_one_sample_in_k_of_its_size_is_not(truth, family, dt, kw):
    full, start = _record(truth, family, dt, **kw)
    copy, idx, words = _diagnose._search_copy(full, start, 2500, _quiet)
    assert 2 * copy.t.size <= full.t.size and "within the force's noise" in words
    sigma = _diagnose.noise_level(full.F)
    err = np.sqrt(np.mean((copy.simulate(start) - full.simulate(start)[idx]) ** 2))
    assert err <= sigma
    assert _uniform_error(full, start, copy.t.size) > sigma  # the copy the diagnosis had
    assert np.array_equal(copy.t, full.t[idx]) and np.array_equal(copy.v, full.v[idx])
    assert np.array_equal(copy.a, full.a[idx])  # the full-rate estimates, not the copy's


def test_the_copy_keeps_every_reversal_and_its_reversal_point():
    """Each sample where the model's direction changes (`Motion.reversal`), and the one
    before it (the reversal point, ``x_prev``), so the memory's branches start where they
    start on every sample."""
    full, start = _record("two_state_power", "two-state", 2e-3, motion="point_to_point",
                          duration=30.0)
    _, idx, _ = _diagnose._search_copy(full, start, 1500, _quiet)
    motion = make_motion(full.t, full.x, full.v).consistent()
    turns = np.flatnonzero(np.asarray(motion.reversal))
    assert turns.size > 10
    assert np.isin(turns, idx).all() and np.isin(turns - 1, idx).all()
    starts = np.flatnonzero(np.asarray(motion.moving)[1:] & ~np.asarray(motion.moving)[:-1])
    assert starts.size > 10 and np.isin(starts + 1, idx).all()


def test_point_to_point_moves_with_a_gms_keep_their_dwells_at_rest():
    """A 20-element GMS start model on point-to-point moves at 2 ms: the dwells are at
    rest (the central difference is exactly 0 there), so the direction of motion changes
    only at the moves' starts, stops and reversals, and a copy of under half the samples
    is faithful. (With `numpy.gradient`'s round-off on the dwells, the direction flipped on
    most of their samples and the search took every sample.)"""
    full, start = _record("gms_power", "gms", 2e-3, motion="point_to_point", duration=30.0)
    assert _diagnose._reversals(full).size < 0.05 * full.t.size
    copy, idx, words = _diagnose._search_copy(full, start, 2500, _quiet)
    assert 2 * copy.t.size < full.t.size and "within the force's noise" in words
    err = np.sqrt(np.mean((copy.simulate(start) - full.simulate(start)[idx]) ** 2))
    assert err <= _diagnose.noise_level(full.F)
