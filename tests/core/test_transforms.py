"""JAX transformations (jit, vmap over trajectories and over models, grad of vmap, vmap of
grad), compilation caching, the closed-loop `step` API, and `simulate`'s input checks."""

import importlib
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import paper

from ..helpers import UM, waypoint_path


# Results of a batched (vmapped) and an unbatched program may differ in the last bits
# (XLA fuses and orders the operations differently); forces are ~30 N.
ATOL = 1e-10  # N
N_BATCH = 640  # trajectory length of the batch tests


def _batch_paths(n=N_BATCH, seeds=(0, 1, 2)):
    """Same-length trajectories: nested presliding loops and a sliding stroke, different
    amplitudes and irregular time steps per seed. Returns (T, X, V) of shape (B, n)."""
    ts, xs, vs = [], [], []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        dt = 1e-3 * rng.uniform(0.5, 1.5, n)
        t = np.concatenate([[0.0], np.cumsum(dt[1:])])
        amp = (60 + 40 * seed) * UM
        x = amp * np.sin(2 * np.pi * 2.5 * t) * np.exp(-t) + 0.6e-3 * np.sin(2 * np.pi * 0.4 * t)
        x[:5] = 0.0  # start at rest (zero state)
        ts.append(t)
        xs.append(x)
        vs.append(np.gradient(x, t))
    return np.asarray(ts), np.asarray(xs), np.asarray(vs)


MODELS = {
    "two_state": paper.two_state,
    "gms5": paper.gms5,
    "lugre": paper.lugre,
    "tustin": paper.tustin,
}


def _stack(models):
    """One model whose parameter leaves have a leading batch axis."""
    return jax.tree.map(lambda *leaves: jnp.stack(leaves), *models)


def _with_fs(model, fs):
    return eqx.tree_at(lambda m: m.stribeck.Fs, model, jnp.asarray(fs, dtype=jnp.float64))


@pytest.mark.parametrize("name", sorted(MODELS))
def test_jit_and_vmap_over_trajectories(name):
    """A jitted vmap over a batch of trajectories (with their velocities given, batched too)
    equals per-trajectory calls."""
    model = MODELS[name]()
    T, X, V = _batch_paths()
    plain = np.stack([np.asarray(jaxfric.simulate(model, t, x, v)) for t, x, v in zip(T, X, V)])
    assert np.isfinite(plain).all() and np.ptp(plain) > 1.0  # not a trivial output
    batched = eqx.filter_jit(eqx.filter_vmap(jaxfric.simulate, in_axes=(None, 0, 0, 0)))
    np.testing.assert_allclose(batched(model, T, X, V), plain, rtol=0, atol=ATOL)
    if name == "two_state":
        _check_vmap_over_models(T[1], X[1], V[1])


def test_vmap_over_trajectories_with_uneven_events():
    """The batched event loop (one block loop shared by the batch): trajectories with many
    events and a stack that overflows, with none (a ramp), and at rest, in one batch,
    equal per-trajectory calls: forces, depth and overflow count."""
    model = paper.two_state(stack_size=3)
    n = N_BATCH
    t = np.linspace(0.0, 0.64, n)
    amp = 80 * UM * (1.0 - t / t[-1])  # shrinking loops: nested reversals, overflow at K=3
    nested = amp * np.sin(2 * np.pi * 12.0 * t)
    ramp = 2e-3 * t
    rest = np.zeros(n)
    T, X = np.stack([t, t, t]), np.stack([ramp, nested, rest])
    plain = []
    for x in X:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the overflow warning, checked below instead
            plain.append(jaxfric.simulate(model, t, x, full_output=True))
    assert int(plain[1].overflow) > 0 and int(plain[0].overflow) == 0
    assert int(np.asarray(plain[1].parts["depth"]).max()) == 3
    batched = eqx.filter_jit(
        eqx.filter_vmap(lambda t, x: jaxfric.simulate(model, t, x, full_output=True))
    )(T, X)
    for i, r in enumerate(plain):
        np.testing.assert_allclose(batched.force[i], r.force, rtol=0, atol=ATOL)
        np.testing.assert_array_equal(batched.parts["depth"][i], r.parts["depth"])
        assert int(batched.overflow[i]) == int(r.overflow)


def _check_vmap_over_models(t, x, v):
    """A TwoState whose leaves carry a batch axis (different Fs, C, l1 per member).
    (Called from the test above: it shares its compiled per-trajectory program.)"""
    base = paper.two_state()
    models = [
        base,
        _with_fs(base, 24.0),
        eqx.tree_at(lambda m: (m.C, m.shape.l1), base, (jnp.asarray(30.0), jnp.asarray(3e-6))),
    ]
    plain = [jaxfric.simulate(m, t, x, v, full_output=True) for m in models]
    forces = np.stack([np.asarray(r.force) for r in plain])
    assert np.abs(forces[0] - forces[1]).max() > 0.1
    assert np.abs(forces[0] - forces[2]).max() > 0.1
    batched = eqx.filter_jit(
        eqx.filter_vmap(lambda m: jaxfric.simulate(m, t, x, v, full_output=True))
    )(_stack(models))
    np.testing.assert_allclose(batched.force, forces, rtol=0, atol=ATOL)
    # The parts and the overflow count are batched too.
    assert batched.overflow.shape == (3,) and batched.parts["depth"].shape == (3, t.size)
    for i, r in enumerate(plain):
        np.testing.assert_array_equal(batched.parts["depth"][i], r.parts["depth"])
        np.testing.assert_allclose(batched.parts["lag"][i], r.parts["lag"], rtol=0, atol=ATOL)


def _loss(model, t, x):
    return jnp.sum(jaxfric.simulate(model, t, x) ** 2) / t.size


def _leaves(tree):
    return [np.asarray(a) for a in jax.tree.leaves(eqx.filter(tree, eqx.is_inexact_array))]


def _assert_trees_close(a, b, rtol=1e-10):
    la, lb = _leaves(a), _leaves(b)
    assert len(la) == len(lb)
    for x, y in zip(la, lb):
        assert np.isfinite(x).all()
        np.testing.assert_allclose(x, y, rtol=rtol, atol=1e-14 * np.abs(y).max())


@pytest.mark.parametrize("name", ["gms5", "two_state"])
def test_grad_of_vmap_and_vmap_of_grad(name):
    """Over trajectories: a vmapped gradient gives each per-item gradient, and the gradient
    of a vmapped batch loss is the sum of the per-item gradients. For TwoState this also
    checks the ``vmap`` rule of its event pass under both orders of transformation."""
    model = MODELS[name]()
    T, X, _ = _batch_paths()
    grad = eqx.filter_jit(eqx.filter_grad(_loss))
    per_item = [grad(model, t, x) for t, x in zip(T, X)]

    vmap_of_grad = eqx.filter_jit(eqx.filter_vmap(eqx.filter_grad(_loss), in_axes=(None, 0, 0)))
    _assert_trees_close(vmap_of_grad(model, T, X), _stack(per_item))

    @eqx.filter_jit
    @eqx.filter_grad
    def grad_of_vmap(m):
        return jnp.sum(eqx.filter_vmap(_loss, in_axes=(None, 0, 0))(m, T, X))

    total = jax.tree.map(lambda *g: sum(g), *per_item)
    _assert_trees_close(grad_of_vmap(model), total)


def test_vmap_of_grad_over_models_gms():
    """Over models (GMS: per-element nu and k get a batch axis too)."""
    T, X, _ = _batch_paths(seeds=(2,))
    t, x = T[0], X[0]
    base = paper.gms5()
    models = [base, _with_fs(base, 28.0), eqx.tree_at(lambda m: m.k, base, base.k * 1.3)]
    grad = eqx.filter_jit(eqx.filter_grad(_loss))
    per_model = [grad(m, t, x) for m in models]
    batched = eqx.filter_jit(eqx.filter_vmap(lambda m: eqx.filter_grad(_loss)(m, t, x)))
    _assert_trees_close(batched(_stack(models)), _stack(per_model))
    # And the gradient of a vmapped-over-models loss w.r.t. the stacked parameters.
    gov = eqx.filter_jit(
        eqx.filter_grad(lambda ms: jnp.sum(eqx.filter_vmap(lambda m: _loss(m, t, x))(ms)))
    )
    _assert_trees_close(gov(_stack(models)), _stack(per_model))


# ---- compilation caching --------------------------------------------------------------


@pytest.fixture
def traces(monkeypatch):
    """Shapes seen by `make_motion`, which runs only while `simulate`'s compiled function
    is traced: one entry per trace."""
    module = importlib.import_module("jaxfric._simulate")
    seen = []
    original = module.make_motion

    def counting(*args, **kwargs):
        seen.append(args[0].shape)
        return original(*args, **kwargs)

    monkeypatch.setattr(module, "make_motion", counting)
    return seen


def test_no_recompilation(traces):
    """New data of the same shape and another model instance of the same structure with
    other values: one trace in all. `full_output` is one more program (the force-only one
    leaves the parts out of the kernel), reused after."""
    n = 777  # a length no other test uses, so no earlier compilation is reused
    t = np.linspace(0.0, 1.0, n)
    x1 = 50 * UM * np.sin(2 * np.pi * 3 * t)
    x2 = 2e-3 * np.sin(2 * np.pi * 1 * t)
    model = paper.two_state()
    f1 = jaxfric.simulate(model, t, x1)
    f2 = jaxfric.simulate(model, t + 0.5, x2)
    # A different instance with other values, built the usual way (Python floats, NumPy
    # and JAX scalars as parameters): same structure, so same compiled program.
    other = jaxfric.TwoState(
        stribeck=jaxfric.Stribeck(Fs=np.float64(25.0), Fc=20, Vs=jnp.asarray(2e-3), delta=0.7),
        shape=jaxfric.PaperShape(a=2600.0, b=-0.27, c=2.3e15, alpha=0.3, beta=1e-6, l1=4e-6),
        sigma2=60.0,
        C=12.0,
    )
    f3 = jaxfric.simulate(other, t, x1)
    # Parameters edited with eqx.tree_at using a NumPy value (same program).
    edited = eqx.tree_at(lambda m: m.C, model, np.float64(20.0))
    f4 = jaxfric.simulate(edited, t, x1)
    assert len(traces) == 1, traces
    assert not np.allclose(f1, f3) and not np.allclose(f1, f2) and not np.allclose(f1, f4)
    full = [jaxfric.simulate(m, t, x1, full_output=True).force for m in (model, edited)]
    assert len(traces) == 2, traces
    np.testing.assert_allclose(full[1], f4, rtol=1e-12)
    # The counter does see a new trace when the structure changes (given velocities).
    jaxfric.simulate(model, t, x1, np.gradient(x1, t))
    assert len(traces) == 3


def test_reversal_bound_and_max_reversals():
    """`TwoState` evaluates its reversal terms on a list of ``max_reversals`` slots: the
    bound `simulate` computes from concrete data (`reversal_bound`, at least the number of
    reversals of `Motion.reversal`), the exact count, and ``n`` (inside ``jit``, where the
    data are traced) give the same forces; a bound below the count gives NaN."""
    T, X, V = _batch_paths()
    model = paper.two_state()
    for t, x, v in zip(T, X, V):
        for vel in (None, v):
            count = int(jnp.sum(jaxfric.motion.make_motion(t, x, vel).reversal))
            bound = jaxfric.reversal_bound(t, x, vel)
            assert 0 < count <= bound <= t.shape[0]
            ref = jaxfric.simulate(model, t, x, vel)
            traced = jax.jit(lambda t, x, vel=vel: jaxfric.simulate(model, t, x, vel))(t, x)
            exact = jaxfric.simulate(model, t, x, vel, max_reversals=count)
            np.testing.assert_allclose(traced, ref, atol=ATOL, rtol=0)
            np.testing.assert_allclose(exact, ref, atol=ATOL, rtol=0)
            with pytest.warns(jaxfric.StackOverflowWarning, match="max_reversals"):
                short = jaxfric.simulate(model, t, x, vel, max_reversals=count - 1,
                                         full_output=True)
            assert int(short.overflow) == 1  # counted, not a silent NaN
            assert np.all(np.isnan(short.force))
            assert np.all(np.isnan(short.parts["hysteresis"]))
    # A motion without reversals has a bound of its own; a negative bound is refused.
    t = np.linspace(0.0, 1.0, 50)
    assert jaxfric.reversal_bound(t, t * 1e-3) == 50  # min(64, n)
    np.testing.assert_allclose(jaxfric.simulate(model, t, t * 1e-3, max_reversals=0),
                               jaxfric.simulate(model, t, t * 1e-3), atol=ATOL, rtol=0)
    with pytest.raises(ValueError, match="max_reversals"):
        jaxfric.simulate(model, t, t * 1e-3, max_reversals=-1)
    # `simulate` computes the bound for models that use it, also under added effects.
    from jaxfric._simulate import _uses_reversal_bound

    assert _uses_reversal_bound(model)
    assert _uses_reversal_bound(model + jaxfric.effects.Offset(0.1))
    assert not _uses_reversal_bound(paper.gms5() + jaxfric.effects.Offset(0.1))


def test_no_recompilation_for_weakly_typed_parameter(traces):
    """A leaf set with ``eqx.tree_at(..., jnp.asarray(20.0))`` is weakly typed; `simulate`
    strips the flag, so the edited model reuses the compiled program."""
    t = np.linspace(0.0, 1.0, 779)  # a length no other test uses
    x = 50 * UM * np.sin(2 * np.pi * 3 * t)
    tustin = paper.tustin()
    jaxfric.simulate(tustin, t, x)
    # Same structure, same dtype (float64), only the weak-type flag differs.
    edited = eqx.tree_at(lambda m: m.sigma2, tustin, jnp.asarray(60.0))
    assert edited.sigma2.dtype == tustin.sigma2.dtype
    jaxfric.simulate(edited, t, x)
    assert len(traces) == 1, traces


# ---- closed loop with the per-sample API ----------------------------------------------


@eqx.filter_jit
def _closed_loop(model, amplitude, n=N_BATCH, dt=5e-4, mass=1.0):
    """A 1 kg mass driven by ``amplitude * sin(2 pi 5 t)`` N against friction, with
    semi-implicit Euler: ``m dv/dt = F_applied - F_friction``. Returns the inputs given to
    `step` (x, v) and its friction force, per step. (Presliding stiffness ~4e6 N/m makes
    omega*dt ~ 1: stable.)"""

    def body(carry, k):
        x, v, state = carry
        state, friction = model.step(state, x, v, dt)
        applied = amplitude * jnp.sin(2 * jnp.pi * 5.0 * k * dt)
        v_new = v + dt * (applied - friction) / mass
        return (x + dt * v_new, v_new, state), (x, v, friction)

    zero = jnp.zeros(())
    steps = jnp.arange(n, dtype=zero.dtype)
    _, out = jax.lax.scan(body, (zero, zero, model.init_state(zero)), steps)
    return out


@pytest.mark.parametrize("name", sorted(MODELS))
def test_closed_loop_step_in_user_scan(name):
    """`step` inside the user's own jitted `lax.scan`: finite, physically sensible, and the
    same forces as `simulate` on the motion the loop produced."""
    model = MODELS[name]()
    dt = 5e-4
    t = dt * np.arange(N_BATCH)
    # Below the breakaway force the mass stays in presliding, within 2*Fs*l1 = 0.22 mm
    # (Tustin has no presliding: it creeps instead); above it the mass slides (~cm).
    for amplitude in (15.0, 60.0):
        x, v, f = (np.asarray(a) for a in _closed_loop(model, jnp.asarray(amplitude)))
        assert np.isfinite(x).all() and np.isfinite(v).all() and np.isfinite(f).all()
        if amplitude < 26.1 and name != "tustin":
            assert np.abs(x).max() < 0.25e-3
        if amplitude > 26.1:
            assert np.abs(x).max() > 1e-3
        assert np.abs(f).max() < 26.1 + 54.0 * np.abs(v).max() + 3.0
        # `step` starts with the state of sample 0 at dt = 0 in `simulate` and at dt here;
        # F_l = 0 then, so the first sample agrees as well.
        np.testing.assert_allclose(
            jaxfric.simulate(model, t, x, v), f, rtol=0, atol=ATOL, err_msg=f"{amplitude} N"
        )


# ---- input validation -----------------------------------------------------------------


def test_rejects_batched_input_with_hint_to_vmap():
    t = np.linspace(0, 1, 10)
    with pytest.raises(ValueError, match="vmap"):
        jaxfric.simulate(paper.tustin(), t, np.zeros((2, 10)))
    with pytest.raises(ValueError, match="vmap"):
        jaxfric.simulate(paper.tustin(), np.stack([t, t]), np.zeros((2, 10)))
    with pytest.raises(ValueError, match="vmap"):
        jaxfric.simulate(paper.tustin(), t, np.zeros(10), np.zeros((10, 1)))


def test_rejects_mismatched_lengths():
    t = np.linspace(0, 1, 10)
    with pytest.raises(ValueError, match="same shape"):
        jaxfric.simulate(paper.tustin(), t, np.zeros(9))
    with pytest.raises(ValueError, match="same shape"):
        jaxfric.simulate(paper.tustin(), t, np.zeros(10), np.zeros(11))
    with pytest.raises(ValueError, match="at least one sample"):
        jaxfric.simulate(paper.tustin(), np.zeros(0), np.zeros(0))


@pytest.mark.parametrize("bad", ["equal", "decreasing"])
def test_rejects_non_increasing_time_naming_the_index(bad):
    t = np.linspace(0, 1, 10)
    t[7] = t[6] if bad == "equal" else t[6] - 0.01
    with pytest.raises(ValueError, match=r"t\[7\] <= t\[6\]"):
        jaxfric.simulate(paper.tustin(), t, np.zeros(10))


@pytest.mark.parametrize("which", ["t", "x", "v"])
@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_rejects_non_finite_values(which, value):
    arrays = {"t": np.linspace(0, 1, 10), "x": np.zeros(10), "v": np.zeros(10)}
    arrays[which][4] = value
    with pytest.raises(ValueError, match=f"{which} has a non-finite value at index 4"):
        jaxfric.simulate(paper.tustin(), arrays["t"], arrays["x"], arrays["v"])


def test_stack_overflow_warns_and_is_reported():
    # Deeply nested presliding loops (amplitudes shrinking, never closing): depth 10.
    waypoints = np.array([0, 100, -90, 80, -70, 60, -50, 40, -30, 20, -10]) * UM
    t, x = waypoint_path(waypoints, 20 * UM, 0.1)
    # Padded to the batch tests' length, with velocities given as they do: the same
    # compiled program as theirs for stack_size=16.
    t = np.concatenate([t, t[-1] + 0.1 * np.arange(1, N_BATCH - t.size + 1)])
    x = np.concatenate([x, np.full(N_BATCH - x.size, x[-1])])
    v = np.diff(x, prepend=x[0]) / np.diff(t, prepend=t[0] - 1.0)
    small = jaxfric.TwoState(
        stribeck=paper.stribeck(), shape=paper.shape(), sigma2=paper.SIGMA2, C=paper.C,
        stack_size=3,
    )
    with pytest.warns(jaxfric.StackOverflowWarning, match="stack_size"):
        out = jaxfric.simulate(small, t, x, v, full_output=True)
    assert int(out.overflow) > 0
    assert np.asarray(out.parts["depth"]).max() <= 3
    assert np.isfinite(np.asarray(out.force)).all()
    with warnings.catch_warnings():
        warnings.simplefilter("error", jaxfric.StackOverflowWarning)
        big = jaxfric.simulate(paper.two_state(stack_size=16), t, x, v, full_output=True)
    assert int(big.overflow) == 0
    assert np.asarray(big.parts["depth"]).max() > 3  # the path does need more than 3
    # Dropping the oldest entries changes the force only after the deep part.
    first_drop = int(np.argmax(np.asarray(big.parts["depth"]) > 3))
    np.testing.assert_allclose(out.force[:first_drop], big.force[:first_drop], atol=1e-12)


def test_mixed_float_dtypes_are_promoted():
    """float32 times with float64 positions (common when t comes from a logger) work under
    strict dtype promotion and give the float64 result."""
    t = np.linspace(0.0, 1.0, 200)
    x = 50 * UM * np.sin(2 * np.pi * 3 * t)
    model = paper.tustin()
    f64 = jaxfric.simulate(model, t, x)
    f_mixed = jaxfric.simulate(model, t.astype(np.float32), x)
    assert f_mixed.dtype == np.float64
    # float32 times differ from float64 ones by ~3e-8 s, which moves v slightly.
    np.testing.assert_allclose(f_mixed, f64, rtol=0, atol=1e-2)
