"""Time to fit: `fitting.fit` against what a user would write without jaxfric (issue 19 item 2).

The baseline is ``scipy.optimize.least_squares`` (method ``"trf"``, ``x_scale="jac"``,
2-point finite differences, its default tolerances) around the Numba loop of the same
two-state model (`benchmarks/numba_two_state.py`, forces equal to jaxfric's to < 1e-9 N).
Both fit the same data from the same start, side by side in one process:

- data: the paper's two-state model (`jaxfric.paper.two_state`) on the mixed sliding and
  presliding motion of `benchmarks/motions.py` at 1 ms, plus 0.05 N Gaussian noise;
- start: every parameter multiplied by 1.15 or 0.85 (a fixed random choice), except ``c``,
  which both hold at its true value: 11 free parameters;
- scipy works on the 11 parameters in SI with their sign as bounds (``b < 0``,
  ``0 < alpha < 1``, the others > 0); jaxfric with its defaults (`fitting.fit`: the
  reparameterised shape with every parameter free, Levenberg-Marquardt in chunks,
  `fitting._chunked.Tolerances`). The shape enters only through ``F(z)/F(X)``, so the
  paper's five shape parameters with ``c`` held and jaxfric's five normalised ones span the
  same models: the same 11-parameter problem.

Timings: jaxfric's *first call* is its first fit at that number of samples in this process
(tracing and compiling for that shape included; each size compiles anew); *warm* is a
second, identical fit (nothing recompiles). scipy is run once per size (it is
deterministic: a second run repeats the same evaluations); its *first call* adds the
Numba kernel's compilation time (measured once, as a fresh process pays it), *warm* is
the run itself. Steps: solver iterations for jaxfric, Jacobian evaluations (``njev``) for
scipy, and ``nfev`` (model simulations besides the Jacobians' 11 each) for both.

Targets (issue 19): warm >= 5x, first call >= 2.5x, RMSE within 1 % of scipy's.

    python benchmarks/fit_speed.py [--quick] [--big] [--sizes 10000 100000] [--json OUT]

``--big`` adds 1e6 samples (minutes); ``--quick`` fits 2000 samples with both solvers cut
short (8 steps, 10 evaluations: a smoke test of the script for
tests/project/test_benchmark_scripts.py, not a measurement). Writes benchmarks/fit_speed.json
unless ``--json`` says otherwise.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import least_squares

import fitting
import jaxfric
from jaxfric import paper


try:
    from benchmarks import numba_two_state as nb
    from benchmarks.motions import mixed_path
except ImportError:  # run as a script: benchmarks/ itself is sys.path[0]
    import numba_two_state as nb
    from motions import mixed_path


#: The parameters both fits move (``c`` is held at its true value).
FREE = ("Fs", "Fc", "Vs", "delta", "sigma2", "C", "a", "b", "alpha", "beta", "l1")
NOISE = 0.05
SEED = 19
TARGETS = {"warm": 5.0, "first": 2.5, "rmse_rel": 0.01}


def start_factors() -> dict[str, float]:
    """Each free parameter x1.15 or x0.85 (fixed random choice, both signs present)."""
    rng = np.random.default_rng(SEED)
    return {name: float(f) for name, f in zip(FREE, rng.choice([1.15, 0.85], len(FREE)))}


def start_model(factors: dict[str, float]):
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


def make_data(n: int):
    t, x = mixed_path(n)
    rng = np.random.default_rng(SEED + n)
    F = np.asarray(jaxfric.simulate(paper.two_state(), t, x)) + NOISE * rng.standard_normal(n)
    return t, x, F


def fit_jaxfric(start, t, x, F, max_steps: int) -> dict:
    tick = time.perf_counter()
    # Defaults: every parameter of the fit representation free. The shape's Pi is a ratio
    # F(z)/F(X), so the paper's (a, b, c, alpha, beta) with c held and jaxfric's five
    # normalised shape parameters span the same models: the same 11-parameter problem.
    res = fitting.fit(start, t, x, F, max_steps=max_steps)
    rmse = float(res.rmse)  # blocks until done
    return {"seconds": time.perf_counter() - tick, "steps": int(res.num_steps),
            "rmse": rmse, "status": res.status, "stopped": res.stopped}


def _bounds(x0: np.ndarray):
    lo = np.where(x0 > 0, 0.0, -np.inf)
    hi = np.where(x0 > 0, np.inf, 0.0)
    ia = FREE.index("alpha")
    hi[ia] = 1.0
    return lo, hi


def fit_scipy(factors, t, x, F, max_nfev: int | None = None) -> dict:
    truth = nb.paper_params()
    x0 = np.array([factors[k] * truth[k] for k in FREE])

    def resid(p):
        params = dict(truth, **dict(zip(FREE, p)))
        return nb.simulate_numba(params, t, x) - F

    tick = time.perf_counter()
    sol = least_squares(resid, x0, method="trf", x_scale="jac", jac="2-point",
                        bounds=_bounds(x0), max_nfev=max_nfev)
    seconds = time.perf_counter() - tick
    return {"seconds": seconds, "steps": int(sol.njev), "nfev": int(sol.nfev),
            "rmse": float(np.sqrt(np.mean(sol.fun**2))), "status": int(sol.status),
            "message": sol.message}


def bench_size(n: int, factors, numba_compile: float, max_steps: int, log,
               max_nfev: int | None = None) -> dict:
    t, x, F = make_data(n)
    floor = float(np.sqrt(np.mean((np.asarray(jaxfric.simulate(paper.two_state(), t, x))
                                   - F) ** 2)))
    start = start_model(factors)
    first = fit_jaxfric(start, t, x, F, max_steps)
    log(f"  n={n}: jaxfric first {first['seconds']:.2f} s")
    warm = fit_jaxfric(start, t, x, F, max_steps)
    log(f"  n={n}: jaxfric warm {warm['seconds']:.2f} s, {warm['steps']} steps, {warm['status']}")
    sp = fit_scipy(factors, t, x, F, max_nfev)
    log(f"  n={n}: scipy {sp['seconds']:.2f} s, {sp['steps']} Jacobians")
    sp_first = sp["seconds"] + numba_compile
    return {
        "n": n, "noise_floor_rmse": floor,
        "jaxfric": {"first_s": first["seconds"], "warm_s": warm["seconds"],
                    "steps": warm["steps"], "steps_first": first["steps"],
                    "rmse": warm["rmse"], "status": warm["status"], "stopped": warm["stopped"]},
        "scipy": {"first_s": sp_first, "warm_s": sp["seconds"], "steps": sp["steps"],
                  "nfev": sp["nfev"], "rmse": sp["rmse"], "status": sp["status"],
                  "message": sp["message"]},
        "ratio_warm": sp["seconds"] / warm["seconds"],
        "ratio_first": sp_first / first["seconds"],
        "rmse_rel": warm["rmse"] / sp["rmse"] - 1.0,
    }


def goals(rows) -> list[dict]:
    out = []
    for r in rows:
        out += [
            {"n": r["n"], "goal": "warm speed-up", "target": f">= {TARGETS['warm']}x",
             "measured": r["ratio_warm"], "met": r["ratio_warm"] >= TARGETS["warm"]},
            {"n": r["n"], "goal": "first-call speed-up", "target": f">= {TARGETS['first']}x",
             "measured": r["ratio_first"], "met": r["ratio_first"] >= TARGETS["first"]},
            {"n": r["n"], "goal": "RMSE vs scipy", "target": "within 1 %",
             "measured": r["rmse_rel"], "met": abs(r["rmse_rel"]) <= TARGETS["rmse_rel"]},
        ]
    return out


def report(rows, numba_compile: float) -> str:
    head = ("n", "jaxfric steps", "first s", "warm s", "RMSE N", "status", "scipy Jacobians",
            "first s", "warm s", "RMSE N", "x first", "x warm", "dRMSE")
    lines = [" | ".join(head)]
    for r in rows:
        j, s = r["jaxfric"], r["scipy"]
        lines.append(" | ".join([
            f"{r['n']:.0e}", str(j["steps"]), f"{j['first_s']:.2f}", f"{j['warm_s']:.2f}",
            f"{j['rmse']:.5f}", j["status"], str(s["steps"]), f"{s['first_s']:.2f}",
            f"{s['warm_s']:.2f}", f"{s['rmse']:.5f}", f"{r['ratio_first']:.2f}",
            f"{r['ratio_warm']:.2f}", f"{100 * r['rmse_rel']:+.2f} %"]))
    lines.append(f"(Numba compile, added to scipy's first call: {numba_compile:.2f} s; "
                 f"noise 0.05 N)")
    for g in goals(rows):
        mark = "met" if g["met"] else "MISSED"
        lines.append(f"goal n={g['n']:.0e} {g['goal']} {g['target']}: "
                     f"{g['measured']:.3g} -> {mark}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2000 samples only (smoke test)")
    ap.add_argument("--big", action="store_true", help="add 1e6 samples (slow)")
    ap.add_argument("--sizes", type=int, nargs="+", default=None)
    ap.add_argument("--max-steps", type=int, default=256)
    ap.add_argument("--json", metavar="OUT",
                    default=str(Path(__file__).with_name("fit_speed.json")))
    args = ap.parse_args(argv)
    sizes = args.sizes or ([2000] if args.quick else [10_000, 100_000])
    if args.big and 1_000_000 not in sizes:
        sizes = [*sizes, 1_000_000]

    def log(msg):
        print(msg, flush=True)

    numba_compile = nb.warm_up()
    factors = start_factors()
    log(f"start factors: {factors}")
    # --quick: a smoke test of the script, both solvers cut short (not a measurement).
    max_steps, max_nfev = (8, 10) if args.quick else (args.max_steps, None)
    rows = [bench_size(n, factors, numba_compile, max_steps, log, max_nfev) for n in sizes]
    print(report(rows, numba_compile))
    result = {
        "command": "python benchmarks/fit_speed.py" + (" --quick" if args.quick else "")
                   + (" --big" if args.big else ""),
        "machine": {"cpu_count": __import__("os").cpu_count(), "python": platform.python_version(),
                    "jax": jax.__version__, "numba": nb.numba.__version__},
        "start_factors": factors, "numba_compile_s": numba_compile, "rows": rows,
        "goals": goals(rows), "targets": TARGETS,
    }
    Path(args.json).write_text(json.dumps(result, indent=1))
    print(f"\nwrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
