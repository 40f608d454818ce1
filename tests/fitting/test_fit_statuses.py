"""Honest statuses of batch fits (issue 21 item 2) and weakly determined directions reported
with their correlations (issue 19 item 1)."""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest

import fitting
import jaxfric
from fitting.cli._io import param_table
from jaxfric import paper


NOISE = 0.05  # N


@pytest.fixture(scope="module")
def tustin_data():
    """Tustin's model on sliding strokes at 1 ms plus 0.05 N of noise; a start 10 % off."""
    t = np.arange(0.0, 2.0, 1e-3)
    x = 1e-3 * (1 - np.cos(2 * np.pi * t / 1.0))
    true = paper.tustin()
    rng = np.random.default_rng(21)
    forces = np.stack([np.asarray(jaxfric.simulate(true, t, x))
                       + NOISE * rng.normal(size=t.shape) for _ in range(3)])
    start = eqx.tree_at(lambda m: (m.stribeck.Fs, m.sigma2), true,
                        (1.1 * true.stribeck.Fs, 0.9 * true.sigma2))
    return t, x, forces, start


def _batch(data, forces, **kw):
    t, x, _, start = data
    shape = forces.shape
    return fitting.fit_batch(start, np.broadcast_to(t, shape), np.broadcast_to(x, shape),
                             forces, **kw)


def test_batch_with_zero_steps_is_not_success(tustin_data):
    res = _batch(tustin_data, tustin_data[2], max_steps=0)
    assert list(np.asarray(res.num_steps)) == [0, 0, 0]
    assert res.status == ["nonlinear_max_steps_reached"] * 3
    assert not np.any(np.asarray(res.converged))
    assert res.stop == ("max_steps",) * 3


def test_batch_marks_a_non_finite_cost_per_dataset(tustin_data):
    forces = np.array(tustin_data[2])
    forces[1, 100] = 1e300  # squared, the cost overflows to inf
    with pytest.warns(jaxfric.data.DataWarning, match=r"dataset 1: F\[100\]"):
        res = _batch(tustin_data, forces)  # named, and that dataset fails alone
    status = res.status
    assert status[0] == status[2] == "successful", status
    assert status[1] != "successful" and not bool(res.converged[1])
    assert res.stop == ("converged", "failed", "converged") and res[1].stop == "failed"
    assert not np.isfinite(float(res.rmse[1]))
    assert np.all(np.isfinite(np.asarray(res.rmse)[[0, 2]]))


def test_weakly_determined_pairs_are_reported_with_their_correlation(tustin_data):
    t, x, forces, start = tustin_data
    res = fitting.fit(start, t, x, forces[0])
    assert bool(res.converged), (res.status, res.stopped)
    corr = np.array(res.corr_fit)
    free = [i for i, n in enumerate(res.fit_names) if n in res.free]
    # Whatever the data, the list holds exactly the free pairs above the threshold.
    expected = {(res.fit_names[i], res.fit_names[j]) for k, i in enumerate(free)
                for j in free[k + 1:] if abs(corr[i, j]) > 0.5}
    assert {(a, b) for a, b, _ in res.weakly_determined(0.5)} == expected
    # A pair made nearly collinear shows in the result, the summary and the CLI table.
    i, j = free[0], free[1]
    corr[i, j] = corr[j, i] = -0.9995
    weak = eqx.tree_at(lambda r: r.corr_fit, res, jnp.asarray(corr))
    pairs = weak.weakly_determined()
    assert pairs[0] == (res.fit_names[i], res.fit_names[j], pytest.approx(-0.9995))
    assert all(abs(c) > fitting._result.WEAK_CORRELATION for _, _, c in pairs)
    for text in (weak.summary(), param_table(weak)):
        assert "weakly determined" in text and "-0.9995" in text
        assert f"{res.fit_names[i]} ~ {res.fit_names[j]}" in text
    # Held parameters are never reported.
    held = dataclasses.replace(weak, free=tuple(n for n in res.free if n != res.fit_names[i]))
    assert all(res.fit_names[i] not in p[:2] for p in held.weakly_determined())


def test_a_batch_fit_that_never_leaves_its_start_is_not_converged(tustin_data):
    """A solver that gives up at once (huge tolerances) claims success after one step at
    its start: off the optimum that is stuck, at the optimum it is converged."""
    t, x, _, start = tustin_data
    clean = np.broadcast_to(np.asarray(jaxfric.simulate(paper.tustin(), t, x)), (2, t.size))
    lazy = optx.LevenbergMarquardt(rtol=1e3, atol=1e3)
    off = _batch(tustin_data, clean, solver=lazy)
    assert float(off.params["Fs"][0]) == float(start.stribeck.Fs)  # it did not move
    assert off.status == ["nonlinear_divergence"] * 2 and off.stop == ("stuck",) * 2
    at = fitting.fit_batch(paper.tustin(), np.broadcast_to(t, clean.shape),
                           np.broadcast_to(x, clean.shape), clean, solver=lazy)
    assert at.status == ["successful"] * 2 and np.all(np.asarray(at.rmse) < 1e-9)
    assert at.stop == ("converged",) * 2
