"""The kind of stop of a fit (`FitResult.stop`, one of `fitting._result.STOPS`), decided
where the fit stops and carried through `fit`, `fit_datasets`, `fit_batch` and the result's
JSON; the diagnosis reads it (`fitting._refits._converged`) instead of the words of
``stopped``. (Kinks, stuck fits and failed checks: test_termination.py,
test_fit_statuses.py, test_honest_fits.py.)"""

import dataclasses

import numpy as np
import optimistix as optx
import pytest

import fitting
import jaxfric
from fitting._refits import _converged
from fitting._result import final_stop, STOPS
from fitting.cli._io import result_json
from jaxfric import paper
from jaxfric.units import LINEAR


@pytest.fixture(scope="module")
def strokes():
    """Tustin's model on +-2 mm strokes (3 s period) at 1 ms, 0.05 N of noise; a start
    with Fs 10 % high."""
    t = np.arange(0.0, 6.0, 1e-3)
    x = 2e-3 * np.sin(2 * np.pi * t / 3.0)
    F = np.asarray(jaxfric.simulate(paper.tustin(), t, x))
    F = F + 0.05 * np.random.default_rng(3).standard_normal(t.size)
    start = fitting.initial_model("tustin", t, x, F)
    return t, x, F, start


def test_converged_and_max_steps_for_fit_and_fit_datasets(strokes):
    t, x, F, start = strokes
    done = fitting.fit(start, t, x, F)
    assert bool(done.converged) and done.stop == "converged", done.stopped
    cut = fitting.fit(start, t, x, F, max_steps=2)
    assert not bool(cut.converged) and cut.stop == "max_steps", cut.stopped
    none = fitting.fit(start, t, x, F, max_steps=0)
    assert none.stop == "max_steps"
    both = fitting.fit_datasets(start, [fitting.Dataset(t=t, x=x, F=F)] * 2, max_steps=2)
    assert both.stop == "max_steps"
    assert set(STOPS) >= {done.stop, cut.stop}


def test_a_minimiser_fit_has_a_stop_kind(strokes):
    """`fit` and `fit_batch` with an optimistix minimiser (one compiled loop, no chunks):
    the kind comes from its result code."""
    t, x, F, start = strokes
    bfgs = optx.BFGS(rtol=1e-8, atol=1e-8)
    cut = fitting.fit(start, t, x, F, solver=bfgs, max_steps=3)
    assert cut.stop == "max_steps", (cut.status, cut.stop)
    both = fitting.fit_batch(start, np.stack([t, t]), np.stack([x, x]), np.stack([F, F]),
                             solver=bfgs, max_steps=3)
    assert both.stop == ("max_steps", "max_steps"), (both.status, both.stop)


def test_batch_kinds_per_dataset_and_in_the_json(strokes):
    t, x, F, start = strokes
    shape = (2, t.size)
    res = fitting.fit_batch(start, np.broadcast_to(t, shape), np.broadcast_to(x, shape),
                            np.stack([F, F[::-1].copy()]), max_steps=256)
    assert isinstance(res.stop, tuple) and len(res.stop) == 2
    assert res[0].stop == res.stop[0] == "converged", res.stop
    assert res[1].stop == res.stop[1] != "", res.stop
    one = fitting.fit(start, t, x, F)
    assert result_json(LINEAR, one, _Measured(t.size))["stop"] == "converged"


@dataclasses.dataclass
class _Measured:
    """What `result_json` reads of a measurement."""

    size: int
    kind: str = LINEAR
    source: str = "m.csv"

    def __len__(self):
        return self.size


def test_final_stop_applies_the_checks():
    ok, div = optx.RESULTS.successful, optx.RESULTS.nonlinear_divergence
    assert final_stop("max_steps", ok, False) == "converged"  # at the optimum at its limit
    assert final_stop("kink", div, False) == "kink"
    assert final_stop("kink", div, True) == "checks"
    assert final_stop("converged", div, True) == "checks"
    assert final_stop("stuck", div, True) == "stuck"
    assert final_stop("kink", optx.RESULTS.nonfinite, False) == "failed"


def test_the_diagnosis_reads_the_stop_kind_not_the_words(strokes):
    """`_converged` takes a fit stopped at a kink as final by its kind, whatever its words
    say, and one cut at its step limit as not final even if its words read like a kink."""
    t, x, F, start = strokes
    cut = fitting.fit(start, t, x, F, max_steps=2)
    assert cut.result == optx.RESULTS.nonlinear_max_steps_reached
    diverged = dataclasses.replace(cut, result=optx.RESULTS.nonlinear_divergence)
    kink = dataclasses.replace(diverged, stop="kink", stopped="stalled where it stood")
    assert _converged(kink)
    looks = dataclasses.replace(diverged, stop="max_steps",
                                stopped="NOT converged: the steps stalled")
    assert not _converged(looks)
    assert not _converged(dataclasses.replace(kink, rmse=np.asarray(np.nan)))
