"""The command line never overwrites an input, turns the library's data errors into one line
naming the file (exit 2), refuses impossible time steps in every command, saves the model it
fitted under its own name, and exports only what a controller may run (issue 35).

Each test drives `fitting.cli.main` with the arguments a user types, and checks the exit
code, the message and that the input files are byte for byte as they were."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

import jaxfric
from jaxfric import paper
from jaxfric._serialize import model_to_dict

from ..helpers import strokes_with_loops


def _save(path: Path, columns: dict) -> Path:
    """A CSV (or, for ``.npz``, an archive) of `columns`."""
    if path.suffix == ".npz":
        np.savez(path, **columns)
    else:
        np.savetxt(path, np.column_stack(list(columns.values())), delimiter=",",
                   header=",".join(columns), comments="", fmt="%.17g")
    return path


def _signal(n=400, seed=0):
    t, x = strokes_with_loops(n, seed)
    F = np.asarray(jaxfric.simulate(paper.two_state(), t, x))
    return t, x, F + 0.02 * np.random.default_rng(seed).normal(size=n)



def _one_line(err: str, command: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"jaxfric {command}: error: "), err
    return lines[0]


def _unchanged(paths: dict):
    for path, content in paths.items():
        assert Path(path).read_bytes() == content, f"{path} was changed"


def _snapshot(*paths) -> dict:
    return {p: Path(p).read_bytes() for p in paths}


# ---- 1. Outputs against inputs and against each other ---------------------------------

def _clash_cases(tmp_path):
    t, x, F = _signal()
    run_csv = _save(tmp_path / "run.csv", {"t": t, "x": x, "F": F})
    run_npz = _save(tmp_path / "run.npz", {"t": t, "x": x, "F": F})
    report = tmp_path / "report"
    report.mkdir()
    inside = _save(report / "diagnosis.json", {"t": t, "x": x, "F": F})  # a CSV so named
    (report / "joint_2").mkdir()
    deeper = _save(report / "joint_2" / "loops.png", {"t": t, "x": x, "F": F})
    hard = tmp_path / "hard.csv"
    os.link(run_csv, hard)
    soft = tmp_path / "soft.csv"
    soft.symlink_to(run_csv)
    fit = tmp_path / "fit.json"
    fit.write_text(json.dumps({"fitted_model": model_to_dict(paper.lugre())}))
    c_dir = tmp_path / "c"
    c_dir.mkdir()
    return {
        "fit --json the input": (["fit", run_csv, "--json", run_csv], "overwrite the input"),
        "fit --plot the input": (["fit", run_csv, "--plot", tmp_path / "." / "run.csv"],
                                 "overwrite the input"),
        "simulate --out the input": (["simulate", run_csv, "--out", run_csv],
                                     "overwrite the input"),
        "simulate an npz onto itself": (["simulate", run_npz, "--out", run_npz],
                                        "overwrite the input"),
        "simulate --out a hard link": (["simulate", run_csv, "--out", hard],
                                       "overwrite the input"),
        "simulate a symbolic link onto its target": (["simulate", soft, "--out", run_csv],
                                                     "overwrite the input"),
        "compare --json the input": (["compare", run_csv, "--json", run_csv],
                                     "overwrite the input"),
        "diagnose an input inside --report": (["diagnose", inside, "--report", report],
                                              "overwrite the input"),
        "diagnose an input in a joint's report folder": (["diagnose", deeper, "--report",
                                                          report], "joint_*/*.png"),
        "fit --params onto itself": (["fit", run_csv, "--params", fit, "--json", fit],
                                     "overwrite the input --params"),
        "export onto its result": (["export", fit, "--mujoco", fit], "overwrite the input"),
        "--json and --plot one file": (["fit", run_csv, "--json", tmp_path / "out",
                                        "--plot", tmp_path / "out"], "same output"),
        "--json a file --report writes": (["diagnose", run_csv, "--json",
                                           tmp_path / "r2" / "diagnosis.json", "--report",
                                           tmp_path / "r2"], "writes too"),
        "--mujoco a file --c writes": (["export", fit, "--c", c_dir, "--mujoco",
                                        c_dir / "jaxfric_model.h"], "writes too"),
    }


_CLASHES = ["fit --json the input", "fit --plot the input", "simulate --out the input",
            "simulate an npz onto itself", "simulate --out a hard link",
            "simulate a symbolic link onto its target", "compare --json the input",
            "diagnose an input inside --report", "diagnose an input in a joint's report folder",
            "fit --params onto itself",
            "export onto its result", "--json and --plot one file",
            "--json a file --report writes", "--mujoco a file --c writes"]


@pytest.mark.parametrize("case", _CLASHES)
def test_no_output_replaces_an_input_or_another_output(tmp_path, run, case):
    cases = _clash_cases(tmp_path)
    assert sorted(cases) == sorted(_CLASHES)
    (tmp_path / "r2").mkdir()
    before = _snapshot(*[p for p in tmp_path.rglob("*") if p.is_file()])
    argv, expected = cases[case]
    rc, out, err = run(*argv)
    assert rc == 2, err
    assert expected in _one_line(err, argv[0])
    assert out == ""  # refused before any work
    _unchanged(before)
    assert sorted(p for p in tmp_path.rglob("*") if p.is_file()) == sorted(before)


def test_an_output_that_is_a_fifo_is_refused_not_replaced(tmp_path, run):
    """The atomic rename would put a regular file in the place of a FIFO or a device
    (``--out /dev/null`` run as root)."""
    t, x, F = _signal()
    data = _save(tmp_path / "run.csv", {"t": t, "x": x, "F": F})
    fifo = tmp_path / "out.fifo"
    os.mkfifo(fifo)
    rc, _, err = run("simulate", data, "--out", fifo)
    assert rc == 2 and "is not a regular file" in _one_line(err, "simulate")
    assert fifo.is_fifo()


def test_an_input_in_a_report_folder_that_the_report_does_not_write_is_fine(tmp_path, run):
    """Only the files a folder output writes clash: data beside a report are left alone."""
    (tmp_path / "c").mkdir()
    fit = tmp_path / "c" / "fit.json"
    fit.write_text(json.dumps({"fitted_model": model_to_dict(paper.tustin())}))
    before = _snapshot(fit)
    rc, _, err = run("export", fit, "--c", tmp_path / "c")
    assert rc == 0, err
    assert (tmp_path / "c" / "jaxfric_model.c").is_file()
    _unchanged(before)


# ---- 2. The library's data errors are one line naming the file -----------------------

def _zero_force_files(tmp_path):
    t, x, F = _signal()
    zero = _save(tmp_path / "zero.csv", {"t": t, "x": x, "F": 0 * F})
    dt = t[1] - t[0]
    rest = np.r_[t[0] - dt * np.arange(20, 0, -1), t]  # 20 samples at rest first
    moving_zero = _save(tmp_path / "moving_zero.csv", {
        "t": rest, "x": np.r_[np.full(20, x[0]), x], "F": np.r_[np.full(20, 0.1), 0 * F]})
    return zero, moving_zero


@pytest.mark.parametrize("argv", [["fit"], ["fit", "--model", "lugre"], ["diagnose"],
                                  ["compare"]])
def test_a_force_of_zero_is_one_line_naming_the_file(tmp_path, run, argv):
    for path, expected in zip(_zero_force_files(tmp_path),
                              ("is 0 N in every row", "the force is zero wherever the data "
                               "move")):
        before = _snapshot(path)
        rc, _, err = run(argv[0], path, *argv[1:], "--max-steps", 1)
        assert rc == 2, err
        line = _one_line(err, argv[0])
        assert line.startswith(f"jaxfric {argv[0]}: error: {path}") and expected in line
        _unchanged(before)


# ---- 3. Time steps: a glitch is refused by every command ------------------------------

def _glitch_files(tmp_path):
    t, x, F = _signal()
    t_ns = t.copy()
    t_ns[200] = t_ns[199] + 1e-9  # a logger glitch: one record 1 ns after the previous
    return (_save(tmp_path / "ns.csv", {"t": t_ns, "x": x, "F": F}),
            _save(tmp_path / "scaled.csv", {"t": 1e-8 * t, "x": x, "F": F}))


@pytest.mark.parametrize("command", ["fit", "simulate", "compare", "diagnose"])
def test_an_impossible_time_step_is_refused_naming_its_row(tmp_path, run, command):
    ns, scaled = _glitch_files(tmp_path)
    out = tmp_path / "out.csv"
    for path, expected in ((ns, "ns.csv:202: column 't', row 201: 1e-09 s after row 200"),
                           (scaled, "scaled.csv:3: column 'x', row 2:")):
        before = _snapshot(path)
        extra = ["--out", out] if command == "simulate" else ["--max-steps", 1]
        rc, _, err = run(command, path, *extra)
        assert rc == 2, err
        line = _one_line(err, command)
        assert expected in line
        assert "median time step" in line if path == ns else "is the unit of t right" in line
        assert not out.exists()  # no force written from an impossible velocity
        _unchanged(before)


DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data"


@pytest.mark.parametrize("name", ["tribometer.csv", "emps_estimation.csv",
                                  "emps_validation.csv"])
def test_measured_records_pass_the_time_step_rules(name):
    """The measured records' steps are between 0.99 and 2.01 times their median
    (docs/reliability.md), far from the 1/1000 the rule refuses; they load."""
    from jaxfric.data import load

    path = DATA / name
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    m = load(path, flip_force=name == "tribometer.csv", check_sign=False)
    dt = np.diff(m.t)
    ratio = dt / np.median(dt)
    assert 0.99 <= ratio.min() and ratio.max() <= 2.01


# ---- 4. The saved model is the model fitted -------------------------------------------

def _params_file(path: Path, model, kind: str) -> Path:
    path.write_text(json.dumps({"model": kind, "fitted_model": model_to_dict(model)}))
    return path


@pytest.mark.parametrize("command", ["fit", "simulate"])
def test_model_and_params_that_disagree_are_refused(tmp_path, run, command):
    t, x, F = _signal()
    data = _save(tmp_path / "run.csv", {"t": t, "x": x, "F": F})
    gms = _params_file(tmp_path / "gms.json", paper.gms5(), "gms")
    before = _snapshot(data, gms)
    rc, _, err = run(command, data, "--model", "tustin", "--params", gms,
                     "--out" if command == "simulate" else "--json", tmp_path / "o")
    assert rc == 2
    line = _one_line(err, command)
    assert "--model tustin" in line and "GMS model" in line
    assert not (tmp_path / "o").exists()
    _unchanged(before)


def test_the_saved_model_name_is_the_model_of_params(tmp_path, run):
    t, x, F = _signal()
    data = _save(tmp_path / "run.csv", {"t": t, "x": x, "F": F})
    tustin = _params_file(tmp_path / "tustin.json", paper.tustin(), "tustin")
    rc, out, err = run("fit", data, "--params", tustin, "--max-steps", 1, "--json",
                       tmp_path / "fit.json")
    assert rc == 0, err
    saved = json.loads((tmp_path / "fit.json").read_text())
    assert saved["model"] == "tustin" and saved["fitted_model"]["class"] == "Tustin"
    assert "tustin: " in out and "two-state" not in out


def test_params_that_are_binary_are_one_line(tmp_path, run):
    t, x, F = _signal()
    data = _save(tmp_path / "run.csv", {"t": t, "x": x, "F": F})
    npz = _save(tmp_path / "run.npz", {"t": t, "x": x, "F": F})
    for command, out in (("simulate", "--out"), ("fit", "--json")):
        rc, _, err = run(command, data, "--params", npz, out, tmp_path / "o")
        assert rc == 2 and "not a JSON file" in _one_line(err, command)


# ---- 5. Export refuses what a controller should not run -------------------------------

_LUGRE_NAMES = ("Fs", "Fc", "Vs", "delta", "sigma0", "sigma1", "sigma2")


def _fit_json(path: Path, *, converged=True, stderr=None, edit=None) -> Path:
    """A fit result of the paper's LuGre model as `jaxfric fit --json` writes it."""
    model = model_to_dict(paper.lugre())
    for key, value in (edit or {}).items():
        (model["stribeck"] if key in ("Fs", "Fc", "Vs", "delta") else model)[key] = value
    params = {"Fs": 26.1, "Fc": 21.6, "Vs": 0.0031, "delta": 0.6,
              "sigma0": model["sigma0"], "sigma1": model["sigma1"], "sigma2": 54.0}
    params.update(edit or {})
    errors = {k: 0.01 * abs(v) for k, v in params.items()}
    errors.update(stderr or {})
    path.write_text(json.dumps({
        "model": "lugre", "file": "run.csv", "params": params, "stderr": errors,
        "units": {"Fs": "N", "Fc": "N", "Vs": "m/s", "delta": "-", "sigma0": "N/m",
                  "sigma1": "N s/m", "sigma2": "N s/m"},
        "data_units": {"F": "N"}, "rmse": 0.05, "r2": 0.99, "converged": converged,
        "status": "successful" if converged else "nonlinear_max_steps_reached",
        "iterations": 12, "fitted_model": model}))
    return path


@pytest.mark.parametrize(("case", "kwargs", "expected"), [
    ("not converged", {"converged": False},
     "the fit did not converge (status nonlinear_max_steps_reached)"),
    ("undetermined", {"stderr": {"Fc": 5e4}}, "undetermined: Fc = 21.6 +- 5e+04 N"),
    ("no standard error", {"stderr": {"sigma1": None}},
     "undetermined: sigma1 = 4160 N s/m has no defined standard error"),
    ("negative Fs", {"edit": {"Fs": -26.1}}, "non-physical: Fs = -26.1 N (must be > 0)"),
])
@pytest.mark.parametrize("target", ["--c", "--mujoco"])
def test_export_refuses_what_should_not_be_exported_unless_forced(tmp_path, run, case,
                                                                   kwargs, expected, target):
    result = _fit_json(tmp_path / "fit.json", **kwargs)
    before = _snapshot(result)
    out = tmp_path / ("c" if target == "--c" else "axis.xml")
    rc, _, err = run("export", result, target, out)
    assert rc == 2, err
    line = _one_line(err, "export")
    assert "not exported" in line and expected in line and "--force" in line
    assert not out.exists()
    rc, _, err = run("export", result, target, out, "--force")
    assert rc == 0, err
    assert f"exported with --force although {expected}" in err
    text = (out / "jaxfric_model.h" if target == "--c" else out).read_text()
    assert "forced export (export option force) despite: " in text and expected in text
    _unchanged(before)


def test_exported_files_carry_the_fits_status_and_errors(tmp_path, run):
    result = _fit_json(tmp_path / "fit.json")
    rc, _, err = run("export", result, "--c", tmp_path / "c", "--mujoco",
                     tmp_path / "axis.xml")
    assert rc == 0, err
    # MuJoCo's fixed exponent replaces the paper's delta = 0.6: said on stderr, not only
    # in the file.
    assert ("warning: MuJoCo approximates the model: the fitted Stribeck exponent delta = "
            "0.6 is replaced by MuJoCo's fixed exponent 2") in err
    header = (tmp_path / "c" / "jaxfric_model.h").read_text()
    xml = (tmp_path / "axis.xml").read_text()
    for text in (header.split("*/")[0], xml.split("-->")[0]):
        assert ("fit: lugre to run.csv: converged (successful) after 12 steps; RMSE 0.05 N, "
                "R2 0.990000") in text
        for name in _LUGRE_NAMES:
            assert f"{name} = " in text
        assert "Fs = 26.1 +- 0.261 N" in text
    # the header is still valid C: the comment is closed once
    assert header.count("*/") == header.count("/*")


@pytest.mark.parametrize("step", ["-1", "nan", "0"])
def test_export_refuses_a_time_step_that_is_not_a_time(tmp_path, run, step):
    result = _fit_json(tmp_path / "fit.json")
    rc, _, err = run("export", result, "--mujoco", tmp_path / "axis.xml", "--timestep", step)
    assert rc == 2 and "must be a finite time > 0" in _one_line(err, "export")
    assert not (tmp_path / "axis.xml").exists()


def test_a_real_unconverged_fit_is_refused_then_forced(tmp_path, run):
    """The pipeline a user runs: a fit stopped by its step limit, then export."""
    t, x, F = _signal()
    data = _save(tmp_path / "run.csv", {"t": t, "x": x, "F": F})
    fit = tmp_path / "fit.json"
    rc, _, err = run("fit", data, "--model", "lugre", "--max-steps", 0, "--json", fit)
    assert rc == 0 and json.loads(fit.read_text())["converged"] is False
    rc, _, err = run("export", fit, "--mujoco", tmp_path / "axis.xml")
    assert rc == 2 and "the fit did not converge" in _one_line(err, "export")
    rc, _, err = run("export", fit, "--mujoco", tmp_path / "axis.xml", "--force")
    assert rc == 0, err
    assert "NOT converged (nonlinear_max_steps_reached) after 0 steps" in (
        tmp_path / "axis.xml").read_text()


# ---- Minor cases of the issue ---------------------------------------------------------

def test_presliding_only_file_fits_without_a_numpy_warning(tmp_path, run):
    """Strokes of 1 um at one speed: the segments' speeds differ only in their last bits.
    (pytest turns any warning into an error: np.polyfit's RankWarning failed here.)"""
    t = np.linspace(0.0, 20.0, 4001)
    x = 0.5e-6 * (2 * np.abs(2 * ((t / 2.3) % 1) - 1) - 1)
    F = np.asarray(jaxfric.simulate(paper.lugre(), t, x))
    F = F + 0.01 * np.random.default_rng(0).normal(size=t.size)
    data = _save(tmp_path / "pre.csv", {"t": t, "x": x, "F": F})
    rc, _, err = run("fit", data, "--model", "lugre", "--max-steps", 0)
    assert rc == 0, err
    assert "RankWarning" not in err and "polyfit" not in err


def test_a_header_of_millions_of_empty_cells_is_refused(tmp_path, run):
    t, x, F = _signal(50)
    body = "\n".join(f"{float(a)!r},{float(b)!r},{float(c)!r}" for a, b, c in zip(t, x, F))
    path = tmp_path / "wide.csv"
    path.write_text("t,x,F" + "," * 3_000_000 + "\n" + body + "\n")
    rc, _, err = run("simulate", path, "--out", tmp_path / "o.csv")
    assert rc == 2
    assert "the header has 3000003 cells, more than the 1000" in _one_line(err, "simulate")
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("encoding", ["latin-1", "utf-8"])
def test_a_micrometre_header_is_read_in_latin1_and_utf8(tmp_path, run, encoding):
    t, x, F = _signal(50)
    body = "\n".join(f"{float(a)!r},{float(1e6 * b)!r},{float(c)!r}"
                     for a, b, c in zip(t, x, F))
    path = tmp_path / "um.csv"
    path.write_bytes(("t,x[µm],F\n" + body + "\n").encode(encoding))
    before = _snapshot(path)
    rc, out, err = run("simulate", path, "--out", tmp_path / "o.csv")
    assert rc == 0, err
    assert "x converted from µm to m" in out
    written = np.loadtxt(tmp_path / "o.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(written[:, 1], x, rtol=1e-12)
    _unchanged(before)
