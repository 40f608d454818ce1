"""Every effect's words on a rotary file (issue 18, item 1 and 4): what a diagnosis of a
joint reports of an effect (its `describe` line through the diagnosis JSON, `speak_json`,
and its parameter units, `unit_for`) never speaks of N alone, mm, um or m/s. The end to end
run of the commands on a joint log is in test_rotary.py; this one covers every effect of
`jaxfric.effects.EFFECTS`, with values, so that a new effect cannot slip through."""

import dataclasses
import re

import numpy as np
import pytest

from fitting._candidates import Candidate
from fitting.cli._io import diagnosis_json
from jaxfric import effects as fx, units


#: One instance of each effect with non-default values (a ripple 50 times per turn).
EXAMPLES = {
    "viscous": fx.Viscous(c_visc=2.0), "quadratic_drag": fx.QuadraticDrag(c_drag=3.0),
    "stribeck": fx.StribeckHump(dF_str=1.0, v_str=2e-3), "inertia": fx.Inertia(mass=0.5),
    "offset": fx.Offset(offset=0.8), "asymmetry": fx.Asymmetry(asym=0.06),
    "cogging": fx.Cogging(cog_sin=0.5, cog_cos=0.2, period=1.3e-3),
    "position_dependence": fx.PositionDependence(pos_1=0.04, pos_2=0.03),
    "position_load": fx.PositionLoad(load_1=0.9, load_2=0.1),
    "drift": fx.Drift(drift_rate=1e-3), "presliding": fx.Presliding(F_pre=1.0, k_pre=1e5),
    "friction_lag": fx.FrictionLag(lag_gain=0.3, tau=0.6),
    "ripple": fx.Ripple(rip_sin=np.array([0.5, 0.2, 0.1]), rip_cos=np.array([0.1, 0.1, 0.1]),
                        period=2 * np.pi / 50),
    "angle_load": fx.AngleLoad(g_sin=1.0, g_cos=-1.0),
    "load_friction": fx.LoadFriction(k_load=0.03),
}


def _linear_words(text: str) -> list[str]:
    """Places where `text` speaks of N alone, mm, um or a speed in m/s (N m is a torque)."""
    clean = re.sub(r"N m\b", "", text)
    return [clean[max(0, m.start() - 30):m.end() + 10]
            for m in re.finditer(r"\bN\b|\bmm\b|mm/s|\bm/s|\[N\]|\bum\b|µm|N/m\b|N s/m\b",
                                 clean)]


def test_every_effect_has_an_example():
    assert set(EXAMPLES) == set(fx.EFFECTS)


class _Diag:
    """The part of a `fitting.Diagnosis` that `diagnosis_json` reads, with one candidate."""

    def __init__(self, effect):
        c = Candidate(effect.name, effect, 0.3, 5.0, True,
                      f"{effect.describe()}; explains 30 % of the held-out residual", "")
        self.json = {"candidates": [c.to_json()], "summary": effect.describe()}

    def to_json(self):
        return dict(self.json)


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_rotary_diagnosis_json_speaks_rotary(name):
    effect = EXAMPLES[name]
    linear = effect.describe()
    out = diagnosis_json(_Diag(effect), units.ROTARY)
    text = str(out["candidates"]) + out["summary"]
    assert not _linear_words(text), (name, _linear_words(text))
    # The test can fail: the same line on a linear file keeps its linear words where it has
    # units at all.
    if re.search(r"\d\s(N|mm|m|kg)\b", linear):
        assert _linear_words(linear) or "kg" in linear, linear


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_rotary_parameter_units(name):
    effect = EXAMPLES[name]
    for f in dataclasses.fields(effect):
        unit = f.metadata.get("unit")
        if unit is None:
            continue
        rotary = units.unit_for(unit, units.ROTARY)
        assert not _linear_words(f"1 {rotary}") and rotary != "m", (name, f.name, rotary)
