"""The acceleration input: what `jaxfric.effects.Inertia` reads. `simulate` takes one (``a=``)
or takes the backward difference of the velocity (a controller's causal choice); a fit or a
diagnosis of measured data takes a zero-phase estimate (`fitting.estimate_derivatives`).

The identification test's truth is not made by jaxfric: the position, velocity and
acceleration are exact, the force is a Stribeck curve of the exact velocity plus a mass
times the exact acceleration, and the position is read through an encoder, as a
measurement would have it."""

import json

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import fitting
import jaxfric
from jaxfric import effects as fx, paper


def _sine(dt=1e-3, T=4.0, amp=0.02, f=1.0):
    """Time (s), position (m), exact velocity (m/s) and acceleration (m/s^2) of a sine."""
    t = np.arange(0.0, T, dt)
    w = 2 * np.pi * f
    return t, amp * np.sin(w * t), amp * w * np.cos(w * t), -amp * w**2 * np.sin(w * t)


def test_simulate_reads_a_given_acceleration_and_else_the_backward_difference():
    t, x, v, a = _sine(dt=2e-3, T=1.0)
    base = paper.tustin()
    model = base + fx.Inertia(mass=3.0)
    f_base = np.asarray(jaxfric.simulate(base, t, x, v))
    given = np.asarray(jaxfric.simulate(model, t, x, v, a=a))
    np.testing.assert_allclose(given - f_base, 3.0 * a, rtol=0, atol=1e-12)
    backward = np.asarray(jaxfric.simulate(model, t, x, v))
    a_back = np.r_[0.0, np.diff(v) / np.diff(t)]
    np.testing.assert_allclose(backward - f_base, 3.0 * a_back, rtol=0, atol=1e-9)


def test_simulate_refuses_a_bad_acceleration():
    t, x, v, a = _sine(dt=2e-3, T=0.2)
    model = paper.tustin() + fx.Inertia(mass=1.0)
    with pytest.raises(ValueError, match="t and a must have the same shape"):
        jaxfric.simulate(model, t, x, v, a=a[:-1])
    bad = a.copy()
    bad[5] = np.nan
    with pytest.raises(ValueError, match="a has a non-finite value at index 5"):
        jaxfric.simulate(model, t, x, v, a=bad)


def test_gradient_of_the_mass_with_a_given_acceleration():
    t, x, v, a = _sine(dt=2e-3, T=0.5)

    def cost(mass):
        model = paper.tustin() + fx.Inertia(mass=mass)
        return jnp.sum(jaxfric.simulate(model, t, x, v, a=a) ** 2)

    g = float(jax.grad(cost)(2.0))
    h = 1e-6
    fd = (float(cost(2.0 + h)) - float(cost(2.0 - h))) / (2 * h)
    assert g == pytest.approx(fd, rel=1e-6)


def test_gradients_with_a_given_acceleration_are_finite_through_reversals():
    """The two-state model plus a mass, along a sine (v = 0 at every reversal) with the
    acceleration given: the gradient of every parameter is finite."""
    t, x, v, a = _sine(dt=2e-3, T=2.0)
    model = paper.two_state() + fx.Inertia(mass=2.0)

    @eqx.filter_grad
    def grad(m):
        return jnp.sum(jaxfric.simulate(m, t, x, v, a=a, max_reversals=8) ** 2)

    leaves = jax.tree.leaves(eqx.filter(grad(model), eqx.is_inexact_array))
    assert leaves and all(bool(jnp.all(jnp.isfinite(g))) for g in leaves)
    assert float(grad(model).effects[0].mass) != 0.0


@pytest.mark.parametrize("method", ["central", "savgol"])
def test_zero_phase_acceleration_of_a_sine(method):
    t, x, _v, a = _sine(dt=1e-3, T=2.0)
    _v_est, a_est = fitting.estimate_derivatives(t, x, method)
    inner = slice(10, -10)
    scale = np.max(np.abs(a))
    assert np.max(np.abs(a_est[inner] - a[inner])) < 1e-3 * scale
    # The backward difference of the backward velocity lags by a sample: 1 ms of a 1 Hz sine
    # is an error of 2 pi 1e-3 of the amplitude, twenty times the zero-phase estimates'.
    a_back = np.r_[0.0, np.diff(jaxfric.motion.velocity(t, x)) / np.diff(t)]
    assert np.max(np.abs(a_back[inner] - a[inner])) > 5e-3 * scale
    assert fitting.estimate_derivatives(t, x, "backward")[1] is None


def test_acceleration_of_a_velocity_column_and_words():
    t, _x, v, a = _sine(dt=1e-3, T=2.0)
    a_est = fitting.estimate_acceleration(t, v)
    # A central difference over +-5 ms of a 1 Hz sine: sin(wh)/(wh) = 1 - 1.6e-4; the
    # first and last 5 samples are one-sided.
    inner = slice(5, -5)
    assert np.max(np.abs(a_est[inner] - a[inner])) < 2e-4 * np.max(np.abs(a))
    assert fitting.estimate_acceleration(t, v, "backward") is None
    from fitting._derivatives import describe

    assert "acceleration: central difference of that velocity over 10 ms" in describe("central")
    assert "over 20 ms" in describe("central", window_s=0.02)
    assert "acceleration: the file's column" in describe("central", column=True,
                                                         acceleration_column=True)
    assert "backward difference (causal)" in describe("backward")


def test_a_mass_is_identified_from_an_encoder_with_the_zero_phase_acceleration():
    """Truth: Stribeck friction of the exact velocity plus 20 kg times the exact
    acceleration along a motion that never stops (v = 0.1 m/s plus a 2 Hz wobble), the
    position read by a 1 um encoder at 1 ms. With the same zero-phase velocity (the default
    central difference), the default acceleration (its central difference over 10 ms)
    finds the mass to 1 % and leaves under half the error that the backward difference of
    that velocity leaves (measured: 19.97 kg, 0.54 N against 16.26 kg, 4.83 N)."""
    dt, w, amp = 1e-3, 2 * np.pi * 2.0, 0.005
    t = np.arange(0.0, 3.0, dt)
    x_true = 0.1 * t + amp * np.sin(w * t)
    v = 0.1 + amp * w * np.cos(w * t)
    a = -amp * w**2 * np.sin(w * t)
    tus = paper.tustin()
    F = np.asarray(tus.stribeck(jnp.asarray(v))) + tus.sigma2 * v + 20.0 * a
    x = np.round(x_true / 1e-6) * 1e-6
    start = paper.tustin() + fx.Inertia(mass=5.0)
    v_est, a_est = fitting.estimate_derivatives(t, x)
    good = fitting.fit(start, t, x, F, v_est, a=a_est)
    causal = fitting.fit(start, t, x, F, v_est)  # a: the backward difference of v_est
    m_good, m_causal = float(good.params["mass"]), float(causal.params["mass"])
    assert m_good == pytest.approx(20.0, rel=0.01)
    assert abs(m_causal - 20.0) > 2 * abs(m_good - 20.0)
    assert float(good.rmse) < 0.5 * float(causal.rmse)
    # The saved model, read back, simulates the prediction bit for bit with that input.
    back = jaxfric.load_model(json.loads(json.dumps(jaxfric.model_to_dict(good.fit_model))))
    again = jaxfric.simulate(back, t, x, v_est, a=a_est)
    assert np.array_equal(np.asarray(good.prediction), np.asarray(again))


def test_command_line_reads_an_acceleration_column(tmp_path):
    """`jaxfric simulate FILE --params MODEL.json` on a file with an ``a`` column: the mass
    term is the mass times that column, not a difference of the positions."""
    import subprocess
    import sys

    t, x, v, a = _sine(dt=2e-3, T=1.0)
    model = paper.tustin() + fx.Inertia(mass=4.0)
    jaxfric.save_model(model, tmp_path / "model.json")
    rows = np.column_stack([t, x, v, a])
    (tmp_path / "run.csv").write_text(
        "t,x,v,a\n" + "\n".join(",".join(repr(float(c)) for c in r) for r in rows))
    r = subprocess.run([sys.executable, "-m", "fitting.cli", "simulate", tmp_path / "run.csv",
                        "--params", tmp_path / "model.json", "--out", tmp_path / "sim.csv"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "acceleration: the file's column" not in r.stdout  # both columns: nothing estimated
    sim = np.genfromtxt(tmp_path / "sim.csv", delimiter=",", names=True)
    base = np.asarray(jaxfric.simulate(paper.tustin(), t, x, v))
    np.testing.assert_allclose(sim["F_modelN"] - base, 4.0 * a, rtol=0, atol=1e-9)


def test_batch_fit_takes_the_acceleration_of_each_dataset():
    """`fit_batch(..., a=)`: each dataset's mass as `fit` finds it with the same input."""
    rows = []
    for mass, f in ((12.0, 1.5), (30.0, 2.5)):
        dt, w, amp = 2e-3, 2 * np.pi * f, 0.004
        t = np.arange(0.0, 2.0, dt)
        x = 0.1 * t + amp * np.sin(w * t)
        v = 0.1 + amp * w * np.cos(w * t)
        a = -amp * w**2 * np.sin(w * t)
        F = np.asarray(paper.tustin().stribeck(jnp.asarray(v))) + mass * a
        rows.append((t, x, v, a, F))
    t, x, v, a, F = (np.stack(c) for c in zip(*rows))
    start = paper.tustin() + fx.Inertia(mass=5.0)
    # The mass term is exact, so the fit can find the mass to far below its standard
    # error (0.08 kg: Tustin's own mismatch, 0.6 N RMS, is the "noise"); the default
    # statistical rule stops within 0.14 standard errors, wherever its step falls, so the
    # fits are asked for more (`decrease`).
    tol = fitting.Tolerances(decrease=1e-8)
    batch = fitting.fit_batch(start, t, x, F, v, a=a, free=["mass", "Fc", "Fs"], tol=tol)
    for i, mass in enumerate((12.0, 30.0)):
        one = fitting.fit(start, t[i], x[i], F[i], v[i], a=a[i], free=["mass", "Fc", "Fs"],
                          tol=tol)
        # Exact data: the mass to 1e-6 (the backward difference of v would miss it by
        # about 1e-3); the same as `fit` to the solvers' tolerance.
        assert float(batch[i].params["mass"]) == pytest.approx(mass, rel=1e-6)
        assert float(batch[i].params["mass"]) == pytest.approx(float(one.params["mass"]),
                                                               rel=1e-5)


def test_a_model_with_a_mass_fitted_and_simulated_from_the_command_line(tmp_path):
    """`jaxfric fit FILE --params MODEL.json` refits a model with a mass on a file without
    velocity or acceleration columns (both estimated, zero phase), and `jaxfric simulate
    FILE --params FIT.json` takes them the same way: its force is the fit's prediction (the
    RMSE to 1e-9)."""
    import subprocess
    import sys

    dt, w, amp = 2e-3, 2 * np.pi * 2.0, 0.004
    t = np.arange(0.0, 2.0, dt)
    x_true = 0.1 * t + amp * np.sin(w * t)
    v = 0.1 + amp * w * np.cos(w * t)
    F = np.asarray(paper.tustin().stribeck(jnp.asarray(v))) - 15.0 * amp * w**2 * np.sin(w * t)
    x = np.round(x_true / 1e-7) * 1e-7
    (tmp_path / "run.csv").write_text(
        "t,x,F\n" + "\n".join(f"{a:.17g},{b:.17g},{c:.17g}" for a, b, c in zip(t, x, F)))
    jaxfric.save_model(paper.tustin() + fx.Inertia(mass=5.0), tmp_path / "start.json")

    def cli(*args):
        r = subprocess.run([sys.executable, "-m", "fitting.cli", *map(str, args)],
                           capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr
        return r

    cli("fit", tmp_path / "run.csv", "--params", tmp_path / "start.json", "--json",
        tmp_path / "fit.json", "--quiet")
    fit = json.loads((tmp_path / "fit.json").read_text())
    assert "acceleration: central difference of that velocity over 10 ms" in fit["velocity"]
    mass = fit["fitted_model"]["effects"][0]["mass"]
    assert mass == pytest.approx(15.0, rel=0.01)
    cli("simulate", tmp_path / "run.csv", "--params", tmp_path / "fit.json", "--out",
        tmp_path / "sim.csv", "--quiet")
    sim = np.genfromtxt(tmp_path / "sim.csv", delimiter=",", names=True)
    rmse = float(np.sqrt(np.mean((sim["F_modelN"] - F) ** 2)))
    assert rmse == pytest.approx(fit["rmse"], rel=1e-9)
    # The Python recipe of docs/using_a_model.md ("Reproducing a fit in Python") gives the
    # same force; without the acceleration (the backward difference) it does not.
    how = fit["derivatives"]
    v_est, a_est = fitting.estimate_derivatives(t, x, how["method"], how["window_s"])
    model = jaxfric.load_model(fit)
    recipe = np.asarray(jaxfric.simulate(model, t, x, v_est, a=a_est))
    assert float(np.sqrt(np.mean((recipe - F) ** 2))) == pytest.approx(fit["rmse"], rel=1e-9)
    plain = np.asarray(jaxfric.simulate(model, t, x, v_est))
    assert float(np.sqrt(np.mean((plain - F) ** 2))) > 1.05 * fit["rmse"]
