"""Starting models read off a measurement (`fitting.initial_model`), on data jaxfric's own
models did not make."""

import numpy as np
import pytest

import jaxfric
from fitting import initial_model
from jaxfric.synthetic import measurement


@pytest.fixture(scope="module")
def foreign():
    t, x, F = measurement("gms_power", ("offset",), noise=0.03, dt=1e-2, seed=6)
    return t, x, F, np.gradient(x, t)


def _rmse(model, t, x, F, v):
    return float(np.sqrt(np.mean((np.asarray(jaxfric.simulate(model, t, x, v)) - F) ** 2)))


def test_lugre_start_saturates_over_the_presliding_extent(foreign):
    # The LuGre start's bristles saturate over the presliding extent the two-state start
    # estimates (sigma0 = 1/l1), so it is about as close to the data as that start; from
    # the shape's initial stiffness it was four times further.
    t, x, F, v = foreign
    two_state = initial_model("two-state", t, x, F, v)
    lugre = initial_model("lugre", t, x, F, v)
    assert float(lugre.sigma0) == pytest.approx(1.0 / float(two_state.shape.l1))
    assert _rmse(lugre, t, x, F, v) < 1.5 * _rmse(two_state, t, x, F, v)
