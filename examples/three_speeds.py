"""A joint recorded at three speeds, one run with a disturbance of its own: held-out runs
tell a physical effect from a property of one run.

The truth (simulated, rotary, N m and rad): Tustin friction (`jaxfric.paper.tustin`'s
values) plus a position ripple of the joint (`cogging`, 1 N m, period 0.3 rad) in every
run; the same back-and-forth trajectory (1 rad amplitude) at periods of 8, 4 and 2 s,
sampled every 5 ms with 0.1 N m of noise. Only the fast run carries a gravity-compensation
error (`angle_load`, 2 N m cos q): a property of that run, not of the joint.

Each run is held out in turn; the model is fitted to the other two (`fitting.fit_datasets`,
what ``jaxfric fit run1.csv run2.csv --validate run3.csv`` does) with and without each
effect, and predicts the held-out run. An effect worth adding lowers the error of every
held-out run; one that does not is a property of the runs it was fitted on. (The effects'
nonlinear parameters start at the truth's period here; the diagnosis searches them.)
Then `fitting.diagnose` gets the three runs and decides the same way by itself (leave one
run out): it must add the cogging and not the angle load.

Writes ``docs/figures/three_speeds.json`` and prints the tables; run from the repository
root: ``python examples/three_speeds.py``.
"""

import json
from pathlib import Path

import numpy as np

import fitting
import jaxfric
from jaxfric import effects, paper


ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "figures" / "three_speeds.json"
PERIODS = {"slow": 8.0, "mid": 4.0, "fast": 2.0}  # s per back-and-forth cycle
RIPPLE = effects.Cogging(cog_sin=0.6, cog_cos=0.8, period=0.3)  # of the joint: every run
DISTURBANCE = effects.AngleLoad(g_cos=2.0)  # of the fast run only
NOISE = 0.1  # N m


def runs(dt: float = 5e-3, cycles: int = 4) -> dict[str, fitting.Dataset]:
    out = {}
    for i, (name, period) in enumerate(PERIODS.items()):
        t = np.arange(0.0, cycles * period, dt)
        phase = 2 * np.pi * t / period
        x = np.sin(phase) + 0.1 * np.sin(3 * phase)  # rad
        v = 2 * np.pi / period * (np.cos(phase) + 0.3 * np.cos(3 * phase))  # rad/s, measured
        truth = paper.tustin() + RIPPLE + ((DISTURBANCE,) if name == "fast" else ())
        F = np.asarray(jaxfric.simulate(truth, t, x, v))
        F = F + NOISE * np.random.default_rng(i).normal(size=t.size)
        out[name] = fitting.Dataset(t=t, x=x, F=F, v=v)
    return out


MODELS = {
    "Tustin": (),
    "+ cogging": (effects.Cogging(period=0.3),),
    "+ cogging + angle_load": (effects.Cogging(period=0.3), effects.AngleLoad()),
}


def held_out_errors(data: dict) -> dict:
    """``{model: {held-out run: RMSE}}`` (N m), each fitted to the two other runs."""
    table = {}
    for label, extra in MODELS.items():
        table[label] = {}
        for held, d in data.items():
            fitted = [r for name, r in data.items() if name != held]
            start = fitting.initial_model("tustin", fitted[0].t, fitted[0].x, fitted[0].F,
                                          fitted[0].v)
            res = fitting.fit_datasets(start + extra if extra else start, fitted)
            pred = np.asarray(jaxfric.simulate(fitting.run_model(res.fit_model, None),
                                               d.t, d.x, d.v))
            table[label][held] = float(np.sqrt(np.mean((pred - d.F) ** 2)))
    return table


def diagnosis_of(data: dict, log=None) -> fitting.Diagnosis:
    """The diagnosis of all runs together (leave one run out), from a Tustin model: what
    ``jaxfric diagnose slow.csv mid.csv fast.csv --model tustin`` does."""
    first = next(iter(data.values()))
    start = fitting.initial_model("tustin", first.t, first.x, first.F, first.v)
    return fitting.diagnose(start, list(data.values()), rotary=True, run_names=list(data),
                            model_name="tustin", log=log)


def main() -> None:
    data = runs()
    table = held_out_errors(data)
    print(f"{'model':<26}" + "".join(f"{'held out: ' + n:>18}" for n in PERIODS))
    for label, row in table.items():
        print(f"{label:<26}" + "".join(f"{row[n]:>18.4g}" for n in PERIODS))
    d = diagnosis_of(data)
    print(d.summary())
    OUT.write_text(json.dumps({"unit": "N m", "noise": NOISE, "held_out_rmse": table,
                               "diagnosis": {"folds": d.folds, "added": d.final.added,
                                             "runs": d.runs,
                                             "candidates": [c.to_json()
                                                            for c in d.candidates],
                                             "trials": d.trials}},
                              indent=2) + "\n")
    print(f"written to {OUT.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
