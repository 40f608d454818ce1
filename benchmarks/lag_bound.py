"""Should a fit bound the lag to the motion? The measurement behind the diagnosis's choice
to flag a long lag rather than forbid it (issue 22, item 6).

    python benchmarks/lag_bound.py [--json OUT.json]

`fitting._plausibility` warns when a fitted lag time exceeds half a long stroke's duration:
the lag state can then take up slow effects (a warm-up drift). A bound would keep it from
doing so, at the price of forbidding a slow lag that is real. This script fits the
two-state model to diagnosis-bench files (`jaxfric.synthetic.measurement`, 10 ms, 0.03
N; three truths, the warm-up drift file and its clean twin: same motion and noise) twice,
on the diagnosis's training blocks: **free**, and **bounded** (``C`` held above
``level / (0.5 * T)``, so that the lag time ``|s(v)|/C`` stays under half the long
stroke's duration ``T``; ``level`` the median sliding force). It prints, per file, the
held-out RMSE (N) and the fitted lag's time constant ``|s(v)|/C`` at the median sliding
speed, and writes JSON.

What would justify a bound: on the clean files it costs little, and on the drift files the
bounded base leaves the drift visible (a larger excess over its clean twin) where the free
one absorbs it.
"""

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import equinox as eqx
import jax
import numpy as np

import fitting
from fitting import _params
from fitting._plausibility import _sliding_speeds, _strokes
from fitting._regimes import holdout_mask
from fitting._transforms import Exp, ParamProps
from jaxfric.synthetic import measurement, TRUTHS


HERE = Path(__file__).resolve().parent


def bounded_props(model, C_min: float):
    """Default properties with ``C`` above `C_min` (N/s)."""
    fit_model = _params.to_fit_representation(model)
    props = _params.default_props(fit_model)
    names = _params.leaf_names(fit_model)
    leaves = [ParamProps(Exp(lower=C_min), free=p.free) if n == "C" else p
              for p, n in zip(_params.props_leaves(props), names)]
    return jax.tree.unflatten(jax.tree.structure(props, is_leaf=_params._is_props), leaves)


def one(truth: str, hidden: tuple, seed: int) -> dict:
    t, x, F = measurement(truth, hidden, 0.03, 1e-2, seed)
    v = fitting.estimate_velocity(t, x)
    a = fitting.estimate_acceleration(t, v)
    test, _ = holdout_mask(t)
    w = (~test).astype(float)
    # In the fit representation, as the diagnosis fits (a restart from a PaperShape can be
    # singular for a nearly straight shape).
    start = fitting.to_fit_representation(fitting.initial_model("two-state", t, x, F, v))
    _, stroke_time = _strokes(t, x, v)
    _, mid, _ = _sliding_speeds(v)
    level = float(np.median(np.abs(F[np.abs(v) >= mid])))
    C_min = level / (0.5 * stroke_time)
    row = {"truth": truth, "hidden": list(hidden), "stroke_s": stroke_time, "C_min": C_min}
    for name, props in (("free", None), ("bounded", bounded_props(start, C_min))):
        s = start
        if props is not None and float(s.C) <= C_min:
            s = eqx.tree_at(lambda m: m.C, s, 2.0 * C_min)
        res = fitting.fit(s, t, x, F, v, weights=w, max_steps=300, props=props, a=a)
        for _ in range(3):  # warm restarts while the fit stops at its step limit
            if bool(res.converged):
                break
            res = fitting.fit(res.model, t, x, F, v, weights=w, max_steps=300, props=props,
                              a=a)
        err = np.asarray(res.prediction) - F
        row[name] = {"rmse_holdout": float(np.sqrt(np.mean(err[test] ** 2))),
                     "C": float(res.model.C),
                     # the lag's time constant |s(v)|/C at the median sliding speed
                     "tau_s": abs(float(res.model.stribeck(np.asarray(mid)))) / float(res.model.C)}
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", default=str(HERE / "lag_bound.json"))
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rows = []
    print("| truth | file | long stroke (s) | free: held-out RMSE, lag | bounded: held-out "
          "RMSE, lag |\n|---|---|---|---|---|")
    for truth in TRUTHS:
        for hidden in ((), ("drift",)):
            r = one(truth, hidden, 5)  # the bench's drift file and its clean twin
            rows.append(r)
            f, b = r["free"], r["bounded"]
            print(f"| {truth} | {' + '.join(hidden) or 'clean'} | {r['stroke_s']:.3g} | "
                  f"{f['rmse_holdout']:.3f} N, {f['tau_s']:.3g} s | "
                  f"{b['rmse_holdout']:.3f} N, {b['tau_s']:.3g} s |", flush=True)
    out = {"machine": {"platform": platform.platform(), "python": sys.version.split()[0]},
           "seconds": time.perf_counter() - t0, "files": rows}
    Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    print(f"\nwrote {args.json} ({out['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
