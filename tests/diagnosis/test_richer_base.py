"""The diagnosis's richer base model (`fitting._start.gms_like`, `fitting._select`): a GMS
started at the fitted two-state model, in each fold at the current model's fit on that
fold's training samples (nested, as the effects are), never at a fit that saw the
held-out blocks. Fast: no fits."""

import equinox as eqx
import numpy as np
import pytest

import jaxfric
from fitting import _refits as R, _select as S
from fitting._start import gms_like
from jaxfric import effects as fx, paper


def _two_state(fs=26.0, l1=4e-6):
    shape = jaxfric.NormalizedPaperShape.from_paper(paper.shape(), paper.stribeck().Fs)
    shape = eqx.tree_at(lambda s: s.l1, shape, np.float64(l1))
    stribeck = jaxfric.Stribeck(Fs=fs, Fc=0.8 * fs, Vs=1e-3, delta=1.0)
    return jaxfric.TwoState(stribeck=stribeck, shape=shape.to_paper(fs), sigma2=50.0, C=9.0)


def test_gms_like_takes_the_fitted_curves_and_only_from_a_presliding_shape():
    m = _two_state()
    g = gms_like(m, 20)
    assert isinstance(g, jaxfric.GMS) and g.nu.shape == (20,)
    assert float(g.stribeck.Fs) == float(m.stribeck.Fs) and float(g.C) == float(m.C)
    assert float(g.sigma2) == float(m.sigma2)
    # its virgin curve is the two-state model's presliding curve at the breakpoints
    lb = float(m.shape.l1) * np.geomspace(1.0, 1e-3, 20)
    pi0 = [float(np.sum(g.k * np.minimum(xi, g.nu / g.k))) for xi in lb]
    np.testing.assert_allclose(pi0, np.asarray(m.shape.pi(lb, m.stribeck.Fs)), rtol=1e-9)
    assert gms_like(g, 20) is None
    assert gms_like(jaxfric.Tustin(stribeck=m.stribeck, sigma2=50.0), 20) is None


def test_a_base_option_keeps_the_effects_and_replaces_the_plain_model():
    m = _two_state() + (fx.Offset(offset=0.5),)
    new = R._replaced(lambda plain: gms_like(plain, 5), m)
    assert isinstance(new.without_effects(), jaxfric.GMS)
    assert [e.name for e in new.effects] == ["offset"]
    assert float(new.effects[0].offset) == 0.5
    fixed = jaxfric.Tustin(stribeck=_two_state().stribeck, sigma2=1.0)  # a plain model
    assert isinstance(R._replaced(fixed, m).without_effects(), jaxfric.Tustin)


def test_a_base_options_fold_fits_start_from_the_current_models_fold_fits():
    """Each fold's start is made from the current model's fit on that fold's training
    samples (what `make` sees), not from the option's start on every sample."""
    folds = S.time_block_folds(np.arange(100.0), 4, 2)
    current = R.Option(("base",), None, frozenset())
    current.fold_models = [_two_state(fs=20.0 + k) + (fx.Offset(offset=0.0),)
                           for k in range(len(folds))]
    seen = []

    def make(plain):
        seen.append(float(plain.stribeck.Fs))
        return gms_like(plain, 5)

    option = R.Option(("GMS",), "the start on every sample", frozenset(), base=True,
                      make=make)
    fitter = R.Fitter(None, workers=1)  # the folds in order (threads: any order)
    starts = []

    def fold_fit(model, on, train):
        starts.append(model)
        fitter.last = None
        return model, np.zeros(100)

    fitter.fold_fit = fold_fit
    option._fold = lambda *args: None
    fitter.cross_validate(option, folds, current)
    assert seen == [20.0, 21.0]
    assert all(isinstance(s.without_effects(), jaxfric.GMS) for s in starts)
    assert [float(s.without_effects().stribeck.Fs) for s in starts] == pytest.approx(
        [20.0, 21.0])


def test_a_curve_that_is_not_concave_has_no_gms_start():
    """A GMS element cannot have negative stiffness: a presliding curve that bends the
    wrong way (here a power law of exponent below 1) gives no start (the diagnosis then
    reads the GMS off the data)."""
    m = _two_state()
    convex = jaxfric.TwoState(stribeck=m.stribeck, shape=jaxfric.PowerShape(l1=4e-6, n=0.5),
                              sigma2=50.0, C=9.0)
    assert gms_like(convex, 20) is None
    concave = eqx.tree_at(lambda t: t.shape, convex, jaxfric.PowerShape(l1=4e-6, n=3.0))
    assert isinstance(gms_like(concave, 20), jaxfric.GMS)


def test_a_two_state_diagnosis_also_tries_a_gms_read_off_the_data():
    """A two-state fit in a poor optimum would hand it to `gms_like`; the GMS option has a
    second start read off the data (`default_base_models`), the better training fit kept.
    A GMS or Tustin base model has no start at the fit to lose, and gets the one."""
    from fitting._base_options import default_base_models, GMS_ELEMENTS
    from fitting._candidates import Data
    from tests.fitting.test_fit_properties import _motion

    t, x = _motion()
    m = _two_state()
    F = np.asarray(jaxfric.simulate(m, t, x))
    data = Data(t=t, x=x, v=np.gradient(x, t), F=F)
    (name, starts), _lugre = default_base_models(m + (fx.Offset(offset=0.5),), data)
    assert name == f"GMS with {GMS_ELEMENTS} elements"
    assert [label for label, _ in starts] == ["read off the data",
                                              "read off the data, fast lag",
                                              "started at the fit"]
    fitted = eqx.tree_at(lambda m: m.C, m, np.float64(1e-3))  # a frozen lag
    read, _, started = (make(fitted) for _, make in starts)
    assert float(started.C) == pytest.approx(1e-3)  # the fit's optimum, handed on
    assert isinstance(read, jaxfric.GMS) and read.nu.shape == (GMS_ELEMENTS,)
    assert float(read.C) != pytest.approx(1e-3)  # read off the data, whatever the fit
    assert read is starts[0][1](m)  # made once
    gms = gms_like(m, 5)
    (_, starts), _lugre = default_base_models(gms, data)
    assert [label for label, _ in starts] == ["read off the data",
                                              "read off the data, fast lag"]


def test_a_gms_read_off_the_data_with_a_slow_lag_also_starts_from_the_FastLag():
    """Read off the data, a GMS's lag comes from crude simulations; from a slow one its fit
    can settle where the lag is a memory of the motion (a jerk-limited stiction file with
    a mass and cogging: 1.72 N RMS, from the fast lag 0.63 N). Like the base fit
    (`lag_starts`), the option also starts from the fastest lag of `LAG_TIMES`; a start
    whose lag is that fast, or whose ``C`` is held, is that start itself (one fit)."""
    from fitting._base_options import _FastLag
    from fitting._start import LAG_TIMES

    slow = jaxfric.paper.gms5()  # C 10.8 N/s: a lag time Fs/C of 0.4 s
    fast = _FastLag(lambda plain: slow, ())(None)
    assert float(fast.C) == pytest.approx(float(slow.stribeck.Fs) / min(LAG_TIMES))
    assert float(slow.C) < float(fast.C)
    assert eqx.tree_equal(eqx.tree_at(lambda g: g.C, fast, slow.C), slow)  # only C moved
    assert _FastLag(lambda plain: slow, ("C",))(None) is slow
    assert _FastLag(lambda plain: fast, ())(None) is fast


def test_the_search_copy_carries_every_start_of_the_base_models():
    """The search copy of a long record must carry every model the search fits: each
    start of each base model, made from the fit, with the fit's effects."""
    from fitting._base_options import base_model_starts, default_base_models, GMS_ELEMENTS
    from fitting._candidates import Data
    from tests.fitting.test_fit_properties import _motion

    t, x = _motion()
    m = _two_state() + (fx.Offset(offset=0.5),)
    F = np.asarray(jaxfric.simulate(m, t, x))
    data = Data(t=t, x=x, v=np.gradient(x, t), F=F)
    made = base_model_starts(default_base_models(m, data), m)
    name = f"GMS with {GMS_ELEMENTS} elements"
    # not the fast-lag start: where a fit begins, not a model the search compares
    assert [n for n, _ in made] == [f"{name} (read off the data)",
                                    f"{name} (started at the fit)",
                                    "LuGre (read off the data)"]
    assert [type(g.without_effects()) for _, g in made] == [jaxfric.GMS, jaxfric.GMS,
                                                             jaxfric.LuGre]
    assert all([e.name for e in g.effects] == ["offset"] for _, g in made)


def test_a_diagnosis_also_tries_a_lugre_read_off_the_data_unless_the_model_is_one():
    """Another family is a base-model option too: a LuGre read off the longest run
    (`initial_model`, made once), whatever the fit is; not for a LuGre base model."""
    from fitting._base_options import default_base_models
    from fitting._candidates import Data
    from tests.fitting.test_fit_properties import _motion

    t, x = _motion()
    m = _two_state()
    F = np.asarray(jaxfric.simulate(m, t, x))
    data = Data(t=t, x=x, v=np.gradient(x, t), F=F)
    _gms, (name, starts) = default_base_models(m + (fx.Offset(offset=0.5),), data)
    assert name == "LuGre" and [label for label, _ in starts] == ["read off the data"]
    ((_, make),) = starts
    lugre = make(m)
    assert isinstance(lugre, jaxfric.LuGre) and make(gms_like(m, 5)) is lugre  # made once
    assert [n for n, _ in default_base_models(lugre + (fx.Offset(offset=0.5),), data)] \
        == ["GMS with 20 elements"]
