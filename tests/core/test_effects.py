"""Effects added to models (`model + effect`): each term against its formula in NumPy, the
per-sample API, gradients, and a joint fit that recovers hidden effect parameters."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import fitting
import jaxfric
from jaxfric import effects as fx, paper


def _motion(n=1500, seed=0):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, n))
    x = 3e-3 * np.sin(2 * np.pi * t / 0.7) + 40e-6 * np.sin(2 * np.pi * t / 0.05)
    return t, x


def _numpy_terms(t, x, base):
    """The module docstring's table, in NumPy, for the instances in EFFECTS below (base
    model: the paper's two-state, whose Stribeck curve the friction lag follows)."""
    v = np.r_[0.0, np.diff(x) / np.diff(t)]
    static = np.asarray(paper.stribeck()(v))
    a = np.r_[0.0, np.diff(v) / np.diff(t)]
    u = (x - 0.5 * (x.min() + x.max())) / (0.5 * (x.max() - x.min()))
    dt = np.r_[0.0, np.diff(t)]
    h, pre = 0.0, np.zeros(t.size)
    y, moved, lag = 0.0, False, np.zeros(t.size)
    for n in range(t.size):
        if n:
            h = min(max(h + 3e5 * (x[n] - x[n - 1]), -1.5), 1.5)
        if v[n] != 0:  # the level lags while moving, is held at rest
            y = y + (1 - np.exp(-dt[n] / 0.02)) * (abs(static[n]) - y) if moved else abs(static[n])
            moved = True
        pre[n] = h - 1.5 * np.sign(v[n])
        lag[n] = 0.3 * np.sign(static[n]) * (y - abs(static[n]))
    return {
        "presliding": pre,
        "friction_lag": lag,
        "viscous": 30.0 * v,
        "quadratic_drag": 2e3 * v * np.abs(v),
        "stribeck": 2.0 * np.exp(-((v / 2e-3) ** 2)) * np.sign(v),
        "inertia": 1.7 * a,
        "offset": np.full(t.size, -0.8),
        "asymmetry": 0.05 * np.abs(base),
        "cogging": 0.4 * np.sin(2 * np.pi * x / 1.3e-3) - 0.2 * np.cos(2 * np.pi * x / 1.3e-3),
        "position_dependence": base * (0.1 * u - 0.05 * u**2),
        "position_load": 0.7 * u - 0.3 * (u**2 - 1 / 3),
        "drift": base * 1e-3 * -np.expm1(-0.3 * (t - t[0])) / 0.3,  # a warm-up, 3.3 s
        "ripple": sum(a * np.sin(k * 2 * np.pi * x / 9e-4) + b * np.cos(k * 2 * np.pi * x / 9e-4)
                      for k, a, b in ((1, 0.3, 0.1), (2, -0.2, 0.05), (3, 0.1, -0.07))),
        "angle_load": 2.5 * np.sin(x) - 1.2 * np.cos(x),
    }


def _effects(x):
    return {
        "viscous": fx.Viscous(c_visc=30.0),
        "quadratic_drag": fx.QuadraticDrag(c_drag=2e3),
        "stribeck": fx.StribeckHump(dF_str=2.0, v_str=2e-3),
        "presliding": fx.Presliding(F_pre=1.5, k_pre=3e5),
        "friction_lag": fx.FrictionLag(lag_gain=0.3, tau=0.02),
        "inertia": fx.Inertia(mass=1.7),
        "offset": fx.Offset(offset=-0.8),
        "asymmetry": fx.Asymmetry(asym=0.05),
        "cogging": fx.Cogging(cog_sin=0.4, cog_cos=-0.2, period=1.3e-3),
        "position_dependence": fx.PositionDependence.for_travel(x, pos_1=0.1, pos_2=-0.05),
        "position_load": fx.PositionLoad.for_travel(x, load_1=0.7, load_2=-0.3),
        "drift": fx.Drift(drift_rate=1e-3, drift_decay=0.3),
        "ripple": fx.Ripple(rip_sin=(0.3, -0.2, 0.1), rip_cos=(0.1, 0.05, -0.07), period=0.9e-3),
        "angle_load": fx.AngleLoad(g_sin=2.5, g_cos=-1.2),
    }


def test_library_has_every_effect():
    # The effects of the load signal are checked against NumPy in test_load_friction.py.
    assert set(fx.EFFECTS) - set(fx.LOAD_EFFECTS) == set(_effects(np.zeros(2)))


def test_each_term_matches_its_formula():
    t, x = _motion()
    model = paper.two_state()
    base = np.asarray(jaxfric.simulate(model, t, x))
    expected = _numpy_terms(t, x, base)
    all_effects = tuple(_effects(x).values())
    out = jaxfric.simulate(model + all_effects, t, x, full_output=True)
    np.testing.assert_allclose(out.parts["base"], base, rtol=0, atol=1e-9)
    for name, want in expected.items():
        assert np.ptp(want) > 0 or name == "offset"
        np.testing.assert_allclose(out.parts[name], want, rtol=1e-9, atol=1e-9, err_msg=name)
    np.testing.assert_allclose(out.force, base + sum(expected.values()), rtol=0, atol=1e-8)


def test_adding_appends_and_rejects_duplicates_and_non_effects():
    m = paper.tustin() + fx.Offset(offset=1.0)
    m2 = m + fx.Inertia(mass=2.0)
    assert isinstance(m2, fx.WithEffects) and [e.name for e in m2.effects] == ["offset", "inertia"]
    assert isinstance(m2.base, jaxfric.Tustin)
    with pytest.raises(ValueError, match="added twice"):
        m2 + fx.Offset(offset=2.0)
    with pytest.raises(TypeError, match="effects"):
        paper.tustin() + 3.0


def test_step_matches_simulate():
    t, x = _motion(n=400, seed=1)
    v = np.r_[0.0, np.diff(x) / np.diff(t)]
    dt = np.diff(t, prepend=t[0])
    model = paper.two_state() + tuple(_effects(x).values())

    @eqx.filter_jit
    def run(m):
        def body(state, inp):
            return m.step(state, *inp)

        return jax.lax.scan(body, m.init_state(x[0]), (x, v, dt))[1]

    np.testing.assert_allclose(run(model), jaxfric.simulate(model, t, x, v), rtol=0, atol=1e-8)


def test_effect_gradients_match_finite_differences():
    t, x = _motion(n=600, seed=2)
    effects = _effects(x)
    model = paper.tustin() + (effects["cogging"], effects["drift"], effects["asymmetry"])

    def loss(m):
        return jnp.sum(jaxfric.simulate(m, t, x) ** 2)

    grad = eqx.filter_jit(jax.grad(loss))(model)
    loss_j = eqx.filter_jit(loss)
    for getter in (lambda m: m.effects[0].period, lambda m: m.effects[0].cog_sin,
                   lambda m: m.effects[1].drift_rate, lambda m: m.effects[2].asym):
        p = float(getter(model))
        h = 1e-6 * abs(p)
        fd = (loss_j(eqx.tree_at(getter, model, jnp.asarray(p + h)))
              - loss_j(eqx.tree_at(getter, model, jnp.asarray(p - h)))) / (2 * h)
        np.testing.assert_allclose(float(getter(grad)), float(fd), rtol=1e-5)


def test_joint_fit_recovers_hidden_effects():
    """Data = Tustin + inertia + offset + cogging + 0.05 N noise. Fitting the model with
    the three effects added (starting at zero amplitude, 10 % off in period) recovers them
    within 4 standard errors, and the RMSE falls to the noise level."""
    t, x = _motion(n=3000, seed=3)
    rng = np.random.default_rng(3)
    truth = paper.tustin() + (fx.Inertia(mass=2.5), fx.Offset(offset=-1.2),
                              fx.Cogging(cog_sin=0.5, cog_cos=0.3, period=1.1e-3))
    F = np.asarray(jaxfric.simulate(truth, t, x)) + 0.05 * rng.normal(size=t.size)
    start = paper.tustin() + (fx.Inertia(mass=1.0), fx.Offset(offset=0.1),
                              fx.Cogging(cog_sin=0.1, cog_cos=0.1, period=1.0e-3))
    base_only = fitting.fit(paper.tustin(), t, x, F)
    res = fitting.fit(start, t, x, F)
    assert res.converged, res.summary()
    assert float(res.rmse) < 0.055
    assert float(base_only.rmse) > 4 * float(res.rmse)
    for name, want in {"mass": 2.5, "offset": -1.2, "cog_sin": 0.5, "cog_cos": 0.3,
                       "period": 1.1e-3}.items():
        err = abs(float(res.params[name]) - want)
        assert err < 4 * float(res.stderr[name]), (name, float(res.params[name]), want)


def test_drift_without_decay_is_linear_and_smooth_through_zero_decay():
    t = jnp.linspace(0.0, 100.0, 201)
    s = fx.Signals(t=t, x=t, v=t, a=t, dt=t, dx=t, t0=t[0], base=jnp.full(t.shape, 20.0),
                   static=t)
    np.testing.assert_allclose(fx.Drift(drift_rate=1e-3).term(s), 20.0 * 1e-3 * t,
                               rtol=1e-14)
    # Across the switch to the series (|u| = 1e-4) the term and its decay derivative agree
    # with the exact formula evaluated in high precision.
    def at(decay):
        return fx.Drift(drift_rate=1e-3, drift_decay=decay).term(s)[-1]

    for decay in (0.0, 0.99e-6, 1.01e-6, -1.01e-6, 1e-3):
        exact = 20.0 * 1e-3 * (-np.expm1(-decay * 100.0) / decay if decay else 100.0)
        np.testing.assert_allclose(at(decay), exact, rtol=1e-12)
    slope = jax.grad(at)(0.0)
    np.testing.assert_allclose(slope, -20.0 * 1e-3 * 100.0**2 / 2, rtol=1e-12)
