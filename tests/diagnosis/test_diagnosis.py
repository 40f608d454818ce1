"""Acceptance tests of the diagnosis on data with a hidden effect (issue 5).

The data come from `jaxfric.examples.hidden_effect_measurement`: the separable diagnosis
motion (slow nested presliding loops, strokes at six speeds in both directions over
different parts of the travel, a varying-velocity segment mid-record) through a "true"
friction that is *not* the fitted model (a two-state model with a `PowerShape` presliding
curve, which the fitted `PaperShape` cannot reproduce exactly), plus hidden effect(s) and
0.05 N of noise.

For every effect of the library the tests assert that the hidden effect is the candidate
of largest held-out gain and is added (`fitting.diagnose`: full refits, blocked
cross-validation), that adding it lowers the RMSE by at least 40 %, that the final RMSE is
near the floor, and that nothing else is added. "Near the floor": within 15 % of the RMSE
the same baseline reaches on the same motion and noise with *no* hidden effect (noise plus
the model mismatch), which is itself checked to be under twice the noise. Clean data:
nothing added. Two hidden effects: both found.

Every whole diagnosis here takes minutes (each refits every candidate and cross-validates
the best), so all of them are slow (``pytest -m slow``); the rule's parts and a quick whole
case are in test_select.py. Cases that do not pass are listed, with the measured reason, in
`KNOWN_FAILURES` and `KNOWN_PAIR_FAILURES` (strict xfail).
"""

import functools
import pathlib

import equinox as eqx
import pytest

import fitting
import jaxfric.paper
from jaxfric.examples import hidden_effect_measurement, HIDDEN_EFFECTS


NOISE = 0.05  # N, hidden_effect_measurement's default
DT = 0.02  # s: 4866 samples, enough for every effect and twice as fast as 10 ms
DATA = pathlib.Path(__file__).resolve().parents[3] / "shared" / "data"


def baseline(names, t, x, F):
    """The model a user would start from, lacking the hidden effect(s): a two-state model
    from `fitting.initial_model`, except where the two-state model contains the effect
    itself: for ``presliding`` a Tustin model (static); for ``friction_lag`` the two-state
    model with its lag made instantaneous (``C`` held at 1e6 N/s: a lag time of 24 us);
    for ``viscous`` the two-state model with its viscous coefficient held at 0.
    Returns ``(model, fixed)``."""
    if "presliding" in names:
        return fitting.initial_model("tustin", t, x, F), ()
    model = fitting.initial_model("two-state", t, x, F)
    if "friction_lag" in names:
        return eqx.tree_at(lambda m: m.C, model, 1e6), ("C",)
    if "viscous" in names:
        return eqx.tree_at(lambda m: m.sigma2, model, 0.0), ("sigma2",)
    return model, ()


@functools.cache
def run(names: tuple[str, ...], seed: int = 0, magnitude: float = 1.0):
    t, x, F, _ = hidden_effect_measurement(names or None, magnitude=magnitude, seed=seed,
                                           dt=DT)
    model, fixed = baseline(names, t, x, F)
    # The data were made by `simulate` with its own backward-difference velocity.
    return fitting.diagnose(model, t, x, F, fixed=fixed, derivatives="backward")


def assert_found(names, seed=0, magnitude=1.0):
    d = run(tuple(names), seed, magnitude)
    first = d.rankings[0][0]
    report = d.summary()
    assert first.name in names, report
    assert first.significant, report
    assert sorted(d.final.added) == sorted(names), report  # and nothing else
    assert d.final.rmse <= 0.6 * d.baseline.rmse, report
    clean = run((), seed).baseline.rmse
    assert clean < 2.0 * NOISE
    assert d.final.rmse <= 1.15 * clean, (d.final.rmse, clean, report)
    return d


@pytest.mark.slow
def test_clean_data_nothing_significant():
    d = run(())
    assert d.final.added == [], d.summary()
    assert not any(c.significant for c in d.rankings[0]), d.summary()
    assert d.baseline.rmse < 2.0 * NOISE  # the fitted model reaches noise + a small mismatch


@pytest.mark.slow
def test_hidden_cogging_found_added_and_error_falls():
    d = assert_found(["cogging"])
    c = d.rankings[0][0]
    # The evidence names the period (1.7 mm hidden) in plain words, and the code line adds it.
    assert "period" in c.evidence and "held out" in c.evidence
    period = float(d.model.effects[0].period)
    assert abs(period / 1.7e-3 - 1.0) < 0.02
    assert c.code.startswith("model + jaxfric.effects.Cogging(")


def test_viscous_is_searched_only_when_the_models_own_is_held():
    """A viscous term next to a free, positive sigma2 enlarges nothing: not a default
    candidate then; with sigma2 held (`fixed`) it is one."""
    from fitting._diagnose import _contained, effect_names

    model = fitting.to_fit_representation(jaxfric.paper.two_state())
    assert _contained(model, ()) == {"viscous"}
    assert _contained(model, ("sigma2",)) == set()
    names = effect_names(None, _contained(model, ()), rotary=False)
    assert "viscous" not in names and "quadratic_drag" in names
    assert "viscous" in effect_names(None, _contained(model, ("sigma2",)), rotary=False)


@pytest.mark.slow
def test_two_hidden_effects_both_found():
    assert_found(["offset", "inertia"])


#: Cases the diagnosis does not pass yet, each with what goes wrong (docs/diagnosis.md).
#: Strict: when one starts to pass, the test fails until it is taken off this list.
_CUT = "measured (DiagnosisRules() with min_gain): "
KNOWN_FAILURES: dict[tuple[str, int, float], str] = {
    ("stribeck", 1, 2.0): _CUT + "the Stribeck hump's refit removes 99.6 % of the training "
    "SSE but stops at max_steps = 150 twice (continued once), alpha and beta_rel "
    "undetermined and not held: not converged, not cross-validated, nothing added",
    ("presliding", 0, 1.0): _CUT + "presliding is no effect candidate; the GMS-20 base is "
    "added (held out 100 %, z 27.6), final 0.160 N RMS; 3 of its 4 fold fits stop at "
    "max_steps = 150",
    ("presliding", 1, 2.0): _CUT + "presliding is no effect candidate; the GMS-20 base is "
    "added (held out 99.9 %, z 7.25), its fit ends at 0.343 N RMS against the clean "
    "file's 0.056 N (its Fc, 0.03 N, lies beyond the data)",
}

#: Pairs of hidden effects the diagnosis does not separate yet (docs/diagnosis.md).
KNOWN_PAIR_FAILURES: dict[tuple[str, ...], str] = {}


@pytest.mark.slow
@pytest.mark.parametrize("seed, magnitude", [(0, 1.0), (1, 2.0)])
@pytest.mark.parametrize("name", HIDDEN_EFFECTS)
def test_every_hidden_effect_is_found(name, seed, magnitude, request):
    reason = KNOWN_FAILURES.get((name, seed, magnitude))
    if reason:
        request.node.add_marker(pytest.mark.xfail(reason=reason, strict=True))
    assert_found([name], seed, magnitude)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_clean_data_nothing_significant_other_seeds(seed):
    d = run((), seed)
    assert d.final.added == [] and not any(c.significant for c in d.rankings[0]), d.summary()


@pytest.mark.slow
@pytest.mark.parametrize("names", [("cogging", "inertia"), ("quadratic_drag", "offset"),
                                   ("asymmetry", "position_dependence"), ("cogging", "drift")],
                         ids="+".join)
def test_pairs_of_hidden_effects(names, request):
    reason = KNOWN_PAIR_FAILURES.get(names)
    if reason:
        request.node.add_marker(pytest.mark.xfail(reason=reason, strict=True))
    assert_found(list(names), seed=3)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, raises=AssertionError, reason=(
    "measured (jaxfric diagnose, docs/figures/emps_diagnosis.json): inertia (99.6 kg), "
    "asymmetry, a position load and a friction lag are added and the error falls to "
    "4.02 %, but the viscous coefficient is 163 N s/m (published 203.4: 20 % off), with a "
    "base curve rising from Fs 16.0 N to Fc 25.0 N, and the plausibility check warns of "
    "it"))
def test_emps_friction_only_model_finds_inertia_and_error_falls():
    path = DATA / "emps_estimation.csv"
    if not path.exists():
        pytest.skip(f"{path} not present")
    from jaxfric import data as jdata

    m = jdata.load(path)
    assert m.force_column == "u"  # the drive force: friction + inertia + offset
    v = m.velocity(0.01)  # as `jaxfric diagnose` does for drive-force data
    model = fitting.initial_model("two-state", m.t, m.x, m.force, v)
    d = fitting.diagnose(model, m.t, m.x, m.force, v)
    assert d.rankings[0][0].name == "inertia", d.summary()
    assert "inertia" in d.final.added
    # The published inverse model reaches about 4 % relative error on this record.
    assert d.final.rel_error < 0.06, d.summary()
    assert d.final.rmse < 0.2 * d.baseline.rmse
    # For the right reasons: the mass and the viscous coefficient of the published inverse
    # model (95.1 kg, 203.4 N s/m) within 15 %; of the plausibility checks, only the note
    # that the Stribeck curve's sliding level lies beyond the fastest measured speed. (With
    # the backward difference of the velocity as acceleration, before the zero-phase one,
    # the base model traded the viscous term for a rising Stribeck curve: 1.2 N s/m.)
    final = d.final.fit.model
    masses = [e.mass for e in final.effects if e.name == "inertia"]
    assert masses and abs(float(masses[0]) / 95.1 - 1) < 0.15, d.summary()
    assert abs(float(final.base.sigma2) / 203.4 - 1) < 0.15, d.summary()
    final_warnings = d.warnings.get("final", [])
    assert all("beyond the data" in w for w in final_warnings), final_warnings


if __name__ == "__main__":
    # Print the diagnosis of one synthetic case, as the tests run it (the README quotes
    # these): python -m tests.test_diagnosis asymmetry position_dependence --seed 3
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("effects", nargs="*", help="hidden effects (none: clean data)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--magnitude", type=float, default=1.0)
    args = parser.parse_args()
    print(run(tuple(args.effects), args.seed, args.magnitude).summary())
