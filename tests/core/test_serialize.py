"""Saved models read back as the same model: every leaf to the bit, the same forces."""

import json

import jax
import numpy as np
import pytest

import fitting
import jaxfric
from jaxfric import effects as fx, paper


def _motion():
    t = np.linspace(0.0, 4.0, 801)
    x = 2e-3 * np.sin(2 * np.pi * t / 2) + 3e-5 * np.sin(2 * np.pi * t * 7)  # inner loops
    return t, x


def _models():
    _, x = _motion()
    every_effect = tuple(
        cls.for_travel(x, pos_1=0.05) if cls is fx.PositionDependence else cls()
        for cls in fx.EFFECTS.values()
    )
    return {
        "two-state": paper.two_state(),
        "two-state, power shape": jaxfric.TwoState(
            stribeck=paper.stribeck(), shape=jaxfric.PowerShape(l1=3e-6, n=1.8), sigma2=50.0,
            C=9.0, stack_size=24),
        "two-state, fit shape": fitting.to_fit_representation(paper.two_state()),
        "gms": paper.gms5(),
        "lugre": paper.lugre(),
        "tustin": paper.tustin(),
        "two-state + every effect": paper.two_state() + every_effect,
    }


@pytest.mark.parametrize("name", list(_models()))
def test_round_trip_is_exact(name, tmp_path):
    model = _models()[name]
    path = tmp_path / "model.json"
    jaxfric.save_model(model, path)
    text = path.read_text()
    json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in saved JSON"))
    back = jaxfric.load_model(path)
    assert jax.tree.structure(back) == jax.tree.structure(model)
    for a, b in zip(jax.tree.leaves(model), jax.tree.leaves(back)):
        assert a.dtype == b.dtype and np.array_equal(np.asarray(a), np.asarray(b))
    t, x = _motion()
    load = 40.0 + 10.0 * np.sin(t)  # for load_friction; the other models ignore it
    np.testing.assert_array_equal(jaxfric.simulate(back, t, x, load=load),
                                  jaxfric.simulate(model, t, x, load=load))


def test_refuses_what_json_cannot_hold_and_what_it_does_not_know(tmp_path):
    bad = paper.tustin() + fx.Offset(offset=float("inf"))
    with pytest.raises(ValueError, match="not finite"):
        jaxfric.save_model(bad, tmp_path / "bad.json")
    spec = jaxfric.model_to_dict(paper.tustin())
    with pytest.raises(ValueError, match="unknown class 'Nope'"):
        jaxfric.model_from_dict({**spec, "class": "Nope"})
    with pytest.raises(ValueError, match="no field"):
        jaxfric.model_from_dict({**spec, "mass": 1.0})
    with pytest.raises(ValueError, match="no saved model"):
        jaxfric.load_model({"params": {}})
