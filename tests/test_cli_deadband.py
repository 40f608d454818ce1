"""`jaxfric simulate --stack-size/--deadband`: memory overflow on noisy standstill is
reported with what to do, and the deadband ('auto': estimated from the positions) removes
it."""

import numpy as np

from .test_cli import run
from .test_direction import standstill_motion


def test_simulate_reports_overflow_and_deadband_removes_it(tmp_path):
    t, x, _ = standstill_motion(11)
    t, x = t[:4000], x[:4000]
    data = tmp_path / "joint.csv"
    np.savetxt(data, np.column_stack([t, x]), delimiter=",", header="t[s],x[m]",
               comments="", fmt="%.17g")
    out = tmp_path / "sim.csv"
    raw = run("simulate", data, "--stack-size", 4, "--out", out)
    assert raw.returncode == 0, raw.stderr
    assert "overflowed" in raw.stderr and "--stack-size" in raw.stderr
    played = run("simulate", data, "--stack-size", 4, "--deadband", "auto", "--out", out)
    assert played.returncode == 0, played.stderr
    assert "overflowed" not in played.stderr
    assert "deadband: auto" in played.stdout
    bad = run("simulate", data, "--deadband", "wide", "--out", out)
    assert bad.returncode != 0 and "--deadband" in bad.stderr
    small = run("simulate", data, "--stack-size", 0, "--out", out)
    assert small.returncode != 0 and "--stack-size" in small.stderr
