"""The command line as a user runs it: a subprocess on good and bad files."""

import html
import json
import os
import subprocess
import sys

import equinox as eqx
import numpy as np
import pytest

import fitting
import jaxfric
from jaxfric import paper

from ..helpers import strokes_with_loops


UM = 1e-6


@pytest.fixture(autouse=True, scope="module")
def _cache_dir(tmp_path_factory):
    """The commands keep compiled programs on disk (`jaxfric.enable_compilation_cache`):
    here in a folder of the test session, not in the user's home."""
    old = os.environ.get("JAXFRIC_CACHE_DIR")
    os.environ["JAXFRIC_CACHE_DIR"] = str(tmp_path_factory.mktemp("xla-cache"))
    yield
    if old is None:
        del os.environ["JAXFRIC_CACHE_DIR"]
    else:
        os.environ["JAXFRIC_CACHE_DIR"] = old


def run(*args, cwd=None, env=None):
    return subprocess.run(
        [sys.executable, "-m", "fitting.cli", *map(str, args)],
        capture_output=True, text=True, cwd=cwd, timeout=600,
        env=None if env is None else {**os.environ, **env},
    )


def _write(path, header, columns):
    rows = np.column_stack(columns)
    path.write_text(header + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows))
    return path


def _synthetic(model, noise, seed=0, n=1500):
    """Presliding loops and strokes at several speeds, irregularly sampled; the force made
    with the central-difference velocity that the command line derives by default."""
    t, x = strokes_with_loops(n, seed)
    rng = np.random.default_rng(seed)
    rng.uniform(size=n)  # the draws the motion took: the noise stays as it was
    v = fitting.estimate_velocity(t, x)
    F = np.asarray(jaxfric.simulate(model, t, x, v)) + noise * rng.normal(size=n)
    return t, x, F


@pytest.mark.parametrize("cmd", [[], ["demo"], ["fit"], ["diagnose"], ["simulate"], ["compare"],
                                 ["export"]])
def test_help(cmd):
    r = run(*cmd, "--help")
    assert r.returncode == 0, r.stderr
    assert "usage: jaxfric" in r.stdout
    if cmd:
        assert "examples:" in r.stdout


def test_fit_tustin_json_and_units(tmp_path):
    """Tustin data (+ 0.02 N noise) written in mm and mN: the fit recovers the parameters
    within their standard errors, and the JSON follows the documented schema, in SI."""
    truth = paper.tustin()
    t, x, F = _synthetic(truth, 0.02)
    path = _write(tmp_path / "run.csv", "t[s],x[mm],F[mN]", (t, x * 1e3, F * 1e3))
    out = tmp_path / "fit.json"
    r = run("fit", path, "--model", "tustin", "--json", out, "--quiet")
    assert r.returncode == 0, r.stderr
    assert r.stdout == ""  # --quiet
    res = json.loads(out.read_text())
    assert {"model", "params", "stderr", "rmse", "nrmse", "converged"} <= set(res)
    assert res["model"] == "tustin" and res["converged"] is True
    assert set(res["params"]) == {"Fs", "Fc", "Vs", "delta", "sigma2"}
    assert res["units"]["sigma2"] == "N s/m"
    # The speeds stay below Vs, so Fc, Vs, delta trade off: their errors are large but
    # honest. Each estimate lies within 4 standard errors of the truth.
    true = {"Fs": truth.stribeck.Fs, "Fc": truth.stribeck.Fc, "Vs": truth.stribeck.Vs,
            "delta": truth.stribeck.delta, "sigma2": truth.sigma2}
    for name, value in true.items():
        if res["stderr"][name] is None:  # undetermined by these data: held, error unknown
            continue
        err = abs(res["params"][name] - float(value))
        assert err < 4 * res["stderr"][name], (name, err, res["stderr"][name])
    assert res["stderr"]["Fs"] < 1e-3 * float(truth.stribeck.Fs)  # sharp: reached at v -> 0
    assert 0.015 < res["rmse"] < 0.025  # the noise level


def test_fit_two_state_prints_table_and_writes_plot(tmp_path):
    truth = paper.two_state()
    t, x, F = _synthetic(truth, 0.05, seed=1)
    path = _write(tmp_path / "run.csv", "t,x,F", (t, x, F))
    r = run("fit", path, "--model", "two-state", "--json", tmp_path / "f.json",
            "--plot", tmp_path / "f.png")
    assert r.returncode == 0, r.stderr
    for name in ("Fs", "Fc", "l1", "C", "alpha"):
        assert f"\n{name:>10} " in r.stdout, name
    assert "m/N" in r.stdout and "N/s" in r.stdout
    res = json.loads((tmp_path / "f.json").read_text())
    assert set(res["params"]) == {"Fs", "Fc", "Vs", "delta", "sigma2", "a", "b", "c", "alpha",
                                  "beta", "l1", "C"}
    assert res["rmse"] < 0.1  # noise 0.05 N; the start (estimated from data) is far worse
    assert (tmp_path / "f.png").stat().st_size > 10_000


def test_fit_keeps_its_compilation_on_disk(tmp_path):
    """A second `jaxfric fit` of the same shape loads the solver from the cache folder
    (JAX logs the hit); an empty JAXFRIC_CACHE_DIR turns the cache off."""
    t, x, F = _synthetic(paper.tustin(), 0.02, n=400)
    path = _write(tmp_path / "run.csv", "t,x,F", (t, x, F))
    cache = tmp_path / "cache"
    # JAX stores programs that took >= 1 s to compile; this small Tustin fit is quicker.
    env = {"JAXFRIC_CACHE_DIR": str(cache), "JAX_LOG_COMPILES": "1",
           "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0"}
    first = run("fit", path, "--model", "tustin", "--quiet", env=env)
    assert first.returncode == 0, first.stderr
    hit = "Persistent compilation cache hit for 'jit__chunk'"
    assert hit not in first.stderr
    assert any("_chunk" in p.name for p in cache.iterdir())
    second = run("fit", path, "--model", "tustin", "--quiet", env=env)
    assert second.returncode == 0, second.stderr
    assert hit in second.stderr
    # Off: no hit, and nothing written where the default folder would be.
    home, xdg = tmp_path / "home", tmp_path / "xdg"
    off = run("fit", path, "--model", "tustin", "--quiet",
              env={**env, "JAXFRIC_CACHE_DIR": "", "HOME": str(home),
                   "XDG_CACHE_HOME": str(xdg)})
    assert off.returncode == 0, off.stderr
    assert "cache hit" not in off.stderr
    assert not xdg.exists() and not (home / ".cache").exists()


def test_fit_warns_on_opposite_sign_and_flip_force_fixes_it(tmp_path):
    t, x, F = _synthetic(paper.tustin(), 0.02, seed=2)
    path = _write(tmp_path / "run.csv", "t,x,F", (t, x, -F))
    r = run("fit", path, "--model", "tustin", "--json", tmp_path / "a.json")
    assert r.returncode == 0
    assert "warning:" in r.stderr and "--flip-force" in r.stderr
    r = run("fit", path, "--model", "tustin", "--flip-force", "--json", tmp_path / "b.json")
    assert r.returncode == 0 and "anti-correlated" not in r.stderr
    assert json.loads((tmp_path / "b.json").read_text())["rmse"] < 0.025


BAD = {
    "missing": (None, "no such file"),
    "empty": ("", "the file is empty"),
    "no_header": ("0.0,0.0,0.0\n0.1,0.1,0.1\n", "no header row"),
    "missing_column": ("t,x\n" + "\n".join(f"{i},{i}" for i in range(20)), "missing column 'F'"),
    "non_numeric": ("t,x,F\n" + "\n".join(f"{i},{i * 1e-6},1" for i in range(5))
                    + "\n5,oops,1\n" + "\n".join(f"{i},{i * 1e-6},1" for i in range(6, 20)),
                    "column 'x', row 6: 'oops' is not a number"),
    "nan": ("t,x,F\n" + "\n".join(f"{i},{i * 1e-6},{'nan' if i == 3 else 1}" for i in range(20)),
            "column 'F', row 4"),
    "time_duplicated": ("t,x,F\n0,0,0\n" + "\n".join(f"{i},{i * 1e-6},1" for i in range(1, 20))
                        .replace("\n2,", "\n1,", 1), "column 't', row 3: time repeats"),
    "too_few": ("t,x,F\n0,0,0\n1,1e-6,1\n", "only 2 samples"),
    "no_motion": ("t,x,F\n" + "\n".join(f"{i},0.001,1" for i in range(20)), "no motion at all"),
    "mm_as_m": ("t,x,F\n" + "\n".join(f"{i},{i * 10.0},1" for i in range(20)), "x[mm]"),
    "absurd": ("t,x,F\n" + "\n".join(f"{i},{i * 1e-6},{5e9 if i == 7 else 1}" for i in range(20)),
               "column 'F', row 8"),
}


@pytest.mark.parametrize("kind", sorted(BAD))
def test_bad_input_one_line_error_exit_2_nothing_written(tmp_path, kind):
    text, expected = BAD[kind]
    path = tmp_path / f"{kind}.csv"
    if text is not None:
        path.write_text(text)
    out = tmp_path / "out.json"
    r = run("fit", path, "--model", "tustin", "--json", out)
    assert r.returncode == 2, (r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr  # one line, no traceback
    assert lines[0].startswith("jaxfric fit: error: ")
    assert f"{kind}.csv" in lines[0] and expected in lines[0], lines[0]
    assert not out.exists()
    assert list(tmp_path.iterdir()) == ([path] if text is not None else [])


@pytest.mark.slow  # a whole diagnosis: every candidate refitted, the best cross-validated
def test_diagnose_json_schema_and_report(tmp_path):
    """A Tustin measurement with a hidden 1 N offset: the JSON has the documented schema,
    the candidates are sorted by score, the offset is found and added, the error falls,
    and the report's figures exist and are not empty."""
    from jaxfric import effects as fx
    from jaxfric.examples import diagnosis_motion

    t, x = diagnosis_motion(dt=4e-2)
    rng = np.random.default_rng(5)
    F = np.asarray(jaxfric.simulate(paper.tustin() + fx.Offset(offset=1.0), t, x))
    path = _write(tmp_path / "run.csv", "t,x,F", (t, x, F + 0.05 * rng.normal(size=t.size)))
    out, report = tmp_path / "d.json", tmp_path / "report"
    # The data were made by `simulate` with its own backward-difference velocity.
    r = run("diagnose", path, "--model", "tustin", "--json", out, "--report", report,
            "--derivatives", "backward")
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    assert d["velocity"].startswith("backward difference")
    assert d["baseline"]["model"] == "tustin" and d["baseline"]["rmse"] > 0.5
    scores = [c["score"] for c in d["candidates"] if c["score"] is not None]
    assert scores and scores == sorted(scores, reverse=True)  # the cross-validated first
    assert {"effect", "score", "significant", "evidence"} <= set(d["candidates"][0])
    assert d["candidates"][0]["effect"] == "offset" and d["candidates"][0]["significant"]
    assert d["after"]["added"] == ["offset"]
    assert d["after"]["rmse"] < 0.06  # the noise level, 0.05 N
    for name in ("time.png", "loops.png", "residuals.png"):
        assert (report / name).stat().st_size > 10_000
    assert json.loads((report / "diagnosis.json").read_text()) == d
    # The page says how the derivatives were taken and what the plausibility checks found.
    page = (report / "report.html").read_text()
    assert html.escape(f"velocity: {d['velocity']}") in page
    assert "Plausibility of the fitted models" in page
    assert all(html.escape(w) in page for ws in d["warnings"].values() for w in ws) \
        if d["warnings"] else "no warning" in page


def test_fit_then_simulate_with_its_parameters_and_compare(tmp_path):
    """`simulate --params FIT.json` reproduces the fitted model's force (its RMSE is the
    fit's), and `compare` reports every model with per-regime errors."""
    t, x, F = _synthetic(paper.tustin(), 0.02, seed=4)
    path = _write(tmp_path / "run.csv", "t,x,F", (t, x, F))
    r = run("fit", path, "--model", "tustin", "--json", tmp_path / "fit.json", "--quiet")
    assert r.returncode == 0, r.stderr
    fit_json = json.loads((tmp_path / "fit.json").read_text())
    fit_rmse = fit_json["rmse"]
    assert fit_json["overflow"] == 0  # memory overflow is part of the result
    r = run("simulate", path, "--params", tmp_path / "fit.json", "--out", tmp_path / "sim.csv")
    assert r.returncode == 0, r.stderr
    sim = np.genfromtxt(tmp_path / "sim.csv", delimiter=",", names=True)
    assert sim.dtype.names == ("ts", "xm", "vms", "F_modelN", "FN")
    np.testing.assert_allclose(sim["ts"], t)
    rmse = float(np.sqrt(np.mean((sim["F_modelN"] - F) ** 2)))
    assert abs(rmse - fit_rmse) < 1e-6 * fit_rmse
    r = run("compare", path, "--models", "tustin,lugre", "--json", tmp_path / "cmp.json")
    assert r.returncode == 0, r.stderr
    cmp = json.loads((tmp_path / "cmp.json").read_text())["models"]
    assert set(cmp) == {"tustin", "lugre"}
    for res in cmp.values():
        assert res["regimes"]["all"]["rmse"] == pytest.approx(res["rmse"], rel=1e-9)
        assert "presliding" in res["regimes"]
    r = run("simulate", path, "--params", tmp_path / "missing.json")
    assert r.returncode == 2 and "missing.json: no such file" in r.stderr


#: The demo's RMSE after the diagnosis before issue 36 (its base fit in a poor optimum whose
#: steady-state curve sits up to 10 N below the measured sliding force at 20 mm/s); the
#: goal is to halve it (it needs the two-state friction lag that does not depend on the
#: sampling, docs/algorithm.md section 4, and a start with a sliding plateau,
#: `fitting._start.LAG_DELTAS`).
DEMO_RMSE_BEFORE = 0.751


# Slow (about 100-300 s under the other tests): the whole demo, fit + diagnosis + report.
@pytest.mark.slow
def test_demo_writes_the_report(tmp_path):
    """The newcomer's first command: the report exists, its figures are not empty, the
    hidden effect of the built-in data is the one found, the error after the diagnosis is
    at most half of `DEMO_RMSE_BEFORE`, and the final model's steady-state curve is within
    10 % of Fs of the measured sliding force in every speed bin (the measured force is
    itself up to 9 % of Fs off the stage's steady state: its friction lag of about 2 s does
    not settle within a stroke)."""
    from fitting._start import swing_travel
    from fitting._steady import steady_curve

    out = tmp_path / "demo"
    r = run("demo", "--out", out, "--json", tmp_path / "demo.json")
    assert r.returncode == 0, r.stderr
    assert "report: " in r.stdout and "hidden effect (cogging) found" in r.stdout
    page = (out / "report.html").read_text()
    for name in ("time.png", "loops.png", "residuals.png"):
        assert (out / name).stat().st_size > 10_000
        assert f'src="{name}"' in page
    summary = json.loads((tmp_path / "demo.json").read_text())
    assert summary["found"] == ["cogging"]
    assert summary["final_rmse_N"] < summary["baseline_rmse_N"]
    assert (out / "example.csv").stat().st_size > 0
    t, x, F = np.loadtxt(out / "example.csv", delimiter=",", skiprows=1).T
    v = np.gradient(x, t)
    curve = steady_curve(t, x, F, v, 2 * swing_travel(x, F))
    model = jaxfric.load_model(summary["diagnosis"]["fitted_model"])
    base = model.base if hasattr(model, "base") else model
    steady = np.asarray(base.stribeck.magnitude(curve.speed)) + float(base.sigma2) * curve.speed
    off = np.abs(steady - curve.force) / float(base.stribeck.Fs)
    assert len(curve) >= 4 and np.all(off < 0.10), dict(zip(curve.speed, off, strict=True))
    assert summary["final_rmse_N"] <= 0.5 * DEMO_RMSE_BEFORE


def test_progress_prints_steps_and_rmse():
    """What `jaxfric fit` prints while it works when its output is a terminal: after each
    compiled chunk, the steps so far and the RMSE, which ends at the fit's."""
    from fitting.cli import commands

    truth = paper.tustin()
    t, x, F = _synthetic(truth, 0.02, n=300)
    lines = []
    start = eqx.tree_at(lambda m: m.stribeck.Fc, truth, truth.stribeck.Fc * 1.3)
    scale = float(np.std(F)) / np.sqrt(F.size)
    res = fitting.fit(start, t, x, F, max_steps=20,
                      progress=commands._progress(lines.append, scale, "N"))
    assert res.num_steps > 1
    assert lines and all(line.lstrip().startswith("step") and "RMSE" in line for line in lines)
    assert f"{float(res.rmse):.4g} N" in lines[-1]


def test_enable_compilation_cache_rules(tmp_path):
    """Where `jaxfric.enable_compilation_cache` puts the cache (in a new process: it sets
    JAX's global configuration)."""
    (tmp_path / "file").write_text("")
    code = f"""
import os, warnings, jax, jaxfric
from jaxfric._config import default_cache_dir
with warnings.catch_warnings(record=True) as w:
    warnings.simplefilter("always")
    assert jaxfric.enable_compilation_cache({str(tmp_path / "file" / "sub")!r}) is None
assert "cannot create" in str(w[0].message)
os.environ["JAXFRIC_CACHE_DIR"] = ""
assert jaxfric.enable_compilation_cache() is None
assert not jax.config.jax_compilation_cache_dir
del os.environ["JAXFRIC_CACHE_DIR"]
os.environ["XDG_CACHE_HOME"] = {str(tmp_path / "xdg")!r}
p = jaxfric.enable_compilation_cache()
assert p == default_cache_dir() and p.is_dir(), p
assert str(p).startswith({str(tmp_path / "xdg")!r}), p
assert jax.config.jax_compilation_cache_dir == str(p)
# every program is kept (JAX's default: those of 1 s and more)
from jaxfric._config import MIN_COMPILE_S
assert jax.config.jax_persistent_cache_min_compile_time_secs == MIN_COMPILE_S == 0
os.environ["JAXFRIC_CACHE_DIR"] = "/elsewhere"
assert jaxfric.enable_compilation_cache() == p  # a folder JAX already has is kept
print("ok")
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=120, env={k: v for k, v in os.environ.items()
                                         if k not in ("JAXFRIC_CACHE_DIR",
                                                      "JAX_COMPILATION_CACHE_DIR")})
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr
