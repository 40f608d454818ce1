"""Throughput of jaxfric: simulation, batches, gradients, fits, against a Numba baseline.

Everything is measured side by side in one run, on one machine, so that every ratio is a
pair measured under the same conditions. Prints tables; ``--json OUT`` writes every number
(plus the machine's facts) for ``benchmarks/make_validation.py``, which writes
docs/validation.md.

Run ``python benchmarks/throughput.py [--quick] [--repeats N] [--json OUT]``.
``--quick`` is a smoke run (about a minute: small sizes, fewer repeats) that exercises every
section; its numbers are not the benchmark. The full run takes several minutes; run it on
a quiet machine.

**How things are timed.** Each case is called once first (the warm-up: tracing, compiling
and one run; its excess over the steady-state time is reported as the compile time), then
`repeats` rounds in which every case of a section is called once in turn (interleaved, so
that a load change on the machine affects all of them alike). Reported: the median over the
rounds. Every JAX result is waited for with ``jax.block_until_ready``. Inputs are on the
device (``jnp.asarray``) before timing; the Numba baseline gets NumPy arrays.

**Sections** (SI units: t in s, x in m, forces in N):

1. *Single trajectory*: ``jaxfric.simulate(model, t, x)`` (the public entry point, with its
   input checks) for `TwoState` (``paper.two_state()``), GMS with N = 5, 10, 50, 200
   elements discretising the paper's shape (``paper.gms(N)``), LuGre (``paper.lugre()``),
   and the Numba baseline (``benchmarks/numba_two_state.py``), on a mixed motion: a 1 mm
   sliding sine with presliding loops of 100 um and 20 um on top (about one reversal per
   0.36 s at 1 kHz sampling). The Numba and jaxfric forces are compared on it too.
2. *Batch*: ``jax.jit(jax.vmap(simulate))`` over B trajectories (random phases; with
   ``max_reversals``, the static bound on the reversals that ``simulate`` computes itself
   on concrete data, as the data are traced under ``vmap``) against
   ``simulate_numba_batch`` (``numba.prange`` over trajectories). Each B is compiled first;
   XLA's own memory analysis (arguments + outputs + temporaries) plus the host copies of
   the inputs give the footprint, and a B whose footprint exceeds ``--mem-budget-gb``
   (default 4 GiB, for a shared machine) is skipped and reported as skipped, each path
   on its own footprint: the pure-JAX path needs about 180 bytes per trajectory-step, so
   it skips B = 4096 at 1e4 steps (about 6.7 GiB) by default (``--mem-budget-gb 8``
   includes it); the forward kernel needs its inputs and outputs only. The Numba batch
   needs 24 bytes per trajectory-step and runs wherever it fits.
3. *Compile times*: first call minus steady state for each model (section 1), and
   ``lower()`` / ``compile()`` timings for the vmapped simulation and the gradients.
4. *Gradients*: ``jax.grad`` of ``sum(simulate(model, t, x)**2)`` with respect to every
   parameter of the two-state model, against the same loss forward; and ``jax.jacfwd`` of
   the force with respect to the model (what a Levenberg-Marquardt step needs).
5. *One Levenberg-Marquardt iteration*: ``fitting.fit`` of the two-state model (all 12
   parameters free; the paper shape is fitted in its 5 normalised coordinates, so the
   solver sees 11) on noisy synthetic data (the paper model on the mixed motion plus
   0.05 N noise), from a start with 7 parameters off by 4-50 %. A fit with ``max_steps=1``
   pays for the problem set-up, the first residual and Jacobian, the final covariance and
   the Python-side assembly of the result; a fit with ``max_steps=5`` pays for all of that
   plus 4 more iterations, each one residual and Jacobian (11 forward-mode columns, as
   `fitting` computes it) and one damped QR solve, whether the step is accepted or not.
   One iteration = (median(max_steps=5) - median(max_steps=1)) / (difference of the
   reported ``num_steps``, checked to be 1 and 5). Four iterations rather than one make
   the difference stand well above the timing noise.
6. *Batch fits*: ``fitting.fit_batch`` of B = 1, 4, 16, 64 small datasets (one compiled
   call that solves them one after the other); time per dataset. Each dataset runs until
   its own termination, so the time per dataset-iteration is over the sum of the
   ``num_steps``. At the second largest B the vmapped solve (``vectorize=True``, one loop
   for all datasets until the slowest stops) is timed side by side.
7. *float32 vs float64*: the two-state model on a nested presliding path (loop amplitudes
   100 um down to 1 um), once in float64 and once in a subprocess with ``JAXFRIC_NO_X64=1``
   (JAX's x64 mode is global to a process, so float32 needs its own); max |F32 - F64| in N
   and relative to Fs. The same loops are also run at absolute positions of 10 cm and 1 m
   (a stage coordinate), where float32 resolves only ~7.5 nm and ~60 nm.

**Goals** (from issue 7), each marked PASS or MISS, never tuned for: the two-state
simulation at least 2x as fast as the Numba baseline (single trajectory, largest size; and
batch, largest B run by both); the two-state model at least 5x as fast as GMS-200; one LM
iteration on 1e5 samples under 0.1 s (n/a when the run used another size, as ``--quick``
does); compile under 5 s for each compiled thing measured.
"""

from __future__ import annotations

import argparse
import functools
import itertools
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import fitting
import jaxfric
from jaxfric import _kernel, paper


try:
    from benchmarks import numba_two_state as nbts
    from benchmarks.motions import mixed_path, perturbed_start, synthetic_force, UM
except ImportError:  # run as a script: benchmarks/ itself is sys.path[0]
    import numba_two_state as nbts
    from motions import mixed_path, perturbed_start, synthetic_force, UM
try:
    from benchmarks.machine import machine_facts
    from benchmarks.throughput_report import GMS_SIZES, ratios_and_goals, report
except ImportError:
    from machine import machine_facts
    from throughput_report import GMS_SIZES, ratios_and_goals, report


#: Sizes of the full run and of ``--quick``.
FULL = {
    "single_n": [100_000, 1_000_000],
    "batch_B": [64, 256, 1024, 4096],
    "batch_n": 10_000,
    "grad_n": [10_000, 100_000],
    "lm_n": 100_000,
    "fit_batch_B": [1, 4, 16, 64],
    "fit_batch_n": 1000,
    "fit_batch_max_steps": 50,
    "repeats": 5,
}
QUICK = {
    "single_n": [20_000],
    "batch_B": [16, 64],
    "batch_n": 1000,
    "grad_n": [5000],
    "lm_n": 5000,
    "fit_batch_B": [2],
    "fit_batch_n": 200,
    "fit_batch_max_steps": 8,
    "repeats": 3,
}
LM_STEPS = (1, 5)  # one LM iteration = (T(5) - T(1)) / 4, see section 5


# ---------------------------------------------------------------------------------------
# Motions
# ---------------------------------------------------------------------------------------


def nested_presliding_path(dt: float = 1e-3, speed: float = 20 * UM):
    """Nested presliding loops from 100 um down to 1 um amplitude, then back to +100 um
    (which closes them all), at constant `speed` (m/s), sampled every `dt` s."""
    turns = np.array([0, 100, -100, 60, -60, 30, -30, 10, -10, 3, -3, 1, -1, 100]) * UM
    xs = [turns[0]]
    for a, b in itertools.pairwise(turns):
        m = max(round(abs(b - a) / speed / dt), 1)
        xs.extend(np.linspace(a, b, m + 1)[1:])
    x = np.asarray(xs)
    return dt * np.arange(x.size), x


# ---------------------------------------------------------------------------------------
# Timing helpers
# ---------------------------------------------------------------------------------------


def _timed(fn: Callable) -> float:
    t0 = time.perf_counter()
    jax.block_until_ready(fn())
    return time.perf_counter() - t0


def measure(cases: dict[str, Callable], repeats: int) -> dict[str, dict]:
    """Warm-up call of each case, then `repeats` interleaved rounds; see the module doc.

    Returns per case ``first_s`` (warm-up call), ``median_s``, ``min_s``, ``times_s`` and
    ``compile_s = first_s - median_s`` (tracing + compilation, for a JAX case).
    """
    out = {name: {"first_s": _timed(fn), "times_s": []} for name, fn in cases.items()}
    for _ in range(repeats):
        for name, fn in cases.items():
            out[name]["times_s"].append(_timed(fn))
    for r in out.values():
        r["median_s"] = statistics.median(r["times_s"])
        r["min_s"] = min(r["times_s"])
        r["compile_s"] = r["first_s"] - r["median_s"]
    return out


def _lower_compile(jitted, *args):
    """``jitted.lower(*args).compile()`` with both phases timed (s)."""
    t0 = time.perf_counter()
    lowered = jitted.lower(*args)
    t1 = time.perf_counter()
    compiled = lowered.compile()
    t2 = time.perf_counter()
    return compiled, t1 - t0, t2 - t1


def _xla_bytes(compiled) -> int | None:
    """Arguments + outputs + temporaries of a compiled XLA program (bytes), if known."""
    try:
        ma = compiled.memory_analysis()
        return int(ma.argument_size_in_bytes + ma.output_size_in_bytes
                   + ma.temp_size_in_bytes)
    except Exception:  # not every backend/version reports it
        return None


# ---------------------------------------------------------------------------------------
# Sections
# ---------------------------------------------------------------------------------------


def jax_models() -> dict:
    models = {"TwoState": paper.two_state()}
    models.update({f"GMS-{n}": paper.gms(n) for n in GMS_SIZES})
    models["LuGre"] = paper.lugre()
    return models


#: The two-state model on its pure-JAX path (``JAXFRIC_EVENT_KERNEL=jax``), timed
#: beside the default (the compiled kernel on the CPU, `jaxfric._kernel`).
PURE = "TwoState (pure JAX)"


def _pure(f, *args, **kwargs):
    """`f` traced and run on the pure-JAX path (`simulate` keys its compilation
    cache on the choice, so both stay compiled side by side)."""
    with _kernel.forced("jax"):
        return f(*args, **kwargs)


def bench_single(sizes, repeats, log) -> dict:
    """Section 1: one long trajectory per size, every model, plus the Numba baseline."""
    params = nbts.params_from_model(paper.two_state())
    rows, checks = [], []
    for n in sizes:
        t, x = mixed_path(n)
        tj, xj = jnp.asarray(t), jnp.asarray(x)
        cases = {name: (lambda m=m, tj=tj, xj=xj: jaxfric.simulate(m, tj, xj))
                 for name, m in jax_models().items()}
        cases[PURE] = lambda tj=tj, xj=xj: _pure(jaxfric.simulate, paper.two_state(), tj, xj)
        cases["Numba two-state"] = lambda t=t, x=x: nbts.simulate_numba(params, t, x)
        log(f"  single n={n:.0e}: {', '.join(cases)}")
        res = measure(cases, repeats)
        for name, r in res.items():
            rows.append({"impl": name, "n": n, "median_s": r["median_s"], "min_s": r["min_s"],
                         "us_per_step": 1e6 * r["median_s"] / n, "first_s": r["first_s"],
                         "compile_s": None if name.startswith("Numba") else r["compile_s"],
                         "times_s": r["times_s"]})
        full = jaxfric.simulate(paper.two_state(), tj, xj, full_output=True)
        f_nb, ovf_nb = nbts.simulate_numba(params, t, x, full_output=True)
        checks.append({
            "n": n,
            "max_abs_diff_N": float(np.max(np.abs(np.asarray(full.force) - f_nb))),
            "overflow_jaxfric": int(full.overflow),
            "overflow_numba": ovf_nb,
            "max_depth": int(np.max(np.asarray(full.parts["depth"]))),
            "reversals": int(np.sum(np.diff(np.sign(np.diff(x))) != 0)),
        })
    return {"rows": rows, "agreement": checks}


def _batch_paths(B, n, rng) -> tuple[np.ndarray, np.ndarray]:
    """B mixed paths of n samples on one time grid: ``(T, X)``, each ``(B, n)``."""
    T = np.tile(mixed_path(n)[0], (B, 1))
    X = np.empty((B, n))
    for j in range(B):
        X[j] = mixed_path(n, rng=rng)[1]
    return T, X


def _batch_agreement(kernel, pure, numba) -> dict:
    """Max |dF| (N) of the default path against Numba and against the pure-JAX path."""
    kernel = np.asarray(kernel)
    out = {"max_abs_diff_N": float(np.max(np.abs(kernel - numba)))}
    if pure is not None:
        out["kernel_vs_pure_max_abs_diff_N"] = float(np.max(np.abs(kernel - np.asarray(pure))))
    return out


def _batched(bound):
    """``jax.jit(jax.vmap(simulate))`` over trajectories, with the static reversal bound."""
    return jax.jit(lambda m, T, X: jax.vmap(
        lambda t, x: jaxfric.simulate(m, t, x, max_reversals=bound))(T, X))


def _footprints(compiled, pure, B, n, budget_bytes):
    """The memory footprints of a batch (XLA's analysis plus the host inputs; Numba's inputs
    and output) and which cases fit the budget: ``(row, run_jax, run_pure, run_numba)``."""
    xla_bytes, pure_bytes = _xla_bytes(compiled), _xla_bytes(pure)
    host_in = 2 * B * n * 8  # NumPy T and X
    numba_bytes = host_in + B * n * 8  # inputs + output
    jax_total = None if xla_bytes is None else xla_bytes + host_in
    pure_total = None if pure_bytes is None else pure_bytes + host_in
    row = {"B": B, "n": n, "xla_bytes": xla_bytes, "jax_footprint_bytes": jax_total,
           "jax_pure_footprint_bytes": pure_total, "numba_footprint_bytes": numba_bytes}

    def fits(total, key):
        if total is not None and total > budget_bytes:
            row[key] = (f"estimated {total / 2**30:.1f} GiB > budget "
                        f"{budget_bytes / 2**30:.1f} GiB")
            return False
        return True

    run_jax = fits(jax_total, "jax_skipped")
    run_pure = run_jax and fits(pure_total, "jax_pure_skipped")
    run_numba = fits(numba_bytes, "numba_skipped")
    return row, run_jax, run_pure, run_numba


def bench_batch(sizes_B, n, repeats, budget_bytes, log) -> dict:
    """Section 2: vmapped jaxfric against the Numba prange batch, per B."""
    model = paper.two_state()
    params = nbts.params_from_model(model)
    dtype = jnp.asarray(0.0).dtype
    rows = []
    rng = np.random.default_rng(7)
    for B in sizes_B:
        T, X = _batch_paths(B, n, rng)
        # Under vmap the positions are traced, so the static bound on the reversals that
        # `simulate` computes itself on concrete data is passed, as a user would.
        bound = max(jaxfric.reversal_bound(T[j], X[j]) for j in range(B))
        spec = jax.ShapeDtypeStruct((B, n), dtype)
        compiled, t_lower, t_compile = _lower_compile(_batched(bound), model, spec, spec)
        pure, _, _ = _pure(_lower_compile, _batched(bound), model, spec, spec)
        row, run_jax, run_pure, run_numba = _footprints(compiled, pure, B, n, budget_bytes)
        row.update(lower_s=t_lower, compile_s=t_compile)
        cases = {}
        if run_jax or run_numba:
            if run_jax:
                Tj, Xj = jnp.asarray(T), jnp.asarray(X)
                cases["jaxfric vmap"] = lambda c=compiled, T=Tj, X=Xj: c(model, T, X)
                if run_pure:
                    cases["pure JAX vmap"] = lambda c=pure, T=Tj, X=Xj: c(model, T, X)
            if run_numba:
                cases["Numba prange"] = (
                    lambda T=T, X=X: nbts.simulate_numba_batch(params, T, X))
        log(f"  batch B={B}, n={n:.0e}: {', '.join(cases) or 'skipped'}"
            + (f" ({row.get('jax_skipped')})" if not run_jax else ""))
        if cases:
            res = measure(cases, repeats)
            for name, key in (("jaxfric vmap", "jax"), ("pure JAX vmap", "jax_pure"),
                              ("Numba prange", "numba")):
                if name in res:
                    r = res[name]
                    row[f"{key}_median_s"] = r["median_s"]
                    row[f"{key}_min_s"] = r["min_s"]
                    row[f"{key}_ns_per_traj_step"] = 1e9 * r["median_s"] / (B * n)
                    row[f"{key}_times_s"] = r["times_s"]
            if run_jax and run_numba:
                row.update(_batch_agreement(compiled(model, Tj, Xj),
                                            pure(model, Tj, Xj) if run_pure else None,
                                            nbts.simulate_numba_batch(params, T, X)))
            cases.clear()
            if run_jax:
                del Tj, Xj
            del T, X
        rows.append(row)
    return {"rows": rows, "budget_bytes": budget_bytes}


def _loss(model, t, x):
    """Sum of squared forces, N^2: a scalar that depends on every parameter."""
    return jnp.sum(jaxfric.simulate(model, t, x) ** 2)


def bench_grad(sizes, repeats, log) -> dict:
    """Section 4: forward loss, its gradient and the force Jacobian (two-state)."""
    model = paper.two_state()
    fwd = jax.jit(_loss)
    grad = jax.jit(jax.grad(_loss))
    jac = jax.jit(jax.jacfwd(lambda m, t, x: jaxfric.simulate(m, t, x)))
    n_params = len(jax.tree.leaves(eqx.filter(model, eqx.is_inexact_array)))
    rows = []
    for n in sizes:
        t, x = mixed_path(n)
        tj, xj = jnp.asarray(t), jnp.asarray(x)
        cases, comp = {}, {}
        for name, f in (("forward", fwd), ("grad", grad), ("jacfwd", jac)):
            c, tl, tc = _lower_compile(f, model, tj, xj)
            comp[name] = {"lower_s": tl, "compile_s": tc}
            cases[name] = lambda c=c, tj=tj, xj=xj: c(model, tj, xj)
        log(f"  grad n={n:.0e}")
        res = measure(cases, repeats)
        row = {"n": n, "n_params": n_params}
        for name, r in res.items():
            row[name] = {"median_s": r["median_s"], "min_s": r["min_s"],
                         "times_s": r["times_s"], **comp[name]}
        row["grad_over_forward"] = res["grad"]["median_s"] / res["forward"]["median_s"]
        row["jacfwd_over_forward"] = res["jacfwd"]["median_s"] / res["forward"]["median_s"]
        rows.append(row)
    return {"rows": rows}


def bench_lm(n, repeats, log) -> dict:
    """Section 5: one Levenberg-Marquardt iteration from fits with two `LM_STEPS` limits."""
    truth = paper.two_state()
    t, x = mixed_path(n)
    F = synthetic_force(truth, t, x, np.random.default_rng(1))
    start = perturbed_start(truth)
    out = {}

    def fit(steps):
        res = fitting.fit(start, t, x, F, max_steps=steps)
        out[steps] = res
        return res.params, res.num_steps

    lo, hi = LM_STEPS
    log(f"  LM fit n={n:.0e}: max_steps={lo} and {hi}")
    res = measure({f"max_steps={k}": (lambda k=k: fit(k)) for k in LM_STEPS}, repeats)
    r_lo, r_hi = res[f"max_steps={lo}"], res[f"max_steps={hi}"]
    steps = {k: int(out[k].num_steps) for k in LM_STEPS}
    extra = max(steps[hi] - steps[lo], 1)
    per_round = [(b - a) / extra for a, b in zip(r_lo["times_s"], r_hi["times_s"])]
    keep = ("first_s", "median_s", "min_s", "times_s", "compile_s")
    return {
        "n": n,
        "natural_params": list(out[lo].names),
        "fit_coordinates": list(out[lo].fit_names),
        "free": list(out[lo].free),
        "max_steps": list(LM_STEPS),
        "num_steps": [steps[k] for k in LM_STEPS],
        "num_steps_ok": all(steps[k] == k for k in LM_STEPS),
        "status": [out[k].status for k in LM_STEPS],
        "fits": [{"max_steps": k, **{q: res[f"max_steps={k}"][q] for q in keep}}
                 for k in LM_STEPS],
        "iteration_s": (r_hi["median_s"] - r_lo["median_s"]) / extra,
        "iteration_s_median_of_rounds": statistics.median(per_round),
    }


def bench_lm_both(n, repeats, log) -> tuple[dict, dict]:
    """Section 5 with the default (the compiled kernels on the CPU), then with the pure-JAX
    one. The fits' programs do not key their caches on the choice: each is traced afresh."""
    jax.clear_caches()
    default = bench_lm(n, repeats, log)
    jax.clear_caches()
    log("  (pure-JAX path)")
    pure = _pure(bench_lm, n, repeats, log)
    jax.clear_caches()
    return default, pure


def bench_fit_batch(sizes_B, n, max_steps, repeats, log) -> dict:
    """Section 6: fitting.fit_batch over B small datasets, time per dataset."""
    truth = paper.two_state()
    start = perturbed_start(truth)
    rng = np.random.default_rng(3)
    rows = []
    compare_B = sizes_B[-2] if len(sizes_B) > 1 else sizes_B[0]
    for B in sizes_B:
        pairs = [mixed_path(n, dt=4e-3, rng=rng) for _ in range(B)]
        T = np.stack([p[0] for p in pairs])
        X = np.stack([p[1] for p in pairs])
        F = np.stack([synthetic_force(truth, T[i], X[i], rng) for i in range(B)])
        out = {}

        def run(T=T, X=X, F=F, out=out, vectorize=False):
            res = fitting.fit_batch(start, T, X, F, max_steps=max_steps, vectorize=vectorize)
            out["vmap" if vectorize else "res"] = res
            return res.params, res.num_steps

        # At one B, also the vmapped solve (`vectorize=True`), side by side.
        compare = B == compare_B
        log(f"  fit_batch B={B}, n={n}" + (" (and vectorize=True)" if compare else ""))
        cases = {"fit_batch": run}
        if compare:
            cases["vmap"] = functools.partial(run, vectorize=True)
        timed = measure(cases, repeats)
        r = timed["fit_batch"]
        steps = np.asarray(out["res"].num_steps)
        status = out["res"].status
        if compare:
            rv, steps_v = timed["vmap"], np.asarray(out["vmap"].num_steps)
            vmap_row = {
                "median_s": rv["median_s"], "compile_s": rv["compile_s"],
                "num_steps_mean": float(np.mean(steps_v)),
                "num_steps_max": int(np.max(steps_v)),
                # one loop for all: every dataset pays for the slowest one's iterations
                "per_dataset_iteration_s": rv["median_s"] / (B * max(int(np.max(steps_v)), 1)),
                "map_over_vmap_time": r["median_s"] / rv["median_s"],
            }
        rows.append({
            "B": B, "n": n, "max_steps": max_steps,
            "median_s": r["median_s"], "min_s": r["min_s"], "times_s": r["times_s"],
            "first_s": r["first_s"], "compile_s": r["compile_s"],
            "per_dataset_s": r["median_s"] / B,
            "num_steps_mean": float(np.mean(steps)), "num_steps_max": int(np.max(steps)),
            # The datasets are solved one after the other (`fit_batch`'s default), each
            # until its own termination: the time per dataset-iteration uses all steps.
            "per_dataset_iteration_s": r["median_s"] / max(int(np.sum(steps)), 1),
            "successful": int(sum(s == "successful" for s in status)),
            **({"vectorize": vmap_row} if compare else {}),
        })
    return {"rows": rows}


# ---- float32 ---------------------------------------------------------------------------


F32_OFFSETS_M = (0.0, 0.1, 1.0)  # absolute positions of the same loops: 0, 10 cm, 1 m


def _float32_worker(inp: str, outp: str) -> int:
    """Child process (JAXFRIC_NO_X64=1): simulate in float32, write the forces and timing."""
    data = np.load(inp)
    model = paper.two_state()
    t = jnp.asarray(data["t"], dtype=jnp.float32)
    forces, dtypes = [], set()
    for off in data["offsets"]:
        x = jnp.asarray(data["x"] + off, dtype=jnp.float32)  # offset added in float64
        force = jaxfric.simulate(model, t, x)
        dtypes.add(str(force.dtype))
        forces.append(np.asarray(force, dtype=np.float64))
    tt, xt = (jnp.asarray(a, dtype=jnp.float32) for a in mixed_path(int(data["n_speed"])))
    r = measure({"f32": lambda: jaxfric.simulate(model, tt, xt)}, int(data["repeats"]))["f32"]
    np.savez(outp, F=np.stack(forces), dtype=",".join(sorted(dtypes)),
             param_dtype=str(model.C.dtype), x64=jaxfric.x64_enabled(),
             speed_median_s=r["median_s"])
    return 0


def bench_float32(n_speed, repeats, log) -> dict:
    """Section 7: max |F32 - F64| on nested presliding loops (100 um down to 1 um), with the
    loops at absolute positions `F32_OFFSETS_M` (float32 resolves ~1e-7 relative)."""
    t, x = nested_presliding_path()
    model = paper.two_state()
    f64 = [np.asarray(jaxfric.simulate(model, t, x + off)) for off in F32_OFFSETS_M]
    tt, xt = (jnp.asarray(a) for a in mixed_path(n_speed))
    speed64 = measure({"f64": lambda: jaxfric.simulate(model, tt, xt)}, repeats)["f64"]
    log(f"  float32 subprocess (JAXFRIC_NO_X64=1), {t.size} samples")
    with tempfile.TemporaryDirectory() as tmp:
        inp, outp = os.path.join(tmp, "in.npz"), os.path.join(tmp, "out.npz")
        np.savez(inp, t=t, x=x, offsets=np.asarray(F32_OFFSETS_M), n_speed=n_speed,
                 repeats=repeats)
        env = dict(os.environ, JAXFRIC_NO_X64="1")
        proc = subprocess.run([sys.executable, os.path.abspath(__file__), "--float32-worker",
                               inp, outp], env=env, capture_output=True, text=True,
                              timeout=900)
        if proc.returncode != 0:
            return {"error": proc.stderr[-2000:]}
        child = dict(np.load(outp))
    fs = float(model.stribeck.Fs)
    rows = []
    for off, a, b in zip(F32_OFFSETS_M, child["F"], f64):
        diff = np.abs(a - b)
        i = int(np.argmax(diff))
        rows.append({"offset_m": off, "max_abs_diff_N": float(diff[i]),
                     "max_rel_to_Fs": float(diff[i] / fs),
                     "rms_diff_N": float(np.sqrt(np.mean(diff**2))),
                     "at_x_um": float(x[i] / UM), "at_t_s": float(t[i])})
    return {
        "path": "nested presliding loops of amplitude 100, 60, 30, 10, 3, 1 um, then back "
                "to +100 um; 20 um/s, dt = 1 ms; t and x cast to float32",
        "samples": int(t.size),
        "float32_dtype": str(child["dtype"]),
        "float32_param_dtype": str(child["param_dtype"]),
        "float32_x64_mode": bool(child["x64"]),
        "Fs_N": fs,
        "rows": rows,
        "speed_n": n_speed,
        "float64_median_s": speed64["median_s"],
        "float32_median_s": float(child["speed_median_s"]),
    }


# ---------------------------------------------------------------------------------------
# Main
# ---------------------------------------------------------------------------------------


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smoke run: small sizes (~1 min)")
    ap.add_argument("--repeats", type=int, default=None, help="timed rounds per case")
    ap.add_argument("--json", metavar="OUT", help="write every number to this JSON file")
    ap.add_argument("--mem-budget-gb", type=float, default=4.0,
                    help="skip batch sizes whose estimated footprint exceeds this (GiB)")
    ap.add_argument("--float32-worker", nargs=2, metavar=("IN", "OUT"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.float32_worker:
        return _float32_worker(*args.float32_worker)
    if not jaxfric.x64_enabled():
        print("JAX x64 mode is off (JAXFRIC_NO_X64 set?): the benchmark needs float64.",
              file=sys.stderr)
        return 2

    cfg = dict(QUICK if args.quick else FULL)
    if args.repeats is not None:
        cfg["repeats"] = max(int(args.repeats), 1)
    reps = cfg["repeats"]
    t_start = time.perf_counter()

    marks = {}

    def log(msg):
        now = time.perf_counter() - t_start
        if msg.startswith("section") or msg == "done":
            marks[msg] = now
        print(f"[{now:7.1f} s] {msg}", flush=True)

    command = "python benchmarks/throughput.py" + "".join(
        f" {a}" for a in (argv if argv is not None else sys.argv[1:]))
    results = {"command": command, "quick": bool(args.quick), "config": cfg,
               "date_utc": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()),
               "machine": machine_facts()}
    log("Numba JIT compile")
    results["numba_compile_s"] = nbts.warm_up()
    log("section 1: single trajectory")
    results["single"] = bench_single(cfg["single_n"], reps, log)
    log("section 2: batch")
    results["batch"] = bench_batch(cfg["batch_B"], cfg["batch_n"], reps,
                                   int(args.mem_budget_gb * 2**30), log)
    log("section 4: gradients")
    results["grad"] = bench_grad(cfg["grad_n"], reps, log)
    log("section 5: one LM iteration")
    results["lm"], results["lm_pure_jax"] = bench_lm_both(cfg["lm_n"], reps, log)
    log("section 6: batch fits")
    results["fit_batch"] = bench_fit_batch(cfg["fit_batch_B"], cfg["fit_batch_n"],
                                           cfg["fit_batch_max_steps"], min(reps, 3), log)
    log("section 7: float32 vs float64")
    results["float32"] = bench_float32(max(cfg["single_n"][0], 10_000), reps, log)
    results["ratios"], results["goals"] = ratios_and_goals(results, cfg)
    results["machine"]["load_average_end"] = (list(os.getloadavg())
                                              if hasattr(os, "getloadavg") else None)
    log("done")
    results["total_s"] = time.perf_counter() - t_start
    names, times = list(marks), list(marks.values())
    results["section_s"] = {a: b - t0 for a, t0, b in zip(names[:-1], times[:-1], times[1:])}
    print()
    print(f"Machine: {results['machine']['cpu']}, {results['machine']['usable_cores']} cores, "
          f"jax {results['machine']['jax']}, numba {results['machine']['numba']} "
          f"({results['machine']['numba_threads']} threads), float64; load average "
          f"{_load(results['machine']['load_average_start'])} -> "
          f"{_load(results['machine']['load_average_end'])}; Numba JIT "
          f"{results['numba_compile_s']:.1f} s")
    print(report(results))
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1, default=_json_default))
        print(f"\nwrote {args.json}")
    return 0


def _load(v):
    return "-" if not v else "/".join(f"{x:.2f}" for x in v)


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


if __name__ == "__main__":
    sys.exit(main())
