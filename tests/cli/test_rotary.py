"""Rotary joints end to end (issue 18, item 1): a joint log in rad / N m and the same log in
deg go through ``fit``, ``compare``, ``diagnose`` and ``simulate`` without unit hacks, give
the same fit to rounding, and no output speaks of mm or of N alone. The commands run in one
subprocess to import JAX once."""

import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

import jaxfric
from jaxfric import data, paper


_RUNNER = r"""
import contextlib, io, json, sys, traceback
from fitting.cli.main import main
out = {}
for name, argv in json.loads(sys.argv[1]).items():
    so, se = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(so), contextlib.redirect_stderr(se):
        try:
            rc = main(argv)
        except BaseException:
            traceback.print_exc()
            rc = "traceback"
    out[name] = {"rc": rc, "stdout": so.getvalue(), "stderr": se.getvalue()}
print(json.dumps(out))
"""


def _joint(n=1500, rate=500.0, seed=0):
    """A joint log: angle (rad), velocity (rad/s), friction torque (N m) at 500 Hz."""
    t = np.arange(n) / rate
    x = 0.5 * np.sin(2 * np.pi * t / 2.0) + 0.02 * np.sin(2 * np.pi * t / 0.37)
    v = np.gradient(x, t)
    F = 0.1 * np.asarray(jaxfric.simulate(paper.tustin(), t, x, v))
    F = F + 0.02 * np.random.default_rng(seed).normal(size=n)
    return t, x, v, F


def _write(path, header, cols):
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=header, comments="",
               fmt="%.17g")
    return path


def _files(tmp):
    t, x, v, F = _joint()
    _, x2, v2, F2 = _joint(seed=1)
    x2, v2, F2 = 2 * x2, 2 * v2, F2 / 20  # a wrist: twice the swing, a twentieth the torque
    _write(tmp / "robot.csv", "t[s],q1[rad],dq1[rad/s],tau1[N m],q2[deg],dq2[deg/s],tau2[mNm]",
           (t, x, v, F, np.degrees(x2), np.degrees(v2), F2 * 1e3))
    _write(tmp / "wrist.csv", "t[s],x[rad],v[rad/s],F[N m]", (t, x2, v2, F2))
    return (_write(tmp / "joint_rad.csv", "t[s],x[rad],v[rad/s],F[N m]", (t, x, v, F)),
            _write(tmp / "joint_deg.csv", "t[s],x[deg],v[deg/s],F[N*m]",
                   (t, np.degrees(x), np.degrees(v), F)),
            _write(tmp / "joint_bare.csv", "t,x,v,F", (t, x, v, F)),
            _write(tmp / "slide.csv", "t[s],x[m],F[N]", (t, x / 10, F)))


def _run(cases):
    r = subprocess.run([sys.executable, "-c", _RUNNER, json.dumps(cases)], capture_output=True,
                       text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def _json(path):
    with open(path) as f:
        return json.load(f)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """fit (rad, deg, no units with --rotary) and simulate."""
    tmp = tmp_path_factory.mktemp("rotary")
    rad, deg, bare, slide = _files(tmp)
    out = {k: str(tmp / k) for k in ("fit_rad.json", "fit_deg.json", "sim.csv", "fit.png",
                                     "robot.json", "wrist.json", "robot_sim.csv")}
    return _run({
        "fit_robot": ["fit", str(tmp / "robot.csv"), "--model", "tustin", "--json",
                      out["robot.json"]],
        "fit_wrist": ["fit", str(tmp / "wrist.csv"), "--model", "tustin", "--json",
                      out["wrist.json"]],
        "simulate_robot": ["simulate", str(tmp / "robot.csv"), "--params", out["robot.json"],
                           "--out", str(tmp / "robot_sim.csv")],
        "fit_rad": ["fit", str(rad), "--model", "tustin", "--json", out["fit_rad.json"],
                    "--plot", out["fit.png"]],
        "fit_deg": ["fit", str(deg), "--model", "tustin", "--json", out["fit_deg.json"]],
        "fit_bare": ["fit", str(bare), "--model", "tustin", "--rotary"],
        "simulate": ["simulate", str(deg), "--params", out["fit_rad.json"], "--out",
                     out["sim.csv"]],
        "simulate_linear": ["simulate", str(slide), "--params", out["fit_rad.json"], "--out",
                            str(tmp / "never.csv")],
    }), out


@pytest.fixture(scope="module")
def slow_runs(tmp_path_factory):
    """compare and diagnose (with their report)."""
    tmp = tmp_path_factory.mktemp("rotary_slow")
    rad, deg, _, _ = _files(tmp)
    out = {k: str(tmp / k) for k in ("cmp.json", "diag.json", "report", "robot_diag.json",
                                     "robot_report", "robot_cmp.json")}
    return _run({
        "compare_robot": ["compare", str(tmp / "robot.csv"), "--models", "tustin",
                          "--max-steps", "10", "--json", out["robot_cmp.json"]],
        "diagnose_robot": ["diagnose", str(tmp / "robot.csv"), "--model", "tustin",
                           "--max-steps", "10", "--json", out["robot_diag.json"],
                           "--report", out["robot_report"]],
        "compare": ["compare", str(rad), "--models", "tustin,lugre", "--max-steps", "15",
                    "--json", out["cmp.json"]],
        "diagnose": ["diagnose", str(deg), "--model", "tustin", "--max-steps", "10",
                     "--json", out["diag.json"], "--report", out["report"]],
    }), out


def _linear_words(text: str) -> list[str]:
    """Places where `text` speaks of mm or of N alone (N m, mN m are torques)."""
    clean = re.sub(r"N m\b", "", text)
    return [clean[max(0, m.start() - 30):m.end() + 10]
            for m in re.finditer(r"\bN\b|\bmm\b|\bmm/s|\[N\]|\bum\b|µm", clean)]


def _texts(res, out, files):
    texts = {f"{name} output": r["stdout"] + r["stderr"] for name, r in res.items()
             if name != "simulate_linear"}
    for key in files:
        texts[key] = json.dumps({k: v for k, v in _json(out[key]).items()
                                 if k != "fitted_model"})
    return texts


def test_fit_and_simulate_run_and_speak_rotary(runs):
    res, out = runs
    for name, r in res.items():
        if name != "simulate_linear":
            assert r["rc"] == 0, (name, r["stderr"])
    for what, text in _texts(res, out, ("fit_rad.json", "fit_deg.json", "robot.json")).items():
        assert _linear_words(text) == [], what
    said = res["fit_rad"]["stdout"]
    assert "N m s/rad" in said and "rad/s" in said
    span = np.ptp(_joint()[1])
    assert f"travel {span:.4g} rad ({np.degrees(span):.4g} deg)" in said


@pytest.mark.slow
def test_compare_and_diagnose_speak_rotary(slow_runs):
    res, out = slow_runs
    for name, r in res.items():
        assert r["rc"] == 0, (name, r["stderr"])
    texts = _texts(res, out, ("cmp.json", "diag.json", "robot_diag.json", "robot_cmp.json"))
    with open(f"{out['report']}/report.html") as f:
        texts["report.html"] = f.read()
    for what, text in texts.items():
        assert _linear_words(text) == [], what
    d = _json(out["diag.json"])
    assert d["kind"] == "rotary" and d["data_units"]["F"] == "N m"
    assert any("rad/s" in name for name in d["baseline"]["regimes"])
    assert "N m]" in texts["report.html"]


def test_rad_and_deg_give_the_same_fit(runs):
    _, out = runs
    a, b = (_json(out[k]) for k in ("fit_rad.json", "fit_deg.json"))
    assert a["kind"] == b["kind"] == "rotary"
    assert a["data_units"]["F"] == "N m" and a["data_units"]["x"] == "rad"
    assert a["units"] == b["units"] and a["units"]["Fc"] == "N m"
    assert a["units"]["sigma2"] == "N m s/rad" and a["units"]["Vs"] == "rad/s"
    for name, value in a["params"].items():
        assert math.isclose(value, b["params"][name], rel_tol=1e-9), name
    assert math.isclose(a["rmse"], b["rmse"], rel_tol=1e-9)


def test_a_file_without_units_is_rotary_by_flag(runs):
    res, _ = runs
    assert "rotary, 1500 samples" in res["fit_bare"]["stdout"]
    assert "N m s/rad" in res["fit_bare"]["stdout"]


def test_simulate_speaks_rotary_and_refuses_a_kind_mismatch(runs):
    res, out = runs
    with open(out["sim.csv"]) as f:
        assert f.readline().strip() == "t[s],x[rad],v[rad/s],F_model[N m],F[N m]"
    sim = data.load(out["sim.csv"], require_force=False)
    assert sim.kind == "rotary"
    fit = _json(out["fit_rad.json"])
    rmse = float(np.sqrt(np.mean((sim.extra["F_model"] - sim.F) ** 2)))
    assert math.isclose(rmse, fit["rmse"], rel_tol=1e-6)  # deg file, rad fit: same model
    r = res["simulate_linear"]
    assert r["rc"] == 2 and "fitted to rotary data" in r["stderr"]
    assert len(r["stderr"].strip().splitlines()) == 1


def test_measurement_records_its_kind(tmp_path):
    t, x, _, F = _joint(200)
    m = data.load(_write(tmp_path / "j.csv", "t,x[mrad],F[mNm]", (t, x * 1e3, F * 1e3)))
    assert m.kind == "rotary" and "rotary" in repr(m)
    np.testing.assert_allclose(m.x, x, rtol=1e-15)
    np.testing.assert_allclose(m.F, F, rtol=1e-15)
    assert m.notes == ("x converted from mrad to rad", "F converted from mNm to N m")
    assert data.load({"t": t, "x": x / 10, "F": F}).kind == "linear"


# ---- several joints in one file (issue 18, item 3) ------------------------------------


def test_several_joints_are_fitted_each_as_if_alone(runs):
    res, out = runs
    robot = _json(out["robot.json"])
    assert list(robot["joints"]) == ["joint 1", "joint 2"] and robot["kind"] == "rotary"
    alone = {"joint 1": _json(out["fit_rad.json"]), "joint 2": _json(out["wrist.json"])}
    for name, single in alone.items():
        joint = robot["joints"][name]
        assert joint["units"] == single["units"]
        for p, value in single["params"].items():
            assert math.isclose(joint["params"][p], value, rel_tol=1e-9), (name, p)
    said = res["fit_robot"]["stdout"]
    assert "tustin per joint:" in said and "=== joint 2 ===" in said
    table = said.split("tustin per joint:")[1].splitlines()
    assert "N m s/rad" in table[2] and table[3].startswith("joint 1")
    assert table[4].startswith("joint 2")


def test_several_joints_are_simulated_each_with_its_model(runs):
    res, out = runs
    assert res["simulate_robot"]["rc"] == 0, res["simulate_robot"]["stderr"]
    with open(out["robot_sim.csv"]) as f:
        header = f.readline().strip()
    assert header == ("t[s],x1[rad],v1[rad/s],F_model1[N m],F1[N m],"
                      "x2[rad],v2[rad/s],F_model2[N m],F2[N m]")
    sim = np.loadtxt(out["robot_sim.csv"], delimiter=",", skiprows=1)
    fits = _json(out["robot.json"])["joints"]
    for i, name in ((1, "joint 1"), (2, "joint 2")):
        rmse = float(np.sqrt(np.mean((sim[:, 4 * i - 1] - sim[:, 4 * i]) ** 2)))
        assert math.isclose(rmse, fits[name]["rmse"], rel_tol=1e-6), name


@pytest.mark.slow
def test_several_joints_are_diagnosed(slow_runs):
    res, out = slow_runs
    d = _json(out["robot_diag.json"])
    assert list(d["joints"]) == ["joint 1", "joint 2"]
    assert all(j["kind"] == "rotary" for j in d["joints"].values())
    assert "diagnosis per joint (RMSE in N m)" in res["diagnose_robot"]["stdout"]
    with open(f"{out['robot_report']}/joint_2/report.html") as f:
        assert "N m" in f.read()
    cmp = _json(out["robot_cmp.json"])
    assert list(cmp["joints"]) == ["joint 1", "joint 2"]
    assert cmp["joints"]["joint 2"]["tustin"]["units"]["sigma2"] == "N m s/rad"


def test_load_joints_layouts_and_units():
    t, x, v, F = _joint(300)
    wide = data.load_joints({"t": t, "q1": x, "dq1": v, "tau1": F, "q2": 2 * x,
                             "tau2[mNm]": F * 1e3, "temperature": np.ones(300)},
                            units={"q": "rad"})
    assert list(wide) == ["joint 1", "joint 2"]
    assert all(m.kind == "rotary" for m in wide.values())  # robot names
    np.testing.assert_allclose(wide["joint 2"].F, F, rtol=1e-15)
    np.testing.assert_array_equal(wide["joint 2"].x, 2 * x)
    assert wide["joint 2"].v is None and "temperature" in wide["joint 1"].extra
    deg = data.load_joints({"t": t, "q1": np.degrees(x), "tau1": F, "q2[rad]": x, "tau2": F},
                           units={"q1": "deg"})
    np.testing.assert_allclose(deg["joint 1"].x, x, rtol=1e-14)
    linear = data.load_joints({"t": t, "x1": x / 100, "F1": F, "x2": x / 50, "F2": F})
    assert all(m.kind == "linear" for m in linear.values())
    long = data.load_joints({"t": np.r_[t, t], "joint": np.r_[np.full(300, 3), np.full(300, 7)],
                             "x[deg]": np.r_[x, 2 * x], "F[N m]": np.r_[F, F]})
    assert list(long) == ["joint 3", "joint 7"]
    np.testing.assert_allclose(long["joint 7"].x, np.radians(2 * x), rtol=1e-15)
    with pytest.raises(data.DataError, match=r"holds several joints.*load_joints"):
        data.load({"t": t, "q1": x, "tau1": F})
    with pytest.raises(data.DataError, match="one joint only"):
        data.load_joints({"t": t, "x": x, "F": F})


def test_one_joint_with_robot_names(tmp_path):
    t, x, v, F = _joint(300)
    path = _write(tmp_path / "j.csv", "time,q[deg],dq,tau", (t, np.degrees(x), v, F))
    m = data.load(path)
    assert m.kind == "rotary"  # the robot names say so
    np.testing.assert_allclose(m.x, x, rtol=1e-14)
    np.testing.assert_array_equal(m.v, v)
    np.testing.assert_array_equal(m.F, F)
    assert "column 'q' read as 'x'" in m.notes and "column 'time' read as 't'" in m.notes
    both = data.load({"t": t, "x": x / 10, "F": F, "tau": 2 * F})  # F present: tau is extra
    assert both.kind == "linear" and "tau" in both.extra


def test_joints_are_simulated_with_the_derivatives_each_was_fitted_with(tmp_path):
    """A joint log without velocity columns fitted with ``--derivatives savgol``: each
    joint's result records it, and ``simulate --params`` takes the same estimate (its RMSE
    is the fit's), unless told otherwise (central differences: another force)."""
    t, x, _, F = _joint()
    _, x2, _, F2 = _joint(seed=1)
    robot = _write(tmp_path / "robot.csv", "t[s],q1[rad],tau1[N m],q2[rad],tau2[N m]",
                   (t, x, F, 2 * x2, F2 / 20))
    fit, sim, other = (str(tmp_path / k) for k in ("fit.json", "sim.csv", "central.csv"))
    res = _run({
        "fit": ["fit", str(robot), "--model", "tustin", "--derivatives", "savgol", "--json",
                fit],
        "simulate": ["simulate", str(robot), "--params", fit, "--out", sim],
        "central": ["simulate", str(robot), "--params", fit, "--derivatives", "central",
                    "--out", other],
    })
    for name, r in res.items():
        assert r["rc"] == 0, (name, r["stderr"])
    joints = _json(fit)["joints"]
    for i, name in ((1, "joint 1"), (2, "joint 2")):
        assert joints[name]["derivatives"] == {"method": "savgol", "window_s": None}
        assert "Savitzky-Golay" in joints[name]["velocity"]
        same, central = (np.loadtxt(p, delimiter=",", skiprows=1) for p in (sim, other))
        rmse = float(np.sqrt(np.mean((same[:, 4 * i - 1] - same[:, 4 * i]) ** 2)))
        assert math.isclose(rmse, joints[name]["rmse"], rel_tol=1e-9), name
        moved = float(np.sqrt(np.mean((central[:, 4 * i - 1] - central[:, 4 * i]) ** 2)))
        assert not math.isclose(moved, rmse, rel_tol=1e-6), name
