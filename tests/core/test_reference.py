"""Agreement with the independent plain-NumPy reference (tests/reference.py)."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import paper

from .. import reference as ref
from ..helpers import nested_path, power_two_state, ref_kwargs, sine_path, strokes_path


TOL = 1e-6  # N


def _reference(model, t, x, v=None):
    kw = ref_kwargs(model)
    if isinstance(model, jaxfric.TwoState):
        return ref.two_state(t, x, v, **kw)
    if isinstance(model, jaxfric.GMS):
        return ref.gms(t, x, v, **kw)
    if isinstance(model, jaxfric.LuGre):
        return ref.lugre(t, x, v, **kw)
    return ref.tustin(t, x, v, **kw)


MODELS = {
    "two_state": paper.two_state,
    "two_state_power": power_two_state,
    "gms5": paper.gms5,
    "gms10": paper.gms10,
    "gms50_from_shape": lambda: paper.gms(50),
    "lugre": paper.lugre,
    "tustin": paper.tustin,
}

PATHS = {
    "nested": lambda: (*nested_path(), None),
    "nested_dwell": lambda: (*nested_path(dwell=0.1), None),
    "strokes": lambda: (*strokes_path(), None),
    "sine_given_v": lambda: sine_path(),
    "sine_irregular_derived_v": lambda: (*sine_path(irregular=True)[:2], None),
    "coarse_nested": lambda: (*nested_path(dt=0.05), None),
}


@pytest.mark.parametrize("path", sorted(PATHS))
@pytest.mark.parametrize("name", sorted(MODELS))
def test_matches_reference(name, path):
    model = MODELS[name]()
    t, x, v = PATHS[path]()
    r = _reference(model, t, x, v)
    out = jaxfric.simulate(model, t, x, v, full_output=True)
    err = np.max(np.abs(np.asarray(out.force) - r["F"]))
    assert err < TOL, f"max |F - F_ref| = {err:.3e} N"
    if isinstance(model, jaxfric.TwoState):
        np.testing.assert_array_equal(np.asarray(out.parts["depth"]), r["depth"])
        assert int(out.overflow) == r["overflow"]


def test_paths_exercise_the_events():
    """The reference paths really contain nested closures, Rule 3 and wiping."""
    t, x, _ = PATHS["nested"]()
    depth = ref.two_state(t, x, **ref_kwargs(paper.two_state()))["depth"]
    assert depth.max() >= 4  # nested inner loops
    drops = np.diff(depth)
    assert (drops == -2).any() and (drops == -1).any()  # Rule 2 and Rule 3 both happen
    t, x, _ = PATHS["strokes"]()
    depth = ref.two_state(t, x, **ref_kwargs(paper.two_state()))["depth"]
    # The reversal at -1.5 mm ends a sliding stroke: wiping keeps the depth at 2 (without
    # it the entry from the 2 mm reversal would stay below and the depth would be 3).
    i_rev = int(np.argmin(x)) + 1
    assert depth[i_rev - 1] == 2 and depth[i_rev] == 2


def test_step_api_matches_simulate():
    """The per-sample `step` (closed-loop API), called from Python one sample at a time,
    gives the same numbers as `simulate`. (Jitted, as a user stepping a loop from Python
    would: eagerly, each call would re-trace the `lax.cond`s of the event logic.)"""
    t, x, v = sine_path(n=3000)
    step = eqx.filter_jit(lambda m, *args: m.step(*args))
    for model in (paper.two_state(), paper.gms5(), paper.lugre(), paper.tustin()):
        state = model.init_state(x[0])
        dt = np.diff(t, prepend=t[0])
        forces = []
        for xi, vi, dti in zip(x[:400], v[:400], dt[:400]):
            state, f = step(model, state, xi, vi, dti)
            forces.append(float(f))
        full = jaxfric.simulate(model, t[:400], x[:400], v[:400])
        np.testing.assert_allclose(forces, np.asarray(full), atol=1e-9, rtol=0)


def test_paper_shape_kappa_matches_analytic():
    """Autodiff kappa (jvp of Pi) equals the reference's analytic derivative of F(x)."""
    sh = paper.shape()
    xi = np.linspace(-1e-7, 1.1 * float(sh.l1), 1001)
    kw = {k: float(getattr(sh, k)) for k in ("a", "b", "c", "alpha", "beta", "l1")}
    p, k, g = sh.pi_kappa_gamma(jnp.asarray(xi), 26.1)
    np.testing.assert_allclose(p, ref.paper_pi(xi, Fs=26.1, **kw), atol=1e-12)
    np.testing.assert_allclose(k, ref.paper_kappa(xi, Fs=26.1, **kw), rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(g, ref.paper_gamma(xi, Fs=26.1, **kw), atol=1e-12)


def test_gms_from_shape_matches_reference_elements():
    sh = paper.shape()
    model = jaxfric.GMS.from_shape(sh, paper.stribeck(), paper.SIGMA2, paper.C, 40)
    nu, k = ref.gms_from_shape_elements(
        lambda xi: ref.paper_pi(xi, Fs=26.1, **{n: float(getattr(sh, n)) for n in
                                                ("a", "b", "c", "alpha", "beta", "l1")}),
        float(sh.l1),
        40,
    )
    np.testing.assert_allclose(model.nu, nu, atol=1e-12)
    np.testing.assert_allclose(model.k, k, rtol=1e-9, atol=1e-3)
    assert abs(float(jnp.sum(model.nu)) - 1.0) < 1e-12


def test_the_reference_passes_its_own_check_against_the_specification(capsys):
    """`tests/reference_check.py`: the reference's shapes, loops and steady states against
    properties the specification states, with nothing from jaxfric."""
    from ..reference_check import _self_check

    assert _self_check(), capsys.readouterr().out
