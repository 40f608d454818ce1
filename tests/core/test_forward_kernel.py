"""The two-state forward pass as a compiled CPU kernel (`jaxfric._kernel.forward`) against the
JAX path (`TwoState._simulate_jax`): forces and parts to rounding, depth and overflow equal, on
motions with dense reversals, nested loops, standstill, overflow and a given noisy velocity,
for every shape family it implements; under ``vmap`` over motions and over parameter sets;
the reversal bound's NaN; derivatives the JAX path's; dispatch only where it applies."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import _kernel, paper
from jaxfric._kernel import forward as fk
from jaxfric._normalized_shape import NormalizedPaperShape
from jaxfric.motion import make_motion

from ..helpers import nested_path, power_two_state, sine_path, strokes_path, UM
from .test_event_kernel import _random_walk, _standstill, _with_stack


pytestmark = pytest.mark.skipif(_kernel.find_compiler() is None,
                                reason="no C++ compiler on this machine")

#: Forces agree to rounding: libm and XLA differ in the last bits of exp/log, and the
#: branch-start forces are summed along the stack rather than by prefix sums.
RTOL = 1e-12


def _normalized(curvature=None, size=16):
    m = paper.two_state(size)
    shape = NormalizedPaperShape.from_paper(m.shape, m.stribeck.Fs)
    if curvature is not None:  # below 1e-6: the series branch of `_ratio`
        shape = eqx.tree_at(lambda s: s.curvature, shape, jnp.asarray(curvature))
    return eqx.tree_at(lambda m: m.shape, m, shape)


MODELS = {"paper_K16": lambda: paper.two_state(), "paper_K3": lambda: paper.two_state(3),
          "power_K5": lambda: _with_stack(power_two_state(), 5),
          "normalized": _normalized, "normalized_small_curvature": lambda: _normalized(3e-7)}


def _noisy_v():
    t, x, v = sine_path(1500, irregular=True, seed=3)
    rng = np.random.default_rng(3)
    return t, x, v + 0.2 * np.std(v) * rng.standard_normal(v.shape)  # sign flips vs dx


MOTIONS = {"random_walk": lambda: (*_random_walk(2000, 0), None),
           "walk_with_rests": lambda: (*_random_walk(1500, 1, stop=0.3), None),
           "nested": lambda: (*nested_path(), None), "strokes": lambda: (*strokes_path(), None),
           "standstill": lambda: (*_standstill(), None), "noisy_v": _noisy_v,
           "constant": lambda: (np.arange(50) * 1e-3, np.zeros(50), None),
           "one_sample": lambda: (np.zeros(1), np.zeros(1), None)}


def _both(model, t, x, v=None, bound=None):
    """(kernel, JAX path) results, each compiled on its own."""
    mo = make_motion(*(None if a is None else jnp.asarray(a) for a in (t, x, v)), bound)

    @eqx.filter_jit
    def kern(m, mo):
        assert fk.supported(m, mo.t, mo.x, mo.v)
        # as `simulate` calls it: the velocity given, or derived in the kernel
        force, parts, overflow = fk.simulate(m, mo.t, mo.x, None if v is None else mo.v,
                                             mo.max_reversals)
        return jaxfric.SimResult(force=force, parts=parts, overflow=overflow)

    @eqx.filter_jit
    def ref(m, mo):
        return m._simulate_jax(mo.consistent())

    return kern(model, mo), ref(model, mo)


def _assert_close(got, want):
    scale = np.max(np.abs(np.asarray(want.force)), initial=1.0)
    for k in ("hysteresis", "lag", "viscous"):
        np.testing.assert_allclose(got.parts[k], want.parts[k], rtol=RTOL, atol=RTOL * scale,
                                   err_msg=k)
    np.testing.assert_allclose(got.force, want.force, rtol=RTOL, atol=RTOL * scale)
    np.testing.assert_array_equal(got.parts["depth"], want.parts["depth"])
    np.testing.assert_array_equal(got.overflow, want.overflow)


@pytest.mark.parametrize("motion", sorted(MOTIONS))
@pytest.mark.parametrize("model_name", sorted(MODELS))
def test_forces_match_the_jax_path(motion, model_name):
    got, want = _both(MODELS[model_name](), *MOTIONS[motion]())
    _assert_close(got, want)


def test_cases_are_reached():
    """Overflow, deep nesting and presliding (gamma < 1) occur on the motions above."""
    got, _ = _both(paper.two_state(3), *MOTIONS["random_walk"]())
    assert int(got.overflow) > 0 and int(np.max(got.parts["depth"])) == 3
    got, _ = _both(paper.two_state(), *MOTIONS["nested"]())
    assert int(np.max(got.parts["depth"])) >= 5
    got, _ = _both(_normalized(3e-7), *MOTIONS["noisy_v"]())
    assert np.isfinite(np.asarray(got.force)).all()


def test_reversal_bound_below_the_count_gives_nan_and_counts():
    t, x, _ = MOTIONS["nested"]()
    count = int(jnp.sum(make_motion(jnp.asarray(t), jnp.asarray(x)).consistent().reversal))
    assert count > 10
    got, want = _both(paper.two_state(), t, x, bound=count - 3)
    assert np.isnan(np.asarray(got.force)).all() and np.isnan(np.asarray(want.force)).all()
    assert int(got.overflow) == int(want.overflow) == 3
    got, want = _both(paper.two_state(), t, x, bound=count)
    _assert_close(got, want)


def _sets(model, k):
    rng = np.random.default_rng(1)
    params, static = eqx.partition(model, eqx.is_inexact_array)
    batched = jax.tree.map(lambda a: a * (1 + 0.2 * jnp.asarray(rng.standard_normal((k,)))),
                           params)
    return batched, static


def test_vmap_over_motions_and_over_parameter_sets(monkeypatch):
    """One kernel call on a batch (threads over rows) equals the JAX path row by row; a
    nested vmap (sets x motions) broadcasts the unbatched inputs."""
    monkeypatch.setenv(_kernel.ENV, "kernel")
    walks = [_random_walk(3000, seed, stop=0.2 * (seed % 2)) for seed in range(6)]
    T, X = (jnp.asarray(np.stack(a)) for a in zip(*walks))
    params, static = _sets(paper.two_state(4), 3)

    def one(p, t, x, jax_path):
        m = eqx.combine(p, static)
        mo = make_motion(t, x).consistent()
        r = m._simulate_jax(mo) if jax_path else m._simulate(mo)
        return r.force, r.parts["depth"], r.overflow

    for jax_path in (False, True):
        inner = jax.vmap(one, in_axes=(None, 0, 0, None))
        outer = jax.jit(jax.vmap(inner, in_axes=(0, None, None, None)), static_argnums=3)
        if jax_path:
            want = outer(params, T, X, True)
        else:
            got = outer(params, T, X, False)
    assert "jaxfric_forward_pass" in jax.jit(jax.vmap(inner, in_axes=(0, None, None, None)),
                                             static_argnums=3).lower(params, T, X,
                                                                     False).as_text()
    scale = np.max(np.abs(np.asarray(want[0])))
    np.testing.assert_allclose(got[0], want[0], rtol=RTOL, atol=RTOL * scale)
    np.testing.assert_array_equal(got[1], want[1])
    np.testing.assert_array_equal(got[2], want[2])
    # simulate_many (lax.map over chunks of a vmap) gives the same forces
    with pytest.warns(jaxfric.StackOverflowWarning):  # K = 4 on a random walk
        many = jaxfric.simulate_many(eqx.combine(params, static), T[0], X[0], chunk=2)
    np.testing.assert_allclose(many, want[0][:, 0], rtol=RTOL, atol=RTOL * scale)


#: Derivatives agree to rounding: the kernel's dual numbers and XLA's JVP of the JAX path
#: are two implementations of the same chain rule, summed over samples in another order.
DERIV_RTOL = 1e-12


@pytest.mark.parametrize("model_name", ["paper_K16", "power_K5", "normalized"])
def test_derivatives_match_the_jax_path(model_name, monkeypatch):
    """grad and jacfwd of simulate with respect to the parameters (the kernel's Jacobian,
    dual numbers in forward.cc) equal those of the JAX path; with respect to the positions
    the JVP rule is the JAX path's own."""
    t, x = _random_walk(800, 2, stop=0.1)
    model = MODELS[model_name]()
    params, static = eqx.partition(model, eqx.is_inexact_array)

    def run(p, x):
        def force(p, x):
            return jaxfric.simulate(eqx.combine(p, static), t, x, max_reversals=800)

        def loss(p, x):
            return jnp.sum(force(p, x) ** 2)

        return (force(p, x), jax.grad(loss)(p, x), jax.jacfwd(force)(p, x),
                jax.grad(loss, argnums=1)(p, x))

    out = {}
    for mode in ("kernel", "jax"):
        monkeypatch.setenv(_kernel.ENV, mode)
        jax.clear_caches()
        out[mode] = jax.tree.map(np.asarray, eqx.filter_jit(run)(params, jnp.asarray(x)))
        text = eqx.filter_jit(run).lower(params, jnp.asarray(x)).as_text()
        assert ("jaxfric_forward_jacobian" in text) is (mode == "kernel")
    leaves = zip(jax.tree.leaves(out["kernel"]), jax.tree.leaves(out["jax"]), strict=True)
    for u, v in leaves:
        np.testing.assert_allclose(u, v, rtol=DERIV_RTOL, atol=DERIV_RTOL * np.max(np.abs(v)))


def test_dispatch(monkeypatch):
    """The kernel where it applies (CPU, float64, the implemented shapes, a plain TwoState);
    the JAX path for other shapes, float32 and ``JAXFRIC_EVENT_KERNEL=jax``."""
    monkeypatch.setenv(_kernel.ENV, "auto")
    mo = make_motion(jnp.arange(5.0), jnp.zeros(5))
    on_cpu = jax.default_backend() == "cpu"
    assert fk.supported(paper.two_state(), mo.t, mo.x, mo.v) is on_cpu
    assert fk.supported(power_two_state(), mo.t, mo.x, mo.v) is on_cpu

    class OtherShape(jaxfric.PowerShape):
        pass

    other = eqx.tree_at(lambda m: m.shape, power_two_state(),
                        OtherShape(l1=jnp.asarray(4e-6), n=jnp.asarray(2.5)))
    assert not fk.supported(other, mo.t, mo.x, mo.v)
    mo32 = make_motion(jnp.arange(5, dtype=jnp.float32), jnp.zeros(5, jnp.float32))
    assert not fk.supported(paper.two_state(), mo32.t, mo32.x, mo32.v)
    monkeypatch.setenv(_kernel.ENV, "jax")
    assert not fk.supported(paper.two_state(), mo.t, mo.x, mo.v)
    t, x, _ = MOTIONS["nested"]()
    jax.clear_caches()
    f_jax = jaxfric.simulate(paper.two_state(), t, x)
    monkeypatch.setenv(_kernel.ENV, "kernel")
    f_kernel = jaxfric.simulate(paper.two_state(), t, x)
    np.testing.assert_allclose(f_kernel, f_jax, rtol=RTOL, atol=RTOL * 30)


def test_under_an_effect_the_base_model_uses_the_kernel(monkeypatch):
    """A TwoState plus an effect (`jaxfric.effects`) gives the JAX path's force and gradient
    with the kernel on its base."""
    from jaxfric import effects

    model = paper.two_state() + effects.Offset(offset=jnp.asarray(0.7))
    t, x, _ = MOTIONS["strokes"]()
    out = {}
    for mode in ("kernel", "jax"):
        monkeypatch.setenv(_kernel.ENV, mode)
        jax.clear_caches()
        out[mode] = np.asarray(jaxfric.simulate(model, t, x + 3 * UM))
        mo = make_motion(jnp.asarray(t), jnp.asarray(x))
        text = eqx.filter_jit(lambda m, mo: m._simulate(mo).force).lower(model, mo).as_text()
        assert ("jaxfric_forward_pass" in text) is (mode == "kernel")
    np.testing.assert_allclose(out["kernel"], out["jax"], rtol=RTOL, atol=RTOL * 30)


def _kernel_calls(fn, *args):
    """The forward kernel's calls in the compiled program of `fn`: (target, HLO line)."""
    text = jax.jit(fn).lower(*args).compile().as_text()
    return [(t, line) for line in text.splitlines() for t in (_kernel.FORWARD_TARGET,
            _kernel.FORWARD_JACOBIAN_TARGET) if f'custom_call_target="{t}"' in line]


def test_force_only_programs_have_the_kernel_write_the_force_only():
    # A program that uses the force alone (simulate without full_output, a fit's Jacobian)
    # has one kernel call whose parts are 0 elements: the parts' call is compiled away.
    with _kernel.forced("kernel"):
        m = paper.two_state()
        t, x, _ = sine_path(300)
        t, x = jnp.asarray(t), jnp.asarray(x)
        calls = _kernel_calls(lambda t, x: jaxfric.simulate(m, t, x), t, x)
        assert [c for c, _ in calls] == [_kernel.FORWARD_TARGET]
        assert "f64[0]" in calls[0][1]
        calls = _kernel_calls(lambda m: jax.jacfwd(
            lambda mm: jaxfric.simulate(mm, t, x))(m), m)
        assert [c for c, _ in calls] == [_kernel.FORWARD_JACOBIAN_TARGET]
        assert "f64[0,12]" in calls[0][1]
        # With the parts used, they are written (by a second call).
        calls = _kernel_calls(
            lambda t, x: jaxfric.simulate(m, t, x, full_output=True).parts["lag"], t, x)
        assert len(calls) == 1 and "f64[0]" not in calls[0][1]
