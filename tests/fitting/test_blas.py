"""`fitting._blas.single_threaded_blas`: every BLAS of the process on one thread inside the
block, nested blocks included, and the previous thread counts back afterwards."""

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from fitting import _blas


def _counts() -> list[int]:
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_single_threaded_blas_sets_and_restores():
    np.ones((2, 2)) @ np.ones((2, 2))  # NumPy's BLAS is loaded
    if not _counts():
        pytest.skip("no BLAS that threadpoolctl controls in this process")
    with threadpool_limits(limits=2, user_api="blas"):  # a count other than 1
        before = _counts()
        with _blas.single_threaded_blas():
            assert _counts() == [1] * len(before)
            with _blas.single_threaded_blas():
                assert _counts() == [1] * len(before)
            assert _counts() == [1] * len(before)  # the outer block holds
        assert _counts() == before


def test_disabled_does_nothing():
    if not _counts():
        pytest.skip("no BLAS that threadpoolctl controls in this process")
    with threadpool_limits(limits=2, user_api="blas"):
        before = _counts()
        _blas.ENABLED = False
        try:
            with _blas.single_threaded_blas():
                assert _counts() == before
        finally:
            _blas.ENABLED = True


def test_a_diagnosis_holds_one_blas_thread_throughout(monkeypatch):
    """`fitting.diagnose` runs fits side by side in threads; per-fit limits alone leave
    them at 1.8-2.9x the CPU time each (benchmarks/profiling/parallel_fits.py), so it
    holds one limit around all of its work: the BLAS is on one thread when its search
    starts and in every fit's thread, also between two fits."""
    from fitting import _diagnose, _refits, diagnose
    from tests.diagnosis.test_select import _tustin_record

    np.ones((2, 2)) @ np.ones((2, 2))
    if not _counts():
        pytest.skip("no BLAS that threadpoolctl controls in this process")
    seen = []
    mapped = _refits.Fitter.map

    def map_(self, fun, items):
        def watched(item):
            seen.append(_counts())
            out = fun(item)
            seen.append(_counts())
            return out
        return mapped(self, watched, items)

    class Stop(Exception):
        pass

    def select(fitter, *args, **kwargs):
        seen.append(_counts())
        fitter.map(lambda i: None, range(2))
        raise Stop

    monkeypatch.setattr(_refits.Fitter, "map", map_)
    monkeypatch.setattr(_diagnose, "select", select)
    start, t, x, F, v, a = _tustin_record(mass=4.0, duration=2.0)
    with threadpool_limits(limits=2, user_api="blas"):
        before = _counts()
        with pytest.raises(Stop):
            diagnose(start, t, x, F, v, a=a, effects=("inertia",))
        assert _counts() == before
    assert len(seen) == 5 and all(c == [1] * len(before) for c in seen)
