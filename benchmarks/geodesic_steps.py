"""Steps and time per fit: `fitting.default_solver` against `fitting.geodesic_solver`
(the same Levenberg-Marquardt and trust region, plus geodesic acceleration), side by side.

The cells are those of `benchmarks/fit_speed.py` (same data, truths and starts). In one
process, per cell, the two solvers are run alternately, `--repeats` times each (the first
fit of each also compiles and is left out of the timing); the table gives each solver's
steps and the median CPU time (``time.process_time``, less sensitive to other processes on
a shared machine than the wall clock) of its warm fits, and their ratio.

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

import numpy as np

import fitting


try:
    from benchmarks import fit_speed as fs
except ImportError:  # run as a script: benchmarks/ itself is sys.path[0]
    import fit_speed as fs


SOLVERS = {"default": fitting.default_solver, "geodesic": fitting.geodesic_solver}


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
    out["cpu_ratio"] = out["geodesic"]["cpu_s"] / out["default"]["cpu_s"]
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
    head = "model | motion | n | steps | geodesic steps | CPU s | geodesic CPU s | ratio"
    print(head, flush=True)
    cells = []
    for model in args.models:
        for n in args.sizes:
            for motion in args.motions:
                c = cell(model, motion, n, args.repeats)
                cells.append(c)
                d, g = c["default"], c["geodesic"]
                print(f"{model} | {motion} | {n:.0e} | {d['steps']} | {g['steps']} | "
                      f"{d['cpu_s']:.3f} | {g['cpu_s']:.3f} | {c['cpu_ratio']:.2f}",
                      flush=True)
    over = {name: sum(c[name]["steps"] > fs.TARGETS["steps"] for c in cells)
            for name in SOLVERS}
    print(f"cells over {fs.TARGETS['steps']} steps: default {over['default']}, "
          f"geodesic {over['geodesic']} (of {len(cells)})")
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
