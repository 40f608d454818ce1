"""What the throughput bench (`benchmarks/throughput.py`) judges and prints: its goals, the
speed ratios measured side by side, and the plain-text tables of a results dict."""

from __future__ import annotations


GMS_SIZES = (5, 10, 50, 200)
LM_TARGET_N = 100_000
GOAL_NUMBA = 2.0  # jaxfric at least this many times as fast as Numba
GOAL_GMS200 = 5.0  # two-state at least this many times as fast as GMS-200
GOAL_LM_S = 0.1  # s per LM iteration on 1e5 samples
GOAL_COMPILE_S = 5.0  # s
GOAL_BATCH_B = 256  # issue 39: batch of 256 x 1e4 at least GOAL_NUMBA x Numba prange
GOAL_LM_KERNEL = 1.5  # issue 39: LM iteration with the kernel this many times as fast as pure JAX
PURE = "TwoState (pure JAX)"


# ---------------------------------------------------------------------------------------
# Ratios and goals
# ---------------------------------------------------------------------------------------


def _single(rows, impl, n):
    for r in rows:
        if r["impl"] == impl and r["n"] == n:
            return r["median_s"]
    return None


def _pure_jax_ratios(results: dict, cfg: dict) -> list:
    """The ratios of the pure-JAX path (``JAXFRIC_EVENT_KERNEL=jax``), when timed."""
    ratios, single = [], results["single"]["rows"]
    for n in cfg["single_n"]:
        ts, nb, pure = (_single(single, k, n) for k in ("TwoState", "Numba two-state", PURE))
        if pure is not None:
            ratios.append({"what": "Numba time / TwoState (pure JAX) time (single)", "n": n,
                           "ratio": nb / pure})
            ratios.append({"what": "TwoState (pure JAX) time / TwoState time (single)",
                           "n": n, "ratio": pure / ts})
    for r in results["batch"]["rows"]:
        if "jax_pure_median_s" in r and "numba_median_s" in r:
            ratios.append({"what": "Numba time / pure-JAX vmap time (batch)", "B": r["B"],
                           "n": r["n"], "ratio": r["numba_median_s"] / r["jax_pure_median_s"]})
    lm, lm_pure = results["lm"], results.get("lm_pure_jax")
    if lm_pure is not None:
        ratios.append({"what": "pure-JAX LM iteration time / kernel LM iteration time",
                       "n": lm["n"], "ratio": lm_pure["iteration_s"] / lm["iteration_s"]})
    return ratios


def _kernel_goals(results: dict, batch_both: list, goal) -> None:
    """Issue 39's goals: the batch of 256 and the LM iteration against pure JAX."""
    at_b = [r for r in batch_both if r["B"] == GOAL_BATCH_B]
    if at_b:
        ratio = at_b[0]["numba_median_s"] / at_b[0]["jax_median_s"]
        goal(f"two-state simulate >= 2x Numba (batch B = {GOAL_BATCH_B})", ratio, GOAL_NUMBA,
             ratio >= GOAL_NUMBA, f"B = {GOAL_BATCH_B}, n = {at_b[0]['n']:.0e}; Numba "
             f"prange on {results['machine']['numba_threads']} threads", "x")
    lm, lm_pure = results["lm"], results.get("lm_pure_jax")
    if lm_pure is not None:
        ratio = lm_pure["iteration_s"] / lm["iteration_s"]
        ok = None if lm["n"] != LM_TARGET_N else ratio >= GOAL_LM_KERNEL
        goal("LM iteration on 1e5 samples >= 1.5x faster with the kernel than pure JAX",
             ratio, GOAL_LM_KERNEL, ok, f"n = {lm['n']:.0e}; pure-JAX iteration time / "
             "kernel iteration time (the two fits timed one after the other)", "x")


def ratios_and_goals(results: dict, cfg: dict) -> tuple[list, list]:
    """Pairwise speed ratios (a/b = how many times as fast the first is) and the goals."""
    ratios, goals = [], []
    single = results["single"]["rows"]
    for n in cfg["single_n"]:
        ts = _single(single, "TwoState", n)
        nb = _single(single, "Numba two-state", n)
        ratios.append({"what": "Numba time / jaxfric TwoState time (single)", "n": n,
                       "ratio": nb / ts})
        for g in GMS_SIZES:
            ratios.append({"what": f"GMS-{g} time / TwoState time (single)", "n": n,
                           "ratio": _single(single, f"GMS-{g}", n) / ts})
        ratios.append({"what": "LuGre time / TwoState time (single)", "n": n,
                       "ratio": _single(single, "LuGre", n) / ts})
    batch_both = [r for r in results["batch"]["rows"]
                  if "jax_median_s" in r and "numba_median_s" in r]
    for r in batch_both:
        ratios.append({"what": "Numba time / jaxfric vmap time (batch)", "B": r["B"],
                       "n": r["n"], "ratio": r["numba_median_s"] / r["jax_median_s"]})
    ratios.extend(_pure_jax_ratios(results, cfg))

    def goal(name, measured, target, ok, detail, unit=""):
        status = "n/a" if ok is None else ("PASS" if ok else "MISS")
        goals.append({"goal": name, "measured": measured, "target": target, "unit": unit,
                      "status": status, "detail": detail})

    n_max = max(cfg["single_n"])
    r_nb = _single(single, "Numba two-state", n_max) / _single(single, "TwoState", n_max)
    goal("two-state simulate >= 2x Numba (single trajectory)", r_nb, GOAL_NUMBA,
         r_nb >= GOAL_NUMBA, f"n = {n_max:.0e}; ratio = Numba time / jaxfric time", "x")
    if batch_both:
        rb = batch_both[-1]
        ratio = rb["numba_median_s"] / rb["jax_median_s"]
        goal("two-state simulate >= 2x Numba (batch)", ratio, GOAL_NUMBA,
             ratio >= GOAL_NUMBA,
             f"B = {rb['B']}, n = {rb['n']:.0e} (largest B run by both); "
             f"Numba on {results['machine']['numba_threads']} threads", "x")
    else:
        goal("two-state simulate >= 2x Numba (batch)", None, GOAL_NUMBA, None,
             "no batch size within the memory budget", "x")
    _kernel_goals(results, batch_both, goal)
    r_g = _single(single, "GMS-200", n_max) / _single(single, "TwoState", n_max)
    goal("two-state >= 5x faster than GMS-200", r_g, GOAL_GMS200, r_g >= GOAL_GMS200,
         f"n = {n_max:.0e}; ratio = GMS-200 time / TwoState time", "x")
    lm = results["lm"]
    ok = None if lm["n"] != LM_TARGET_N else lm["iteration_s"] < GOAL_LM_S
    goal("one LM iteration on 1e5 samples < 0.1 s", lm["iteration_s"], GOAL_LM_S, ok,
         f"measured on n = {lm['n']:.0e} samples, {len(lm['fit_coordinates'])} fit "
         f"coordinates ({len(lm['natural_params'])} parameters)"
         + ("" if ok is not None else "; not assessed: run used another size"), "s")
    ts_compile = max(r["compile_s"] for r in single if r["impl"] == "TwoState")
    goal("compile < 5 s: TwoState simulate", ts_compile, GOAL_COMPILE_S,
         ts_compile < GOAL_COMPILE_S, "first call minus steady state, worst size", "s")
    rows_b = results["batch"]["rows"]
    if rows_b:
        cb = max(r["lower_s"] + r["compile_s"] for r in rows_b)
        goal("compile < 5 s: TwoState vmapped batch", cb, GOAL_COMPILE_S,
             cb < GOAL_COMPILE_S, "lower + compile, worst B", "s")
    grad_rows = results["grad"]["rows"]
    for what in ("grad", "jacfwd"):
        cg = max(r[what]["lower_s"] + r[what]["compile_s"] for r in grad_rows)
        goal(f"compile < 5 s: TwoState {what}", cg, GOAL_COMPILE_S, cg < GOAL_COMPILE_S,
             "lower + compile, worst size", "s")
    cl = max(f["compile_s"] for f in lm["fits"])
    goal("compile < 5 s: LM fit (fitting.fit)", cl, GOAL_COMPILE_S, cl < GOAL_COMPILE_S,
         "first call minus steady state, worst max_steps", "s")
    cf = max(r["compile_s"] for r in results["fit_batch"]["rows"])
    goal("compile < 5 s: batch fit (fitting.fit_batch)", cf, GOAL_COMPILE_S,
         cf < GOAL_COMPILE_S, "first call minus steady state, worst B", "s")
    return ratios, goals


# ---------------------------------------------------------------------------------------
# Printing
# ---------------------------------------------------------------------------------------


def table(headers, rows) -> str:
    """A plain-text table, first column left-aligned, the others right-aligned."""
    cells = [[str(c) for c in row] for row in rows]
    widths = [max(len(h), *(len(r[i]) for r in cells)) if cells else len(h)
              for i, h in enumerate(headers)]

    def fmt(row):
        return "  ".join(c.ljust(w) if i == 0 else c.rjust(w)
                         for i, (c, w) in enumerate(zip(row, widths)))

    return "\n".join([fmt(headers), fmt(["-" * w for w in widths])] + [fmt(r) for r in cells])


def _f(v, spec=".3g", none="-"):
    return none if v is None else format(v, spec)


def _gib(b):
    return "-" if b is None else f"{b / 2**30:.2f}"


def report(results: dict) -> str:
    """All tables of a results dict."""
    out = []
    s = results["single"]
    out.append("Single trajectory (jaxfric.simulate; Numba: simulate_numba), median of "
               f"{results['config']['repeats']} after a warm-up")
    out.append(table(
        ["impl", "n", "median s", "us/step", "compile s"],
        [[r["impl"], f"{r['n']:.0e}", _f(r["median_s"], ".4f"), _f(r["us_per_step"], ".3f"),
          _f(r["compile_s"], ".2f")] for r in s["rows"]]))
    out.append("Numba vs jaxfric forces on that path: " + "; ".join(
        f"n={c['n']:.0e}: max |dF| = {c['max_abs_diff_N']:.1e} N, overflow "
        f"{c['overflow_jaxfric']}/{c['overflow_numba']}, max depth {c['max_depth']}, "
        f"{c['reversals']} reversals" for c in s["agreement"]))
    out.append("")
    b = results["batch"]
    out.append(f"Batch (n = {b['rows'][0]['n']:.0e} steps each; memory budget "
               f"{b['budget_bytes'] / 2**30:.1f} GiB)" if b["rows"] else "Batch: none")
    out.append(table(
        ["B", "jax vmap s", "jax ns/traj-step", "pure JAX s", "Numba s", "Numba ns/traj-step",
         "Numba/jax", "Numba/pure", "jax GiB", "compile s", "note"],
        [[str(r["B"]), _f(r.get("jax_median_s"), ".4f"), _f(r.get("jax_ns_per_traj_step"), ".1f"),
          _f(r.get("jax_pure_median_s"), ".4f"),
          _f(r.get("numba_median_s"), ".4f"), _f(r.get("numba_ns_per_traj_step"), ".1f"),
          _f(r["numba_median_s"] / r["jax_median_s"], ".3f")
          if "jax_median_s" in r and "numba_median_s" in r else "-",
          _f(r["numba_median_s"] / r["jax_pure_median_s"], ".3f")
          if "jax_pure_median_s" in r and "numba_median_s" in r else "-",
          _gib(r.get("jax_footprint_bytes")), _f(r["lower_s"] + r["compile_s"], ".2f"),
          r.get("jax_skipped", "") or r.get("numba_skipped", "")] for r in b["rows"]]))
    out.append("")
    g = results["grad"]
    out.append("Gradients, two-state (loss = sum F^2; jacfwd = dF/dparams, 12 columns)")
    out.append(table(
        ["n", "forward s", "grad s", "grad/fwd", "jacfwd s", "jacfwd/fwd", "compile grad s",
         "compile jacfwd s"],
        [[f"{r['n']:.0e}", _f(r["forward"]["median_s"], ".4f"), _f(r["grad"]["median_s"], ".4f"),
          _f(r["grad_over_forward"], ".2f"), _f(r["jacfwd"]["median_s"], ".4f"),
          _f(r["jacfwd_over_forward"], ".2f"),
          _f(r["grad"]["lower_s"] + r["grad"]["compile_s"], ".2f"),
          _f(r["jacfwd"]["lower_s"] + r["jacfwd"]["compile_s"], ".2f")] for r in g["rows"]]))
    out.append("")
    lm = results["lm"]
    out.append(f"Levenberg-Marquardt, two-state, n = {lm['n']:.0e}, "
               f"{len(lm['fit_coordinates'])} fit coordinates; num_steps {lm['num_steps']}")
    out.append(table(
        ["fit", "median s", "compile s"],
        [[f"max_steps={f['max_steps']}", _f(f["median_s"], ".4f"), _f(f["compile_s"], ".2f")]
         for f in lm["fits"]]
        + [["one iteration (difference / extra steps)", _f(lm["iteration_s"], ".4f"), ""]]
        + ([["one iteration, pure-JAX path", _f(results["lm_pure_jax"]["iteration_s"],
                                                       ".4f"), ""]]
           if "lm_pure_jax" in results else [])))
    out.append("")
    fb = results["fit_batch"]
    out.append("Batch fits (fitting.fit_batch, two-state, all parameters free)")
    out.append(table(
        ["B", "n", "median s", "s/dataset", "steps mean/max", "s/(dataset*iter)",
         "successful", "compile s"],
        [[str(r["B"]), str(r["n"]), _f(r["median_s"], ".3f"), _f(r["per_dataset_s"], ".4f"),
          f"{r['num_steps_mean']:.1f}/{r['num_steps_max']}",
          _f(r["per_dataset_iteration_s"], ".2e"), f"{r['successful']}/{r['B']}",
          _f(r["compile_s"], ".2f")] for r in fb["rows"]]))
    out.append("")
    f32 = results["float32"]
    if "error" in f32:
        out.append(f"float32: the subprocess failed: {f32['error']}")
    else:
        out.append(f"float32 vs float64, two-state: {f32['path']} ({f32['samples']} samples); "
                   f"float32 run: dtype {f32['float32_dtype']}, x64 {f32['float32_x64_mode']}")
        out.append(table(
            ["loops at x0 =", "max |F32-F64| N", "% of Fs", "RMS N", "at x - x0 (um)"],
            [[f"{r['offset_m']:g} m", f"{r['max_abs_diff_N']:.3e}",
              f"{100 * r['max_rel_to_Fs']:.3g}", f"{r['rms_diff_N']:.2e}",
              f"{r['at_x_um']:.2f}"] for r in f32["rows"]]))
        out.append(f"speed on the mixed path, n = {f32['speed_n']:.0e}: float32 "
                   f"{f32['float32_median_s']:.4f} s, float64 {f32['float64_median_s']:.4f} s")
    out.append("")
    out.append("Ratios (times as fast)")
    out.append(table(["pair", "size", "ratio"],
                     [[r["what"], f"B={r['B']}, n={r['n']:.0e}" if "B" in r else f"n={r['n']:.0e}",
                       _f(r["ratio"], ".3f")] for r in results["ratios"]]))
    out.append("")
    out.append("Goals (issues 7 and 39)")
    out.append(table(["goal", "measured", "target", "status", "detail"],
                     [[gl["goal"], _f(gl["measured"], ".3g") + gl["unit"]
                       if gl["measured"] is not None else "-",
                       _f(gl["target"], "g") + gl["unit"], gl["status"], gl["detail"]]
                      for gl in results["goals"]]))
    return "\n".join(out)
