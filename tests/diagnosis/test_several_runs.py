"""The diagnosis of several runs (issue 38): the runs concatenated in one record
(`fitting._candidates.Data`), leave-one-run-out folds (`fitting._select.run_folds`) and
their blocks, fits of every run at once with per-run parameters, and a whole diagnosis of
three runs where one run carries a disturbance of its own (slow)."""

import sys
from pathlib import Path

import numpy as np
import pytest

import fitting
import jaxfric
from fitting import _refits as R, _select as S
from fitting._candidates import _code
from fitting._diagnose import _records
from jaxfric import effects as fx


def _runs(lengths=(120, 80, 100), seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for i, n in enumerate(lengths):
        t = 5.0 * i + np.arange(n) * (1e-2 * (i + 1))  # other rates, other clocks
        x = np.sin(2 * np.pi * t / (t[-1] - t[0]))
        out.append(fitting.Dataset(t=t, x=x, F=rng.normal(size=n)))
    return out


def test_run_folds_hold_out_each_run_once_in_blocks():
    data, _ = _records(_runs(), "central", None)
    assert data.lengths == (120, 80, 100) and data.n_runs == 3
    folds = S.run_folds(data.t, data.lengths, blocks=20)
    assert len(folds) == 3
    held = np.stack([te > 0 for _, te in folds])
    assert np.all(held.sum(axis=0) == 1)  # every sample held out exactly once
    for (train, test), sl in zip(folds, data.slices()):
        assert np.all(test[sl] > 0) and not np.any(np.delete(test, np.r_[sl]) > 0)
        assert np.all(train[sl] == 0) and np.all(np.delete(train, np.r_[sl]) == 1)
    blocks = S._blocks(folds)
    # 20 blocks in total: ceil(20 / 3) = 7 time blocks per held-out run, in that run only
    assert [k for k, _ in blocks] == [0] * 7 + [1] * 7 + [2] * 7
    assert sorted(np.concatenate([idx for _, idx in blocks]).tolist()) == list(
        range(data.t.size))
    for k, idx in blocks:
        sl = data.slices()[k]
        assert sl.start <= idx.min() and idx.max() < sl.stop


def test_one_run_folds_unchanged():
    """One run: the time-block folds, their blocks by contiguity as before."""
    t = np.linspace(0, 10, 400)
    assert len(S._blocks(S.time_block_folds(t, 20, 4))) == 20


def test_data_every_and_runs_keep_the_runs_apart():
    data, _ = _records(_runs(), "central", None)
    copy, idx = data.every(3)
    assert copy.lengths == (40, 27, 34)
    assert np.array_equal(copy.t, data.t[idx])
    assert [r.t[0] for r in copy.runs()] == [r.t[0] for r in data.runs()]


def test_fit_of_runs_has_an_offset_per_run_and_predicts_a_left_out_run_at_their_mean():
    """`Fitter.fit` fits all runs at once, one offset per run; with a run's weights at 0,
    it is not fitted, and is predicted with the mean offset of the runs fitted."""
    model = jaxfric.Tustin(jaxfric.Stribeck(Fs=2.0, Fc=1.5, Vs=0.05, delta=2.0), sigma2=1.0)
    offsets = (0.5, -0.3, 1.0)
    runs = []
    for i, off in enumerate(offsets):
        t = np.arange(0.0, 4.0, 1e-2)
        x = (1 + 0.2 * i) * np.sin(2 * np.pi * t / 2.0)
        v = np.gradient(x, t)
        F = np.asarray(jaxfric.simulate(model, t, x, v)) + off
        runs.append(fitting.Dataset(t=t, x=x, F=F, v=v))
    data, _ = _records(runs, "central", None)
    fitter = R.Fitter(data, max_steps=100)
    start = fitting.to_fit_representation(model + fx.Offset())
    fitted, pred = fitter.fit(start, frozenset({0}))
    got = np.asarray(fitted.effects[0].effect.offset)
    assert got == pytest.approx(offsets, abs=1e-6)
    assert np.max(np.abs(pred - data.F)) < 1e-6
    # the one-liner a report gives adds a plain offset: the mean over the runs
    assert _code(fitted.effects[0]).endswith("Offset(offset=0.4)")
    train = np.ones(data.t.size)
    train[data.slices()[2]] = 0.0  # run 3 left out
    fitted, pred = fitter.fit(start, frozenset({0}), weights=train)
    sl = data.slices()[2]
    assert pred[sl] - np.asarray(jaxfric.simulate(model, runs[2].t, runs[2].x, runs[2].v)) \
        == pytest.approx(np.full(sl.stop - sl.start, np.mean(offsets[:2])), abs=1e-6)


def test_several_runs_input_is_checked():
    runs = _runs()
    with pytest.raises(ValueError, match="given per run"):
        fitting.diagnose(jaxfric.paper.tustin(), runs, runs[0].x)
    bad = [runs[0], fitting.Dataset(t=runs[1].t, x=runs[1].x, F=runs[1].F[:-1])]
    with pytest.raises(ValueError, match="run 1"):
        fitting.diagnose(jaxfric.paper.tustin(), bad)


def _ripple_of(model) -> tuple[float, float]:
    """``(period, amplitude)`` of the strongest position ripple among `model`'s effects: a
    cogging, or the strongest harmonic of a ripple (its period over the harmonic's
    number); ``(nan, 0)`` without one."""
    best = (float("nan"), 0.0)
    for e in getattr(model, "effects", ()):
        if e.name == "cogging":
            amps = [float(np.hypot(e.cog_sin, e.cog_cos))]
            periods = [float(e.period)]
        elif e.name == "ripple":
            amps = list(np.hypot(np.asarray(e.rip_sin), np.asarray(e.rip_cos)))
            periods = [float(e.period) / (k + 1) for k in range(len(amps))]
        else:
            continue
        k = int(np.argmax(amps))
        if amps[k] > best[1]:
            best = (periods[k], float(amps[k]))
    return best


@pytest.mark.slow
def test_three_runs_find_the_shared_ripple_and_not_one_runs_disturbance():
    """The three-speeds example (examples/three_speeds.py), shortened: the position ripple
    of the joint (1 N m, period 0.3 rad) is in every run and is added (as a cogging, or as a
    ripple whose strongest harmonic has that period: the same force); the angle load of the
    fast run alone is not, and every run's held-out error falls."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "examples"))
    from three_speeds import diagnosis_of, runs

    d = diagnosis_of(runs(dt=1e-2, cycles=2))
    assert d.folds == "runs"
    assert "angle_load" not in d.final.added
    assert {"cogging", "ripple"} & set(d.final.added)
    period, amplitude = _ripple_of(d.model)
    assert period == pytest.approx(0.3, rel=0.02) and amplitude == pytest.approx(1.0, rel=0.1)
    for row in d.runs:  # every run's held-out error falls with the ripple
        assert row["rmse_holdout"][-1] < row["rmse_holdout"][0]
