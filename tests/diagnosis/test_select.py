"""The diagnosis's decision by full refits and blocked cross-validation (`fitting._select`,
`fitting.diagnose`, `fitting._rules`): its parts on small cases, and one whole
diagnosis of a Tustin model on a short record (fast: a memoryless base model)."""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from fitting import _candidates as C, _refits as R, _select as S, diagnose
from fitting._per_run import with_runs
from fitting._rules import DiagnosisRules
from jaxfric import effects as fx


def test_time_block_folds_hold_out_every_sample_once_in_contiguous_blocks():
    t = np.sort(np.random.default_rng(0).uniform(0, 10, 997))
    folds = S.time_block_folds(t, 20, 4)
    tests = np.stack([te for _, te in folds])
    assert np.all(tests.sum(axis=0) == 1)  # every sample held out exactly once
    for train, test in folds:
        assert np.all(train + test == 1)
    blocks = S._blocks(folds)
    assert len(blocks) == 20
    assert sorted(np.concatenate([idx for _, idx in blocks]).tolist()) == list(range(t.size))


def test_folds_are_a_plain_argument_one_run_per_fold():
    """Leave-one-run-out: one block per fold, judged the same way."""
    n = 300
    run = np.repeat([0, 1, 2], n // 3)
    folds = [((run != k).astype(float), (run == k).astype(float)) for k in range(3)]
    assert [k for k, _ in S._blocks(folds)] == [0, 1, 2]


def test_judge_block_statistic():
    rng = np.random.default_rng(1)
    n = 2000
    F = rng.standard_normal(n)
    folds = S.time_block_folds(np.arange(n, dtype=float), 20, 4)
    cur = R.Option(("base",), None, frozenset())
    cur.fold_preds = [np.zeros(n)] * 4
    better = R.Option(("e",), None, frozenset())
    better.fold_preds = [0.5 * F] * 4  # removes 75 % of the SSE in every block
    S.judge(better, cur, folds, F)
    assert better.gain == pytest.approx(0.75)
    assert better.z > 10
    same = R.Option(("noise",), None, frozenset())
    same.fold_preds = [0.05 * rng.standard_normal(n)] * 4  # fits nothing
    S.judge(same, cur, folds, F)
    assert same.gain < 0 and same.z < 2


class _Judged:
    """A fitter whose options' fold fits are already made (nothing to refit); each option
    adds ``sizes[option.model]`` free coordinates (none without `sizes`)."""

    def __init__(self, F, sizes=None):
        n = F.size
        self.data = C.Data(t=np.arange(n, dtype=float), x=np.zeros(n), v=np.zeros(n), F=F)
        self.sizes = sizes

    def cross_validate(self, option, folds, current=None):
        pass

    reference = cross_validate

    def n_free(self, model, on):
        return 10 + (0 if self.sizes is None or model is None else self.sizes[model])


def test_significant_is_not_relevant():
    """An option that removes 0.8 % of every block's SSE, evenly: significant (z far above
    2) but not shown to remove `min_gain` (1 %), so it does not qualify; one removing 5 %
    as evenly does."""
    n = 2000
    F = np.random.default_rng(4).standard_normal(n)
    folds = S.time_block_folds(np.arange(n, dtype=float), 20, 4)
    cur = R.Option(("base",), None, frozenset())
    cur.fold_preds = [np.zeros(n)] * 4
    small, large = (R.Option((name,), None, frozenset()) for name in ("small", "large"))
    small.fold_preds = [(1 - np.sqrt(1 - 0.008)) * F] * 4
    large.fold_preds = [(1 - np.sqrt(1 - 0.05)) * F] * 4
    for o in (small, large):
        S.judge(o, cur, folds, F, z=2.0)
    assert small.gain == pytest.approx(0.008) and small.z > 10
    assert small.lower == pytest.approx(0.008)  # no spread: shown as measured
    assert small.lower < DiagnosisRules().min_gain <= large.lower

    fitter = _Judged(F)
    rules = DiagnosisRules(blocks=20, folds=4)
    assert S._cross_validate(fitter, cur, [small], folds, rules, lambda *_: None) is None
    assert S._cross_validate(fitter, cur, [small, large], folds, rules,
                             lambda *_: None) is large
    assert S._cross_validate(fitter, cur, [small], folds,
                             DiagnosisRules(min_gain=0.0), lambda *_: None) is small


def _looks_alike(gains, sizes, noise, base=None):
    """`_cross_validate` over options removing the shares `gains` of every block's SSE
    (with `noise` in their predictions), of `sizes` added free coordinates; `base[k]`:
    option k is a base-model change."""
    n = 2000
    rng = np.random.default_rng(5)
    F = rng.standard_normal(n)
    folds = S.time_block_folds(np.arange(n, dtype=float), 20, 4)
    cur = R.Option(("base",), None, frozenset())
    cur.fold_preds = [np.zeros(n)] * 4
    options = []
    for k, share in enumerate(gains):
        o = R.Option((f"option {k}",), k, frozenset(), base=bool(base and base[k]))
        o.fold_preds = [(1 - np.sqrt(1 - share)) * F + noise * rng.standard_normal(n)] * 4
        options.append(o)

    chosen = S._cross_validate(_Judged(F, sizes), cur, options, folds,
                               DiagnosisRules(blocks=20, folds=4), lambda *_: None)
    return options.index(chosen), chosen


def test_a_look_alike_that_predicts_as_well_is_named_with_the_one_added():
    """Two options of equal size that both qualify, one removing 50.5 % and the other
    50 % of every block's SSE: the larger is added, and the data do not tell the two apart
    (their difference, with noise in the blocks, under z); against one removing 20 %, no
    tie."""
    k, chosen = _looks_alike([0.5, 0.505, 0.2], [0, 0, 0], noise=0.05)
    assert k == 1
    assert [name for name, _ in chosen.ties] == ["option 0"]
    assert chosen.ties[0][1] < DiagnosisRules().z


def test_an_effect_the_data_do_not_tell_apart_from_a_base_model_change_is_added():
    """A base-model change (36 added coordinates, a GMS for a two-state model) that
    removes 50.5 % of every block's SSE and an effect (2) that removes 50 %: the data do
    not tell them apart, and the effect is added, the base-model change named as a
    look-alike; where the base-model change removes clearly more (70 %), it is added."""
    k, chosen = _looks_alike([0.505, 0.5], [36, 2], noise=0.05, base=[True, False])
    assert k == 1 and [name for name, _ in chosen.ties] == ["option 0"]
    k, chosen = _looks_alike([0.7, 0.5], [36, 2], noise=0.05, base=[True, False])
    assert k == 0 and chosen.ties == []


def test_between_effects_the_larger_gain_is_added_whatever_their_size():
    """Two effects the data do not tell apart, a gravity load (2 coordinates) removing
    50.5 % of every block's SSE and an offset (1) removing 50 %: the larger gain is added,
    the other named as a look-alike."""
    k, chosen = _looks_alike([0.505, 0.5], [2, 1], noise=0.05)
    assert k == 0 and [name for name, _ in chosen.ties] == ["option 1"]


def _judged(scale, keep):
    """An option judged against a current model that predicts 0 on ``F = scale * noise``
    (blocks of 100 samples, 20 blocks, 4 folds): in fold ``k`` it predicts
    ``(1 - keep[k]) * F``, so it leaves the share ``keep[k] ** 2`` of each block's SSE."""
    n = 2000
    F = np.random.default_rng(3).standard_normal(n) * scale
    folds = S.time_block_folds(np.arange(n, dtype=float), 20, 4)
    cur = R.Option(("base",), None, frozenset())
    cur.fold_preds = [np.zeros(n)] * 4
    o = R.Option(("e",), None, frozenset())
    o.fold_preds = [(1.0 - k) * F for k in keep]
    S.judge(o, cur, folds, F)
    return o


def test_blocks_of_one_fold_move_together_and_are_counted_so():
    """The blocks of a fold share one fitted model: when what an option removes is set per
    fold (its fit on that fold's training data), 20 blocks are 4 pieces of evidence. Held
    out, the option removes 5.8, 3.9, 0 and -1 % of the SSE in the blocks of folds 0-3:
    the blocks taken as independent would give z = 3.4, the folds give z under 2."""
    keep = np.exp(-0.5 * np.array([0.03, 0.02, 0.0, -0.005]))  # log ratios per fold
    o = _judged(np.ones(2000), keep)
    r = np.repeat([0.03, 0.02, 0.0, -0.005], 5)
    assert r.mean() / (r.std(ddof=1) / np.sqrt(20)) > 3
    assert 0 < o.gain and o.z < 2
    assert o.block_folds == sorted(o.block_folds) and len(o.block_gains) == 20


def test_an_effect_that_improves_every_block_qualifies_however_uneven_the_blocks():
    """An effect removing half the held-out SSE of every block (a mass: its term is large
    where the accelerations are) is evidence in every block, though two blocks carry 99 %
    of the SSE: the rule compares blocks by the log of their SSE ratio, not by SSE."""
    scale = np.ones(2000)
    scale[300:400] = scale[1500:1600] = 30.0
    o = _judged(scale, [np.sqrt(0.5)] * 4)
    d = np.asarray(o.block_gains)
    assert d.mean() / (d.std(ddof=1) / np.sqrt(d.size)) < 2  # the SSE differences alone
    assert o.gain == pytest.approx(0.5) and o.z > 10


def test_standard_error_of_the_mean_block_statistic():
    rng = np.random.default_rng(0)
    d = rng.standard_normal(20)
    plain = d.std(ddof=1) / np.sqrt(20)
    assert S.standard_error(d, np.zeros(20)) == pytest.approx(plain)  # one fold: blocks
    folds = np.arange(20) % 4
    assert S.standard_error(d, folds) >= plain
    shifted = d + np.array([3.0, 1.0, -1.0, -3.0])[folds]  # a fold-level error
    f_sums = np.array([np.sum(shifted[folds == k] - shifted.mean()) for k in range(4)])
    assert S.standard_error(shifted, folds) == pytest.approx(
        np.sqrt(4 / 3 * np.sum(f_sums**2)) / 20)
    assert S.standard_error(d[:1], folds[:1]) == np.inf


def _record(span=100.0, n=1001):
    t = np.linspace(0.0, span, n)
    return C.Data(t, np.zeros(n), np.zeros(n), np.zeros(n))


def test_physical_ranges_come_from_field_metadata():
    data = _record()
    assert C.physical(fx.Inertia(mass=2.0), data) == ""
    assert "mass" in C.physical(fx.Inertia(mass=-0.1), data)
    assert "c_drag" in C.physical(fx.QuadraticDrag(c_drag=-1.0), data)
    assert "lag_gain" in C.physical(fx.FrictionLag(lag_gain=1.5, tau=0.1), data)
    assert C.physical(fx.Offset(offset=-3.0), data) == ""  # an offset may have either sign
    assert C.switchable("inertia") and C.switchable("cogging")
    assert not C.switchable("presliding")  # no linear parameter to switch it off


def test_a_drift_faster_than_a_tenth_of_the_record_is_not_physical():
    # A change settled within one stretch of the record (a start-up transient: measured,
    # 0.4 s on a 97 s clean LuGre-truth file) is not a drift; the shortest time constant
    # of the drift's own grid is the limit, either sign of the decay.
    data = _record(span=100.0)
    assert C.physical(fx.Drift(drift_rate=0.01, drift_decay=1 / 12.0), data) == ""
    assert C.physical(fx.Drift(drift_rate=0.01, drift_decay=-1 / 12.0), data) == ""
    assert C.physical(fx.Drift(drift_rate=0.01), data) == ""  # linear: wear
    for decay in (1 / 0.4, -1 / 8.0):
        assert "drift_decay" in C.physical(fx.Drift(drift_rate=0.01, drift_decay=decay), data)
    assert C.physical(fx.Drift(drift_rate=0.01, drift_decay=1 / 8.0), _record(span=50.0)) == ""


def test_physical_checks_every_runs_value_of_a_relative_per_run_parameter():
    # A drift level is per run relative to a reference run, whose value the leaf does not
    # store: run 2's level 1.5 (outside [-1, 1]) must be seen with run 2 the reference.
    model = with_runs(jaxfric.paper.two_state() + fx.Drift(drift_level=0.2), 3)
    (e,) = model.effects
    e = eqx.tree_at(lambda e: e.effect.drift_level, e, jnp.array([1.5, 0.2]))
    data = _record()
    assert "drift_level" in C.physical(e, data)
    moved = e.rereferenced(1)  # run 2's 1.5 is now the reference, not stored
    assert np.all(np.abs(np.asarray(moved.effect.drift_level)) <= 1.0)
    assert "drift_level" in C.physical(moved, data)
    assert C.physical(eqx.tree_at(lambda e: e.effect.drift_level, e,
                                  jnp.array([0.5, 0.2])), data) == ""


def test_start_effect_finds_the_cogging_period_on_its_grid():
    t = np.linspace(0, 20, 4000)
    x = 4e-3 * np.sin(2 * np.pi * t / 10)
    v = np.gradient(x, t)
    F = 20 * np.tanh(v / 1e-3)
    resid = 0.5 * np.sin(2 * np.pi * x / 1.3e-3) + 0.2 * np.cos(2 * np.pi * x / 1.3e-3)
    data = C.Data(t, x, v, F)
    base = jaxfric.Tustin(jaxfric.Stribeck(Fs=20.0, Fc=20.0, Vs=1e-3, delta=2.0), sigma2=0.0)
    e = C.start_effect("cogging", data, base, resid)
    assert float(e.period) == pytest.approx(1.3e-3, rel=0.03)
    assert float(np.hypot(e.cog_sin, e.cog_cos)) == pytest.approx(np.hypot(0.5, 0.2), rel=0.1)


def test_start_effect_sees_only_the_training_samples():
    """A fold's grid start is picked on its training samples: a cogging of another period
    in the held-out half does not move it."""
    t = np.linspace(0, 20, 4000)
    x = 4e-3 * np.sin(2 * np.pi * t / 10)
    v = np.gradient(x, t)
    data = C.Data(t, x, v, 20 * np.tanh(v / 1e-3))
    train = (t < 10).astype(float)
    resid = np.where(train > 0, 0.5 * np.sin(2 * np.pi * x / 1.3e-3),
                     2.0 * np.sin(2 * np.pi * x / 0.5e-3))
    base = jaxfric.Tustin(jaxfric.Stribeck(Fs=20.0, Fc=20.0, Vs=1e-3, delta=2.0), sigma2=0.0)
    e = C.start_effect("cogging", data, base, resid, weights=train)
    assert float(e.period) == pytest.approx(1.3e-3, rel=0.03)
    assert float(C.start_effect("cogging", data, base, resid).period) == pytest.approx(
        0.5e-3, rel=0.03)


def test_rules_are_checked():
    with pytest.raises(ValueError):
        DiagnosisRules(folds=1)
    with pytest.raises(ValueError):
        DiagnosisRules(z=0.0)
    with pytest.raises(ValueError, match="min_gain"):
        DiagnosisRules(min_gain=1.0)
    with pytest.raises(dataclasses_frozen()):
        DiagnosisRules().z = 3.0


def dataclasses_frozen():
    import dataclasses

    return dataclasses.FrozenInstanceError


def _tustin_record(mass: float, seed: int = 0, duration: float = 20.0):
    """A Tustin truth on point-to-point moves, 5 ms sampling, with a mass `mass`."""
    from jaxfric import trajectories

    t = np.arange(0.0, duration, 5e-3)
    x = trajectories.point_to_point(t, np.random.default_rng(seed), accel_time=0.05)
    v = np.gradient(x, t)
    a = np.gradient(v, t)
    truth = jaxfric.Tustin(jaxfric.Stribeck(Fs=24.0, Fc=20.0, Vs=3e-3, delta=2.0),
                           sigma2=60.0)
    F = np.asarray(jaxfric.simulate(truth, t, x, v)) + mass * a
    F = F + 0.1 * np.random.default_rng(100 + seed).standard_normal(t.size)
    start = jaxfric.Tustin(jaxfric.Stribeck(Fs=20.0, Fc=18.0, Vs=5e-3, delta=2.0),
                           sigma2=40.0)
    return start, t, x, F, v, a


def test_how_far_the_search_goes_is_a_budget_of_diagnose_not_a_rule():
    """`max_added` is `diagnose`'s, as `max_steps` is: not one of the rule's thresholds."""
    assert "max_added" not in {f.name for f in dataclasses.fields(DiagnosisRules)}
    start, t, x, F, v, a = _tustin_record(mass=4.0, duration=6.0)
    with pytest.raises(ValueError, match="max_added"):
        diagnose(start, t, x, F, v, a=a, max_added=-1)


def test_diagnose_quick_case():
    """The whole path on a tiny case: one candidate, one round, two folds."""
    start, t, x, F, v, a = _tustin_record(mass=4.0, duration=6.0)
    rules = DiagnosisRules(blocks=8, folds=2, tried=1)
    d = diagnose(start, t, x, F, v, a=a, effects=("inertia",), base_models=(),
                    rules=rules, max_added=1)
    assert d.final.added == ["inertia"]
    assert float(d.model.effects[0].mass) == pytest.approx(4.0, rel=0.05)
    assert d.candidates[0].t_stat >= rules.z
    assert d.to_json()["after"]["added"] == ["inertia"]


@pytest.mark.slow
def test_diagnose_finds_a_mass_and_adds_nothing_to_its_clean_twin():
    start, t, x, F, v, a = _tustin_record(mass=4.0)
    d = diagnose(start, t, x, F, v, a=a, effects=("inertia", "offset", "quadratic_drag"),
                    model_name="tustin", base_models=())
    assert d.final.added == ["inertia"]
    assert float(d.model.effects[0].mass) == pytest.approx(4.0, rel=0.05)
    assert d.final.rmse_holdout < 0.5 * d.baseline.rmse_holdout
    assert d.candidates[0].name == "inertia" and d.candidates[0].significant
    start, t, x, F, v, a = _tustin_record(mass=0.0)
    clean = diagnose(start, t, x, F, v, a=a, effects=("inertia", "offset", "quadratic_drag"),
                        base_models=())
    assert clean.final.added == []


def test_a_base_model_option_of_several_starts_is_one_option():
    """A base-model option is fitted from each of its starts and the better training fit
    kept: one option (one trial, one place among the `tried`), its evidence naming the
    start; a start given alone (a plain model) is one start."""
    start, t, x, F, v, a = _tustin_record(mass=0.0, duration=6.0)
    far = eqx.tree_at(lambda m: m.stribeck.Vs, start, np.float64(1.0))  # a poor start
    rules = DiagnosisRules(blocks=8, folds=2, tried=1)
    d = diagnose(start, t, x, F, v, a=a, effects=("offset",), rules=rules, max_added=1,
                 base_models=[("Tustin again", (("far", far), ("near", start))),
                              ("Tustin far", far)])
    base = [tr for tr in d.trials if tr["effects"][0].startswith("Tustin")]
    assert [tr["effects"] for tr in base] == [["Tustin again"], ["Tustin far"]]
    again, alone = (next(c for c in d.candidates if c.name == n)
                    for n in ("Tustin again", "Tustin far"))
    assert again.evidence.startswith("near;") and alone.evidence.startswith("as given;")
    assert base[0]["sse_train"] < base[1]["sse_train"]
    assert base[0]["start"] == "near" and base[1]["other_starts"] == []
    assert [o["start"] for o in base[0]["other_starts"]] == ["far"]
    with pytest.raises(ValueError, match="needs a start"):
        diagnose(start, t, x, F, v, a=a, effects=("offset",), rules=rules,
                 base_models=[("nothing", ())])


def test_an_options_fit_cut_at_its_step_limit_is_continued_once():
    """An option's fit on every sample gets the budget of a fold fit: where it stops at
    its step limit it is continued once from there, and judged by the continuation."""
    from types import SimpleNamespace

    import optimistix as optx

    F = np.zeros(10)
    fitter = R.Fitter(SimpleNamespace(F=F))
    calls = []

    def fit(model, on, weights=None):
        calls.append(model)
        cut = len(calls) == 1
        fitter.last = SimpleNamespace(
            result=optx.RESULTS.nonlinear_max_steps_reached if cut else
            optx.RESULTS.successful, stop="max_steps" if cut else "converged",
            stopped="max_steps = 150 reached" if cut else "", rmse=0.0)
        return f"fit {len(calls)}", np.zeros(10)

    fitter.fit = fit
    o = R.Option(("offset",), "start", frozenset())
    S._refit(fitter, o, True, R.Option(("base",), None, frozenset()), lambda *_: None)
    assert calls == ["start", "fit 1"] and o.fitted == "fit 2"
    assert o.unconverged == ""


def test_the_starts_of_one_option_race_and_only_the_leader_is_continued():
    """A base-model option's starts get `max_steps` each; the better training fit is kept
    and only it is continued where it stopped."""
    from types import SimpleNamespace

    import optimistix as optx

    F = np.zeros(10)
    fitter = R.Fitter(SimpleNamespace(F=F))
    calls = []
    level = {"near": 1.0, "far": 2.0, "near fitted": 0.5}

    def fit(model, on, weights=None):
        calls.append(model)
        done = model == "near fitted"
        fitter.last = SimpleNamespace(
            result=optx.RESULTS.successful if done else
            optx.RESULTS.nonlinear_max_steps_reached, stop="converged" if done else
            "max_steps", stopped="" if done else "max_steps = 150 reached", rmse=0.0)
        return f"{model} fitted", np.full(10, level[model])

    fitter.fit = fit
    group = [R.Option(("GMS",), m, frozenset(), base=True, start=m) for m in ("far", "near")]
    current = R.Option(("base",), None, frozenset())
    for o in group:
        S._refit(fitter, o, False, current, lambda *_: None)
    kept = S._kept(fitter, group, current, lambda *_: None)
    assert calls == ["far", "near", "near fitted"]
    assert kept is group[1] and kept.fitted == "near fitted fitted" and not kept.unconverged
    assert group[0].unconverged  # the one behind is left where it stopped


def test_a_base_options_start_is_chosen_by_held_out_error_not_by_its_training_fit():
    """A base-model option's starts are cross-validated together: the one that removes
    the most held-out SSE is kept (in the option's place, its fit on every sample
    continued where it stopped), though another fits the training samples better (a slow
    lag that remembers the motion); where the training leader also predicts best, it
    stays, and nothing is refitted."""
    from types import SimpleNamespace

    import optimistix as optx

    n = 40
    F = np.zeros(n)
    folds = S.time_block_folds(np.arange(n, dtype=float), 4, 2)
    rules = DiagnosisRules(blocks=4, folds=2)

    def case(held_out):
        fitter, fits = R.Fitter(SimpleNamespace(F=F)), []

        def cross_validate(option, folds, current=None):
            if not option.fold_preds:
                option.fold_preds = [np.full(n, held_out[option.start])] * len(folds)

        def fit(model, on, weights=None):
            fits.append(model)
            fitter.last = SimpleNamespace(result=optx.RESULTS.successful, stop="converged",
                                          stopped="", rmse=0.0)
            return f"{model}, continued", np.full(n, 0.1)

        fitter.cross_validate, fitter.fit = cross_validate, fit
        current = R.Option(("base",), None, frozenset(), fold_preds=[np.ones(n)] * 2,
                           fold_converged=[True, True])
        kept = R.Option(("GMS",), None, frozenset(), base=True, start="slow lag", sse=1.0,
                        fitted="slow fit", optimism=0.3)
        kept.rivals = [R.Option(("GMS",), None, frozenset(), base=True, start="fast lag",
                                sse=5.0, fitted="fast fit",
                                unconverged="fit on every sample: max_steps")]
        chosen = S._cross_validate(fitter, current, [kept], folds, rules, lambda *_: None)
        return kept, chosen, fits

    kept, chosen, fits = case({"slow lag": 0.8, "fast lag": 0.5})
    assert chosen is kept and kept.start == "fast lag" and fits == ["fast fit"]
    assert kept.fitted == "fast fit, continued" and not kept.unconverged
    assert kept.gain == pytest.approx(0.75) and kept.optimism == 0.3
    assert [r.start for r in kept.rivals] == ["slow lag"]
    assert kept.rivals[0].gain == pytest.approx(0.36)
    kept, chosen, fits = case({"slow lag": 0.5, "fast lag": 0.8})
    assert chosen is kept and kept.start == "slow lag" and kept.fitted == "slow fit"
    assert fits == [] and kept.rivals[0].gain == pytest.approx(0.36)


def test_a_fit_cut_at_its_step_limit_is_no_evidence():
    """The quick case with every fit cut at three steps: the mass's fit on every sample
    has no final values to add, so the mass is not added, and its evidence says why."""
    start, t, x, F, v, a = _tustin_record(mass=4.0, duration=6.0)
    rules = DiagnosisRules(blocks=8, folds=2, tried=1)
    d = diagnose(start, t, x, F, v, a=a, effects=("inertia",), base_models=(),
                 rules=rules, max_steps=3, max_added=1)
    assert d.final.added == []
    assert "not converged" in d.candidates[0].evidence
    assert d.trials[0]["converged"] is False


@pytest.mark.parametrize("max_steps", [3, 150])
def test_the_reference_is_the_current_fold_fit_continued_with_an_options_budget(max_steps):
    """Equal effort: where the current model's fold fit stopped at its step limit, the
    reference an option is judged against is that fit continued with the budget an option
    gets from it (`Fitter.fold_fit`), and it fits the training samples better; a fold fit
    that converged is its own reference."""
    from fitting._params import to_fit_representation

    start, t, x, F, v, a = _tustin_record(mass=4.0, duration=6.0)
    folds = S.time_block_folds(t, 8, 2)
    fitter = R.Fitter(C.Data(t, x, v, F, a), max_steps=max_steps)
    cur = R.Option(("base",), to_fit_representation(start), frozenset())
    fitter.cross_validate(cur, folds)
    assert cur.fold_converged == [max_steps > 3] * 2
    fitter.reference(cur, folds)
    for k, (train, _) in enumerate(folds):
        if cur.fold_converged[k]:
            assert cur.fold_refs[k] is cur.fold_preds[k]
            continue
        continued = fitter.fold_fit(cur.fold_models[k], cur.on, train)[1]
        np.testing.assert_allclose(cur.fold_refs[k], continued, rtol=1e-12)
        assert np.sum(train * (cur.fold_refs[k] - F) ** 2) < np.sum(
            train * (cur.fold_preds[k] - F) ** 2)
