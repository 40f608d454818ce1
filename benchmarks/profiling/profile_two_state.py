"""Where the time of one two-state simulation goes: cumulative stages, side by side.

On the CPU `jaxfric.simulate` runs the whole two-state forward pass in one compiled kernel
(`jaxfric._kernel.forward`), timed here as the row "forward kernel (= simulate)". The JAX
path (`TwoState._simulate_jax`: on GPU/TPU, and what the kernel is checked against) runs in
stages, each a method of the model that this script calls in the same order: the motion's
per-sample inputs (velocity, direction, last direction) and the Stribeck values; the event
pass (sequential, on stopped gradients: the compiled CPU kernel of `jaxfric._kernel` by
default, the pure-JAX ``lax.while_loop`` over blocks and events with
``JAXFRIC_EVENT_KERNEL=jax``); the forward fill of its records (which entry each sample
uses; the kernel returns it filled); the branch-start forces (evaluated on the list of
reversals, then gathered per sample); the branch force ``F_h`` and ``gamma`` (the shape
function at every sample); and the friction lag (its coefficients and the linear
recurrence), which completes the simulation. Each row below is a separately compiled
function that runs the stages up to and including that one and returns the sum of that
stage's outputs (so that writing them to memory is not timed; row 6 and the kernel's row
are whole simulations and write the force), and the difference between consecutive rows is the
cost of a stage, approximately (the compiler may fuse or overlap stages differently when
they end a function than inside the whole simulation). Also timed: the whole simulation's
``jax.jacfwd`` over the 12 parameters (what a Levenberg-Marquardt iteration needs), through
the kernel's Jacobian (dual numbers) and through the JAX path.

Run ``python benchmarks/profiling/profile_two_state.py [--n N] [--batch B | --params B]
[--repeats R] [--json OUT]``; the JSON's ``meta.event_pass`` says which event pass ran.
All cases are called once in turn per round (interleaved); medians over the rounds, in ns
per sample, on the mixed motion of `benchmarks/throughput.py` (`benchmarks/motions.py`).
With ``--batch B`` the stages run under ``jax.vmap`` over B such motions with random
phases (ns per trajectory-step; no ``jacfwd`` row); with ``--params B`` under ``jax.vmap``
over B parameter sets (5 % spread) on one motion (ns per set-step; no ``jacfwd`` row).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxfric import _kernel, paper
from jaxfric._models import two_state
from jaxfric.motion import make_motion, reversal_bound


try:
    from benchmarks.motions import mixed_path
except ImportError:  # run as a script: benchmarks/profiling/ is sys.path[0]
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from motions import mixed_path


def _over(stages, p, T, X, param_sets):
    """`stages` on one trajectory, vmapped over trajectories, or over parameter sets."""
    if param_sets:
        return jax.vmap(lambda q: stages(q, T, X))(p)
    if T.ndim == 1:
        return stages(p, T, X)
    return jax.vmap(lambda t, x: stages(p, t, x))(T, X)


def _stages(model, T, X, bound, param_sets=False):
    """The staged functions of `params`: on one trajectory if `T`, `X` are 1-D, else
    vmapped over their rows (as ``jax.vmap(jaxfric.simulate)`` runs). With `param_sets`,
    `params` has a leading batch axis and the stages are vmapped over it on the one
    trajectory ``(T, X)`` (a Monte-Carlo over parameters)."""
    params, static = eqx.partition(model, eqx.is_inexact_array)

    def upto(stage):
        """The simulation up to and including `stage` (as `TwoState._simulate` runs it)."""

        def run(p):
            out = _over(stages, p, T, X, param_sets)
            if stage >= 6:
                return out
            # One number from the stage's outputs: computing them is timed, writing them
            # to memory (several n-element arrays) is not.
            return sum(jnp.sum(a.astype(jnp.float64)) for a in jax.tree.leaves(out))

        def stages(p, t, x):
            m = eqx.combine(p, static)
            mo = make_motion(t, x, max_reversals=bound)
            if stage == 1:
                return m.stribeck.effective(mo.v, mo.last_d), m.stribeck.rest(mo.prev_last_d)
            s, rec = m._stage_events(mo)
            if stage == 2:  # what the fill reads, and one entry of the popped list
                return s, rec.event, rec.popped[0], rec.overflow
            active, depth, popped_until = two_state._fill_records(rec)
            if stage == 3:
                return active, depth, popped_until
            h_e = m._stage_branch_starts(mo, rec, popped_until)
            x_e, s_e = m._entry(mo, active)
            if stage == 4:
                return h_e, x_e, s_e
            f_h, _, gamma = m._branch(mo.x, s, x_e, h_e, s_e)
            if stage == 5:
                return f_h, gamma
            if stage == 6:
                return m._simulate_jax(mo.consistent()).force
            return m._simulate(mo).force  # as `jaxfric.simulate` runs it on concrete data

        return run

    names = [
        "1. motion inputs + Stribeck values",
        "2. + event pass",
        "3. + forward fill of the event records",
        "4. + branch-start forces (reversal list)",
        "5. + branch force F_h, gamma (shape)",
        "6. + friction lag (= JAX path)",
        "forward kernel (= simulate)",
    ]
    cases = {name: jax.jit(upto(i + 1)) for i, name in enumerate(names)}
    if T.ndim == 1 and not param_sets:
        cases["jacfwd, kernel (12 parameters)"] = jax.jit(jax.jacfwd(upto(7)))
        cases["jacfwd, JAX path (12 parameters)"] = jax.jit(jax.jacfwd(upto(6)))
    return params, cases


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="samples (default 1e6)")
    ap.add_argument("--batch", type=int, default=0,
                    help="profile a vmapped batch of this many trajectories of n samples "
                         "(random phases, as in the throughput batch section); ns per "
                         "trajectory-step")
    ap.add_argument("--params", type=int, default=0,
                    help="profile a vmap over this many parameter sets (every parameter "
                         "times 1 + 0.05 N(0, 1)) on one trajectory of n samples; ns per "
                         "set-step")
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--json", help="write the results to this file")
    args = ap.parse_args(argv)
    if not jax.config.jax_enable_x64:
        raise SystemExit("run in float64 (the default with jaxfric imported)")

    if args.batch:
        rng = np.random.default_rng(0)
        T, X = map(np.stack, zip(*[mixed_path(args.n, rng=rng) for _ in range(args.batch)]))
        bound = max(reversal_bound(t, x) for t, x in zip(T, X))
    else:
        T, X = mixed_path(args.n)
        bound = reversal_bound(T, X)
    params, cases = _stages(paper.two_state(), jnp.asarray(T), jnp.asarray(X), bound,
                            param_sets=bool(args.params))
    if args.params:
        rng = np.random.default_rng(0)
        params = jax.tree.map(
            lambda a: jnp.asarray(a * (1 + 0.05 * rng.standard_normal((args.params,
                                                                       *jnp.shape(a))))),
            params)
    per = args.n * max(args.batch, args.params, 1)
    for f in cases.values():
        jax.block_until_ready(f(params))
    times = {k: [] for k in cases}
    for _ in range(args.repeats):
        for k, f in cases.items():
            t0 = time.perf_counter()
            jax.block_until_ready(f(params))
            times[k].append(time.perf_counter() - t0)
    rows, prev = [], 0.0
    what = (f"B = {args.batch} trajectories (vmap) of " if args.batch else
            f"{args.params} parameter sets (vmap) on one trajectory of " if args.params else "")
    unit = "ns/traj-step" if args.batch else "ns/set-step" if args.params else "ns/sample"
    print(f"two-state simulation, {what}n = {args.n:.0e}, medians of {args.repeats} rounds")
    print(f"{'stage (cumulative)':44s} {unit:>12s} {'stage ns':>9s}")
    for k, ts in times.items():
        ns = statistics.median(ts) * 1e9 / per
        stage = ns - prev if k[0].isdigit() else None
        prev = ns if k[0].isdigit() else prev
        rows.append({"stage": k, "ns_per_sample": ns, "stage_ns_per_sample": stage})
        print(f"{k:44s} {ns:12.1f} {'' if stage is None else f'{stage:9.1f}'}")
    if args.json:
        meta = {"n": args.n, "batch": args.batch, "params": args.params,
                "repeats": args.repeats,
                "jax": jax.__version__,
                "event_pass": ("kernel" if _kernel.mode() != "jax" and _kernel.available()
                               else "pure JAX"),
                "devices": [str(d) for d in jax.devices()]}
        with open(args.json, "w") as fh:
            json.dump({"meta": meta, "rows": rows}, fh, indent=2)


if __name__ == "__main__":
    main()
