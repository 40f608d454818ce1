"""The C export (`jaxfric.export.to_c`) compiled with the system C compiler reproduces
`jaxfric.simulate` sample by sample (to 1e-9 of max|F|) for every model kind and every
exportable effect, on motions with dense reversals, nested loops, standstill and long
sliding; what has no C translation is refused by name."""

import itertools
import json
import os
import re
import subprocess
import sys
import warnings

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import effects as fx, GMS, NormalizedPaperShape, paper
from jaxfric.export import compile_c, EXPORTABLE, ExportError, find_compiler, to_c

from ..helpers import NESTED, power_two_state, UM


CC = find_compiler()
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler: 'cc' is not on the PATH")

TOL = 1e-9  # of max |F|


def _segments(rng):
    """Position increments (m): rest, dense random reversals with pauses, nested loops,
    rest, long sliding strokes at several speeds, loops at the end of a stroke."""
    rest = np.zeros(30)
    dense = rng.normal(0.0, 0.4 * UM, 500) * (rng.uniform(size=500) > 0.2)
    loops = np.diff(np.concatenate(
        [np.linspace(a, b, max(2, round(abs(b - a) / 2.0)) + 1)[1:]
         for a, b in itertools.pairwise(NESTED)])) * UM
    slide = np.concatenate([np.full(400, 10 * UM), np.full(300, -3 * UM), rest,
                            np.full(250, -8 * UM), np.full(200, 0.5 * UM)])
    tail = rng.normal(0.0, 2 * UM, 150)
    return np.concatenate([rest, dense, loops, rest, slide, tail])


def trajectory(seed: int, velocity: str = "backward"):
    """``(t, x, v)`` from t = 5 s, irregularly sampled (0.5-1.5 ms); `velocity`
    ``"backward"`` (the backward difference, as `simulate` derives it) or ``"central"`` (a
    zero-phase estimate whose sign can disagree with the step at reversals)."""
    rng = np.random.default_rng(seed)
    dx = _segments(rng)
    t = 5.0 + np.concatenate([[0.0], np.cumsum(rng.uniform(0.5e-3, 1.5e-3, dx.size))])
    x = 1e-3 + np.concatenate([[0.0], np.cumsum(dx)])
    if velocity == "backward":
        v = np.r_[0.0, np.diff(x) / np.diff(t)]
    else:
        v = np.gradient(x, t)
        v[np.abs(v) < 1e-7] = 0.0  # some exact rests
    return t, x, v


MOTIONS = [trajectory(1), trajectory(2, "central")]


def load_signal(t):
    """A transmitted load (N) that changes sign and size along the motion."""
    return 40.0 * np.sin(2 * np.pi * (t - t[0]) / 0.7) + 15.0


def _normalized():
    m = paper.two_state()
    return eqx.tree_at(lambda m: m.shape, m,
                       NormalizedPaperShape.from_paper(m.shape, m.stribeck.Fs))


def _small_curvature():
    m = _normalized()
    return eqx.tree_at(lambda m: m.shape.curvature, m, jnp.asarray(3e-7))


MODELS = {
    "two_state_paper": paper.two_state,
    "two_state_normalized": _normalized,
    "two_state_normalized_series": _small_curvature,
    "two_state_power": power_two_state,
    "two_state_stack3": lambda: paper.two_state(stack_size=3),
    "gms5": paper.gms5,
    "gms_from_shape": lambda: GMS.from_shape(paper.shape(), paper.stribeck(), paper.SIGMA2,
                                             paper.C, 12),
    "lugre": paper.lugre,
    "tustin": paper.tustin,
}


def _effects(x):
    """One instance of every exportable effect, with clearly nonzero parameters."""
    return {
        "viscous": fx.Viscous(c_visc=40.0),
        "quadratic_drag": fx.QuadraticDrag(c_drag=3e3),
        "stribeck": fx.StribeckHump(dF_str=3.0, v_str=2e-3),
        "inertia": fx.Inertia(mass=0.8),
        "offset": fx.Offset(offset=0.7),
        "asymmetry": fx.Asymmetry(asym=0.06),
        "cogging": fx.Cogging(cog_sin=0.4, cog_cos=-0.3, period=150 * UM),
        "position_dependence": fx.PositionDependence.for_travel(x, pos_1=0.05, pos_2=-0.03),
        "position_load": fx.PositionLoad.for_travel(x, load_1=0.5, load_2=0.2),
        "drift": fx.Drift(drift_rate=0.02, drift_decay=0.5),
        "presliding": fx.Presliding(F_pre=2.0, k_pre=2e6),
        "friction_lag": fx.FrictionLag(lag_gain=0.6, tau=0.03),
        "ripple": fx.Ripple(rip_sin=(0.3, -0.1, 0.05), rip_cos=(0.2, 0.08, -0.04),
                            period=300 * UM),
        "angle_load": fx.AngleLoad(g_sin=3.0, g_cos=-1.5),
        "load_friction": fx.LoadFriction(k_load=0.03),
    }


@pytest.fixture(scope="session")
def build(tmp_path_factory):
    """``build(key, model)``: the compiled export of `model`, once per key per session."""
    if CC is None:
        pytest.skip("no C compiler: 'cc' is not on the PATH")
    cache = {}

    def get(key, model):
        if key not in cache:
            cache[key] = compile_c(model, tmp_path_factory.mktemp(key), cc=CC)
        return cache[key]

    return get


def _reference(model, t, x, v, load=None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", jaxfric.StackOverflowWarning)
        return np.asarray(jaxfric.simulate(model, t, x, v, load=load))


def _check(compiled, model):
    """The compiled step against `simulate` on both motions, with the load signal given to
    both (read only by the load_friction effect)."""
    for t, x, v in MOTIONS:
        want = _reference(model, t, x, v, load_signal(t))
        got = compiled.run(t, x, v, load=load_signal(t))
        scale = np.max(np.abs(want))
        assert scale > 0.5
        err = np.abs(got - want)
        assert np.max(err) <= TOL * scale, (
            f"max error {np.max(err):.3g} N at sample {int(np.argmax(err))} "
            f"(limit {TOL * scale:.3g} N)")


def test_motions_have_what_they_promise():
    for _, x, v in MOTIONS:
        d = np.sign(v)
        moving = d[d != 0]
        assert np.count_nonzero(moving[1:] != moving[:-1]) > 100  # dense reversals
        assert np.count_nonzero(v == 0) > 50  # standstill
        assert np.ptp(x) > 3e-3  # long sliding (l1*Fs is ~0.1 mm)


@needs_cc
@pytest.mark.parametrize("name", sorted(MODELS))
def test_models_match_simulate(build, name):
    model = MODELS[name]()
    _check(build(name, model), model)


@needs_cc
def test_small_stack_overflows_in_both():
    """The 3-entry stack really overflows on these motions (so that path is compared)."""
    t, x, v = MOTIONS[0]
    with pytest.warns(jaxfric.StackOverflowWarning):
        jaxfric.simulate(paper.two_state(stack_size=3), t, x, v)


@needs_cc
@pytest.mark.parametrize("name", EXPORTABLE)
def test_each_effect_matches_simulate(build, name):
    model = paper.lugre() + _effects(MOTIONS[0][1])[name]
    _check(build(f"lugre_{name}", model), model)


@needs_cc
@pytest.mark.parametrize("base", ["two_state_paper", "gms5"])
def test_all_effects_together_match_simulate(build, base):
    model = MODELS[base]() + tuple(_effects(MOTIONS[0][1]).values())
    _check(build(f"{base}_all_effects", model), model)


def test_every_effect_is_exportable_and_tested():
    assert set(EXPORTABLE) == set(fx.EFFECTS)
    assert set(_effects(np.zeros(2))) == set(EXPORTABLE)


@needs_cc
def test_a_model_that_reads_the_load_has_only_the_step_with_load(build, tmp_path):
    """With load_friction the export has no ``jaxfric_step`` (a caller that forgets the
    load does not link) and says so; without a load effect it has both steps, and the plain
    one is the step with load 0. The compiled model refuses to run without the load."""
    model = paper.two_state() + fx.LoadFriction(k_load=0.03)
    header, source = to_c(model, tmp_path)
    h = header.read_text()
    assert "#define JAXFRIC_NEEDS_LOAD 1" in h
    assert "double jaxfric_step(" not in h + source.read_text()
    assert ("double jaxfric_step_load(jaxfric_state *s, double t, double x, double v, "
            "double load);") in h
    compiled = build("two_state_paper_load", model)
    t, x, v = MOTIONS[0]
    with pytest.raises(ValueError, match="needs the load signal"):
        compiled.run(t, x, v)
    # the load really matters: it changes the force, as in simulate
    assert np.max(np.abs(compiled.run(t, x, v, load=load_signal(t))
                         - compiled.run(t, x, v, load=np.zeros_like(t)))) > 0.5
    plain = to_c(paper.two_state(), tmp_path / "plain")[0].read_text()
    assert "#define JAXFRIC_NEEDS_LOAD 0" in plain
    assert "double jaxfric_step(jaxfric_state *s, double t, double x, double v);" in plain


@needs_cc
def test_generated_code_is_plain_c99(tmp_path):
    """Only <math.h>, no allocation, warning-free under -Wall -Wextra -pedantic, and the
    fitted values appear as named constants with units."""
    model = paper.two_state() + (fx.Cogging(cog_sin=0.1, cog_cos=0.0, period=1e-3),)
    header, source = to_c(model, tmp_path)
    text = header.read_text() + source.read_text()
    assert sorted(set(re.findall(r"#include\s*(\S+)", text))) == ['"jaxfric_model.h"',
                                                                   "<math.h>"]
    for word in ("malloc", "calloc", "free(", "static double jf_state"):
        assert word not in text
    assert re.search(r"#define JF_FS \(26\.1\) /\* stribeck\.Fs \[N\] \*/", text)
    assert re.search(r"#define JF_COG_SIN \(0\.1\) /\* effect cogging\.cog_sin \[N\] \*/", text)
    h = header.read_text()
    assert "double jaxfric_step(jaxfric_state *s, double t, double x, double v);" in h
    assert "void jaxfric_init(jaxfric_state *s, double t0, double x0);" in h
    assert "#define JAXFRIC_STACK_SIZE 16" in h
    run = subprocess.run([CC, "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-c",
                          str(source), "-o", str(tmp_path / "m.o")], capture_output=True,
                         text=True)
    assert run.returncode == 0, run.stderr


@needs_cc
@pytest.mark.parametrize("name", list(MODELS))
def test_every_model_compiles_warning_free(tmp_path, name):
    """No unused helper or variable for any model kind: -Wall -Wextra -Werror."""
    _, source = to_c(MODELS[name](), tmp_path)
    run = subprocess.run([CC, "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-c",
                          str(source), "-o", str(tmp_path / "m.o")], capture_output=True,
                         text=True)
    assert run.returncode == 0, run.stderr


def test_export_from_a_fit_json_is_the_model_export(tmp_path):
    model = paper.lugre() + fx.Offset(offset=0.25)
    result = tmp_path / "fit.json"
    from jaxfric._serialize import model_to_dict

    result.write_text(json.dumps({"fitted_model": model_to_dict(model), "rmse": 0.1}))
    a = [p.read_text() for p in to_c(result, tmp_path / "a")]
    b = [p.read_text() for p in to_c(model, tmp_path / "b")]
    assert a == b


class _Unknown(fx.AbstractEffect):
    name = "made_up"

    def term(self, s):
        return s.v


def test_unknown_effect_is_refused_by_name(tmp_path):
    with pytest.raises(ExportError, match="made_up"):
        to_c(paper.lugre() + _Unknown(), tmp_path)
    assert not list(tmp_path.iterdir())  # nothing half-written


def test_unknown_shape_and_model_are_refused(tmp_path):
    class Wavy(jaxfric.PowerShape):
        pass

    model = eqx.tree_at(lambda m: m.shape, paper.two_state(), Wavy(l1=4e-6, n=2.0))
    with pytest.raises(ExportError, match="Wavy"):
        to_c(model, tmp_path)
    with pytest.raises(ExportError, match="expected a jaxfric model"):
        to_c(object(), tmp_path)


def _cli(*args):
    env = {**os.environ, "JAXFRIC_CACHE_DIR": ""}
    return subprocess.run([sys.executable, "-m", "fitting.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=300, env=env)


def test_cli_export_writes_the_same_code_as_to_c(tmp_path):
    from jaxfric._serialize import model_to_dict

    model = paper.two_state() + fx.Drift(drift_rate=0.01)
    result = tmp_path / "diag.json"
    result.write_text(json.dumps({"fitted_model": model_to_dict(model)}))
    r = _cli("export", result, "--c", tmp_path / "new" / "c")
    assert r.returncode == 0, r.stderr
    assert "jaxfric_model.c" in r.stdout
    want = [p.read_text() for p in to_c(model, tmp_path / "ref")]
    got = [(tmp_path / "new" / "c" / n).read_text() for n in ("jaxfric_model.h",
                                                                "jaxfric_model.c")]
    assert got == want
    assert "jaxfric_step_load" not in r.stdout  # nothing to say: the plain step will do
    loaded = tmp_path / "load.json"
    loaded.write_text(json.dumps({"fitted_model": model_to_dict(
        paper.two_state() + fx.LoadFriction(k_load=0.03))}))
    r = _cli("export", loaded, "--c", tmp_path / "load")
    assert r.returncode == 0, r.stderr
    assert "step: jaxfric_step_load(&s, t, x, v, load)" in r.stdout


@pytest.mark.parametrize("content, expected", [
    (None, "no such file"),
    ('{"rmse": 0.1}', "no saved model"),
    ("{not json", "not a readable JSON file"),
])
def test_cli_export_bad_input_one_line_exit_2(tmp_path, content, expected):
    result = tmp_path / "result.json"
    if content is not None:
        result.write_text(content)
    r = _cli("export", result, "--c", tmp_path / "out")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("jaxfric export: error: "), r.stderr
    assert expected in lines[0]
    assert not (tmp_path / "out").exists()


@needs_cc
def test_c_compensator_example_removes_most_of_the_tracking_error(tmp_path):
    """examples/c_compensator.py: the exported step as friction feedforward in a C control
    loop (the plant's friction is the same model, so the feedforward is nearly exact)."""
    from ..helpers import load_example

    out = load_example("c_compensator").build_and_run(paper.two_state(), tmp_path, 1e-4, CC)
    errors = [float(line.rsplit(":", 1)[1].split()[0]) for line in out.splitlines()
              if "max tracking error" in line]
    without, with_ff = errors
    assert without > 1e-5  # friction visibly disturbs the PD loop
    assert with_ff < 0.05 * without


# ---- MuJoCo (the optional extra `mujoco`) ---------------------------------------------


def _mujoco_forces(xml: str, t, x, v):
    """Friction force (jaxfric's sign) of the MJCF's actuator with the joint driven along
    ``(t, x, v)`` (uniform steps equal to the model's timestep): per sample, the joint is put
    at the sample's position and velocity, one ``mj_step`` integrates the bristle state, and
    the force is minus the actuator's force and its damping."""
    mujoco = pytest.importorskip("mujoco")
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    out = np.empty_like(t)
    for i in range(t.size):
        data.qpos[0], data.qvel[0] = x[i], v[i]
        mujoco.mj_step(model, data)
        out[i] = -(data.actuator_force[0] + data.qfrc_damper[0])
    return out


def _recorded_motion(dt):
    """A 1.5 mm stroke motion with 60 um loops, resampled at `dt` (uniform), v analytic."""
    t = np.arange(0.0, 4.0, dt)
    w1, w2 = 2 * np.pi / 1.5, 2 * np.pi / 4.0
    x = 60 * UM * np.sin(w1 * t) + 1.5e-3 * np.sin(w2 * t)
    v = 60 * UM * w1 * np.cos(w1 * t) + 1.5e-3 * w2 * np.cos(w2 * t)
    return t, x, v


@pytest.mark.parametrize("joint", ["slide", "hinge"])
def test_mujoco_dcmotor_matches_jaxfric_lugre_within_1_percent(tmp_path, joint):
    pytest.importorskip("mujoco")
    from jaxfric.export import to_mujoco

    dt = 2e-4
    lugre = paper.lugre()
    lugre = eqx.tree_at(lambda m: m.stribeck.delta, lugre, jnp.asarray(2.0))
    model = lugre + (fx.Viscous(c_visc=20.0),
                     fx.Cogging(cog_sin=0.8, cog_cos=-0.5, period=5e-4))
    path = to_mujoco(model, tmp_path / "axis.xml", joint=joint, timestep=dt)
    xml = path.read_text()
    assert f'type="{joint}"' in xml and 'input="none"' in xml
    assert "nothing approximated" in xml
    t, x, v = _recorded_motion(dt)
    want = np.asarray(jaxfric.simulate(model, t, x, v))
    got = _mujoco_forces(xml, t, x, v)
    assert np.max(np.abs(got - want)) <= 0.01 * np.max(np.abs(want))


def test_mujoco_export_says_what_it_approximates_and_refuses_the_rest(tmp_path):
    from jaxfric.export import mjcf

    xml = mjcf(paper.lugre())  # the paper's delta is 0.6
    assert "delta = 0.6 is replaced by MuJoCo's fixed exponent 2" in xml
    for model, name in ((paper.two_state(), "TwoState"), (paper.tustin(), "Tustin"),
                        (paper.gms5(), "GMS"), (paper.lugre() + fx.Offset(offset=1.0),
                                                "offset")):
        with pytest.raises(ExportError, match=name) as err:
            mjcf(model)
        assert "jaxfric fit FILE --model lugre" in str(err.value)


def test_cli_export_mujoco_and_its_refusal(tmp_path):
    from jaxfric._serialize import model_to_dict

    good, bad = tmp_path / "lugre.json", tmp_path / "two_state.json"
    good.write_text(json.dumps({"fitted_model": model_to_dict(paper.lugre())}))
    bad.write_text(json.dumps({"fitted_model": model_to_dict(paper.two_state())}))
    r = _cli("export", good, "--mujoco", tmp_path / "axis.xml", "--joint", "hinge")
    assert r.returncode == 0, r.stderr
    xml = (tmp_path / "axis.xml").read_text()
    assert 'type="hinge"' in xml and "<dcmotor" in xml and "exponent 2" in xml
    r = _cli("export", bad, "--mujoco", tmp_path / "no.xml")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "TwoState" in r.stderr and "--model lugre" in r.stderr
    assert not (tmp_path / "no.xml").exists()
