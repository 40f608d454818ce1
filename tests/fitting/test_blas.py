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
