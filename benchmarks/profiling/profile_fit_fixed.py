"""A fit's fixed cost, stage by stage: what `fitting.fit` spends besides its iterations.

Fits the data of ``benchmarks/throughput.py`` section 5 (the paper's two-state model on the
mixed motion, 0.05 N noise, 1e5 samples; the start with 7 parameters off by 4-50 %) with
``max_steps=1`` and ``max_steps=5`` (after one warm-up fit each, which compiles), and times
the stages of each fit by wrapping the functions that make them up (each wrapper waits for
its JAX results, so that a stage's time is its own, not the next one's):

- ``check``: `fitting._data.check_dataset` (the input checks) and ``problem``:
  `fitting._problem._problem` (the solver's view of the model);
- ``chunk``: `fitting._chunked._chunk`, the compiled solver steps (one Jacobian and one
  damped solve per step; the one Jacobian of ``max_steps=1`` is its whole solve);
- ``stop rule``: `fitting._chunked._stop_reason`, ``undetermined``:
  `fitting._chunked.undetermined_leaves`, ``costless``: `fitting._chunked._costless` (a
  further residual when some parameters look undetermined);
- ``finish``: `fitting._chunked._finish`, the covariance, the delta method, the metrics
  (compiled);
- ``assemble``: `fitting._result._assemble` (the `FitResult`), ``re-simulate``:
  `jaxfric.simulate` of the fitted model in `fitting._fit._as_simulated` (the prediction a
  saved fit reproduces);
- ``other``: the rest of the wall time of `fitting.fit` (Python between the stages).

Each round also times the same fit with OpenBLAS's own threads (`fitting._blas` switched
off: ``ENABLED = False``), reported as ``total_blas_threads_s``, and with Python's cyclic
garbage collector left running (`fitting._gc` switched off), ``total_gc_s``.

Prints a table of medians over ``--repeats`` fits per ``max_steps`` and the difference per
extra step; writes benchmarks/profiling/profile_fit_fixed.json (``--json``). The machine's
load average is recorded: on a shared machine, trust the split rather than the seconds.

    python benchmarks/profiling/profile_fit_fixed.py [--n 100000] [--repeats 5] [--json OUT]
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import os
import statistics
import sys
import time
from pathlib import Path

import jax
import numpy as np

import fitting
import jaxfric
from fitting import _blas, _chunked, _fit, _gc
from jaxfric import paper


try:
    from benchmarks.machine import machine_facts
    from benchmarks.motions import mixed_path, perturbed_start, synthetic_force
except ImportError:  # run as a script: benchmarks/profiling/ is sys.path[0]
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from machine import machine_facts
    from motions import mixed_path, perturbed_start, synthetic_force


#: (stage, module, attribute) of the wrapped functions (module docstring).
STAGES = (
    ("check", _fit, "check_dataset"),
    ("problem", _fit, "_problem"),
    ("chunk", _chunked, "_chunk"),
    ("stop rule", _chunked, "_stop_reason"),
    ("undetermined", _chunked, "undetermined_leaves"),
    ("costless", _chunked, "_costless"),
    ("finish", _chunked, "_finish"),
    ("assemble", _fit, "_assemble"),
    ("re-simulate", _fit.jaxfric, "simulate"),
)


@contextlib.contextmanager
def timed_stages(seconds: dict):
    """Wrap the functions of `STAGES` so that each call adds its time (results waited for)
    to ``seconds[stage]``; restored on exit."""
    saved = []
    for stage, module, name in STAGES:
        fn = getattr(module, name)
        saved.append((module, name, fn))

        @functools.wraps(fn)
        def wrapper(*args, _fn=fn, _stage=stage, **kwargs):
            t0 = time.perf_counter()
            out = jax.block_until_ready(_fn(*args, **kwargs))
            seconds[_stage] = seconds.get(_stage, 0.0) + time.perf_counter() - t0
            return out

        setattr(module, name, wrapper)
    try:
        yield
    finally:
        for module, name, fn in saved:
            setattr(module, name, fn)


def profile(n: int, repeats: int, log=print) -> dict:
    """Per ``max_steps`` (1, 5): the stages' medians as a fit runs by default, and the
    totals with OpenBLAS's own threads and with the garbage collector running (interleaved
    rounds; module docstring)."""
    truth = paper.two_state()
    t, x = mixed_path(n)
    F = synthetic_force(truth, t, x, np.random.default_rng(1))
    start = perturbed_start(truth)
    rows = {}
    for steps in (1, 5):
        t0 = time.perf_counter()
        fitting.fit(start, t, x, F, max_steps=steps)
        first = time.perf_counter() - t0
        runs, threaded, collected = [], [], []
        for _ in range(repeats):
            seconds: dict = {}
            with timed_stages(seconds):
                t0 = time.perf_counter()
                res = fitting.fit(start, t, x, F, max_steps=steps)
                seconds["total"] = time.perf_counter() - t0
            seconds["other"] = seconds["total"] - sum(
                v for k, v in seconds.items() if k != "total")
            runs.append(seconds)
            for module, into in ((_blas, threaded), (_gc, collected)):
                module.ENABLED = False
                try:
                    t0 = time.perf_counter()
                    fitting.fit(start, t, x, F, max_steps=steps)
                    into.append(time.perf_counter() - t0)
                finally:
                    module.ENABLED = True
        names = [s for s, _, _ in STAGES] + ["other", "total"]
        rows[steps] = {"max_steps": steps, "num_steps": int(res.num_steps),
                       "first_s": first,
                       "median_s": {k: statistics.median(r.get(k, 0.0) for r in runs)
                                    for k in names},
                       "total_blas_threads_s": statistics.median(threaded),
                       "total_gc_s": statistics.median(collected),
                       "runs": runs, "blas_threads_runs_s": threaded,
                       "gc_runs_s": collected}
        log(f"max_steps={steps}: {rows[steps]['median_s']['total']:.3f} s "
            f"(first call {first:.1f} s); with OpenBLAS's threads "
            f"{rows[steps]['total_blas_threads_s']:.3f} s, with the collector "
            f"{rows[steps]['total_gc_s']:.3f} s")
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", metavar="OUT",
                    default=str(Path(__file__).with_name("profile_fit_fixed.json")))
    args = ap.parse_args(argv)
    rows = profile(args.n, args.repeats)
    one, five = rows[1], rows[5]
    extra = max(five["num_steps"] - one["num_steps"], 1)
    print(f"\nn = {args.n:.0e}, medians of {args.repeats} fits (s)")
    print("| stage | max_steps=1 | max_steps=5 | per extra step |")
    print("|---|---:|---:|---:|")
    for k in one["median_s"]:
        a, b = one["median_s"][k], five["median_s"][k]
        print(f"| {k} | {a:.4f} | {b:.4f} | {(b - a) / extra:.4f} |")
    for key, label in (("total_blas_threads_s", "total, OpenBLAS's threads"),
                       ("total_gc_s", "total, garbage collector running")):
        a, b = one[key], five[key]
        print(f"| {label} | {a:.4f} | {b:.4f} | {(b - a) / extra:.4f} |")
    out = {"command": f"python benchmarks/profiling/profile_fit_fixed.py --n {args.n} "
                      f"--repeats {args.repeats}",
           "n": args.n, "repeats": args.repeats, "load_average": os.getloadavg(),
           "machine": machine_facts(), "fits": [one, five],
           "jaxfric": jaxfric.__version__ if hasattr(jaxfric, "__version__") else None}
    Path(args.json).write_text(json.dumps(out, indent=1))
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
