"""The Numba baseline of benchmarks/throughput.py computes the same model as jaxfric.

`benchmarks/numba_two_state.py` is a hand-written float64 loop of docs/algorithm.md section 4;
a speed comparison only means something if it gives the same forces as
`jaxfric.simulate(paper.two_state(), ...)`: here to < 1e-9 N on nested reversals, strokes
with small loops at the ends, and an irregularly sampled two-sine path with a given
velocity, and with a 3-entry stack that overflows (same overflow count). Its analytic
shape (Pi, gamma) is checked against the independent NumPy reference too.
"""

import warnings

import numpy as np
import pytest


pytest.importorskip("numba")

import jaxfric
from benchmarks import numba_two_state as nb
from jaxfric import paper

from . import reference
from .helpers import nested_path, sine_path, strokes_path


TOL = 1e-9  # N


def test_paper_params_match_jaxfric():
    assert nb.params_from_model(paper.two_state()) == pytest.approx(nb.paper_params(), rel=1e-15)


def test_shape_pi_gamma_match_reference():
    """The baseline's analytic Pi and gamma = Pi - xi*kappa (with the clip at 1) against the
    independent reference, from 0 through the clipped part to beyond l1."""
    p = nb.paper_params()
    sh = {k: p[k] for k in ("a", "b", "c", "alpha", "beta", "l1")}
    Fs, l1 = p["Fs"], p["l1"]
    consts = nb.shape_constants(p)
    xi = np.linspace(0.0, 1.1 * l1, 1201)
    got = np.array([nb._pi_gamma(q, *consts) for q in xi])
    np.testing.assert_allclose(got[:, 0], reference.paper_pi(xi, **sh, Fs=Fs), rtol=0, atol=1e-12)
    np.testing.assert_allclose(got[:, 1], reference.paper_gamma(xi, **sh, Fs=Fs), rtol=0,
                               atol=1e-12)


@pytest.mark.parametrize(("path", "stack_size"),
                         [("nested", 16), ("strokes", 16), ("sine", 16), ("nested", 3)])
def test_forces_agree_with_jaxfric(path, stack_size):
    if path == "nested":
        t, x = nested_path()
        v = None
    elif path == "strokes":
        t, x = strokes_path()
        v = None
    else:
        t, x, v = sine_path(n=4000, irregular=True)
    model = paper.two_state(stack_size)
    with warnings.catch_warnings():  # K = 3 overflows on purpose: both must drop alike
        warnings.simplefilter("ignore", jaxfric.StackOverflowWarning)
        ref = jaxfric.simulate(model, t, x, v, full_output=True)
    force, overflow = nb.simulate_numba(nb.params_from_model(model), t, x, v, stack_size,
                                        full_output=True)
    assert overflow == int(ref.overflow)
    assert (overflow > 0) == (stack_size == 3)
    assert np.max(np.abs(force - np.asarray(ref.force))) < TOL


def test_batch_equals_single():
    t, x = nested_path(dt=4e-3)
    X = np.stack([x, 0.5 * x, -x + 3e-6])
    T = np.stack([t, t + 1.0, t])
    params = nb.paper_params()
    F = nb.simulate_numba_batch(params, T, X)
    for j in range(X.shape[0]):
        np.testing.assert_array_equal(F[j], nb.simulate_numba(params, T[j], X[j]))

