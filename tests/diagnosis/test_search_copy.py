"""The diagnosis's search copy (`fitting._diagnose._search_copy`): about `search_samples`
samples evenly in time, as many where the base model's states change, and every change of
the direction of motion with the sample before it, doubled until the base model simulated
on the copy is within the force's noise of its full-rate simulation. A copy of one sample
in k of the same size is not: it misses the reversal points and charges the lag's
forcing after each reversal and start over a long step (measured here: 0.4 N against
0.1 N of noise on point-to-point moves at 2 ms, 0.1 N on the 1 ms diagnosis motion, 1 N
against 0.25 N on the EMPS record)."""

import pathlib

import equinox as eqx
import numpy as np
import pytest

import fitting
from fitting import _diagnose
from fitting._candidates import Data
from fitting._select import _blocks, time_block_folds
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


def test_the_copy_spreads_its_samples_in_time_and_where_the_states_change():
    t = np.linspace(0.0, 10.0, 10_001)
    ref = np.where(t < 1.0, 100.0 * t, 100.0)  # the state changes only in the first second
    d = Data(t, np.zeros_like(t), np.zeros_like(t), ref)
    idx = np.unique(_diagnose._spread(d, np.r_[0.0, np.abs(np.diff(ref))], 200))
    early = np.count_nonzero(t[idx] < 1.0)
    assert 200 <= early <= 225  # 200 where the state changes, plus time's
    assert np.max(np.diff(t[idx])) <= 10.0 / 199 + 1e-3  # and 200 evenly in time
    assert idx[0] == 0 and idx[-1] == t.size - 1


def test_the_copy_of_several_runs_keeps_each_run_and_its_first_sample():
    t = np.linspace(0.0, 1.0, 1000)
    runs = [np.sin(2 * np.pi * (i + 1) * t) for i in range(3)]
    d = Data(np.concatenate([t, t, t]), np.concatenate(runs), np.concatenate(runs),
             np.concatenate(runs), lengths=(1000, 1000, 1000))
    copy, _ = d.take(_diagnose._spread(d, np.abs(np.gradient(d.F)), 300))
    assert sum(copy.lengths) == copy.t.size and all(180 <= n <= 220 for n in copy.lengths)
    assert [r.t[0] for r in copy.runs()] == [0.0, 0.0, 0.0]


def test_held_out_blocks_on_an_uneven_copy_are_contiguous_and_of_equal_duration():
    full, start = _record("two_state_power", "two-state", 2e-3, motion="point_to_point",
                          duration=30.0)
    copy, _, _ = _diagnose._search_copy(full, start, 1500, _quiet)
    assert np.ptp(np.diff(copy.t)) > 10 * np.median(np.diff(full.t))  # uneven
    folds = time_block_folds(copy.t, 20, 4)
    blocks = [idx for _, idx in _blocks(folds)]
    assert len(blocks) == 20 and all(np.all(np.diff(b) == 1) for b in blocks)
    starts = sorted(copy.t[b[0]] for b in blocks)
    width = (copy.t[-1] - copy.t[0]) / 20
    step = np.max(np.diff(copy.t))
    assert np.allclose(np.diff(starts), width, atol=step)  # equal duration, not count


def test_emps_copy_follows_the_states_not_their_sum():
    """EMPS (real data; the drive force u) with the Stribeck curve and lag a diagnosis
    fits there (a drop of 100 N near 36 mm/s, a lag time constant of 13 to 130 ms): the
    lag cancels most of the drop in the force, not in the states a long step integrates.
    The copy spread by the states' change is faithful; spread by the force's change
    (`_spread` of its total variation) it is not (0.5 N RMS), nor is one sample in k."""
    path = DATA / "emps_estimation.csv"
    if not path.exists():
        pytest.skip(f"{path} not present")
    d = np.genfromtxt(path, delimiter=",", names=True)
    full, _ = _diagnose._record(d["t"], d["x"], d["u"], None, None, None, "central", 0.01)
    m = fitting.initial_model("two-state", full.t, full.x, full.F, full.v)
    m = eqx.tree_at(lambda m: (m.stribeck.Fs, m.stribeck.Fc, m.stribeck.Vs, m.stribeck.delta,
                               m.C, m.sigma2), m,
                    tuple(np.float64(v) for v in (112.0, 11.3, 0.0356, 19.2, 847.0, 283.0)))
    copy, _, words = _diagnose._search_copy(full, m, 5000, _quiet)
    assert 2 * copy.t.size <= full.t.size and "within the force's noise" in words
    sigma = _diagnose.noise_level(full.F)
    ref = full.simulate(m)
    assert _uniform_error(full, m, copy.t.size) > sigma
    by_force = np.r_[_diagnose._spread(full, np.r_[0.0, np.abs(np.diff(ref))], 5000),
                     _diagnose._reversals(full)]
    c, i = full.take(by_force)
    assert np.sqrt(np.mean((c.simulate(m) - ref[i]) ** 2)) > sigma


def test_the_copy_is_faithful_for_the_base_models_the_search_tries_too():
    """The copy made for the base model alone need not carry another model the search
    tries (here one with a steep Stribeck drop at 5 mm/s and a fast lag, as on EMPS)
    within the noise; the copy made for both does."""
    full, start = _record("gms_power", "two-state", 2e-3, motion="point_to_point",
                          duration=30.0)
    other = eqx.tree_at(lambda m: (m.stribeck.Fs, m.stribeck.Vs, m.stribeck.delta, m.C),
                        start, (5 * start.stribeck.Fc, np.float64(5e-3), np.float64(10.0),
                                np.float64(1e3)))
    sigma = _diagnose.noise_level(full.F)
    ref = full.simulate(other)

    def error(copy, idx):
        return np.sqrt(np.mean((copy.simulate(other) - ref[idx]) ** 2))

    alone, idx, _ = _diagnose._search_copy(full, start, 2500, _quiet)
    assert 2 * alone.t.size <= full.t.size and error(alone, idx) > sigma
    copy, idx, words = _diagnose._search_copy(full, start, 2500, _quiet, [("other", other)])
    assert 2 * copy.t.size <= full.t.size and "their simulations differ" in words
    assert error(copy, idx) <= sigma
