"""The diagnosis runs its independent fits in threads (`fitting._refits.Fitter.map`): the
results are those of one fit after another, in order; the calls really overlap; an error
is raised at once and the calls not begun are dropped; ``JAXFRIC_WORKERS`` sets how many
run at once."""

import threading
import time

import equinox as eqx
import numpy as np
import pytest

from fitting import _refits as R, diagnose
from fitting._rules import DiagnosisRules

from .test_select import _tustin_record


def _fitter(workers):
    return R.Fitter(None, workers=workers)


def test_map_returns_the_results_in_order_and_runs_the_calls_at_once():
    """Two calls that each wait for the other finish only if they run at the same time."""
    barrier = threading.Barrier(2, timeout=10)

    def meet(i):
        time.sleep(0.01 * (3 - i))  # the first one ends last
        barrier.wait()
        return i * i

    assert _fitter(2).map(meet, range(2)) == [0, 1]
    assert _fitter(1).map(lambda i: i + 1, range(5)) == [1, 2, 3, 4, 5]


def test_map_raises_at_once_and_drops_the_calls_not_begun():
    """Call 0 fails at once, the others take 0.3 s each: waiting for the running ones
    would take 0.3 s, running the 19 others 3 s."""
    begun = []

    def fail_first(i):
        begun.append(i)
        if i == 0:
            raise RuntimeError("fit 0 failed")
        time.sleep(0.3)
        return i

    t0 = time.perf_counter()
    with pytest.raises(RuntimeError, match="fit 0 failed"):
        _fitter(2).map(fail_first, range(20))
    assert time.perf_counter() - t0 < 0.25
    time.sleep(3.2)  # every call would have begun by now had they not been dropped
    assert len(begun) <= 4  # call 0, the other worker's, and what began before the raise


def test_each_thread_sees_its_own_last_fit():
    f = _fitter(2)
    barrier = threading.Barrier(2, timeout=10)

    def fit(i):
        f.last = i
        barrier.wait()  # both have set theirs
        return f.last

    assert f.map(fit, range(2)) == [0, 1]


@pytest.mark.parametrize("given", ["0", "-1", "two", "1.5"])
def test_the_number_of_workers_is_checked(monkeypatch, given):
    monkeypatch.setenv("JAXFRIC_WORKERS", given)
    with pytest.raises(ValueError, match="JAXFRIC_WORKERS"):
        R.default_workers()
    monkeypatch.setenv("JAXFRIC_WORKERS", " 3 ")
    assert R.default_workers() == 3
    monkeypatch.delenv("JAXFRIC_WORKERS")
    assert R.default_workers() >= 1


def test_a_diagnosis_in_threads_is_the_diagnosis_one_fit_after_another(monkeypatch):
    """Every trial's fits (effects, pairs, a base model's starts, the folds) give the
    same numbers whether they run at once or one after another."""
    start, t, x, F, v, a = _tustin_record(mass=4.0, duration=6.0)
    far = eqx.tree_at(lambda m: m.stribeck.Vs, start, np.float64(1.0))
    rules = DiagnosisRules(blocks=8, folds=2, tried=2)
    out = {}
    for workers in ("1", "2"):
        monkeypatch.setenv("JAXFRIC_WORKERS", workers)
        d = diagnose(start, t, x, F, v, a=a, effects=("inertia", "offset", "quadratic_drag"),
                     rules=rules, max_added=2,
                     base_models=[("Tustin again", (("far", far), ("near", start)))])
        out[workers] = d
    one, two = out["1"], out["2"]
    assert one.final.added == two.final.added == ["inertia"]
    assert [tr["effects"] for tr in one.trials] == [tr["effects"] for tr in two.trials]

    def numbers(trial):
        return {k: v for k, v in trial.items() if not isinstance(v, (list, dict))}

    assert [numbers(tr) for tr in one.trials] == [numbers(tr) for tr in two.trials]
    assert any(tr["z"] is not None for tr in one.trials)  # a cross-validation compared
    assert float(one.model.effects[0].mass) == float(two.model.effects[0].mass)


def test_compile_ahead_compiles_what_the_fit_to_come_runs(monkeypatch):
    """After `Fitter.compile_ahead` (a fit of no step, in a thread), the fit of that model
    traces no solver program of its own; with one worker nothing is started."""
    from fitting import _chunked
    from fitting._candidates import Data

    start, t, x, F, v, a = _tustin_record(mass=4.0, duration=3.37)  # a length of its own
    traced = []
    inner = _chunked._chunk_steps

    def counting(*args, **kwargs):
        traced.append(threading.current_thread().name)
        return inner(*args, **kwargs)

    monkeypatch.setattr(_chunked, "_chunk_steps", counting)
    data = Data(t=t, x=x, v=v, F=F, a=a)
    assert R.Fitter(data, workers=1).compile_ahead([lambda: (start, frozenset())]) == []
    fitter = R.Fitter(data, workers=2, max_steps=20)
    threads = fitter.compile_ahead([lambda: (start, frozenset())])
    for thread in threads:
        thread.join()
    assert traced and set(traced) == {"jaxfric-compile"}
    _, pred = fitter.fit(start, frozenset())
    assert len(traced) == 1 and int(fitter.last.num_steps) > 0
    assert np.all(np.isfinite(pred))
