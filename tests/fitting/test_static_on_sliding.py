"""A static model (`jaxfric.Tustin`) is fitted on the steady sliding samples in
``jaxfric compare`` (it cannot represent presliding), and the table and JSON say so."""

import json
import os
import subprocess
import sys

import numpy as np

import jaxfric
from jaxfric.synthetic import truth
from jaxfric.trajectories import FAMILIES


def test_compare_fits_tustin_on_steady_sliding_and_says_so(tmp_path):
    t = np.arange(0.0, 30.0, 1e-2)
    x = FAMILIES["point_to_point"](t)
    model = truth("lugre")  # presliding over about 30 um after every reversal
    F = np.asarray(jaxfric.simulate(model, t, x, np.gradient(x, t)))
    F = F + 0.03 * np.random.default_rng(0).standard_normal(t.size)
    path = tmp_path / "moves.csv"
    np.savetxt(path, np.column_stack([t, x, F]), delimiter=",", header="t,x,F", comments="")
    r = subprocess.run([sys.executable, "-m", "fitting.cli", "compare", str(path), "--models",
                        "tustin", "--json", str(tmp_path / "c.json")],
                       capture_output=True, text=True, timeout=600, env=os.environ.copy())
    assert r.returncode == 0, r.stderr
    res = json.loads((tmp_path / "c.json").read_text())["models"]["tustin"]
    n = int(res["fitted_on"].split()[0])
    assert res["fitted_on"] == f"{n} steady sliding samples" and 0 < n < t.size
    assert f"tustin to its {n} steady sliding samples" in r.stdout
    # "rmse" is the whole file's, as in the regimes' "all"; the fit's own is beside it
    assert res["rmse"] == res["regimes"]["all"]["rmse"]
    assert res["rmse_fitted_samples"] < 0.05  # the noise (0.03 N) on steady sliding
    fitted = jaxfric.Tustin(
        stribeck=jaxfric.Stribeck(**{k: res["params"][k] for k in ("Fs", "Fc", "Vs", "delta")}),
        sigma2=res["params"]["sigma2"])
    speed = np.geomspace(5e-3, 1.8e-2, 8)  # the moves' cruise speeds

    def steady(m):
        return np.asarray(m.stribeck.magnitude(speed)) + float(m.sigma2) * speed

    assert np.max(np.abs(steady(fitted) - steady(model))) < 0.005 * float(model.stribeck.Fs)
