"""What the diagnosis saves without changing what it decides (`fitting._select`): a fit of
the superset of effects computes its Jacobian over the free coordinates only
(`fitting._problem._Problem.narrowed`, the same fit bit for bit), and an option that
cannot qualify (not physical, or its fit on every sample not converged) is not
cross-validated."""

import types

import jax
import numpy as np

import jaxfric
from fitting import _params, _select as S
from fitting._candidates import _off, Data
from fitting._data import Dataset
from fitting._fit import fit_datasets
from fitting._problem import _problem
from fitting._rules import DiagnosisRules
from jaxfric import effects as fx


def _superset_record():
    """A Tustin truth with an offset on point-to-point moves, and the diagnosis's superset
    (Tustin + every switchable effect, held at 0) with its base and the offset free."""
    from jaxfric import trajectories

    t = np.arange(0.0, 6.0, 5e-3)
    x = trajectories.point_to_point(t, np.random.default_rng(0), accel_time=0.05)
    v = np.gradient(x, t)
    a = np.gradient(v, t)
    truth = jaxfric.Tustin(jaxfric.Stribeck(Fs=24.0, Fc=20.0, Vs=3e-3, delta=2.0),
                           sigma2=60.0)
    F = np.asarray(jaxfric.simulate(truth, t, x, v)) + 0.7
    F = F + 0.1 * np.random.default_rng(1).standard_normal(t.size)
    data = Data(t, x, v, F, a)
    names = [n for n in fx.EFFECTS if S.switchable(n) and n not in fx.ROTARY_EFFECTS
             and n not in fx.LOAD_EFFECTS]
    start = jaxfric.Tustin(jaxfric.Stribeck(Fs=20.0, Fc=18.0, Vs=5e-3, delta=2.0),
                           sigma2=40.0)
    superset = _params.to_fit_representation(start) + tuple(
        _off(data.grid(n)[0]) for n in names)
    fit_model, props = S.Fitter(data).props(superset, frozenset({names.index("offset")}))
    return data, fit_model, props


def test_a_superset_fit_is_the_same_with_the_jacobian_of_its_free_coordinates_only():
    data, fit_model, props = _superset_record()
    problem, _ = _problem(fit_model, props, None, True)
    narrow = problem.narrowed()
    free = int(np.sum(np.asarray(problem.layout.coordinate_mask())))
    assert problem.width is None and narrow.width is not None
    assert free <= narrow.width < sum(problem.layout.sizes)
    d = [Dataset(t=data.t, x=data.x, F=data.F, v=data.v, a=data.a)]
    wide = fit_datasets(fit_model, d, props=props, max_steps=60)
    fast = fit_datasets(fit_model, d, props=props, max_steps=60, narrow=True)
    assert int(fast.num_steps) == int(wide.num_steps) > 1
    assert fast.stop == wide.stop
    for a, b in zip(jax.tree.leaves(wide.fit_model), jax.tree.leaves(fast.fit_model)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    np.testing.assert_array_equal(np.asarray(wide.stderr["offset"]),
                                  np.asarray(fast.stderr["offset"]))


def test_a_model_with_most_coordinates_free_keeps_its_whole_jacobian():
    start = jaxfric.Tustin(jaxfric.Stribeck(Fs=20.0, Fc=18.0, Vs=5e-3, delta=2.0),
                           sigma2=40.0)
    problem, _ = _problem(start + (fx.Offset(offset=0.0),), None, None, True)
    assert problem.narrowed().width is None


class _Fitter:
    """Records which options it cross-validates; each 'fold fit' halves the error."""

    def __init__(self, F):
        self.data, self.validated = types.SimpleNamespace(F=F), []

    def cross_validate(self, option, folds, current=None):
        pass

    def reference(self, current, folds):
        pass

    def cross_validate_nested(self, option, current, folds, new):
        self.validated.append(option.name)
        option.fold_preds = [0.5 * self.data.F] * len(folds)

    def n_free(self, model, on):
        return len(on)


def test_an_option_that_cannot_qualify_is_not_cross_validated_nor_takes_a_place():
    n = 400
    F = np.random.default_rng(2).standard_normal(n)
    folds = S.time_block_folds(np.arange(n, dtype=float), 8, 2)
    current = S.Option(("base",), None, frozenset())
    current.fold_preds = [np.zeros(n)] * len(folds)
    model = types.SimpleNamespace(effects=[fx.Offset(offset=0.0), fx.Inertia(mass=0.0),
                                           fx.QuadraticDrag(c_drag=0.0)])
    bent = S.Option(("offset",), model, frozenset({0}), physical="offset = -1 outside")
    cut = S.Option(("inertia",), model, frozenset({1}), unconverged="max_steps reached")
    good = S.Option(("quadratic_drag",), model, frozenset({2}))
    fitter = _Fitter(F)
    lines = []
    # The ones that cannot qualify take none of the `tried` places (here 1): the third
    # best training fit is the one cross-validated.
    tried = S._admissible([bent, cut, good], lines.append)[:1]
    chosen = S._cross_validate(fitter, current, tried, folds,
                               DiagnosisRules(blocks=8, folds=2), lines.append)
    assert fitter.validated == ["quadratic_drag"]
    assert chosen is good
    assert "not physical" in bent.skipped and "not converged" in cut.skipped
    assert np.isnan(bent.z) and np.isnan(cut.z) and not good.skipped
    assert any("cannot qualify" in line for line in lines)


def test_a_base_options_starts_are_fitted_once_each():
    # A GMS started at the fit falls back to the one read off the data (a fit whose
    # presliding curve gives no GMS): the two starts are one fit, made once.
    read = jaxfric.paper.gms5()
    starts = (("read off the data", lambda plain: read),
              ("started at the fit", lambda plain: read))
    made = S._base_starts(starts, None, jaxfric.paper.two_state())
    assert [(label, start) for label, _, start in made] == [("read off the data", read)]
    # two starts of their own are both fitted
    other = (("a", lambda plain: jaxfric.paper.gms5()), ("b", lambda plain: read))
    assert len(S._base_starts(other, None, jaxfric.paper.two_state())) == 2
    # in a later round, one start: its own fit of the round before
    fitted = jaxfric.paper.gms10()
    assert S._base_starts(starts, ("b", other[1][1], fitted),
                          jaxfric.paper.two_state()) == [("b", other[1][1], fitted)]
