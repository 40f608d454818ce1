"""`fitting._blas.single_threaded_blas`: every OpenBLAS of the process on one thread inside
the block, nested blocks included, and the previous thread counts back afterwards."""

import numpy as np
import pytest

from fitting import _blas


def test_single_threaded_blas_sets_and_restores():
    np.ones((2, 2)) @ np.ones((2, 2))  # NumPy's BLAS is loaded
    libs = _blas._openblas_libraries()
    if not libs:
        pytest.skip("no OpenBLAS in this process")
    for _, put in libs:
        put(2)  # a count other than 1, so that the test can tell
    try:
        before = [get() for get, _ in libs]
        with _blas.single_threaded_blas():
            assert [get() for get, _ in libs] == [1] * len(libs)
            with _blas.single_threaded_blas():
                assert [get() for get, _ in libs] == [1] * len(libs)
            assert [get() for get, _ in libs] == [1] * len(libs)  # the outer block holds
        assert [get() for get, _ in libs] == before
    finally:
        for (_, put), count in zip(libs, before):
            put(count)


def test_disabled_does_nothing():
    libs = _blas._openblas_libraries()
    if not libs:
        pytest.skip("no OpenBLAS in this process")
    before = [get() for get, _ in libs]
    _blas.ENABLED = False
    try:
        with _blas.single_threaded_blas():
            assert [get() for get, _ in libs] == before
    finally:
        _blas.ENABLED = True
