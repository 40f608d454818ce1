"""Where the time of one two-state simulation goes: cumulative stages, side by side.

`TwoState._simulate` runs in stages (see benchmarks/NOTES.md): the motion's per-sample
inputs (velocity, direction, last direction) and the Stribeck values; the event pass (the
sequential ``lax.while_loop`` over blocks and events, on stopped gradients); and the
vectorised second pass (forward fill of the records, branch-start forces, the branch
force, the lag recurrence). Each row below is a separately compiled function that runs
the stages up to and including that one, so the difference between consecutive rows is
the cost of a stage, approximately (each row also writes its outputs to memory, which the
whole simulation fuses away or keeps, and the compiler may fuse differently). Also timed:
the whole simulation's ``jax.jacfwd`` over the 12 parameters (what a Levenberg-Marquardt
iteration needs).

Run ``python benchmarks/profile_two_state.py [--n N] [--repeats R] [--json OUT]``. All cases
are called once in turn per round (interleaved); medians over the rounds, in ns per sample,
on the mixed motion of `benchmarks/throughput.py` (`benchmarks/motions.py`).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import equinox as eqx
import jax
import jax.numpy as jnp

from jaxfric import paper
from jaxfric._inputs import make_motion, reversal_bound


try:
    from benchmarks.motions import mixed_path
except ImportError:  # run as a script: benchmarks/ itself is sys.path[0]
    from motions import mixed_path


def _stages(model, t, x):
    def motion(p):
        m = eqx.combine(p, static)
        mo = make_motion(t, x)
        s = m.stribeck.effective(mo.v, mo.last_d)
        return s, mo.reversal, mo.x_prev, m.stribeck.rest(mo.prev_last_d)

    def events(p):
        s, reversal, x_prev, s_r = motion(p)
        return eqx.combine(p, static)._event_pass(x, s, reversal, x_prev, s_r)

    def full(p):  # as `jaxfric.simulate` runs it on concrete data
        return eqx.combine(p, static)._simulate(make_motion(t, x, max_reversals=bound)).force

    bound = reversal_bound(t, x)

    params, static = eqx.partition(model, eqx.is_inexact_array)
    cases = {
        "1. motion inputs + Stribeck values": jax.jit(motion),
        "2. + event pass (while_loop)": jax.jit(events),
        "3. + vectorised second pass (= simulate)": jax.jit(full),
        "jacfwd of simulate (12 parameters)": jax.jit(jax.jacfwd(full)),
    }
    return params, cases


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="samples (default 1e6)")
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--json", help="write the results to this file")
    args = ap.parse_args(argv)
    if not jax.config.jax_enable_x64:
        raise SystemExit("run in float64 (the default with jaxfric imported)")

    t_np, x_np = mixed_path(args.n)
    params, cases = _stages(paper.two_state(), jnp.asarray(t_np), jnp.asarray(x_np))
    for f in cases.values():
        jax.block_until_ready(f(params))
    times = {k: [] for k in cases}
    for _ in range(args.repeats):
        for k, f in cases.items():
            t0 = time.perf_counter()
            jax.block_until_ready(f(params))
            times[k].append(time.perf_counter() - t0)
    rows, prev = [], 0.0
    print(f"two-state simulation, n = {args.n:.0e}, medians of {args.repeats} rounds")
    print(f"{'stage (cumulative)':44s} {'ns/sample':>10s} {'stage ns':>9s}")
    for k, ts in times.items():
        ns = statistics.median(ts) * 1e9 / args.n
        stage = ns - prev if k[0].isdigit() else None
        prev = ns if k[0].isdigit() else prev
        rows.append({"stage": k, "ns_per_sample": ns, "stage_ns_per_sample": stage})
        print(f"{k:44s} {ns:10.1f} {'' if stage is None else f'{stage:9.1f}'}")
    if args.json:
        meta = {"n": args.n, "repeats": args.repeats, "jax": jax.__version__,
                "devices": [str(d) for d in jax.devices()]}
        with open(args.json, "w") as fh:
            json.dump({"meta": meta, "rows": rows}, fh, indent=2)


if __name__ == "__main__":
    main()
