"""Cost of the exported C step (`jaxfric.export`) per sample, next to jaxfric and Numba.

For each model the export is compiled with the system C compiler (``cc -O2 -std=c99``) and
timed as a controller would run it: one C loop calling the step (``jaxfric_step_load``,
which ``jaxfric_step`` wraps with the load 0) on every sample of arrays
(`jaxfric.export.compile_c`; one ``ctypes`` call per pass, so Python is not in the loop).
Next to it, on the same motion and in the same run: ``jaxfric.simulate`` (the
whole-trajectory JAX path, after its compilation) per sample, the Numba baseline
(``benchmarks/numba_two_state.py``, two-state only), and ``jax.jit(model.step)`` called once
per sample from Python (what a Python control loop would pay per call; on fewer samples).
The C forces are checked against ``simulate`` (max error relative to max |F|).

Motion: ``benchmarks/motions.mixed_path`` (a 1 mm sliding sine with presliding loops of 100
and 20 um, 1 kHz), velocity by backward difference. Timings are medians over `--repeats`
rounds, the cases interleaved in each round. The target is <= 100 ns per C step on one core.

Run ``python benchmarks/c_step.py [--n N] [--repeats R] [--json OUT]`` (default JSON:
benchmarks/c_step.json). SI units throughout.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

import jax
import numpy as np

import jaxfric
from jaxfric import effects as fx, paper
from jaxfric.export import compile_c, find_compiler


try:
    from benchmarks.motions import mixed_path
except ImportError:  # run as a script: benchmarks/ itself is sys.path[0]
    from motions import mixed_path

HERE = Path(__file__).resolve().parent
TARGET_NS = 100.0


def models(x) -> dict:
    """The exported models, by name."""
    effects = (fx.Viscous(c_visc=5.0), fx.Offset(offset=0.2), fx.Inertia(mass=0.1),
               fx.Cogging(cog_sin=0.3, cog_cos=0.1, period=1e-3),
               fx.PositionLoad.for_travel(x, load_1=0.2, load_2=0.05),
               fx.FrictionLag(lag_gain=0.3, tau=0.02))
    return {
        "two_state": paper.two_state(),
        "two_state + 6 effects": paper.two_state() + effects,
        "gms5": paper.gms5(),
        "gms50": paper.gms(50),
        "lugre": paper.lugre(),
        "tustin": paper.tustin(),
    }


def _numba():
    try:
        try:
            from benchmarks import numba_two_state as nbts
        except ImportError:
            import numba_two_state as nbts
        nbts.warm_up()
        return nbts
    except ImportError:
        return None


def _step_per_call(model, t, x, v, calls: int) -> float:
    """Seconds per call of ``model.step`` under ``jax.jit`` from a Python loop (after
    compiling)."""
    step = jax.jit(lambda state, x, v, dt: model.step(state, x, v, dt))
    state = model.init_state(x[0])
    dt = np.diff(t, prepend=t[0])
    for i in range(2):  # compile for these argument types
        _, f = step(state, x[i], v[i], dt[i])
    jax.block_until_ready(f)
    start = time.perf_counter()
    for i in range(calls):
        state, f = step(state, x[i], v[i], dt[i])
    jax.block_until_ready(f)
    return (time.perf_counter() - start) / calls


def measure(n: int, repeats: int, step_calls: int, folder: Path) -> list[dict]:
    t, x = mixed_path(n)
    v = np.r_[0.0, np.diff(x) / np.diff(t)]
    nbts = _numba()
    cases = models(x)
    compiled, rows = {}, {}
    for name, model in cases.items():
        compiled[name] = compile_c(model, folder / name.replace(" ", "_").replace("+", "p"))
        want = np.asarray(jaxfric.simulate(model, t, x, v))  # also compiles simulate
        got = compiled[name].run(t, x, v)
        rows[name] = {"model": name, "max_rel_error": float(np.max(np.abs(got - want))
                                                              / np.max(np.abs(want))),
                      "c": [], "jaxfric": [], "numba": []}
    if nbts is not None:
        params = nbts.params_from_model(cases["two_state"])
    for _ in range(repeats):
        for name, model in cases.items():
            r = rows[name]
            r["c"].append(compiled[name].time_per_step(t, x, v, reps=3))
            start = time.perf_counter()
            jax.block_until_ready(jaxfric.simulate(model, t, x, v))
            r["jaxfric"].append((time.perf_counter() - start) / n)
            if name == "two_state" and nbts is not None:
                start = time.perf_counter()
                nbts.simulate_numba(params, t, x, v)
                r["numba"].append((time.perf_counter() - start) / n)
    out = []
    for name, model in cases.items():
        r = rows[name]
        med = {k: statistics.median(r[k]) * 1e9 if r[k] else None
               for k in ("c", "jaxfric", "numba")}
        step_ns = _step_per_call(model, t, x, v, step_calls) * 1e9 if step_calls else None
        out.append({"model": name, "c_ns_per_step": med["c"],
                    "jaxfric_simulate_ns_per_sample": med["jaxfric"],
                    "numba_ns_per_sample": med["numba"],
                    "jaxfric_jit_step_ns_per_call": step_ns,
                    "c_max_error_rel_to_max_force": r["max_rel_error"],
                    "meets_target": med["c"] <= TARGET_NS})
    return out


def _fmt(v, digits=1):
    return "-" if v is None else f"{v:.{digits}f}"


def table(rows: list[dict]) -> str:
    lines = [f"{'model':<22} {'C step':>9} {'simulate':>9} {'Numba':>9} {'jit step':>10} "
             f"{'C/simulate':>10} {'C error':>9}",
             f"{'':<22} {'ns':>9} {'ns/sample':>9} {'ns/sample':>9} {'ns/call':>10} "
             f"{'':>10} {'rel.':>9}"]
    for r in rows:
        ratio = r["c_ns_per_step"] / r["jaxfric_simulate_ns_per_sample"]
        lines.append(f"{r['model']:<22} {_fmt(r['c_ns_per_step']):>9} "
                     f"{_fmt(r['jaxfric_simulate_ns_per_sample']):>9} "
                     f"{_fmt(r['numba_ns_per_sample']):>9} "
                     f"{_fmt(r['jaxfric_jit_step_ns_per_call'], 0):>10} {ratio:>10.2f} "
                     f"{r['c_max_error_rel_to_max_force']:>9.1e}")
    return "\n".join(lines)


def markdown(rows: list[dict]) -> str:
    """The table of docs/using_a_model.md (ns per step or sample; us per Python call)."""
    lines = ["| model | C step, ns | `simulate`, ns/sample | Numba, ns/sample "
             "| JAX `step` per call from Python, us |", "|---|---:|---:|---:|---:|"]
    for r in rows:
        call = r["jaxfric_jit_step_ns_per_call"]
        lines.append(f"| {r['model']} | {_fmt(r['c_ns_per_step'], 0)} "
                     f"| {_fmt(r['jaxfric_simulate_ns_per_sample'], 0)} "
                     f"| {_fmt(r['numba_ns_per_sample'], 0)} "
                     f"| {_fmt(None if call is None else call / 1e3, 0)} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100_000, help="samples (default: %(default)s)")
    ap.add_argument("--repeats", type=int, default=7, help="rounds (default: %(default)s)")
    ap.add_argument("--step-calls", type=int, default=2000,
                    help="samples for the per-call jit step (0: skip; default: %(default)s)")
    ap.add_argument("--json", default=str(HERE / "c_step.json"), help="output JSON")
    args = ap.parse_args(argv)
    if find_compiler() is None:
        print("no C compiler ('cc') on the PATH: nothing to measure")
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        rows = measure(args.n, args.repeats, args.step_calls, Path(tmp))
    print(f"C step vs jaxfric, {args.n} samples, median of {args.repeats} rounds "
          f"(target: C <= {TARGET_NS:.0f} ns/step)")
    print(table(rows))
    print("\nas Markdown (docs/using_a_model.md):\n" + markdown(rows))
    sys.path.insert(0, str(HERE.parent))
    from benchmarks.machine import machine_facts

    meta = {"n": args.n, "repeats": args.repeats, "cc_flags": "-O2 -std=c99",
            "platform": platform.platform(), "python": platform.python_version(),
            "jax": jax.__version__, "cores": os.cpu_count(),
            "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
            "target_ns": TARGET_NS,
            "date_utc": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M"),
            "cpu": machine_facts()["cpu"]}
    Path(args.json).write_text(json.dumps({"meta": meta, "rows": rows}, indent=1) + "\n")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
