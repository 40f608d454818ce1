"""The friction lag of the two-state model does not depend on the sampling (docs/algorithm.md
section 4, step 4): on a motion of piecewise-constant speed (rest, strokes at 1-20 mm/s,
reversals at speed, a dwell), sampled every 20 ms at the speed changes, F_l follows the same
motion sampled every 0.1 ms. A step that reverses or starts the motion crosses the whole
presliding range (144 um) at 10 mm/s; charging the Stribeck drop ``s(v) - Fs`` on it with
gamma = 1 would put up to ``Fs - Fc`` (5 N) into F_l."""

import numpy as np

import jaxfric
from jaxfric.examples import diagnosis_truth


FINE = 1e-4  # s
#: (speed m/s, duration s): every duration a multiple of the coarse sampling.
PROFILE = [(0.0, 0.2), (10e-3, 0.4), (-10e-3, 0.6), (2e-3, 1.0), (0.0, 0.3), (2e-3, 0.5),
           (-5e-3, 0.8), (20e-3, 0.3), (-1e-3, 1.0)]


def _motion():
    v = np.concatenate([[0.0]] + [np.full(round(T / FINE), s) for s, T in PROFILE])
    t = np.arange(v.size) * FINE
    x = np.concatenate([[0.0], np.cumsum(v[1:] * FINE)])
    return t, x, v


def test_the_lag_does_not_depend_on_the_sampling():
    model = diagnosis_truth()
    t, x, v = _motion()
    fine = np.asarray(jaxfric.simulate(model, t, x, v, full_output=True).parts["lag"])
    assert np.abs(fine).max() > 0.3 * (24.0 - 19.0)  # the motion does excite the lag
    for every in (20, 200):  # 2 ms and 20 ms
        coarse = jaxfric.simulate(model, t[::every], x[::every], v[::every], full_output=True)
        err = np.abs(np.asarray(coarse.parts["lag"]) - fine[::every])
        assert err.max() < 0.02 * (24.0 - 19.0), (every, err.max())
