"""Time to fit: `fitting.fit` against what a user would write without jaxfric, over several
motions, two sizes and every model family (issue 36 item 4).

The baseline is ``scipy.optimize.least_squares`` (method ``"trf"``, ``x_scale="jac"``,
2-point finite differences, its default tolerances) around a simulation of the same model:
for the two-state model the Numba loop of `benchmarks/numba_two_state.py` (forces equal to
jaxfric's to < 1e-9 N); for GMS (5 elements), LuGre and Tustin, for which no Numba version
exists, ``jax.jit(jaxfric.simulate)`` of the parameter vector (what a JAX user without
`fitting` would write). Both fit the same data from the same start, side by side in one
process:

- motions (1 ms sampling): ``mixed`` (`benchmarks.motions.mixed_path`: a 1 mm sliding sine
  with presliding sines on top), ``strokes`` (`jaxfric.trajectories.sine_strokes`: +-2 mm
  at 0.1 Hz with +-30 um wiggles at 1.7 Hz), ``p2p`` (`point_to_point`: trapezoidal moves
  with dwells), ``robot`` (`robot_log`: band-limited random velocity) with 0.2 N of noise
  (a noisy log) where the others have 0.05 N;
- truths: `jaxfric.paper` (``two_state``, ``gms5``, ``lugre``, ``tustin``);
- start: every free parameter of the truth multiplied by 1.15 or 0.85 (a fixed random
  choice per model; the GMS weights renormalised); the two-state model holds ``c`` at its
  true value in both fits (its shape enters only through ``F(z)/F(X)``: the paper's five
  shape parameters with ``c`` held and jaxfric's five normalised ones span the same
  models), every other parameter is free;
- scipy works on the parameters in SI with positive bounds (``b < 0`` and ``0 < alpha < 1``
  for the two-state shape), the GMS weights as log-ratios to the first (the coordinates of
  jaxfric's `Simplex`); jaxfric with its defaults (`fitting.fit`).

Timings: jaxfric's *first call* is its first fit of that model at that number of samples in
this process (tracing and compiling included); *warm* is a second, identical fit. scipy is
run once per cell (deterministic); its *first call* adds the compilation of its simulation
(the Numba kernels, measured once, as a fresh process pays it; or the jitted simulation's
first call minus a warm one), *warm* is the run itself. Steps: solver iterations for
jaxfric, accepted and rejected (each simulates at least once), Jacobian evaluations
(``njev``: the start and each accepted step) for scipy, whose rejected steps show only in
``nfev``; the goal of 40 steps is judged on jaxfric's count, the stricter one.

Targets (issue 36): <= 40 steps everywhere; for the two-state model at 1e5 samples warm >=
5x and first call >= 2.5x; RMSE within 1 % of scipy's everywhere.

    python benchmarks/fit_speed.py [--quick] [--sizes 10000 100000] [--models ...]
                                   [--motions ...] [--json OUT]

``--update`` re-measures only the cells asked for (``--sizes``, ``--models``, ``--motions``)
and replaces them in the existing JSON, keeping its other cells: each cell carries the UTC
time it was measured (``measured_utc``), and the JSON's ``note`` says which cells come from
which run (the page docs/validation.md prints it).

``--quick`` fits 2000 samples of the two-state model on the mixed motion with both solvers
cut short (8 steps, 10 evaluations: a smoke test of the script for
tests/project/test_benchmark_scripts.py, not a measurement). Writes benchmarks/fit_speed.json
unless ``--json`` says otherwise. JSON: ``rows`` (two-state on the mixed motion, one per
size), ``cells`` (every motion x model x size: ``motion, model, n, noise, jaxfric{first_s,
warm_s, steps, rmse, status, stop, stopped, undetermined}, scipy{first_s, warm_s, steps, nfev,
rmse, status, message, baseline}, ratio_warm, ratio_first, rmse_rel``), ``goals`` (one per
cell and target, with ``met``), ``summary``, the ``machine`` (`benchmarks/machine.py`) and
the ``date_utc`` of the run that wrote the file.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import least_squares

import fitting
import jaxfric
from jaxfric import paper, trajectories


try:
    from benchmarks import numba_two_state as nb
    from benchmarks.motions import mixed_path
except ImportError:  # run as a script: benchmarks/ itself is sys.path[0]
    import numba_two_state as nb
    from motions import mixed_path


FREE = ("Fs", "Fc", "Vs", "delta", "sigma2", "C", "a", "b", "alpha", "beta", "l1")
NOISE = 0.05
SEED = 19
TARGETS = {"steps": 40, "warm": 5.0, "first": 2.5, "rmse_rel": 0.01}
MODELS = {"two-state": paper.two_state, "gms5": paper.gms5, "lugre": paper.lugre,
          "tustin": paper.tustin}
#: name -> (positions for times t, noise in N)
MOTIONS = {
    "mixed": (lambda t: mixed_path(t.size)[1], NOISE),
    "strokes": (lambda t: trajectories.sine_strokes(t, stroke=2e-3, freq=0.1, wiggle=30e-6,
                                                    wiggle_freq=1.7), NOISE),
    "p2p": (lambda t: trajectories.point_to_point(t), NOISE),
    "robot": (lambda t: trajectories.robot_log(t), 0.2),
}


def start_factors() -> dict[str, float]:
    """Each free two-state parameter x1.15 or x0.85 (fixed random choice, both present)."""
    rng = np.random.default_rng(SEED)
    return {name: float(f) for name, f in zip(FREE, rng.choice([1.15, 0.85], len(FREE)))}


def start_model(factors: dict[str, float]):
    """The two-state start: the paper's model with `factors` applied (``c`` as it is)."""
    m = paper.two_state()
    leaves = {
        "Fs": lambda m: m.stribeck.Fs, "Fc": lambda m: m.stribeck.Fc,
        "Vs": lambda m: m.stribeck.Vs, "delta": lambda m: m.stribeck.delta,
        "sigma2": lambda m: m.sigma2, "C": lambda m: m.C, "a": lambda m: m.shape.a,
        "b": lambda m: m.shape.b, "alpha": lambda m: m.shape.alpha,
        "beta": lambda m: m.shape.beta, "l1": lambda m: m.shape.l1,
    }
    for name, f in factors.items():
        m = eqx.tree_at(leaves[name], m, jnp.asarray(f * float(leaves[name](m))))
    return m


def other_start(truth, seed: int):
    """Every parameter leaf of `truth` (elementwise) x1.15 or x0.85; GMS weights
    renormalised to sum to one."""
    params, static = eqx.partition(truth, eqx.is_inexact_array)
    leaves, tree = jax.tree.flatten(params)
    rng = np.random.default_rng(seed)
    names = fitting._params.leaf_names(truth)
    out = []
    for name, leaf in zip(names, leaves):
        moved = np.asarray(leaf) * rng.choice([1.15, 0.85], np.shape(leaf))
        out.append(jnp.asarray(moved / moved.sum() if name == "nu" else moved))
    return eqx.combine(jax.tree.unflatten(tree, out), static)


def make_data(n: int, motion: str = "mixed", model: str = "two-state"):
    t = 1e-3 * np.arange(n, dtype=np.float64)
    path, noise = MOTIONS[motion]
    x = np.asarray(path(t))
    rng = np.random.default_rng(SEED + n)
    clean = np.asarray(jaxfric.simulate(MODELS[model](), t, x))
    return t, x, clean + noise * rng.standard_normal(n)


def fit_jaxfric(start, t, x, F, max_steps: int) -> dict:
    tick = time.perf_counter()
    res = fitting.fit(start, t, x, F, max_steps=max_steps)
    rmse = float(res.rmse)  # blocks until done
    return {"seconds": time.perf_counter() - tick, "steps": int(res.num_steps),
            "rmse": rmse, "status": res.status, "stop": res.stop, "stopped": res.stopped,
            "undetermined": list(res.undetermined)}


def _bounds(x0: np.ndarray):
    lo = np.where(x0 > 0, 0.0, -np.inf)
    hi = np.where(x0 > 0, np.inf, 0.0)
    ia = FREE.index("alpha")
    hi[ia] = 1.0
    return lo, hi


def _solve(resid, x0, bounds, max_nfev):
    tick = time.perf_counter()
    sol = least_squares(resid, x0, method="trf", x_scale="jac", jac="2-point",
                        bounds=bounds, max_nfev=max_nfev)
    return sol, time.perf_counter() - tick


def _scipy_out(sol, seconds, compile_s, baseline) -> dict:
    return {"warm_s": seconds, "first_s": seconds + compile_s, "steps": int(sol.njev),
            "nfev": int(sol.nfev), "rmse": float(np.sqrt(np.mean(sol.fun**2))),
            "status": int(sol.status), "message": sol.message, "baseline": baseline}


def fit_scipy_two_state(factors, t, x, F, numba_compile, max_nfev=None) -> dict:
    truth = nb.paper_params()
    x0 = np.array([factors[k] * truth[k] for k in FREE])

    def resid(p):
        params = dict(truth, **dict(zip(FREE, p)))
        return nb.simulate_numba(params, t, x) - F

    sol, seconds = _solve(resid, x0, _bounds(x0), max_nfev)
    return _scipy_out(sol, seconds, numba_compile, "numba")


def fit_scipy_jax(start, t, x, F, max_nfev=None) -> dict:
    """scipy around ``jax.jit`` of `jaxfric.simulate` of the parameter vector: positive
    parameters in SI, GMS weights as log-ratios to the first."""
    params, static = eqx.partition(start, eqx.is_inexact_array)
    leaves, tree = jax.tree.flatten(params)
    names = fitting._params.leaf_names(start)
    parts, lo = [], []
    for name, leaf in zip(names, leaves):
        a = np.ravel(np.asarray(leaf))
        parts.append(np.log(a[1:] / a[0]) if name == "nu" else a)
        lo.append(np.full(parts[-1].shape, -np.inf if name == "nu" else 0.0))
    sizes = [p.size for p in parts]
    x0, lo = np.concatenate(parts), np.concatenate(lo)

    def unpack(vec):
        out, k = [], 0
        for name, leaf, size in zip(names, leaves, sizes):
            part = vec[k:k + size]
            k += size
            if name == "nu":
                part = jax.nn.softmax(jnp.concatenate([jnp.zeros(1), part]))
            out.append(part.reshape(jnp.shape(leaf)))
        return eqx.combine(jax.tree.unflatten(tree, out), static)

    sim = jax.jit(lambda vec: jaxfric.simulate(unpack(vec), t, x))
    tick = time.perf_counter()
    np.asarray(sim(jnp.asarray(x0)))
    first = time.perf_counter() - tick
    tick = time.perf_counter()
    np.asarray(sim(jnp.asarray(x0 * 1.0000001)))
    compile_s = max(first - (time.perf_counter() - tick), 0.0)

    def resid(p):
        return np.asarray(sim(jnp.asarray(p))) - F

    sol, seconds = _solve(resid, x0, (lo, np.full(x0.shape, np.inf)), max_nfev)
    return _scipy_out(sol, seconds, compile_s, "jax.jit(jaxfric.simulate)")


def bench_cell(motion: str, model: str, n: int, numba_compile: float, max_steps: int, log,
               max_nfev: int | None = None) -> dict:
    t, x, F = make_data(n, motion, model)
    truth = MODELS[model]()
    floor = float(np.sqrt(np.mean((np.asarray(jaxfric.simulate(truth, t, x)) - F) ** 2)))
    factors = start_factors()
    start = (start_model(factors) if model == "two-state"
             else other_start(truth, SEED + len(model)))
    first = fit_jaxfric(start, t, x, F, max_steps)
    warm = fit_jaxfric(start, t, x, F, max_steps)
    if model == "two-state":
        sp = fit_scipy_two_state(factors, t, x, F, numba_compile, max_nfev)
    else:
        sp = fit_scipy_jax(start, t, x, F, max_nfev)
    row = {
        "motion": motion, "model": model, "n": n, "noise": MOTIONS[motion][1],
        "noise_floor_rmse": floor,
        "jaxfric": {"first_s": first["seconds"], "warm_s": warm["seconds"],
                    "steps": warm["steps"], "steps_first": first["steps"],
                    "rmse": warm["rmse"], "status": warm["status"], "stop": warm["stop"],
                    "stopped": warm["stopped"],
                    "undetermined": warm["undetermined"]},
        "scipy": sp,
        "ratio_warm": sp["warm_s"] / warm["seconds"],
        "ratio_first": sp["first_s"] / first["seconds"],
        "rmse_rel": warm["rmse"] / sp["rmse"] - 1.0,
    }
    log(f"  {motion:8s} {model:9s} n={n:.0e}: jaxfric {warm['steps']} steps "
        f"{first['seconds']:.2f}/{warm['seconds']:.2f} s {warm['status']}; scipy "
        f"{sp['steps']} Jacobians {sp['first_s']:.2f}/{sp['warm_s']:.2f} s; x warm "
        f"{row['ratio_warm']:.2f}, dRMSE {100 * row['rmse_rel']:+.2f} %")
    return row


def goals(cells) -> list[dict]:
    out = []
    for r in cells:
        key = {"motion": r["motion"], "model": r["model"], "n": r["n"]}
        out.append({**key, "goal": "steps", "target": f"<= {TARGETS['steps']}",
                    "measured": r["jaxfric"]["steps"],
                    "met": r["jaxfric"]["steps"] <= TARGETS["steps"]})
        out.append({**key, "goal": "RMSE vs scipy", "target": "within 1 %",
                    "measured": r["rmse_rel"], "met": r["rmse_rel"] <= TARGETS["rmse_rel"]})
        if r["model"] == "two-state" and (r["n"] >= 100_000 or r["n"] == 2000):
            out += [
                {**key, "goal": "warm speed-up", "target": f">= {TARGETS['warm']}x",
                 "measured": r["ratio_warm"], "met": r["ratio_warm"] >= TARGETS["warm"]},
                {**key, "goal": "first-call speed-up", "target": f">= {TARGETS['first']}x",
                 "measured": r["ratio_first"], "met": r["ratio_first"] >= TARGETS["first"]},
            ]
    return out


def report(cells, numba_compile: float) -> str:
    head = ("motion", "model", "n", "steps", "first s", "warm s", "RMSE N", "status",
            "scipy Jac", "first s", "warm s", "RMSE N", "x first", "x warm", "dRMSE")
    lines = [" | ".join(head)]
    for r in cells:
        j, s = r["jaxfric"], r["scipy"]
        lines.append(" | ".join([
            r["motion"], r["model"], f"{r['n']:.0e}", str(j["steps"]), f"{j['first_s']:.2f}",
            f"{j['warm_s']:.2f}", f"{j['rmse']:.5f}", j["status"], str(s["steps"]),
            f"{s['first_s']:.2f}", f"{s['warm_s']:.2f}", f"{s['rmse']:.5f}",
            f"{r['ratio_first']:.2f}", f"{r['ratio_warm']:.2f}",
            f"{100 * r['rmse_rel']:+.2f} %"]))
    lines.append(f"(Numba compile, added to scipy's first call for the two-state model: "
                 f"{numba_compile:.2f} s)")
    every = goals(cells)
    missed = [g for g in every if not g["met"]]
    lines.append(f"goals met: {len(every) - len(missed)} of {len(every)}")
    for g in missed:
        lines.append(f"MISSED {g['motion']} {g['model']} n={g['n']:.0e} {g['goal']} "
                     f"{g['target']}: {g['measured']:.3g}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="2000 samples, two-state on the mixed motion (smoke test)")
    ap.add_argument("--sizes", type=int, nargs="+", default=None)
    ap.add_argument("--models", nargs="+", default=list(MODELS), choices=list(MODELS))
    ap.add_argument("--motions", nargs="+", default=list(MOTIONS), choices=list(MOTIONS))
    ap.add_argument("--max-steps", type=int, default=256)
    ap.add_argument("--json", metavar="OUT",
                    default=str(Path(__file__).with_name("fit_speed.json")))
    ap.add_argument("--update", action="store_true",
                    help="replace only the cells measured now in the existing JSON")
    args = ap.parse_args(argv)
    sizes = args.sizes or ([2000] if args.quick else [10_000, 100_000])
    models, motions = ((["two-state"], ["mixed"]) if args.quick
                       else (args.models, args.motions))
    kept = _kept_cells(args.json, sizes, models, motions) if args.update else []

    def log(msg):
        print(msg, flush=True)

    numba_compile = nb.warm_up()
    factors = start_factors()
    log(f"two-state start factors: {factors}")
    # --quick: a smoke test of the script, both solvers cut short (not a measurement).
    max_steps, max_nfev = (8, 10) if args.quick else (args.max_steps, None)
    cells = []
    # Model by model (the two-state model, which carries the speed targets, first), each
    # over its sizes: a run stopped early has whole models.
    for model in models:
        for n in sizes:
            for motion in motions:
                cell = bench_cell(motion, model, n, numba_compile, max_steps, log, max_nfev)
                cell["measured_utc"] = time.strftime("%Y-%m-%d %H:%M", time.gmtime())
                cells.append(cell)
                # Written after every cell: a long run interrupted keeps what it measured.
                write(args, factors, numba_compile, kept, cells, partial=True)
    print(report(cells, numba_compile))
    write(args, factors, numba_compile, kept, cells, partial=False)
    print(f"\nwrote {args.json}")
    return 0


def _key(cell) -> tuple:
    return cell["motion"], cell["model"], cell["n"]


def _kept_cells(path, sizes, models, motions) -> list:
    """The cells of the JSON at `path` that this ``--update`` run does not re-measure."""
    path = Path(path)
    if not path.exists():
        return []
    old = json.loads(path.read_text()).get("cells", [])
    return [c for c in old if not (c["n"] in sizes and c["model"] in models
                                   and c["motion"] in motions)]


def _note(kept, new) -> str | None:
    """Which cells come from which run, when they come from several (``--update``): the
    time span of each model's cells (each cell's ``measured_utc`` says when it ran)."""
    if not kept:
        return None
    spans = []
    for model in MODELS:
        when = sorted({c.get("measured_utc", "an earlier run") for c in kept + new
                       if c["model"] == model})
        if when:
            spans.append(f"{model} {when[0]}" + (f" to {when[-1]}" if len(when) > 1 else ""))
    return ("cells measured in several runs (--update), by model (UTC): " + "; ".join(spans)
            + ". Each model's cells ran with the code of their time.")


def _status_note(cells) -> str | None:
    """The cells whose jaxfric fit is not converged, with the first words of why."""
    bad = [f"{c['model']} {c['motion']} {c['n']:.0e}".replace("e+0", "e")
           for c in cells if c["jaxfric"]["status"] != "successful"]
    return (f"jaxfric fits NOT converged: {', '.join(bad)} (`stopped` in the JSON says why)."
            if bad else None)


def write(args, factors, numba_compile, kept, new, partial: bool) -> None:
    try:  # run as a script: benchmarks/ itself is sys.path[0]
        from machine import machine_facts
    except ImportError:
        from benchmarks.machine import machine_facts

    cells = sorted(kept + new, key=lambda c: (list(MODELS).index(c["model"]), c["n"],
                                              list(MOTIONS).index(c["motion"])))
    every = goals(cells)
    rows = [c for c in cells if c["model"] == "two-state" and c["motion"] == "mixed"]
    result = {
        "command": "python benchmarks/fit_speed.py" + (" --quick" if args.quick else ""),
        "quick": args.quick, "partial": partial,
        "machine": {**machine_facts(), "numba": nb.numba.__version__,
                    "load_average_end": list(os.getloadavg())},
        "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
        "start_factors": factors, "numba_compile_s": numba_compile,
        "rows": rows, "cells": cells, "goals": every, "targets": TARGETS,
        "summary": {"goals": len(every), "met": sum(g["met"] for g in every),
                    "max_steps_jaxfric": max(c["jaxfric"]["steps"] for c in cells)},
    }
    note = " ".join(n for n in (_note(kept, new), _status_note(cells)) if n)
    if note:
        result["note"] = note
    Path(args.json).write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    raise SystemExit(main())
