"""Write BENCHMARKS.md and the documentation's benchmark page from the JSON of
``benchmarks/throughput.py``.

Run ``python benchmarks/make_benchmarks_md.py RESULTS.json [--montecarlo MC.json]``
(``MC.json`` from ``benchmarks/montecarlo_speed.py``, rendered as a section of its own):
it writes ``BENCHMARKS.md``
at the repository root and ``docs/benchmarks.md`` (the same text, with links relative to
``docs/``). Everything in the pages comes from the JSON (no number is typed in here): the
machine, the command that reproduces the run, every table and the goals with PASS/MISS.
Why the numbers are what they are is explained once, by hand, in
``docs/benchmark_notes.md``, which both pages link to.

Units: seconds (s), microseconds per step (us/step), nanoseconds per trajectory-step, N.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def md_table(headers, rows, align=None) -> str:
    """A Markdown table; `align` is a string of 'l'/'r' per column (default: l then r)."""
    align = align or ("l" + "r" * (len(headers) - 1))
    sep = ["---:" if a == "r" else "---" for a in align]
    lines = ["| " + " | ".join(headers) + " |", "| " + " | ".join(sep) + " |"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def f(v, spec=".3g", none="-"):
    return none if v is None else format(v, spec)


def _n(n):
    return f"{n:.0e}".replace("e+0", "e")


def section_machine(d) -> str:
    m = d["machine"]
    def la(v):
        return "-" if not v else " / ".join(f"{x:.2f}" for x in v)

    load = (f"{la(m.get('load_average_start'))} at the start, "
            f"{la(m.get('load_average_end'))} at the end (1 / 5 / 15 min)")
    rows = [
        ["CPU", m.get("cpu")],
        ["cores (usable / logical)", f"{m.get('usable_cores')} / {m.get('logical_cores')}"],
        ["memory", f"{m.get('memory_gib')} GiB"],
        ["load average", load],
        ["platform", m.get("platform")],
        ["Python", m.get("python")],
        ["jax / jaxlib", f"{m.get('jax')} / {m.get('jaxlib')}"],
        ["equinox / optimistix", f"{m.get('equinox')} / {m.get('optimistix')}"],
        ["numba (threads)", f"{m.get('numba')} ({m.get('numba_threads')})"],
        ["numpy", m.get("numpy")],
        ["JAX devices", ", ".join(m.get("jax_devices") or [])],
        ["precision", f"{m.get('float_dtype')} (jax_enable_x64 = {m.get('jax_x64')})"],
        ["XLA_FLAGS", m.get("xla_flags") or "(unset)"],
        # The commit is provenance for whoever re-runs the numbers: it stays in the JSON
        # (machine.git_commit); the page, read by users, names where to find it.
        ["code", "the commit in the JSON's `machine.git_commit`" + (
            " (with uncommitted changes)" if m.get("git_dirty") else "")],
        ["date (UTC)", d.get("date_utc", "-")],
        ["total run time", f"{d.get('total_s', 0):.0f} s"],
    ]
    return md_table(["", ""], rows, "ll")


def section_goals(d) -> str:
    rows = [[g["goal"], "-" if g["measured"] is None else f(g["measured"]) + g["unit"],
             f(g["target"], "g") + g["unit"],
             f"**{g['status']}**", g["detail"]] for g in d["goals"]]
    return md_table(["goal", "measured", "target", "status", "how"], rows, "lrrll")


def section_single(d) -> str:
    s = d["single"]
    rows = [[r["impl"], _n(r["n"]), f(r["median_s"], ".4f"), f(r["us_per_step"], ".3f"),
             f(r["min_s"], ".4f"), f(r["compile_s"], ".2f")] for r in s["rows"]]
    out = [md_table(["model", "steps", "median s", "us/step", "min s", "compile s"], rows)]
    agree = "; ".join(
        f"n = {_n(c['n'])}: max |F_jaxfric - F_Numba| = {c['max_abs_diff_N']:.1e} N, "
        f"{c['reversals']} reversals, max stack depth {c['max_depth']}, overflow "
        f"{c['overflow_jaxfric']} (jaxfric) / {c['overflow_numba']} (Numba)"
        for c in s["agreement"])
    out.append(f"\nSame forces on the benchmark motion: {agree}.")
    return "\n".join(out)


def section_batch(d) -> str:
    b = d["batch"]
    if not b["rows"]:
        return "No batch sizes were run."
    rows = []
    for r in b["rows"]:
        both = "jax_median_s" in r and "numba_median_s" in r
        note = "; ".join(x for x in (r.get("jax_skipped") and "jaxfric skipped: "
                                     + r["jax_skipped"],
                                     r.get("numba_skipped") and "Numba skipped: "
                                     + r["numba_skipped"]) if x)
        rows.append([
            str(r["B"]), f(r.get("jax_median_s"), ".4f"), f(r.get("jax_ns_per_traj_step"), ".1f"),
            f(r.get("numba_median_s"), ".4f"), f(r.get("numba_ns_per_traj_step"), ".1f"),
            f(r["numba_median_s"] / r["jax_median_s"], ".3f") if both else "-",
            f(r["jax_footprint_bytes"] / 2**30, ".2f") if r.get("jax_footprint_bytes") else "-",
            f(r["lower_s"] + r["compile_s"], ".2f"), note or ""])
    n = b["rows"][0]["n"]
    head = (f"{_n(n)} steps per trajectory; memory budget {b['budget_bytes'] / 2**30:.1f} GiB "
            "(jaxfric footprint = XLA arguments + outputs + temporaries from "
            "`compiled.memory_analysis()`, plus the host copies of the inputs).\n")
    return head + "\n" + md_table(
        ["B", "jaxfric vmap s", "ns/traj-step", "Numba prange s", "ns/traj-step",
         "Numba time / jaxfric time", "jaxfric GiB", "compile s", "note"], rows,
        "rrrrrrrrl")


def section_compile(d) -> str:
    rows = []
    for r in d["single"]["rows"]:
        if r["compile_s"] is not None:
            rows.append([f"simulate {r['impl']}, n = {_n(r['n'])}", f(r["compile_s"], ".2f"),
                         "first call - steady state"])
    for r in d["batch"]["rows"]:
        rows.append([f"vmap simulate TwoState, B = {r['B']}", f(r["lower_s"] + r["compile_s"],
                                                                 ".2f"),
                     f"lower {r['lower_s']:.2f} + compile {r['compile_s']:.2f}"])
    for r in d["grad"]["rows"]:
        for what, label in (("forward", "TwoState loss (forward)"),
                            ("grad", "jax.grad of the TwoState loss"),
                            ("jacfwd", "jax.jacfwd of the TwoState force")):
            q = r[what]
            rows.append([f"{label}, n = {_n(r['n'])}",
                         f(q["lower_s"] + q["compile_s"], ".2f"),
                         f"lower {q['lower_s']:.2f} + compile {q['compile_s']:.2f}"])
    for fit in d["lm"]["fits"]:
        rows.append([f"fitting.fit, max_steps = {fit['max_steps']}, n = {_n(d['lm']['n'])}",
                     f(fit["compile_s"], ".2f"), "first call - steady state"])
    for r in d["fit_batch"]["rows"]:
        rows.append([f"fitting.fit_batch, B = {r['B']}", f(r["compile_s"], ".2f"),
                     "first call - steady state"])
    rows.append(["Numba kernels (single + prange, with and without v)",
                 f(d.get("numba_compile_s"), ".2f"), "first calls on tiny inputs"])
    return md_table(["what", "s", "how"], rows, "lrl")


def section_grad(d) -> str:
    rows = [[_n(r["n"]), f(r["forward"]["median_s"], ".4f"), f(r["grad"]["median_s"], ".4f"),
             f(r["grad_over_forward"], ".2f"), f(r["jacfwd"]["median_s"], ".4f"),
             f(r["jacfwd_over_forward"], ".2f")] for r in d["grad"]["rows"]]
    return ("Loss `sum(simulate(model, t, x)**2)`; `jax.grad` with respect to all "
            f"{d['grad']['rows'][0]['n_params']} parameters; `jax.jacfwd` of the force "
            "(one column per parameter, what a Levenberg-Marquardt step needs).\n\n"
            + md_table(["steps", "forward s", "grad s", "grad / forward", "jacfwd s",
                        "jacfwd / forward"], rows))


def section_lm(d) -> str:
    lm = d["lm"]
    rows = [[f"`fitting.fit(..., max_steps={x['max_steps']})`", f(x["median_s"], ".4f"),
             f(x["compile_s"], ".2f")] for x in lm["fits"]]
    extra = lm["num_steps"][-1] - lm["num_steps"][0]
    rows.append([f"one iteration = difference / {extra}", f(lm["iteration_s"], ".4f"), ""])
    head = (f"Two-state model, {_n(lm['n'])} samples, all {len(lm['natural_params'])} "
            f"parameters free ({len(lm['fit_coordinates'])} solver coordinates: "
            f"{', '.join(lm['fit_coordinates'])}). Reported num_steps {lm['num_steps']} "
            f"(expected {lm['max_steps']}: {'yes' if lm['num_steps_ok'] else 'NO'}). "
            "Each extra iteration is one residual + Jacobian evaluation and one damped QR "
            "solve; the set-up, covariance and result assembly cancel in the difference. "
            f"Median over rounds of the per-round difference: "
            f"{lm['iteration_s_median_of_rounds']:.4f} s.\n\n")
    return head + md_table(["fit", "median s", "compile s"], rows)


def section_fit_batch(d) -> str:
    rows = [[str(r["B"]), str(r["n"]), f(r["median_s"], ".3f"), f(r["per_dataset_s"], ".4f"),
             f"{r['num_steps_mean']:.1f} / {r['num_steps_max']}",
             f(r["per_dataset_iteration_s"], ".2e"), f"{r['successful']}/{r['B']}",
             f(r["compile_s"], ".2f")] for r in d["fit_batch"]["rows"]]
    ms = d["fit_batch"]["rows"][0]["max_steps"] if rows else "-"
    return (f"`fitting.fit_batch` of the two-state model (all parameters free, max_steps = "
            f"{ms}) on B synthetic datasets with random phases, solved one after the other "
            "in one compiled call (`fit_batch`'s default), each until its own termination: "
            "s/(dataset x iteration) is over the sum of the num_steps.\n\n"
            + md_table(["B", "samples", "median s", "s / dataset", "num_steps mean / max",
                        "s / (dataset x iteration)", "successful", "compile s"], rows)
            + _vectorize_note(d["fit_batch"]["rows"]))


def _vectorize_note(rows) -> str:
    for r in rows:
        v = r.get("vectorize")
        if v:
            return (f"\n\nSide by side at B = {r['B']}, the vmapped solve "
                    f"(`fit_batch(..., vectorize=True)`: one loop for all datasets, until the "
                    f"slowest stops) took {v['median_s']:.3f} s (num_steps max "
                    f"{v['num_steps_max']}; {v['per_dataset_iteration_s']:.2e} s per "
                    f"dataset x iteration of the slowest) and compiled in "
                    f"{v['compile_s']:.2f} s, against {r['median_s']:.3f} s and "
                    f"{r['compile_s']:.2f} s one dataset after the other (time ratio "
                    f"{v['map_over_vmap_time']:.2f}).")
    return ""


def section_float32(d) -> str:
    x = d["float32"]
    if "error" in x:
        return f"The float32 subprocess failed:\n\n```\n{x['error']}\n```"
    rows = [[f"{r['offset_m']:g} m", f"{r['max_abs_diff_N']:.3e}",
             f"{100 * r['max_rel_to_Fs']:.3g} %", f"{r['rms_diff_N']:.2e}",
             f"{r['at_x_um']:.2f}"] for r in x["rows"]]
    return (f"Two-state model, {x['path']} ({x['samples']} samples); float64 in the benchmark "
            f"process, float32 in a subprocess with `JAXFRIC_NO_X64=1` (forces "
            f"{x['float32_dtype']}, parameters {x['float32_param_dtype']}). Fs = "
            f"{x['Fs_N']} N. The same loops placed at larger absolute positions show what a "
            "stage coordinate costs in float32.\n\n"
            + md_table(["loops at x0", "max abs(F32 - F64) N", "relative to Fs", "RMS N",
                        "where (x - x0, um)"], rows)
            + f"\n\nSpeed on the mixed motion, {_n(x['speed_n'])} steps: float32 "
            f"{x['float32_median_s']:.4f} s, float64 {x['float64_median_s']:.4f} s.")


def section_ratios(d) -> str:
    rows = [[r["what"], f"B = {r['B']}, n = {_n(r['n'])}" if "B" in r else f"n = {_n(r['n'])}",
             f(r["ratio"], ".3f")] for r in d["ratios"]]
    return ("Each ratio divides two medians measured in the same run, interleaved "
            "(> 1: the second is faster).\n\n" + md_table(["pair", "size", "ratio"], rows))


def section_fit_speed(fs: dict | None, json_name: str) -> str:
    """Time to fit (``benchmarks/fit_speed.py``): jaxfric against scipy + Numba."""
    if fs is None:
        return "Not measured in this run (`python benchmarks/fit_speed.py`)."
    rows = []
    for r in fs["rows"]:
        j, s = r["jaxfric"], r["scipy"]
        rows.append([_n(r["n"]), j["steps"], j["status"], f(j["first_s"]), f(j["warm_s"]),
                     f(j["rmse"], ".5f"), s["steps"], f(s["first_s"]), f(s["warm_s"]),
                     f(s["rmse"], ".5f"), f(r["ratio_first"]), f(r["ratio_warm"]),
                     f"{100 * r['rmse_rel']:+.2f} %"])
    table = md_table(["n", "jaxfric steps", "status", "first s", "warm s", "RMSE N",
                      "scipy Jacobians", "first s", "warm s", "RMSE N", "x first", "x warm",
                      "RMSE jaxfric/scipy - 1"], rows)
    goals = md_table(["n", "goal", "target", "measured", ""],
                     [[_n(g["n"]), g["goal"], g["target"], f(g["measured"]),
                       "PASS" if g["met"] else "MISS"] for g in fs["goals"]], align="lllrl")
    return "\n".join([
        "`fitting.fit` (defaults) against `scipy.optimize.least_squares` (trf, "
        "`x_scale=\"jac\"`, 2-point differences) around the Numba loop, same data (the "
        "mixed motion, paper model + 0.05 N noise) and start (11 parameters x1.15 or x0.85, "
        "c held); scipy's first call adds the Numba compilation "
        f"({f(fs['numba_compile_s'])} s). One run of `{fs.get('command')}` "
        f"(`{json_name}`); the method is in the script's docstring.", "", table, "",
        goals])


#: The hand-written explanation of the numbers, relative to the repository root.
NOTES = "docs/benchmark_notes.md"


def section_montecarlo(mc: dict, json_name: str) -> str:
    """The section of `benchmarks/montecarlo_speed.py`, from its JSON."""
    rows = [[r["case"], r["size"]["B"], _n(r["size"]["n"]), f(r["jaxfric_s"], ".4f"),
             f(r.get("vmap_s"), ".4f"), f(r["numba_s"], ".4f"), f(r["ratio"], ".2f"),
             f(r.get("ratio_vmap"), ".2f"), "PASS" if r["ratio"] >= 2 else "**MISS**",
             f(r["max_abs_diff_N"], ".2g")] for r in mc["rows"]]
    ops = [[o["op"], f(o["ns_per_element"], ".2f"),
            f(o["max_rel_diff_to_power"], ".2g")] for o in mc["ops"]]
    m = mc["machine"]
    load = " / ".join(f"{v:.2f}" for v in m.get("load_average") or [])
    quick = ("> **A `--quick` smoke run**: the sizes are too small to mean anything.\n\n"
             if mc.get("quick") else "")
    return (
        quick + "Target: jaxfric >= 2x a Numba `prange` loop of the same "
        "algorithm. jaxfric = `jaxfric.simulate_many` for the batches (`simulate` for one "
        "trajectory), vmap = `jax.vmap` of `jaxfric.simulate`; ratio = Numba time / "
        "jaxfric time; max abs(dF) = the largest force difference to Numba and to the vmap. "
        "Medians of "
        f"{mc['repeats']} interleaved rounds of one run ({m.get('date_utc')} UTC, Numba on "
        f"{m.get('numba_threads')} threads, load average {load} at the end: the machine "
        "is shared, so only the ratios of one run mean much). Generated from "
        f"`{json_name}`; reproduce with `{mc['command']}`. Why the target is missed, "
        "measured stage by stage: the benchmark notes.\n\n"
        + md_table(["case", "B", "n", "jaxfric s", "vmap s", "Numba s", "ratio",
                    "ratio (vmap)", ">= 2x", "max abs(dF) N"], rows, "lrrrrrrrlr")
        + "\n\nfloat64 elementwise operations (XLA on the CPU, ns per element of a "
        "B x n array):\n\n" + md_table(["operation", "ns/element",
                                          "max relative difference to x ** p"], ops))


def render(d: dict, json_name: str, notes_link: str = NOTES, mc: dict | None = None,
           mc_name: str = "", fit_speed: dict | None = None,
           fit_speed_name: str = "benchmarks/fit_speed.json") -> str:
    quick = d.get("quick")
    parts = ["# Benchmarks", ""]
    parts.append(
        "Throughput of jaxfric (simulation, batches, gradients, fits) against a hand-written "
        "Numba version of the same two-state algorithm (`benchmarks/numba_two_state.py`, "
        "checked equal to < 1e-9 N in `tests/test_numba_baseline.py`), all measured side by "
        "side in one run. Medians over the timed rounds after a warm-up call; the warm-up's "
        "excess is the compile time. The method is described in the docstring of "
        "`benchmarks/throughput.py`. Generated by `benchmarks/make_benchmarks_md.py` from "
        f"`{json_name}`: do not edit the numbers by hand.")
    if quick:
        parts += ["", "> **This is a `--quick` smoke run** (small sizes, few repeats): it shows "
                      "that the script works, not how fast jaxfric is."]
    parts += ["", "## Reproduce", "", "```bash",
              d.get("command", "python benchmarks/throughput.py --json OUT.json"),
              *([mc["command"]] if mc is not None else []),
              f"python benchmarks/make_benchmarks_md.py {json_name}"
              + (f" --montecarlo {mc_name}" if mc is not None else ""), "```", "",
              f"Repeats: {d['config']['repeats']}. Sizes: {json.dumps(d['config'])}.", "",
              "## Machine", "", section_machine(d), "",
              "## Goals", "", section_goals(d), "",
              "## Why", "",
              f"Where the time goes, why the missed goals are missed (measured, with the "
              f"profiles that show it) and what was tried: [the benchmark notes]({notes_link}).",
              "",
              "## Single trajectory", "",
              "`jaxfric.simulate(model, t, x)` (the public call, with its input checks) on a "
              "mixed motion: a 1 mm, 0.2 Hz sliding sine plus 100 um (1.3 Hz) and 20 um "
              "(4.1 Hz) presliding sines, sampled at 1 kHz. GMS-N discretises the paper's "
              "shape (`paper.gms(N)`).", "", section_single(d), "",
              "## Batches", "", section_batch(d), "",
              "## Gradients", "", section_grad(d), "",
              "## One Levenberg-Marquardt iteration", "", section_lm(d), "",
              "## Batch fits", "", section_fit_batch(d), "",
              "## Time to fit against scipy + Numba", "",
              section_fit_speed(fit_speed, fit_speed_name), "",
              "## Compile times", "", section_compile(d), "",
              "## float32 against float64 (presliding)", "", section_float32(d), "",
              "## Ratios", "", section_ratios(d), ""]
    if mc is not None:
        parts += ["## Monte-Carlo, batch and single trajectory against Numba prange", "",
                  section_montecarlo(mc, mc_name), ""]
    return "\n".join(parts)


def main(argv=None) -> int:
    root = Path(__file__).resolve().parents[1]
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("json", help="output of benchmarks/throughput.py --json")
    ap.add_argument("--out", default=str(root / "BENCHMARKS.md"),
                    help="Markdown file to write (default: BENCHMARKS.md at the repo root)")
    ap.add_argument("--docs", default=str(root / "docs" / "benchmarks.md"),
                    help="the documentation page (default: docs/benchmarks.md; '' for none)")
    ap.add_argument("--montecarlo", default="",
                    help="JSON of benchmarks/montecarlo_speed.py to add as a section")
    ap.add_argument("--fit-speed", default="benchmarks/fit_speed.json",
                    help="output of benchmarks/fit_speed.py (skipped if missing)")
    args = ap.parse_args(argv)
    d = json.loads(Path(args.json).read_text())
    mc = json.loads(Path(args.montecarlo).read_text()) if args.montecarlo else None
    fs_path = Path(args.fit_speed)
    fs = json.loads(fs_path.read_text()) if fs_path.is_file() else None
    extra = {"mc": mc, "mc_name": args.montecarlo, "fit_speed": fs,
             "fit_speed_name": args.fit_speed}
    Path(args.out).write_text(render(d, args.json, **extra))
    print(f"wrote {args.out}")
    if args.docs:
        Path(args.docs).write_text(render(d, args.json, notes_link=Path(NOTES).name, **extra))
        print(f"wrote {args.docs}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
