"""What XLA's building blocks cost on this machine: the numbers behind the profile.

docs/benchmark_notes.md explains the two-state model's speed against a Numba loop with the
price of the operations its vectorised passes are made of. This script measures them,
side by side (all cases called once in turn per round, medians), in float64:

- elementwise functions over n = 1e6 samples (ns per element): a multiplication, the
  exponential, ``expm1``, the logarithm, and a power with a traced exponent;
- a ``lax.scan`` with a one-add body over n samples (ns per step), and the same scan
  under ``vmap`` over 256 rows of n/100 samples (ns per row-step), as the vmapped
  simulation runs its scans;
- the event pass of `TwoState` on the benchmark motion (`benchmarks/motions.py`,
  n = 1e6): the number of reversals and events, the loop's iterations (blocks plus events)
  and its time per iteration.

Run ``python benchmarks/profiling/xla_costs.py [--n N] [--repeats R] [--json OUT]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxfric import paper
from jaxfric._models import two_state
from jaxfric.motion import make_motion


try:
    from benchmarks.motions import mixed_path
except ImportError:  # run as a script: benchmarks/profiling/ is sys.path[0]
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from motions import mixed_path


def _scan_sum(a):
    def body(c, v):
        c = c + v
        return c, c

    return jax.lax.scan(body, jnp.zeros(a.shape[1:], a.dtype), a)[1]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="samples (default 1e6)")
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--json", help="write the results to this file")
    args = ap.parse_args(argv)
    if not jax.config.jax_enable_x64:
        raise SystemExit("run in float64 (the default with jaxfric imported)")
    n = args.n
    rng = np.random.default_rng(0)
    u = jnp.asarray(rng.uniform(0.1, 2.0, n))
    p = jnp.asarray(1.7)
    ub = jnp.asarray(rng.normal(size=(256, max(n // 100, 1))))  # 256 x 1e4 at n = 1e6

    model = paper.two_state()
    t, x = map(jnp.asarray, mixed_path(n))
    mo = make_motion(t, x)
    s = model.stribeck.effective(mo.v, mo.last_d)
    s_r = model.stribeck.rest(mo.prev_last_d)
    ev_args = [jax.block_until_ready(a) for a in (x, s, mo.reversal, mo.x_prev, s_r)]

    cases = {  # name: (function, argument, unit count, unit)
        "x * 2": (jax.jit(lambda a: a * 2.0), u, n, "ns/element"),
        "exp(x)": (jax.jit(jnp.exp), u, n, "ns/element"),
        "expm1(x)": (jax.jit(jnp.expm1), u, n, "ns/element"),
        "log(x)": (jax.jit(jnp.log), u, n, "ns/element"),
        "x ** p (p traced)": (jax.jit(lambda a, q=p: a**q), u, n, "ns/element"),
        "lax.scan, one add per step": (jax.jit(_scan_sum), u, n, "ns/step"),
        f"the same under vmap, {ub.shape[0]} rows": (
            jax.jit(jax.vmap(_scan_sum)), ub, ub.size, "ns/row-step"),
        "TwoState event pass (one trajectory)": (
            jax.jit(lambda *a: model._event_pass(*a).table), ev_args, n, "ns/sample"),
    }

    def call(f, a):
        return f(*a) if isinstance(a, list) else f(a)

    outs = {k: jax.block_until_ready(call(f, a)) for k, (f, a, _, _) in cases.items()}
    times = {k: [] for k in cases}
    for _ in range(args.repeats):
        for k, (f, a, _, _) in cases.items():
            t0 = time.perf_counter()
            jax.block_until_ready(call(f, a))
            times[k].append(time.perf_counter() - t0)

    table = np.asarray(outs["TwoState event pass (one trajectory)"])
    events = int(np.count_nonzero(table[:-1, 1] > 0))
    reversals = int(np.count_nonzero(np.asarray(mo.reversal)))
    iterations = -(-n // two_state._WINDOW) + events
    ev_s = statistics.median(times["TwoState event pass (one trajectory)"])

    rows = []
    print(f"XLA building blocks, float64, medians of {args.repeats} rounds")
    print(f"{'operation':44s} {'time':>9s}  unit")
    for k, (_, _, count, unit) in cases.items():
        value = statistics.median(times[k]) * 1e9 / count
        rows.append({"operation": k, "value": value, "unit": unit})
        print(f"{k:44s} {value:9.2f}  {unit}")
    event_facts = {"n": n, "reversals": reversals, "events": events,
                   "window": two_state._WINDOW, "iterations": iterations,
                   "us_per_iteration": ev_s * 1e6 / iterations}
    print(f"\nevent pass on the benchmark motion, n = {n:.0e}: {reversals} reversals, "
          f"{events} events, {iterations} iterations (blocks of {two_state._WINDOW} plus "
          f"events), {event_facts['us_per_iteration']:.2f} us per iteration")
    if args.json:
        meta = {"n": n, "repeats": args.repeats, "jax": jax.__version__,
                "devices": [str(d) for d in jax.devices()]}
        with open(args.json, "w") as fh:
            json.dump({"meta": meta, "rows": rows, "event_pass": event_facts}, fh, indent=2)


if __name__ == "__main__":
    main()
