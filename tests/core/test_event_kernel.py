"""The two-state event pass as a compiled CPU kernel (`jaxfric._kernel`) against the pure-JAX
event loop: records bit-identical on motions with dense reversals, nested loops, standstill
and memory overflow, one by one and batched under ``vmap``; the JAX path's forces, ``grad``
and ``jacfwd`` the same with both event passes; the fallback when forced or when there is no
compiler; the kernel the default on the CPU."""

import logging

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import _kernel, paper
from jaxfric._models import two_state as ts
from jaxfric.motion import make_motion

from ..helpers import nested_path, power_two_state, sine_path, strokes_path, UM


HAVE_KERNEL = _kernel.find_compiler() is not None
needs_kernel = pytest.mark.skipif(not HAVE_KERNEL, reason="no C++ compiler on this machine")


def _random_walk(n, seed, step=2 * UM, stop=0.0):
    """A random walk (a reversal every few samples, loops of every size), with runs of
    standstill (a fraction `stop` of the samples repeat the previous position)."""
    rng = np.random.default_rng(seed)
    dx = step * rng.standard_normal(n)
    dx[rng.random(n) < stop] = 0.0
    x = np.cumsum(dx) + 40 * UM * np.sin(np.linspace(0, 20, n))
    return np.arange(n) * 1e-3, x


def _standstill(n=900):
    """Strokes with long rests at the turning points, and a rest at the start."""
    t = np.arange(n) * 1e-3
    x = 30 * UM * np.clip(1.5 * np.sin(2 * np.pi * 3 * t), -1, 1)
    x[:40] = x[40]
    return t, x


def _motions():
    t, x, _ = sine_path(1500)
    out = {"random_walk": _random_walk(2000, 0), "walk_with_rests": _random_walk(1500, 1, stop=0.3),
           "nested": nested_path(), "strokes": strokes_path(), "sine": (t, x),
           "standstill": _standstill(), "constant": (np.arange(50) * 1e-3, np.zeros(50))}
    return out


MOTIONS = _motions()


def _with_stack(model, size):
    return jaxfric.TwoState(stribeck=model.stribeck, shape=model.shape, sigma2=model.sigma2,
                            C=model.C, stack_size=size)

MODELS = {"paper_K16": lambda: paper.two_state(), "paper_K3": lambda: paper.two_state(3),
          "paper_K4": lambda: paper.two_state(4),
          "power_K5": lambda: _with_stack(power_two_state(), 5)}


def _pass(model, *inputs):
    return eqx.filter_jit(lambda m, *a: m._event_pass(*a))(model, *inputs)


def _inputs(model, t, x):
    mo = make_motion(jnp.asarray(t), jnp.asarray(x)).consistent()
    s = model.stribeck.effective(mo.v, mo.last_d)
    return mo.x, s, mo.reversal, mo.x_prev, model.stribeck.rest(mo.prev_last_d)


def _records(mode, monkeypatch, f, *args):
    """`f(*args)` traced afresh with ``JAXFRIC_EVENT_KERNEL=mode``."""
    monkeypatch.setenv(_kernel.ENV, mode)
    jax.clear_caches()
    return jax.tree.map(np.asarray, eqx.filter_jit(f)(*args))


def _event_pass(model, *inputs):
    rec = model._event_pass(*inputs)
    return rec.table, rec.popped, rec.overflow, ts._fill_records(rec)


def _assert_same(a, b):
    for u, v in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        assert u.dtype == v.dtype and u.shape == v.shape
        np.testing.assert_array_equal(u, v)


#: Each motion with the memories that matter for it: small ones overflow, 16 does not.
CASES = [("random_walk", "paper_K3"), ("random_walk", "paper_K16"), ("random_walk", "power_K5"),
         ("walk_with_rests", "paper_K4"), ("walk_with_rests", "power_K5"),
         ("nested", "paper_K3"), ("nested", "paper_K16"), ("strokes", "paper_K4"),
         ("sine", "power_K5"), ("standstill", "paper_K16"), ("constant", "paper_K3")]


@needs_kernel
@pytest.mark.parametrize(("motion", "model_name"), CASES)
def test_records_bit_identical(motion, model_name, monkeypatch):
    model = MODELS[model_name]()
    inputs = _inputs(model, *MOTIONS[motion])
    want = _records("jax", monkeypatch, _event_pass, model, *inputs)
    got = _records("kernel", monkeypatch, _event_pass, model, *inputs)
    _assert_same(got, want)
    table = want[0]
    if motion in ("random_walk", "nested"):
        assert (table[:-1, 1] > 0).sum() > 20  # many events, closures among them
        assert want[1][0] >= 0
    if motion == "random_walk" and model.stack_size <= 4:
        assert want[2] > 0  # the memory overflowed


def test_records_exercise_wiping_closure_and_overflow():
    """The motions above reach the cases they are meant to."""
    model = paper.two_state(3)
    rec = _pass(model, *_inputs(model, *MOTIONS["random_walk"]))
    depth = np.asarray(rec.depth)
    assert int(rec.overflow) > 0 and depth.max() == 3
    assert (np.asarray(rec.popped) >= 0).sum() > 10  # loops closed


@needs_kernel
@pytest.mark.parametrize("params_batched", [False, True])
def test_vmap_records_bit_identical(params_batched, monkeypatch):
    """A batch of trajectories (and of parameter sets, where l1 varies): one kernel call on
    the whole batch equals the batched JAX loop, record for record."""
    model = paper.two_state(4)
    walks = [_random_walk(800, seed, stop=0.2 * (seed % 2)) for seed in range(5)]
    inputs = [jnp.stack(a) for a in zip(*[_inputs(model, t, x) for t, x in walks])]
    if params_batched:
        factors = jnp.linspace(0.3, 3.0, 5)
        models = jax.vmap(lambda f: eqx.tree_at(lambda m: m.shape.l1, model,
                                                model.shape.l1 * f))(factors)
        axes = (eqx.if_array(0), 0, 0, 0, 0, 0)
    else:
        models, axes = model, (None, 0, 0, 0, 0, 0)
    f = eqx.filter_vmap(_event_pass, in_axes=axes)
    want = _records("jax", monkeypatch, f, models, *inputs)
    got = _records("kernel", monkeypatch, f, models, *inputs)
    _assert_same(got, want)
    # and one row of the batch alone
    row = _records("kernel", monkeypatch, _event_pass, model, *[a[2] for a in inputs])
    if not params_batched:
        _assert_same(row, jax.tree.map(lambda a: a[2], got))


@needs_kernel
def test_nested_vmap_with_shared_motion(monkeypatch):
    """vmap over parameter sets of a vmap over trajectories (the kernel broadcasts the
    unbatched dimensions)."""
    model = paper.two_state(5)
    walks = [_random_walk(300, seed) for seed in range(3)]
    inputs = [jnp.stack(a) for a in zip(*[_inputs(model, t, x) for t, x in walks])]
    models = jax.vmap(lambda f: eqx.tree_at(lambda m: m.shape.l1, model, model.shape.l1 * f))(
        jnp.asarray([0.5, 1.0]))
    inner = eqx.filter_vmap(_event_pass, in_axes=(None, 0, 0, 0, 0, 0))
    f = eqx.filter_vmap(inner, in_axes=(eqx.if_array(0), None, None, None, None, None))
    want = _records("jax", monkeypatch, f, models, *inputs)
    got = _records("kernel", monkeypatch, f, models, *inputs)
    _assert_same(got, want)


def _simulate_jax(model, t, x):
    """The JAX path of a simulation (`TwoState._simulate_jax`): its event pass is the
    kernel or the JAX loop, its smooth pass is JAX either way (`jaxfric.simulate` itself runs
    the forward kernel on the CPU, tests/core/test_forward_kernel.py)."""
    return model._simulate_jax(make_motion(jnp.asarray(t), jnp.asarray(x)).consistent()).force


def _forces_and_derivatives(model, t, x):
    params, static = eqx.partition(model, eqx.is_inexact_array)

    def force(p):
        return _simulate_jax(eqx.combine(p, static), t, x)

    def loss(p):
        return jnp.sum(force(p) ** 2)

    return force(params), jax.grad(loss)(params), jax.jacfwd(force)(params)


@needs_kernel
@pytest.mark.parametrize("motion", ["random_walk", "standstill"])
def test_simulate_grad_jacfwd_same_with_both_paths(motion, monkeypatch):
    """With the same event records, the smooth pass is the same code: forces, gradients and
    Jacobians come out the same (to the last bits XLA may fuse differently in the two
    programs)."""
    model = paper.two_state(4)
    t, x = MOTIONS[motion]
    t, x = t[:600], x[:600]
    want = _records("jax", monkeypatch, _forces_and_derivatives, model, t, x)
    got = _records("kernel", monkeypatch, _forces_and_derivatives, model, t, x)
    for u, v in zip(jax.tree.leaves(got), jax.tree.leaves(want), strict=True):
        np.testing.assert_allclose(u, v, rtol=1e-13, atol=1e-12 * np.max(np.abs(v)))


@needs_kernel
def test_vmap_of_simulate_and_of_grad(monkeypatch):
    model = paper.two_state()
    walks = [_random_walk(400, seed) for seed in range(3)]
    T, X = (np.stack(a) for a in zip(*walks))
    params, static = eqx.partition(model, eqx.is_inexact_array)

    def run(p, T, X):
        sim = jax.vmap(lambda t, x: _simulate_jax(eqx.combine(p, static), t, x))
        return sim(T, X), jax.vmap(jax.grad(
            lambda q, t, x: jnp.sum(_simulate_jax(eqx.combine(q, static), t, x))),
            in_axes=(None, 0, 0))(p, T, X)

    want = _records("jax", monkeypatch, run, params, T, X)
    got = _records("kernel", monkeypatch, run, params, T, X)
    for u, v in zip(jax.tree.leaves(got), jax.tree.leaves(want), strict=True):
        np.testing.assert_allclose(u, v, rtol=1e-13, atol=1e-12 * np.max(np.abs(v)))


def test_fallback_forced(monkeypatch):
    monkeypatch.setenv(_kernel.ENV, "jax")
    model = paper.two_state()
    assert not _kernel.use_kernel(*_inputs(model, *MOTIONS["nested"])[:2])
    jax.clear_caches()
    rec = _pass(model, *_inputs(model, *MOTIONS["nested"]))
    assert rec.filled is None  # the JAX loop's records
    t, x = MOTIONS["nested"]
    assert np.isfinite(np.asarray(jaxfric.simulate(model, t, x))).all()


def test_bad_mode_is_an_error(monkeypatch):
    monkeypatch.setenv(_kernel.ENV, "fast")
    with pytest.raises(ValueError, match="JAXFRIC_EVENT_KERNEL"):
        _kernel.use_kernel(jnp.zeros(3))


def test_no_compiler_falls_back_with_one_line(monkeypatch, tmp_path, caplog):
    """Without a compiler (none on PATH, empty cache): one logged line, the JAX path, and
    simulate works; forcing the kernel then raises."""
    monkeypatch.setattr(_kernel, "_state", {})
    monkeypatch.setattr(_kernel, "find_compiler", lambda: None)
    monkeypatch.setenv("JAXFRIC_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv(_kernel.ENV, "auto")
    with caplog.at_level(logging.WARNING, logger="jaxfric"):
        assert not _kernel.use_kernel(jnp.zeros(3))
        assert not _kernel.use_kernel(jnp.zeros(3))  # decided once
    lines = [r.getMessage() for r in caplog.records if r.name == "jaxfric"]
    assert len(lines) == 1 and "\n" not in lines[0] and "pure-JAX" in lines[0]
    jax.clear_caches()
    t, x = MOTIONS["nested"]
    assert np.isfinite(np.asarray(jaxfric.simulate(paper.two_state(), t, x))).all()
    monkeypatch.setenv(_kernel.ENV, "kernel")
    with pytest.raises(RuntimeError, match="no C\\+\\+ compiler"):
        _kernel.use_kernel(jnp.zeros(3))
    jax.clear_caches()


@pytest.mark.parametrize("value", ["", "0"])
def test_a_cache_variable_that_turns_the_cache_off_keeps_the_kernel_in_the_default_folder(
        monkeypatch, tmp_path, value):
    """``JAXFRIC_CACHE_DIR`` empty or ``0`` means no compilation cache
    (`jaxfric.enable_compilation_cache`); the kernel still needs a folder, the default one,
    not ``./0`` in whatever folder the process runs in."""
    monkeypatch.setenv("JAXFRIC_CACHE_DIR", value)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert _kernel.cache_dir() == tmp_path / "jaxfric"
    monkeypatch.setenv("JAXFRIC_CACHE_DIR", str(tmp_path / "mine"))
    assert _kernel.cache_dir() == tmp_path / "mine"


def test_kernel_is_the_default_on_cpu(monkeypatch):
    monkeypatch.delenv(_kernel.ENV, raising=False)
    x = jnp.zeros(3)
    assert _kernel.use_kernel(x, x) is (HAVE_KERNEL and jax.default_backend() == "cpu")
    assert not _kernel.use_kernel(x.astype(jnp.float32))  # float32: the JAX path


@needs_kernel
def test_build_is_cached(tmp_path):
    first = _kernel.build(tmp_path)
    stamp = first.stat().st_mtime_ns
    assert _kernel.build(tmp_path) == first and first.stat().st_mtime_ns == stamp
    assert [p.name for p in tmp_path.iterdir()] == [first.name]  # no leftovers
