"""Load-dependent friction (issue 18, item 4): the ``load`` column of a file, the load signal
carried to `jaxfric.simulate` and the fits, `jaxfric.effects.LoadFriction` against a NumPy
transcription of its formula, the clear error without a load, the screen that looks for it
only when there is a load, and (slow) the diagnosis naming it on a truth that is not
jaxfric's own model (a GMS with a power-law virgin curve, the load friction added there
with ``sign(v)``, not with jaxfric's effect)."""

import functools

import equinox as eqx
import numpy as np
import pytest

import fitting
import jaxfric
from fitting._diagnose import effect_names
from jaxfric import effects as fx, paper
from jaxfric.data import load


def _motion(seed=0, n=1500):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    x = 4e-3 * np.sin(2 * np.pi * t / 5.0) + 0.6e-3 * np.sin(2 * np.pi * t / 1.7)
    L = 50.0 + 30.0 * np.sin(2 * np.pi * t / 6.3 + 1.0) + rng.normal(0.0, 1.0, n)
    return t, x, L


@pytest.mark.parametrize("base", [paper.tustin(), paper.two_state()])
def test_term_matches_numpy_formula(base):
    t, x, L = _motion()
    v = np.gradient(x, t)
    f0 = np.asarray(jaxfric.simulate(base, t, x, v))
    f1 = np.asarray(jaxfric.simulate(base + fx.LoadFriction(k_load=0.04), t, x, v, load=L))
    static = np.asarray(base.stribeck(v))
    ratio = np.divide(f0, np.abs(static), out=np.zeros_like(f0), where=static != 0)
    expected = 0.04 * np.abs(L) * np.clip(ratio, -1.0, 1.0)
    np.testing.assert_allclose(f1 - f0, expected, rtol=1e-12, atol=1e-12)
    # In steady sliding the factor is sign(v) (the papers' static form).
    sliding = (np.abs(f0) > np.abs(static)) & (np.sign(f0) == np.sign(v))
    assert sliding.sum() > 100
    np.testing.assert_allclose((f1 - f0)[sliding], (0.04 * np.abs(L) * np.sign(v))[sliding])


def test_step_matches_simulate():
    t, x, L = _motion(n=300)
    v = np.asarray(jaxfric.motion.backward_velocity(t, x))
    model = paper.two_state() + fx.LoadFriction(k_load=0.05)
    want = np.asarray(jaxfric.simulate(model, t, x, v, load=L))
    # Jitted, as a user stepping a loop from Python would (eagerly, each call re-traces
    # the event logic's `lax.cond`s: 175 s for these 300 samples).
    step = eqx.filter_jit(lambda m, *args, load: m.step(*args, load=load))
    state = model.init_state(x[0])
    got = []
    for i in range(t.size):
        state, f = step(model, state, x[i], v[i], t[i] - t[i - 1] if i else 0.0, load=L[i])
        got.append(float(f))
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)


def test_without_a_load_signal_is_a_clear_error():
    t, x, _ = _motion(n=50)
    model = paper.tustin() + fx.LoadFriction(k_load=0.05)
    with pytest.raises(ValueError, match="load_friction effect needs the load signal"):
        jaxfric.simulate(model, t, x)
    with pytest.raises(ValueError, match="load"):
        jaxfric.simulate(model, t, x, load=np.ones(49))
    # Models without the effect ignore a load.
    np.testing.assert_array_equal(jaxfric.simulate(paper.tustin(), t, x, load=np.ones(50)),
                                  jaxfric.simulate(paper.tustin(), t, x))


def test_load_column_is_read_with_its_unit(tmp_path):
    t, x, L = _motion(n=200)
    F = np.asarray(jaxfric.simulate(paper.tustin(), t, x))
    rows = "\n".join(f"{a},{b},{c},{d}" for a, b, c, d in zip(t, x * 1e3, F, L * 1e3))
    (tmp_path / "lin.csv").write_text("t[s],x[mm],F[N],load[mN]\n" + rows + "\n")
    m = load(tmp_path / "lin.csv")
    np.testing.assert_allclose(m.load, L, rtol=1e-12)
    assert m.unit("load") == "N"
    rows = "\n".join(f"{a},{b},{c},{d}" for a, b, c, d in zip(t, x * 300, F, L))
    (tmp_path / "rot.csv").write_text("t[s],q[rad],tau[N m],load[N*m]\n" + rows + "\n")
    m = load(tmp_path / "rot.csv")
    assert m.kind == "rotary" and m.unit("load") == "N m"
    np.testing.assert_allclose(m.load, L, rtol=1e-12)
    (tmp_path / "bad.csv").write_text("t[s],x[mm],F[N],load[deg]\n" + rows + "\n")
    with pytest.raises(ValueError, match="column 'load': unknown unit 'deg'"):
        load(tmp_path / "bad.csv")


def test_fit_recovers_the_load_coefficient():
    t, x, L = _motion(seed=3)
    truth = paper.tustin() + fx.LoadFriction(k_load=0.03)
    F = np.asarray(jaxfric.simulate(truth, t, x, load=L))
    start = paper.tustin() + fx.LoadFriction(k_load=0.0)
    res = fitting.fit(start, t, x, F, load=L, max_steps=200)
    assert abs(float(res.model.effects[0].k_load) - 0.03) < 1e-6
    assert float(res.rmse) < 1e-6
    with pytest.raises(ValueError, match="load signal"):
        fitting.fit(start, t, x, F, max_steps=5)


def test_screened_only_with_a_load():
    assert "load_friction" not in effect_names(None, set(), rotary=True)
    assert "load_friction" in effect_names(None, set(), rotary=False, has_load=True)
    with pytest.raises(ValueError, match="need the load signal"):
        effect_names(["load_friction"], set(), rotary=False)


def test_describe_has_no_linear_unit():
    text = fx.LoadFriction(k_load=0.031).describe()
    assert "3.1 %" in text and " N" not in text and " m" not in text


@functools.cache
def _diagnosed(hidden: tuple[str, ...]):
    """A foreign-truth file (`jaxfric.synthetic`, seed 11) with its load, diagnosed from the
    two-state model as a user would."""
    from jaxfric.synthetic import measurement

    t, x, F, L = measurement("gms_power", hidden, noise=0.03, dt=1e-2, seed=11, load=True)
    start = fitting.initial_model("two-state", t, x, F, fitting.estimate_velocity(t, x))
    return fitting.diagnose(start, t, x, F, model_name="two-state", load=L)


@pytest.mark.slow
def test_diagnosis_names_hidden_load_friction_first():
    d = _diagnosed(("load_friction",))
    assert d.final.added and d.final.added[0] == "load_friction", d.summary()
    k = float(next(e for e in d.model.effects if e.name == "load_friction").k_load)
    assert 0.02 < k < 0.04, k  # the truth's 3 % of |load|
    clean = _diagnosed(())
    assert "load_friction" not in clean.final.added, clean.summary()


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    "measured: load_friction (k_load 2.83 % for the truth's 3 %, z 6.25) then a Stribeck "
    "hump are added; the held-out RMSE falls from 0.914 to 0.609 N, removing 0.306 N of "
    "the 0.852 N the hidden load adds over the clean file (36 %, needs 50 %)"))
def test_diagnosis_removes_half_the_error_the_hidden_load_adds():
    # As in test_diagnosis_foreign.py: at least half the held-out error the hidden effect
    # adds over the same file without it is removed (the rest is the truth's GMS that the
    # two-state model does not match).
    d, clean = _diagnosed(("load_friction",)), _diagnosed(())
    excess = d.baseline.rmse_holdout - clean.final.rmse_holdout
    assert d.baseline.rmse_holdout - d.final.rmse_holdout >= 0.5 * excess, d.summary()


def test_c_export_takes_the_load_and_matches_simulate(tmp_path):
    """The exported ``jaxfric_step_load`` gives `simulate`'s force with the load signal
    (tests/export/test_export_c.py checks every model and effect the same way)."""
    from jaxfric.export import compile_c, find_compiler

    if find_compiler() is None:
        pytest.skip("no C compiler: 'cc' is not on the PATH")
    model = paper.tustin() + fx.LoadFriction(k_load=0.02)
    t, x, L = _motion(n=400)
    v = np.r_[0.0, np.diff(x) / np.diff(t)]
    want = np.asarray(jaxfric.simulate(model, t, x, v, load=L))
    got = compile_c(model, tmp_path).run(t, x, v, load=L)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.max(np.abs(want)))


def test_cli_simulate_reads_the_load_column_and_names_a_missing_one(tmp_path):
    from ..cli.test_cli import run

    t, x, L = _motion(n=400)
    model = paper.tustin() + fx.LoadFriction(k_load=0.03)
    F = np.asarray(jaxfric.simulate(model, t, x, load=L))
    jaxfric.save_model(model, tmp_path / "model.json")
    with_load = tmp_path / "with.csv"
    np.savetxt(with_load, np.column_stack([t, x, F, L]), delimiter=",",
               header="t[s],x[m],F[N],load[N]", comments="", fmt="%.17g")
    r = run("simulate", with_load, "--params", tmp_path / "model.json", "--derivatives",
            "backward", "--out", tmp_path / "s.csv")
    assert r.returncode == 0, r.stderr
    sim = np.genfromtxt(tmp_path / "s.csv", delimiter=",", names=True)
    np.testing.assert_allclose(sim["F_modelN"], F, rtol=1e-12, atol=1e-12)
    without = tmp_path / "without.csv"
    np.savetxt(without, np.column_stack([t, x, F]), delimiter=",", header="t[s],x[m],F[N]",
               comments="", fmt="%.17g")
    r = run("simulate", without, "--params", tmp_path / "model.json", "--out",
            tmp_path / "s2.csv")
    assert r.returncode == 2
    assert "load_friction" in r.stderr and "'load' column" in r.stderr


def test_each_joint_of_a_robot_log_reads_its_own_load_column(tmp_path):
    """``load1..loadN`` beside ``q1..qN``/``tau1..tauN``: each joint gets its own load (in
    the file's unit), and the command line simulates each joint with it."""
    from ..cli.test_cli import run

    t, x, L1 = _motion(seed=1, n=400)
    L2 = 3.0 * L1[::-1]
    model = paper.tustin() + fx.LoadFriction(k_load=0.03)
    F1, F2 = (np.asarray(jaxfric.simulate(model, t, x, load=L)) for L in (L1, L2))
    jaxfric.save_model(model, tmp_path / "model.json")
    path = tmp_path / "robot.csv"
    np.savetxt(path, np.column_stack([t, x, x, F1, F2, L1, L2]), delimiter=",",
               header="t[s],q1[rad],q2[rad],tau1[N m],tau2[N m],load1[N m],load2[N m]",
               comments="", fmt="%.17g")
    joints = jaxfric.data.load_joints(path)
    assert [m.unit("load") for m in joints.values()] == ["N m", "N m"]
    np.testing.assert_array_equal(joints["joint 2"].load, L2)
    r = run("simulate", path, "--params", tmp_path / "model.json", "--derivatives",
            "backward", "--deadband", "0", "--out", tmp_path / "s.csv")
    assert r.returncode == 0, r.stderr
    sim = np.genfromtxt(tmp_path / "s.csv", delimiter=",", names=True)
    np.testing.assert_allclose(sim["F_model1N_m"], F1, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(sim["F_model2N_m"], F2, rtol=1e-12, atol=1e-12)
