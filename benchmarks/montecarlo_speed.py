"""Monte-Carlo, batch and single-trajectory throughput of the two-state model against Numba.

Issue 19 item 3 asks for jaxfric >= 2x a Numba ``prange`` loop of the same algorithm
(`benchmarks/numba_two_state.py`) in three uses, all timed here side by side in one run:

- Monte-Carlo over parameters: `jaxfric.simulate_many` of B parameter sets (every
  inexact leaf of the paper model times ``1 + 0.05 * N(0, 1)``) on one trajectory, and
  the plain ``jax.vmap`` of `jaxfric.simulate` over them, against
  `simulate_numba_params` (``prange`` over the sets). Under ``vmap`` the motion
  (velocity, directions, reversals, reversal list) does not depend on the batched
  parameters, so JAX computes it once; the events, the Stribeck values, the shape
  and the lag depend on them (the loop-closure test ``(x - x_k)/(S - s_k) >= theta_k``
  involves ``S = s(v)``, ``Fs`` and ``l1``), so they run per set.
- A batch of B trajectories (random phases of the mixed motion) with one model,
  `jaxfric.simulate_many` and ``jax.vmap(jaxfric.simulate)``, against
  `simulate_numba_batch`.
- One trajectory of n samples, `jaxfric.simulate` against `simulate_numba`.

Also timed: the float64 elementwise operations the simulation is made of (``pow`` against
``exp(p * log(x))``, ``exp``, ``log``) on B x n elements, the reason the power in
`jaxfric._numerics._pos_pow` is written as an exponential of a logarithm.

Each jaxfric case runs twice, side by side: with the default (the two-state forward pass in
the compiled CPU kernel, `jaxfric._kernel.forward`, looping over the batch on up to
``len(os.sched_getaffinity(0))`` threads) and on the pure-JAX path
(``JAXFRIC_EVENT_KERNEL=jax``; ``pure`` columns). Every case is called once per round,
interleaved; medians over the rounds after a warm-up call. The machine is shared, so only
the ratios of one run mean much. Numba runs on ``numba.get_num_threads()`` threads; XLA on
the CPU runs the pure-JAX programs on one.

Run ``python benchmarks/montecarlo_speed.py [--quick] [--repeats R] [--json OUT]``
(defaults: B = 256, n = 1e4, single n = 1e5 and 1e6; ``--quick``: B = 8, n = 2000, single
n = 2000, 1 repeat, a smoke test). It prints a table and writes the JSON that
``benchmarks/make_validation.py`` renders into docs/validation.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numba
import numpy as np

import jaxfric
from jaxfric import _kernel, paper


try:
    from benchmarks import numba_two_state as nbts
    from benchmarks.motions import mixed_path
except ImportError:  # run as a script: benchmarks/ itself is sys.path[0]
    import numba_two_state as nbts
    from motions import mixed_path


def _median_times(cases: dict, repeats: int) -> dict[str, float]:
    """Median wall time (s) of each case, called once per round, interleaved, after a
    warm-up call of each."""
    for fn in cases.values():
        jax.block_until_ready(fn())
    times = {k: [] for k in cases}
    for _ in range(repeats):
        for k, fn in cases.items():
            t0 = time.perf_counter()
            jax.block_until_ready(fn())
            times[k].append(time.perf_counter() - t0)
    return {k: statistics.median(v) for k, v in times.items()}


def _spread(model, B: int, rng):
    """B parameter sets: every inexact leaf times ``1 + 0.05 * N(0, 1)`` (a batched model)."""
    params, static = eqx.partition(model, eqx.is_inexact_array)
    leaves, tree = jax.tree.flatten(params)
    batched = [jnp.asarray(leaf * (1 + 0.05 * rng.standard_normal((B, *jnp.shape(leaf)))))
               for leaf in leaves]
    return jax.tree.unflatten(tree, batched), static


def _pure(f, *args, **kwargs):
    """`f` on the pure-JAX path (``JAXFRIC_EVENT_KERNEL=jax``): `simulate` and
    `simulate_many` key their compilation caches on it, so both paths stay compiled."""
    with _kernel.forced("jax"):
        return f(*args, **kwargs)


def _row(what, size, times, diff):
    """`times`: medians of ``many`` (`jaxfric.simulate_many`, or `simulate` for one
    trajectory; the default, the compiled kernel on the CPU), ``pure`` (the
    same on the pure-JAX path), ``vmap`` (``jax.vmap`` of `simulate`; absent for
    one trajectory) and ``numba``."""
    return {"case": what, "size": size, "jaxfric_s": times["many"],
            "pure_jax_s": times["pure"],
            "vmap_s": times.get("vmap"), "numba_s": times["numba"],
            "ratio": times["numba"] / times["many"],
            "ratio_pure_jax": times["numba"] / times["pure"],
            "ratio_vmap": times["numba"] / times["vmap"] if "vmap" in times else None,
            "max_abs_diff_N": diff}


def bench_montecarlo(B, n, repeats) -> dict:
    model = paper.two_state()
    P, static = _spread(model, B, np.random.default_rng(0))
    t, x = mixed_path(n)
    bound = jaxfric.reversal_bound(t, x)
    tj, xj = jnp.asarray(t), jnp.asarray(x)
    run = jax.jit(jax.vmap(lambda p: jaxfric.simulate(eqx.combine(p, static), tj, xj,
                                                      max_reversals=bound)))
    models = eqx.combine(P, static)
    sets = [nbts.params_from_model(eqx.combine(jax.tree.map(lambda a, j=j: a[j], P), static))
            for j in range(B)]
    times = _median_times({"many": lambda: jaxfric.simulate_many(models, t, x),
                           "pure": lambda: _pure(jaxfric.simulate_many, models, t, x),
                           "vmap": lambda: run(P),
                           "numba": lambda: nbts.simulate_numba_params(sets, t, x)}, repeats)
    F = np.asarray(jaxfric.simulate_many(models, t, x))
    diff = float(np.max(np.abs(F - nbts.simulate_numba_params(sets, t, x))))
    diff = max(diff, float(np.max(np.abs(F - np.asarray(run(P))))),
               float(np.max(np.abs(F - np.asarray(_pure(jaxfric.simulate_many, models, t, x))))))
    return _row(f"Monte-Carlo: {B} parameter sets (5 % spread), one trajectory",
                {"B": B, "n": n}, times, diff)


def bench_batch(B, n, repeats) -> dict:
    model = paper.two_state()
    rng = np.random.default_rng(1)
    T, X = map(np.stack, zip(*[mixed_path(n, rng=rng) for _ in range(B)]))
    bound = max(jaxfric.reversal_bound(t, x) for t, x in zip(T, X))
    Tj, Xj = jnp.asarray(T), jnp.asarray(X)
    run = jax.jit(jax.vmap(lambda t, x: jaxfric.simulate(model, t, x, max_reversals=bound)))
    params = nbts.params_from_model(model)
    times = _median_times({"many": lambda: jaxfric.simulate_many(model, T, X, model_axis=None),
                           "pure": lambda: _pure(jaxfric.simulate_many, model, T, X,
                                                 model_axis=None),
                           "vmap": lambda: run(Tj, Xj),
                           "numba": lambda: nbts.simulate_numba_batch(params, T, X)}, repeats)
    F = np.asarray(jaxfric.simulate_many(model, T, X, model_axis=None))
    diff = float(np.max(np.abs(F - nbts.simulate_numba_batch(params, T, X))))
    diff = max(diff, float(np.max(np.abs(F - np.asarray(run(Tj, Xj))))))
    return _row(f"batch: {B} trajectories, one model", {"B": B, "n": n}, times, diff)


def bench_single(n, repeats) -> dict:
    model = paper.two_state()
    t, x = mixed_path(n)
    params = nbts.params_from_model(model)
    times = _median_times({"many": lambda: jaxfric.simulate(model, t, x),
                           "pure": lambda: _pure(jaxfric.simulate, model, t, x),
                           "numba": lambda: nbts.simulate_numba(params, t, x)}, repeats)
    F = np.asarray(jaxfric.simulate(model, t, x))
    diff = max(float(np.max(np.abs(F - nbts.simulate_numba(params, t, x)))),
               float(np.max(np.abs(F - np.asarray(_pure(jaxfric.simulate, model, t, x))))))
    return _row("one trajectory (simulate)", {"B": 1, "n": n}, times, diff)


def bench_ops(B, n, repeats) -> list[dict]:
    """ns per float64 element of the operations the simulation is made of."""
    rng = np.random.default_rng(2)
    u = jnp.asarray(rng.uniform(1e-3, 1.0, (B, n)))
    p = jnp.asarray(rng.uniform(0.2, 1.5, (B, 1)))
    ops = {
        "x ** p (XLA power)": jax.jit(lambda u, p: jnp.sum(u**p)),
        "exp(p * log(x))": jax.jit(lambda u, p: jnp.sum(jnp.exp(p * jnp.log(u)))),
        "exp(x)": jax.jit(lambda u, p: jnp.sum(jnp.exp(p * u))),
        "log(x)": jax.jit(lambda u, p: jnp.sum(jnp.log(p * u))),
        "x * p": jax.jit(lambda u, p: jnp.sum(p * u)),
    }
    times = _median_times({k: (lambda f=f: f(u, p)) for k, f in ops.items()}, repeats)
    a = np.asarray(u**p)
    rel = float(np.max(np.abs(np.asarray(jnp.exp(p * jnp.log(u))) - a) / a))
    return [{"op": k, "ns_per_element": s * 1e9 / (B * n),
             "max_rel_diff_to_power": rel if k.startswith("exp(p") else None}
            for k, s in times.items()]


def machine() -> dict:
    return {"platform": platform.platform(), "python": platform.python_version(),
            "jax": jax.__version__, "numba": numba.__version__,
            "numba_threads": numba.get_num_threads(), "cores": os.cpu_count(),
            "load_average": list(os.getloadavg()),
            "date_utc": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime())}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="tiny sizes, one repeat (smoke test)")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--json", help="write the results to this file")
    args = ap.parse_args(argv)
    if not jax.config.jax_enable_x64:
        raise SystemExit("run in float64 (the default with jaxfric imported)")
    B, n, singles = (8, 2000, [2000]) if args.quick else (256, 10_000, [100_000, 1_000_000])
    repeats = 1 if args.quick else args.repeats
    nbts.warm_up()
    start = time.perf_counter()
    rows = [bench_montecarlo(B, n, repeats), bench_batch(B, n, repeats)]
    rows += [bench_single(m, repeats) for m in singles]
    ops = bench_ops(B, n, repeats)
    print(f"two-state simulate against Numba prange ({numba.get_num_threads()} threads), "
          f"medians of {repeats} rounds; ratio = Numba time / jaxfric time (target >= 2); "
          "jaxfric: the compiled forward kernel (default), pure: the pure-JAX path")
    print(f"{'case':62s} {'B':>5s} {'n':>8s} {'jaxfric s':>10s} {'pure s':>8s} "
          f"{'vmap s':>8s} {'Numba s':>9s} {'ratio':>6s} {'(pure)':>6s} {'(vmap)':>6s} "
          f"{'max |dF| N':>10s}")
    for r in rows:
        vm = "-" if r["vmap_s"] is None else f"{r['vmap_s']:.4f}"
        rv = "-" if r["ratio_vmap"] is None else f"{r['ratio_vmap']:.2f}"
        print(f"{r['case']:62s} {r['size']['B']:5d} {r['size']['n']:8.0e} "
              f"{r['jaxfric_s']:10.4f} {r['pure_jax_s']:8.4f} {vm:>8s} {r['numba_s']:9.4f} "
              f"{r['ratio']:6.2f} {r['ratio_pure_jax']:6.2f} {rv:>6s} "
              f"{r['max_abs_diff_N']:10.2g}")
    print(f"\nfloat64 elementwise operations on {B} x {n} elements (ns per element):")
    for o in ops:
        extra = (f"  (max relative difference to the power: {o['max_rel_diff_to_power']:.2g})"
                 if o["max_rel_diff_to_power"] is not None else "")
        print(f"  {o['op']:22s} {o['ns_per_element']:6.2f}{extra}")
    if args.json:
        out = {"quick": args.quick, "repeats": repeats, "machine": machine(),
               "command": "python benchmarks/montecarlo_speed.py --json " + args.json,
               "total_s": time.perf_counter() - start, "rows": rows, "ops": ops}
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=2)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
