"""Where the first fit's time goes: every compilation of a fresh process, logged.

The compile goal of `benchmarks/throughput.py` takes a fit's first call minus its steady
state. This script says what that first call is made of: it runs `fitting.fit` (and then
`fitting.fit_batch`) of the two-state model once each in this process, with JAX's
``jax_log_compiles`` on, and prints every XLA compilation (what was compiled, seconds,
the line of jaxfric/fitting that asked for it), the tracing of the solve, and the wall
time of each call. Run it in a fresh process:

    python benchmarks/profiling/fit_compile.py [--n 10000] [--batch 4] [--warm-cache] [--json OUT]

With ``--warm-cache`` the same calls are then run twice more, each in a new process that
shares a fresh persistent compilation cache folder (`jaxfric.enable_compilation_cache`,
what the ``jaxfric`` command turns on): the first fills it, the second is reported. (The
in-process run is cold unless JAX_COMPILATION_CACHE_DIR is set; its JSON says which.)

Same data as the throughput script (the paper's two-state model on the mixed motion plus
0.05 N noise, started 4-50 % off; batch datasets of 1000 samples at 4 ms).
"""

from __future__ import annotations

import argparse
import json
import logging
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

import jax
import numpy as np

import fitting
import jaxfric
from jaxfric import paper


try:
    from benchmarks.motions import mixed_path, perturbed_start, synthetic_force
except ImportError:  # run as a script: benchmarks/profiling/ is sys.path[0]
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from motions import mixed_path, perturbed_start, synthetic_force


class _Log(logging.Handler):
    """Collects JAX's compile and trace messages with the project line that caused them."""

    def __init__(self):
        super().__init__()
        self.events = []

    def emit(self, record):
        msg = record.getMessage()
        kind = ("compile" if "XLA compilation" in msg else
                "trace" if msg.startswith("Finished tracing") else None)
        if kind is None:
            return
        frames = [f"{f.filename.rsplit('/', 2)[-2]}/{f.filename.rsplit('/', 1)[-1]}:{f.lineno}"
                  for f in traceback.extract_stack()
                  if ("/jaxfric/" in f.filename or "/fitting/" in f.filename)
                  and not f.filename.endswith("_compile.py")]  # the jit wrapper: its caller
        name = msg.split(" of ", 1)[-1] if kind == "compile" else msg.split("tracing ", 1)[-1]
        self.events.append({"kind": kind, "what": name.split(" in ")[0].split(" for ")[0],
                            "s": float(msg.rsplit(" in ", 1)[-1].split()[0]),
                            "where": frames[-1] if frames else "?"})


def _call(log, fn):
    start = len(log.events)
    t0 = time.perf_counter()
    jax.block_until_ready(fn().params)
    wall = time.perf_counter() - t0
    events = log.events[start:]
    compiles = [e for e in events if e["kind"] == "compile"]
    return {"wall_s": wall, "compilations": len(compiles),
            "compile_s": sum(e["s"] for e in compiles),
            "largest": max(compiles, key=lambda e: e["s"]) if compiles else None,
            "trace_s": sum(e["s"] for e in events if e["kind"] == "trace"), "events": events}


def _data(n: int, batch: int):
    """The start model, one dataset of n samples and `batch` datasets of 1000 samples."""
    truth = paper.two_state()
    t, x = mixed_path(n)
    F = synthetic_force(truth, t, x, np.random.default_rng(1))
    rng = np.random.default_rng(3)
    pairs = [mixed_path(1000, dt=4e-3, rng=rng) for _ in range(batch)]
    T = np.stack([p[0] for p in pairs])
    X = np.stack([p[1] for p in pairs])
    FB = np.stack([synthetic_force(truth, T[i], X[i], rng) for i in range(batch)])
    return perturbed_start(truth), (t, x, F), (T, X, FB)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=float, default=1e4, help="samples of the single fit")
    parser.add_argument("--batch", type=int, default=4, help="datasets of the batch fit")
    parser.add_argument("--json", help="write the results here")
    parser.add_argument("--warm-cache", action="store_true",
                        help="also time the calls in a new process with a warm disk cache")
    parser.add_argument("--cache-dir", help=argparse.SUPPRESS)  # used by --warm-cache
    args = parser.parse_args(argv)
    n = int(args.n)
    if args.cache_dir:
        jaxfric.enable_compilation_cache(args.cache_dir)

    start, (t, x, F), (T, X, FB) = _data(n, args.batch)

    log = _Log()
    logger = logging.getLogger("jax")
    saved = logger.level, logger.propagate
    logger.addHandler(log)
    logger.setLevel(logging.WARNING)
    logger.propagate = False  # the messages are collected, not printed
    jax.config.update("jax_log_compiles", True)
    calls = {
        f"fitting.fit, n = {n}, max_steps = 50 (first fit)":
            lambda: fitting.fit(start, t, x, F, max_steps=50),
        "the same again (compiled)": lambda: fitting.fit(start, t, x, F, max_steps=50),
        f"fitting.fit_batch, B = {args.batch}, n = 1000, max_steps = 50":
            lambda: fitting.fit_batch(start, T, X, FB, max_steps=50),
    }
    try:
        results = {name: _call(log, fn) for name, fn in calls.items()}
    finally:
        jax.config.update("jax_log_compiles", False)
        logger.removeHandler(log)
        logger.setLevel(saved[0])
        logger.propagate = saved[1]

    cache = jax.config.jax_compilation_cache_dir or None
    print(f"this process, disk cache: {cache or 'none'}")
    _table(results)
    first = next(iter(results.values()))
    print("\nCompilations of the first fit:")
    for e in first["events"]:
        if e["kind"] == "compile":
            print(f"  {e['s']:7.3f} s  {e['what']:<40} {e['where']}")
    out = {"meta": {"n": n, "batch": args.batch, "jax": jax.__version__, "cache_dir": cache},
           "calls": results}
    if args.warm_cache:
        out["warm_cache"] = _warm(argv_n=["--n", str(n), "--batch", str(args.batch)])
        print("\nA new process with a warm disk cache (filled by one run before it):")
        _table(out["warm_cache"])
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
        print(f"\nwrote {args.json}")


def _table(results) -> None:
    print(f"{'call':<58} {'wall s':>7} {'compilations':>12} {'compile s':>9} "
          f"{'trace s':>7}  largest compilation")
    for name, r in results.items():
        big = r["largest"]
        largest = f"{big['what']} {big['s']:.2f} s ({big['where']})" if big else "-"
        print(f"{name:<58} {r['wall_s']:7.2f} {r['compilations']:12d} {r['compile_s']:9.2f} "
              f"{r['trace_s']:7.2f}  {largest}")


def _warm(argv_n) -> dict:
    """Run this script twice in new processes sharing a new cache folder; the second's
    calls. (Compilations loaded from the cache are still logged, with their load time.)"""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, __file__, *argv_n, "--cache-dir", str(Path(tmp) / "cache")]
        for run in ("fill", "warm"):
            js = Path(tmp) / f"{run}.json"
            subprocess.run([*cmd, "--json", str(js)], check=True, capture_output=True)
        return json.loads(js.read_text())["calls"]


if __name__ == "__main__":
    main()
