"""The computation behind ``jaxfric demo``: the whole story on built-in example data.

1. The package makes a measurement (`example_measurement`): the `diagnosis_motion`
   excitation through a "stage" whose friction is a two-state model with a different
   presliding shape family (`PowerShape`) and Stribeck curve than the model that will be
   fitted, plus a hidden cogging force (0.67 N, period 1.7 mm). The stage runs on a grid
   ten times finer than the sampling (with its exact velocity), and the file holds what a
   sensor records every 20 ms: the position quantised to a 0.1 um encoder and the force
   with 0.05 N of noise, no velocity. Seeded: the same data on every machine.
2. A two-state model with the paper's shape family, starting from values estimated from the
   data, is fitted; the diagnosis refits it with each candidate effect and adds those that
   blocked cross-validation supports (`fitting.diagnose`).
3. The report: ``report.html`` with the figures, the error per regime before and after,
   the candidates with their evidence, and the parameters with units and standard errors;
   plus ``diagnosis.json``, ``summary.json`` and the measurement as ``example.csv``.
"""

import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

import jaxfric
from jaxfric import effects as fx
from jaxfric.examples import diagnosis_motion, diagnosis_truth

from .._derivatives import estimate_velocity
from ._output import atomic_file, output_folder, write_json


NOISE_N = 0.05
HIDDEN = "cogging"


#: The stage is simulated on a grid this many times finer than the sampling.
FINE = 10
#: Encoder resolution (m per count).
ENCODER = 0.1e-6


def example_measurement(seed: int = 0, dt: float = 2e-2):
    """``(t, x, F, truth)`` in s, m, N: see the module docstring."""
    t_fine, x_fine = diagnosis_motion(dt=dt / FINE, seed=seed)
    stage = diagnosis_truth()  # PowerShape presliding, Stribeck 24/19 N, sigma2 50, C 9
    truth = stage + fx.Cogging(cog_sin=0.6, cog_cos=0.3, period=1.7e-3)
    force = np.asarray(jaxfric.simulate(truth, t_fine, x_fine, np.gradient(x_fine, t_fine)))
    t, x = t_fine[::FINE], np.round(x_fine[::FINE] / ENCODER) * ENCODER
    rng = np.random.default_rng(seed)
    F = force[::FINE] + rng.normal(0.0, NOISE_N, t.size)
    return t, x, F, truth


def run(out: Path, log=print) -> dict:
    """The demo into the folder `out` (made if need be); returns the summary."""
    t0 = time.perf_counter()
    # A folder made here is removed again if the demo does not finish (Ctrl-C, an error).
    with output_folder(out):
        return _run(out, t0, log)


def _run(out: Path, t0: float, log) -> dict:
    from .. import diagnose, initial_model
    from .report import write_report

    t, x, F, _ = example_measurement()
    with atomic_file(out / "example.csv") as f:
        np.savetxt(f, np.column_stack([t, x, F]), delimiter=",", header="t[s],x[m],F[N]",
                   comments="", fmt="%.10g")
    log(f"example measurement: {t.size} samples over {t[-1]:.0f} s, travel "
        f"{np.ptp(x) * 1e3:.1f} mm, noise {NOISE_N} N, one hidden effect "
        f"(written to {out / 'example.csv'})")
    start = initial_model("two-state", t, x, F)
    log("fitting the two-state model and diagnosing what it misses "
        "(the first fit includes compilation) ...")
    d = diagnose(start, t, x, F, model_name="two-state", log=log)
    log("")
    log(d.summary())
    m = SimpleNamespace(t=t, x=x, F=F, velocity=lambda: estimate_velocity(t, x))
    page = write_report(
        out, m, d, title="jaxfric demo: find the missing effect",
        intro=(f"Built-in example data ({t.size} samples): the friction of a simulated stage "
               "(a two-state model with another presliding shape and Stribeck curve than the "
               "fitted one) plus one hidden effect, sampled as a sensor would (a 0.1 um encoder, "
               f"{NOISE_N} N of noise, no velocity: the diagnosis takes a central difference). "
               "The hidden effect "
               f"was <b>{HIDDEN}</b>: 0.67 N, period 1.7 mm."),
    )
    found = d.final.added
    summary = {
        "samples": int(t.size),
        "noise_N": NOISE_N,
        "hidden_effect": HIDDEN,
        "found": found,
        "baseline_rmse_N": d.baseline.rmse,
        "final_rmse_N": d.final.rmse,
        "seconds": time.perf_counter() - t0,
        "report": str(page),
        "diagnosis": d.to_json(),
    }
    write_json(out / "summary.json", summary)
    verdict = "found" if found and found[0] == HIDDEN else "NOT found"
    log(f"\nhidden effect ({HIDDEN}) {verdict}; RMSE {d.baseline.rmse:.3f} N -> "
        f"{d.final.rmse:.3f} N (noise {NOISE_N} N)")
    return summary
