"""Steps and time per fit, side by side: ``optimistix`` (``optx.LevenbergMarquardt`` with
MINPACK's trust-region update, whose Jacobian is a linearised simulation run again for each
use), ``plain`` (`fitting.geodesic_solver(accelerate=False)`: the same steps, its Jacobian
materialised once per accepted point) and ``geodesic`` (`fitting.default_solver`: plus
geodesic acceleration, one more simulation per step).

The cells are those of `benchmarks/fit_speed.py` (same data, truths and starts). In one
process, per cell, the two solvers are run alternately, `--repeats` times each (the first
fit of each also compiles and is left out of the timing); the table gives each solver's
steps and the median CPU time (``time.process_time``, less sensitive to other processes on
a shared machine than the wall clock) of its warm fits, and the ratio geodesic/optimistix.

    python benchmarks/geodesic_steps.py [--models two-state tustin] [--motions mixed strokes]
                                        [--sizes 100000] [--repeats 3] [--json OUT]

Writes benchmarks/geodesic_steps.json unless ``--json`` says otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import equinox as eqx
import numpy as np
import optimistix as optx

import fitting
from fitting import _solve


try:
    from benchmarks import fit_speed as fs
except ImportError:  # run as a script: benchmarks/ itself is sys.path[0]
    import fit_speed as fs


def optimistix_solver():
    """``optx.LevenbergMarquardt`` with the trust-region update of `fitting.default_solver`."""
    return eqx.tree_at(lambda s: s.search, optx.LevenbergMarquardt(rtol=1e-6, atol=1e-6),
                       _solve._search())


SOLVERS = {"optimistix": optimistix_solver,
           "plain": lambda: fitting.geodesic_solver(accelerate=False),
           "geodesic": fitting.default_solver}


def cell(model: str, motion: str, n: int, repeats: int) -> dict:
    t, x, F = fs.make_data(n, motion, model)
    truth = fs.MODELS[model]()
    start = (fs.start_model(fs.start_factors()) if model == "two-state"
             else fs.other_start(truth, fs.SEED + len(model)))
    runs: dict[str, list] = {name: [] for name in SOLVERS}
    for _ in range(repeats + 1):
        for name, make in SOLVERS.items():
            tick = time.process_time()
            res = fitting.fit(start, t, x, F, solver=make())
            rmse = float(res.rmse)  # blocks until done
            runs[name].append((time.process_time() - tick, int(res.num_steps), rmse,
                               res.status))
    out = {"model": model, "motion": motion, "n": n}
    for name, r in runs.items():
        warm = [c for c, *_ in r[1:]]
        out[name] = {"steps": r[-1][1], "cpu_s": float(np.median(warm)), "rmse": r[-1][2],
                     "status": r[-1][3]}
    out["cpu_ratio"] = out["geodesic"]["cpu_s"] / out["optimistix"]["cpu_s"]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", default=list(fs.MODELS), choices=list(fs.MODELS))
    ap.add_argument("--motions", nargs="+", default=list(fs.MOTIONS),
                    choices=list(fs.MOTIONS))
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", metavar="OUT",
                    default=str(Path(__file__).with_name("geodesic_steps.json")))
    args = ap.parse_args(argv)
    head = ("model | motion | n | optimistix steps | plain steps | geodesic steps | "
            "optimistix CPU s | plain CPU s | geodesic CPU s | ratio")
    print(head, flush=True)
    cells = []
    for model in args.models:
        for n in args.sizes:
            for motion in args.motions:
                c = cell(model, motion, n, args.repeats)
                cells.append(c)
                o, p, g = c["optimistix"], c["plain"], c["geodesic"]
                print(f"{model} | {motion} | {n:.0e} | {o['steps']} | {p['steps']} | "
                      f"{g['steps']} | {o['cpu_s']:.3f} | {p['cpu_s']:.3f} | "
                      f"{g['cpu_s']:.3f} | {c['cpu_ratio']:.2f}", flush=True)
    over = {name: sum(c[name]["steps"] > fs.TARGETS["steps"] for c in cells)
            for name in SOLVERS}
    print(f"cells over {fs.TARGETS['steps']} steps: " + ", ".join(
        f"{name} {count}" for name, count in over.items()) + f" (of {len(cells)})")
    command = " ".join(["python benchmarks/geodesic_steps.py", *(argv or sys.argv[1:])])
    result = {"command": command, "repeats": args.repeats,
              "machine": {"cpu_count": os.cpu_count(), "python": platform.python_version(),
                          "load_average_end": list(os.getloadavg())},
              "cells": cells, "over_40_steps": over}
    Path(args.json).write_text(json.dumps(result, indent=1))
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
