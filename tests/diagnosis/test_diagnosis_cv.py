"""The diagnosis by full refits and blocked cross-validation (`fitting.diagnose`) on
files jaxfric did not make with its own families: a 60-element GMS truth with a power-law
virgin curve (`jaxfric.synthetic`), point-to-point moves with short strong accelerations
(2 ms sampling, position only: the velocity is derived), and today's diagnosis motion.
Slow: each diagnosis refits every candidate and cross-validates the best (tens of minutes
with the GMS base candidate on a loaded 2-core machine)."""

import numpy as np
import pytest

import fitting
from fitting import diagnose
from jaxfric import synthetic
from jaxfric.effects import EFFECTS


pytestmark = pytest.mark.slow


def _p2p(hidden):
    return synthetic.measurement("gms_power", hidden, dt=2e-3, motion="point_to_point",
                                 duration=30.0, noise=0.1)


def _diagnose(t, x, F):
    start = fitting.initial_model("two-state", t, x, F, fitting.estimate_velocity(t, x))
    return diagnose(start, t, x, F, model_name="two-state")


def _true_mass(t_fine_dt=2e-4):
    """The mass `synthetic.hidden_force` hides on the point-to-point file: 2 N at the 90th
    percentile of |a| on its fine grid."""
    from jaxfric import trajectories

    t = np.arange(0.0, 30.0, t_fine_dt)
    x = trajectories.point_to_point(t, np.random.default_rng(0))
    a = np.gradient(np.gradient(x, t), t)
    return 2.0 / np.quantile(np.abs(a)[np.abs(a) > 0.01 * np.abs(a).max()], 0.9)


def test_point_to_point_mass_error_is_found_and_recovered():
    """The mass is the first effect added, with its value, and the held-out error falls;
    a GMS base model may be added before or after it (the two-state model's presliding
    mismatch is most of the residual: the base model is the limit here), as in the
    other point-to-point and diagnosis-motion tests."""
    d = _diagnose(*_p2p(("inertia",)))
    assert [n for n in d.final.added if n in EFFECTS][:1] == ["inertia"], \
        d.summary()
    mass = float(next(e for e in d.model.effects if e.name == "inertia").mass)
    assert mass == pytest.approx(_true_mass(), rel=0.2)
    assert d.final.rmse_holdout < d.baseline.rmse_holdout


def test_point_to_point_quadratic_drag_is_found():
    """Searched on every sample (one sample in 3 changes the simulation by far more than
    the noise): a GMS base model first (the two-state model is the limit here), then the
    drag."""
    d = _diagnose(*_p2p(("quadratic_drag",)))
    assert "quadratic_drag" in d.final.added


def test_point_to_point_clean_file_gets_no_effect():
    d = _diagnose(*_p2p(()))
    assert [n for n in d.final.added if n in EFFECTS] == []


@pytest.mark.parametrize(("truth", "hidden"), [
    ("gms_power", "cogging"),
    ("lugre", "offset"),
])
def test_diagnosis_motion_singles_are_still_found(truth, hidden):
    """Found, possibly after the base model was replaced by a GMS (the truth's family)."""
    d = _diagnose(*synthetic.measurement(truth, (hidden,), dt=1e-2))
    assert [n for n in d.final.added if n in EFFECTS] == [hidden]
