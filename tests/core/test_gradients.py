"""Gradients with respect to every parameter: finite everywhere, nonzero where the physics
says a parameter matters, and equal to central finite differences away from events.

Every model's gradient is taken on one trajectory of `N_GRAD` samples, and windows of it
are selected with a weight array (data, not structure), so that each model's gradient
program (seconds to compile) is compiled once.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import paper

from .. import reference as ref
from ..helpers import power_two_state, ref_kwargs


UM = 1e-6
N_GRAD = 1200
N_REST = 5  # samples at rest at x = 0 before any motion (the zero state)


def segment_path(segments, n_total=N_GRAD, n_rest=N_REST, dwell_dt=1e-2):
    """A motion of exactly `n_total` samples: `n_rest` samples at rest at x = 0, then the
    `segments`, then rest until the end.

    Each segment is ``(target_um, speed_um_per_s, n_samples)``: a constant-velocity move to
    ``target_um`` in ``n_samples`` equal steps (reversal points are hit exactly), or, with
    speed 0, a dwell of ``n_samples`` samples ``dwell_dt`` apart.
    """
    t, x = [0.0], [0.0]
    for _ in range(n_rest):
        t.append(t[-1] + 1e-3)
        x.append(0.0)
    for target, speed, n in segments:
        a = x[-1]
        if speed == 0:
            for _ in range(n):
                t.append(t[-1] + dwell_dt)
                x.append(a)
            continue
        b = target * UM
        duration = abs(b - a) / (speed * UM)
        for i in range(1, n + 1):
            t.append(t[-1] + duration / n)
            x.append(a + (b - a) * i / n)
    if len(t) > n_total:
        raise ValueError(f"path has {len(t)} samples, more than {n_total}")
    while len(t) < n_total:
        t.append(t[-1] + dwell_dt)
        x.append(x[-1])
    return np.asarray(t), np.asarray(x)


# Presliding (paper shape: full sliding needs 2*Fs*l1 = 224 um after a reversal, 112 um
# from the virgin state): nested inner loops closing onto outer ones (Rule 2), returns to
# the virgin curve at 80 um and at -90 um (Rule 3), a slow fine segment after a reversal
# (so that even the stiffest GMS elements stick for a few samples), dwells; then sliding
# strokes at changing speed (C and the Stribeck curve matter), reversals after them
# (wiping-out), and small loops at the stroke ends.
#
# Sample counts are chosen so that no sample lands exactly on an earlier reversal point
# while passing it: there a GMS element returns exactly to its slip limit (Masing memory),
# a tie that rounding decides, i.e. an event decision *at* its threshold.
EVENTS = [
    (80, 40, 40), (0, 0, 5), (20, 40, 30), (60, 40, 20), (35, 40, 15), (50, 40, 10),
    (40, 40, 5), (70, 40, 20), (10, 40, 31), (90, 40, 37), (88, 2, 50), (-100, 40, 90),
    (0, 0, 5), (-20, 40, 40), (-60, 40, 20), (-30, 40, 15), (-70, 40, 19), (100, 40, 90),
    (600, 1000, 60), (1500, 3000, 60), (0, 0, 5), (1440, 100, 30), (1480, 50, 20),
    (1460, 50, 10), (-500, 2000, 100), (-1500, 300, 100), (-1470, 60, 30), (-1490, 30, 20),
    (-1430, 60, 29),
]
T, X = segment_path(EVENTS)
I_STROKE = int(np.argmax(X > 150 * UM))  # first sample of the first sliding stroke


def _window(lo, hi):
    w = np.zeros(N_GRAD)
    w[lo:hi] = 1.0
    return jnp.asarray(w)


WINDOWS = {
    "all": _window(0, N_GRAD),
    "rest": _window(0, N_REST + 1),  # the zero state, including the very first sample
    "first_step": _window(N_REST + 1, N_REST + 2),  # the first moving sample
    "presliding": _window(N_REST + 1, I_STROKE),
    "sliding": _window(I_STROKE, N_GRAD),
}


def _gms_from_power_shape():
    # A concave shape: every element has k_i > 0 and nu_i > 0 (the paper shape's clipped
    # top would give k_1 = nu_1 = 0, a parameter that cannot matter).
    return jaxfric.GMS.from_shape(
        jaxfric.PowerShape(l1=4e-6, n=2.5), paper.stribeck(), paper.SIGMA2, paper.C, 6
    )


MODELS = {
    "two_state_paper": paper.two_state,
    "two_state_power": power_two_state,
    "gms5": paper.gms5,
    "gms_from_shape": _gms_from_power_shape,
    "lugre": paper.lugre,
    "tustin": paper.tustin,
}

#: Parameters (path inside the model) that must influence the force in each window.
MUST_MATTER = {
    "presliding": {
        "two_state_paper": [".stribeck.Fs", ".shape.a", ".shape.b", ".shape.c", ".shape.alpha",
                            ".shape.beta", ".shape.l1", ".sigma2"],
        "two_state_power": [".stribeck.Fs", ".shape.l1", ".shape.n", ".sigma2"],
        "gms5": [".stribeck.Fs", ".nu", ".k", ".sigma2"],
        "gms_from_shape": [".stribeck.Fs", ".nu", ".k", ".sigma2"],
        "lugre": [".stribeck.Fs", ".sigma0", ".sigma1", ".sigma2"],
        "tustin": [".stribeck.Fs", ".stribeck.Fc", ".stribeck.Vs", ".stribeck.delta", ".sigma2"],
    },
    "sliding": {
        "two_state_paper": [".stribeck.Fs", ".stribeck.Fc", ".stribeck.Vs", ".stribeck.delta",
                            ".shape.l1", ".sigma2", ".C"],
        "two_state_power": [".stribeck.Fs", ".stribeck.Fc", ".stribeck.Vs", ".stribeck.delta",
                            ".shape.l1", ".shape.n", ".sigma2", ".C"],
        "gms5": [".stribeck.Fs", ".stribeck.Fc", ".stribeck.Vs", ".stribeck.delta", ".nu",
                 ".sigma2", ".C"],
        "gms_from_shape": [".stribeck.Fs", ".stribeck.Fc", ".stribeck.Vs", ".stribeck.delta",
                           ".nu", ".sigma2", ".C"],
        "lugre": [".stribeck.Fs", ".stribeck.Fc", ".stribeck.Vs", ".stribeck.delta",
                  ".sigma0", ".sigma2"],
        "tustin": [".stribeck.Fs", ".stribeck.Fc", ".stribeck.Vs", ".stribeck.delta",
                   ".sigma2"],
    },
}


def loss(model, w, t=T, x=X):
    """Weighted mean square force, N^2: the weight array selects a window."""
    force = jaxfric.simulate(model, t, x)
    return jnp.sum(w * force**2) / N_GRAD


# Jitted as a whole: compiling forward and backward in one program is about twice as fast
# as letting `jax.grad` differentiate the jitted `simulate` from outside.
grad_loss = eqx.filter_jit(eqx.filter_grad(loss))


def _finite(tree):
    return all(np.isfinite(np.asarray(leaf)).all() for leaf in jax.tree.leaves(tree))


def model_grads(name):
    """``{window: (loss, {leaf path: gradient})}`` for `MODELS[name]`.

    Compiling a model's gradient is the expensive part (seconds); the windows are data, so
    all of them share one compilation.
    """
    model = MODELS[name]()
    return {
        key: (float(loss(model, w)), _named_leaves(grad_loss(model, w)))
        for key, w in WINDOWS.items()
    }


def _named_leaves(tree):
    """``{".stribeck.Fs": array, ...}`` for every inexact-array leaf."""
    params = eqx.filter(tree, eqx.is_inexact_array)
    return {
        jax.tree_util.keystr(path): np.asarray(leaf)
        for path, leaf in jax.tree_util.tree_leaves_with_path(params)
    }


def test_path_exercises_the_events():
    """The gradient path really has rest, dwells, nested closures, Rule 3 and wiping
    (checked with the independent NumPy reference, which is cheap at this length)."""
    out = ref.two_state(T, X, **ref_kwargs(paper.two_state()))
    depth = out["depth"]
    v = np.diff(X, prepend=X[0])
    assert (v[: N_REST + 1] == 0).all() and (v[N_REST + 1] != 0)
    assert (np.diff(X)[I_STROKE:] == 0).sum() >= 10  # dwells after the strokes
    assert depth.max() >= 5
    drops = np.diff(depth)
    assert (drops == -2).sum() >= 3  # Rule 2 (inner loops close onto outer ones)
    assert (drops == -1).sum() >= 2  # Rule 3 (back on the virgin curve)
    # Wiping: the reversal at -1.5 mm ends a sliding stroke that started at the 1.5 mm
    # reversal; the entries below that branch start (the zero state) are dropped, so the
    # depth stays 2 (it would be 3 without wiping).
    i_min = int(np.argmin(X))
    i_rev = i_min + int(np.argmax(X[i_min:] != X[i_min]))  # first sample moving back
    assert depth[i_rev - 1] == 2 and depth[i_rev] == 2
    assert out["overflow"] == 0


# ---- every parameter of every model on the event path --------------------------------


FIRST_STEP_MATTERS = {
    "two_state_paper": ".stribeck.Fs",
    "two_state_power": ".shape.l1",
    "gms5": ".k",
    "gms_from_shape": ".k",
    "lugre": ".sigma0",
    "tustin": ".stribeck.Fs",
}


def _check_finite(name, grads):
    """Finite gradient in every window of the path (rest, reversals, closures, wiping,
    dwells): a NaN in any sample's derivative would contaminate the weighted sum."""
    params = _named_leaves(MODELS[name]())
    for window, (_, g) in grads.items():
        assert set(g) == set(params), window  # every parameter leaf gets a gradient
        bad = {k: v for k, v in g.items() if not np.isfinite(v).all()}
        assert not bad, f"{window}: non-finite gradients {bad}"


def _check_nonzero_where_it_matters(name, grads):
    p = _named_leaves(MODELS[name]())
    for window, keys in MUST_MATTER.items():
        value, g = grads[window]
        for key in keys[name]:
            # Sensitivity to a relative change of each parameter, against the loss itself:
            # "nonzero" must not mean 1e-30 from rounding.
            sens = np.abs(g[key] * p[key])
            assert (sens > 1e-7 * value).all(), (
                f"{window}, {key}: d loss / d log p = {g[key] * p[key]}"
            )


def _check_zero_state(name, grads):
    """Before any motion the force is identically 0, whatever the parameters: its gradient
    is exactly 0 (and finite: no 0 * inf from 1/|s| or |v|**delta at v = 0, nor from
    xi = 0/0 on the zero state). The first moving sample has a nonzero gradient."""
    force = jaxfric.simulate(MODELS[name](), T, X)
    np.testing.assert_array_equal(np.asarray(force[: N_REST + 1]), 0.0)
    for key, val in grads["rest"][1].items():
        np.testing.assert_array_equal(val, 0.0, err_msg=f"rest window, {key}")
    g_first = grads["first_step"][1]
    # What must matter at the first step of 2 um: the initial stiffness (for GMS only the
    # stiffnesses, since no gms5 element slips within 2 um), and the viscous term.
    assert np.any(g_first[FIRST_STEP_MATTERS[name]] != 0)
    assert abs(g_first[".sigma2"]) > 0


# ---- finite differences away from events ----------------------------------------------

#: Relative step of the central differences. Truncation error ~ H_REL**2 ~ 1e-10
#: (relative); rounding error ~ eps * |loss| / (H_REL * |d loss/d log p|) ~ 1e-16 * 300 /
#: (1e-5 * 0.3) ~ 1e-8 for the least influential parameter. Observed: <= 4e-9.
H_REL = 1e-5
#: So 1e-6 leaves two orders of magnitude of margin and still catches any real error in a
#: derivative (a missed term is typically >= 1e-3 relative).
RTOL = 1e-6


def _perturbed(model, key, index, delta):
    params, static = eqx.partition(model, eqx.is_inexact_array)
    paths_leaves, treedef = jax.tree_util.tree_flatten_with_path(params)
    leaves = []
    for path, leaf in paths_leaves:
        if leaf is not None and jax.tree_util.keystr(path) == key:
            leaf = jnp.asarray(np.asarray(leaf)).at[index].add(delta)
        leaves.append(leaf)
    return eqx.combine(jax.tree_util.tree_unflatten(treedef, leaves), static)


@eqx.filter_jit
def _gms_slip_flags(model, t, x):
    """Per-sample slip flags of every GMS element, from the `step` API."""
    motion = jaxfric.motion.make_motion(t, x)

    def body(state, inp):
        state, _ = model.step(state, *inp)
        return state, state.slipping

    _, flags = jax.lax.scan(body, model.init_state(x[0]), (motion.x, motion.v, motion.dt))
    return flags


def _events(model):
    """The discrete decisions along the path: what a perturbation must not change."""
    if isinstance(model, jaxfric.TwoState):
        out = jaxfric.simulate(model, T, X, full_output=True)
        return np.asarray(out.parts["depth"]), int(out.overflow)
    if isinstance(model, jaxfric.GMS):
        return np.asarray(_gms_slip_flags(model, jnp.asarray(T), jnp.asarray(X)))
    return None  # LuGre, Tustin: direction comes from the data only


def _same_events(a, b):
    if a is None:
        return b is None
    if isinstance(a, tuple):
        return np.array_equal(a[0], b[0]) and a[1] == b[1]
    return np.array_equal(a, b)


def _check_finite_differences(name, grads):
    """Central differences with a relative step per parameter (values span 1e-6 .. 1e15 in
    SI), on the whole event path: the path is fixed, and at that step no reversal,
    closure, wiping or stick/slip decision changes (asserted), so the loss is smooth there.
    For GMS this includes stick/slip transitions: the slip pattern is checked unchanged."""
    model = MODELS[name]()
    w = WINDOWS["all"]
    value, grads = grads["all"]
    events = _events(model)
    if isinstance(model, jaxfric.GMS):
        assert events.any() and not events.all()  # the path has stick and slip phases
    for key, p in _named_leaves(model).items():
        g = grads[key]
        for index in np.ndindex(p.shape):
            # A leaf of little influence gets a longer step: the rounding error of the
            # difference, ~eps*|loss|/h, is then at most RTOL of its derivative.
            h_rel = max(H_REL, np.finfo(float).eps * value / (RTOL * abs(g[index] * p[index])
                                                              + 1e-300))
            h = h_rel * abs(p[index])
            assert h > 0, f"{key}{index} = 0: relative step impossible"
            plus = _perturbed(model, key, index, h)
            minus = _perturbed(model, key, index, -h)
            assert _same_events(_events(plus), events), f"{key}{index}: +h changes events"
            assert _same_events(_events(minus), events), f"{key}{index}: -h changes events"
            fd = (float(loss(plus, w)) - float(loss(minus, w))) / (2 * h)
            # Compare d loss / d log p; the absolute floor is for leaves with tiny
            # influence, where rounding in the loss (~1e-13 relative) dominates.
            err = abs(fd - g[index]) * abs(p[index])
            assert err <= RTOL * abs(g[index] * p[index]) + 1e-11 * value, (
                f"{key}{index}: grad {g[index]:.10e}, FD {fd:.10e}"
            )


@pytest.mark.parametrize("name", sorted(MODELS))
def test_gradients(name):
    """Every parameter leaf of every model on the event path: finite in every window,
    exactly 0 in the zero state, nonzero where the parameter matters, and equal to central
    finite differences.

    One test per model on purpose: compiling a model's gradient costs seconds, and
    pytest-xdist hands consecutive tests to different workers, each of which would
    compile it again.
    """
    grads = model_grads(name)
    _check_finite(name, grads)
    _check_zero_state(name, grads)
    _check_nonzero_where_it_matters(name, grads)
    _check_finite_differences(name, grads)


def test_gms_from_shape_differentiable_in_the_shape():
    """`GMS.from_shape` is differentiable in the shape's parameters (its docstring says so):
    gradient through the element construction and the simulation equals central FD."""

    def loss_shape(sp):
        gms = jaxfric.GMS.from_shape(
            jaxfric.PowerShape(l1=sp[0], n=sp[1]), paper.stribeck(), paper.SIGMA2, paper.C, 6
        )
        return loss(gms, WINDOWS["presliding"])

    loss_shape = jax.jit(loss_shape)
    sp = jnp.asarray([4e-6, 2.5])
    g = np.asarray(jax.jit(jax.grad(loss_shape))(sp))
    assert np.isfinite(g).all() and (g != 0).all()
    for i in range(2):
        h = H_REL * float(sp[i])
        fd = (float(loss_shape(sp.at[i].add(h))) - float(loss_shape(sp.at[i].add(-h)))) / (2 * h)
        np.testing.assert_allclose(g[i], fd, rtol=RTOL)


# ---- the very first sample through the per-sample API ---------------------------------


@eqx.filter_jit
def _step_gradients(model):
    """Gradients through the per-sample API from `init_state`: the first sample (dt = 0,
    v = 0) w.r.t. the parameters and x0, and a first motion of 1 um at 1 mm/s."""
    g_rest = eqx.filter_grad(lambda m: m.step(m.init_state(0.0), 0.0, 0.0, 0.0)[1])(model)
    g_move = eqx.filter_grad(lambda m: m.step(m.init_state(0.0), 1e-6, 1e-3, 1e-3)[1])(model)
    g_x0 = jax.grad(lambda x0: model.step(model.init_state(x0), x0, 0.0, 0.0)[1])(0.0)
    return g_rest, g_move, g_x0


def test_two_state_step_gradients_at_first_sample():
    """As a closed-loop user differentiates it: `step` from `init_state`."""
    g_rest, g_move, g_x0 = _step_gradients(paper.two_state())
    assert _finite((g_rest, g_move, g_x0))
    assert all(np.all(v == 0) for v in _named_leaves(g_rest).values())
    assert float(g_x0) == 0.0
    g_move = _named_leaves(g_move)
    assert g_move[".stribeck.Fs"] != 0 and g_move[".shape.l1"] != 0


# ---- double-where guards at the singular points ---------------------------------------


@jax.jit
def _stribeck_guards(st, v):
    fs = (st, st.magnitude, lambda u: st.effective(u, 1.0), lambda u: st.effective(u, 0.0))
    d_v = [jax.grad(f)(v) for f in fs] + [jax.grad(jax.grad(f))(v) for f in fs]
    d_s = eqx.filter_grad(lambda s: s(v))(st)
    d_mag = eqx.filter_grad(lambda s: s.magnitude(v))(st)
    d_eff = eqx.filter_grad(lambda s: s.effective(v, -1.0))(st)
    return d_v, d_s, d_mag, d_eff


def test_stribeck_gradients_at_zero_velocity():
    st = paper.stribeck()
    d_v, d_s, d_mag, d_eff = _stribeck_guards(st, jnp.asarray(0.0))
    # d s / d v at 0: s jumps there; the guarded value is finite (not NaN from |v|**0.6).
    assert _finite(d_v)
    # w.r.t. the parameters at v = 0: s(0) = 0 for all of them; |s|(0) = Fs exactly.
    assert _named_leaves(d_s) == {".Fs": 0.0, ".Fc": 0.0, ".Vs": 0.0, ".delta": 0.0}
    assert _named_leaves(d_mag) == {".Fs": 1.0, ".Fc": 0.0, ".Vs": 0.0, ".delta": 0.0}
    assert _named_leaves(d_eff) == {".Fs": -1.0, ".Fc": 0.0, ".Vs": 0.0, ".delta": 0.0}
    # Just off 0 the delta-gradient involves log|v|: finite, and Vs matters.
    d_v, d_s, _, _ = _stribeck_guards(st, jnp.asarray(-1e-12))
    assert _finite((d_v, d_s)) and _named_leaves(d_s)[".Vs"] != 0


SHAPES = {
    "paper": paper.shape,
    "power_2.5": lambda: jaxfric.PowerShape(l1=4e-6, n=2.5),
    "power_1.5": lambda: jaxfric.PowerShape(l1=4e-6, n=1.5),
    "power_1": lambda: jaxfric.PowerShape(l1=4e-6, n=1.0),
}


@jax.jit
def _shape_guards(shape, xi, fs):
    def pkg(sh, z, s_st):
        p, k, g = sh.pi_kappa_gamma(z, s_st)
        return p + k * 1e-7 + g  # kappa in N/m is ~1e6: scale it to the others

    return {
        "pi": shape.pi(xi, fs),
        "d_xi": jax.grad(lambda z: shape.pi(z, fs))(xi),
        "d_xi_all": jax.grad(lambda z: pkg(shape, z, fs))(xi),
        "d_par": eqx.filter_grad(lambda sh: pkg(sh, xi, fs))(shape),
        "d_par_pi": eqx.filter_grad(lambda sh: sh.pi(xi, fs))(shape),
        "d_sst": jax.grad(lambda s: pkg(shape, xi, s))(fs),
    }


@pytest.mark.parametrize("shape_name", sorted(SHAPES))
def test_shape_gradients_at_singular_points(shape_name):
    """Pi, kappa and gamma and their gradients w.r.t. xi, every shape parameter and s_st
    are finite at xi = 0, xi < 0, xi = l1 (and one ulp below), xi > l1."""
    shape = SHAPES[shape_name]()
    l1 = float(shape.l1)
    points = {"zero": 0.0, "negative": -1e-7, "l1": l1, "just_below_l1": np.nextafter(l1, 0.0),
              "beyond": 3.0 * l1}
    for where, xi in points.items():
        out = _shape_guards(shape, jnp.asarray(xi), jnp.asarray(26.1))
        assert _finite(out), f"{where}: {out}"
        pi_val, d_xi = float(out["pi"]), float(out["d_xi"])
        # d Pi / d log p: exactly 0 analytically where Pi is clipped; under jit XLA's pow
        # gives (0 + beta)**alpha and beta**alpha derivatives that differ by ~1e-16.
        par_pi = [abs(g * p) < 1e-12 for g, p in
                  zip(_named_leaves(out["d_par_pi"]).values(), _named_leaves(shape).values())]
        if where == "zero":
            assert pi_val == 0.0 and d_xi > 0  # kappa(0): the one-sided initial stiffness
        elif where == "negative":
            # Clipped to 0: no dependence on xi or on any parameter through Pi.
            assert pi_val == 0.0 and d_xi == 0.0 and all(par_pi)
        elif where in ("l1", "beyond"):
            assert pi_val == 1.0 and d_xi == 0.0 and all(par_pi)
