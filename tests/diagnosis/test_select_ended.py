"""Which fits the diagnosis's rule takes as final (`fitting._refits._converged`): a fit
whose steps gain nothing at a kink of the cost (stalled, or the solver's step test first)
ended by a rule of its own, its values final, though `fit` reports it NOT converged; a fit
cut at its step limit, stuck at its start, a failed solve, or one failing `fit`'s own
checks did not."""

import types

import numpy as np
import optimistix as optx
import pytest

from fitting._refits import _converged


STALL = ("NOT converged: the steps stalled: the last 8 gained under 0.01 noise variances, "
         "482 predicted, more than chance allows (10.4): the linear model does not hold here "
         "(a kink of the cost) and the fit may be stuck")


def _res(result, stopped, stop, rmse=0.1):
    """A fit's result as `fit` sets it: result code, words and stop kind
    (`fitting._result.STOPS`)."""
    return types.SimpleNamespace(result=result, stopped=stopped, stop=stop,
                                 rmse=np.asarray(rmse))


@pytest.mark.parametrize("res, ended", [
    (_res(optx.RESULTS.successful, "the Gauss-Newton decrease left is 0.3 noise variances",
          "converged"), True),
    (_res(optx.RESULTS.nonlinear_divergence, STALL, "kink"), True),
    (_res(optx.RESULTS.nonlinear_max_steps_reached, "max_steps = 300 reached", "max_steps"),
     False),
    (_res(optx.RESULTS.nonlinear_divergence, STALL, "kink", rmse=np.nan), False),
    (_res(optx.RESULTS.nonlinear_divergence, STALL + "; NOT converged: pinned at a bound "
          "of its transform: Fs", "checks"), False),
    (_res(optx.RESULTS.nonlinear_divergence, "NOT converged: the solver's own test fired "
          "(last step within rtol/atol) before the fit settled: 933 noise variances "
          "predicted left", "kink"), True),
    (_res(optx.RESULTS.nonlinear_divergence, "the solver's own test fired without moving "
          "the fit although the gradient is not nil (cosine 1e-2): the fit is stuck", "stuck"),
     False),
    (_res(optx.RESULTS.nonlinear_divergence, "the solver stopped (non-finite cost)",
          "failed"), False),
], ids=["converged", "stalled at a kink", "step limit", "non-finite", "pinned",
        "step test before settling", "stuck at its start",
        "failed"])
def test_a_fit_stalled_at_a_kink_is_final(res, ended):
    assert _converged(res) is ended
