"""Write docs/validation.md from the benchmarks' summary JSONs (no number is typed here).

    python benchmarks/make_validation.py [--check]

Reads, relative to the repository root: ``benchmarks/diagnosis_bench.json``,
``benchmarks/diagnosis_bench_runs.json``,
``benchmarks/fit_speed.json``, ``benchmarks/throughput.json``,
``benchmarks/montecarlo_speed.json``, ``benchmarks/c_step.json``,
``benchmarks/diagnose_speed.json``, ``benchmarks/compiler_options.json`` and the real-data
results ``docs/figures/emps_diagnosis.json`` and ``docs/figures/tribometer.json``. A
missing file gives its section a line saying so. It also writes the bench's table per
truth and motion into docs/diagnosis.md, between its `BENCH_MARKS` lines. ``--check``
writes nothing and exits 1 when either committed page differs from what the JSONs give
(``tests/project/test_validation_page.py`` does the same). Units: s, ns, N.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "validation.md"
#: docs/diagnosis.md carries the bench's table per truth and motion between these lines.
DIAGNOSIS_PAGE = ROOT / "docs" / "diagnosis.md"
BENCH_MARKS = ("<!-- bench table: made by benchmarks/make_validation.py from "
               "benchmarks/diagnosis_bench.json; do not edit -->", "<!-- end of bench table -->")
SOURCES = {
    "diagnosis": "benchmarks/diagnosis_bench.json",
    "diagnosis_runs": "benchmarks/diagnosis_bench_runs.json",
    "fit_speed": "benchmarks/fit_speed.json",
    "throughput": "benchmarks/throughput.json",
    "montecarlo": "benchmarks/montecarlo_speed.json",
    "c_step": "benchmarks/c_step.json",
    "diagnose_speed": "benchmarks/diagnose_speed.json",
    "compiler_options": "benchmarks/compiler_options.json",
    "emps": "docs/figures/emps_diagnosis.json",
    "tribometer": "docs/figures/tribometer.json",
}


def fmt(v, spec=".3g") -> str:
    if v is None:
        return "-"
    if isinstance(v, (int, float)):
        return format(v, spec)
    return str(v)


def table(headers: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(fmt(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def status(met) -> str:
    return "-" if met is None else ("met" if met else "**MISSED**")


def goals_table(goals: list[tuple]) -> str:
    """`goals`: ``(goal, measured, target, met)``."""
    return table(["goal", "measured", "target", "status"],
                 [[g, m, t, status(ok)] for g, m, t, ok in goals])


def _find(d: dict, *keys):
    """The first of `keys` found at the top of `d` or in its "machine" or "meta"."""
    for where in (d, d.get("machine") or {}, d.get("meta") or {}):
        for k in keys:
            if where.get(k) not in (None, ""):
                return where[k]
    return None


def machine_line(d: dict) -> str:
    cpu = _find(d, "cpu")
    cores = _find(d, "usable_cores", "logical_cores", "cores", "cpus", "cpu_count")
    date = _find(d, "date_utc")
    missing = " and ".join(w for w, v in (("CPU", cpu), ("date", date)) if not v)
    return (f"Machine: {cpu + ', ' if cpu else ''}{cores or '?'} cores"
            + (f"; run {date} UTC" if date else "")
            + (f"; {missing} not recorded." if missing else "."))


def _percent(v, spec=".0f") -> str:
    return "-" if v is None else f"{format(100 * v, spec)} %"


def command(cmd: str, json_path: str | None = None) -> str:
    """A code block; an ``--json`` path of the recorded command (a scratch file) is shown as
    the committed JSON's."""
    if json_path:
        cmd = re.sub(r"--json \S+", f"--json {json_path}", cmd)
    return f"Reproduce:\n\n```\n{cmd}\n```"


def _ratio(k: int, n: int) -> str:
    return f"{k} of {n} ({100 * k / max(n, 1):.0f} %)"


def bench_by_truth(d: dict) -> str:
    """The bench per motion, truth, sampling interval, noise level and starting model: the
    targets counted on each (``found / files``), the median share of the excess error
    removed where the effect was found, and the files whose base model was changed."""
    rows = sorted([c.get("motion", "diagnosis"), truth, f"{1e3 * c['dt_s']:g}",
                   f"{c['noise_N']:g}", c["start"], "{} / {}".format(*b["singles"]),
                   "{} / {}".format(*b["pairs"]), f"{b['added_on_clean']} / {b['clean_files']}",
                   "{} / {}".format(*b["found_half_excess_removed"]),
                   _percent(b.get("median_excess_removed")),
                   "{} / {}".format(*b["base_model_changed"]) if "base_model_changed" in b
                   else "-"]
                  for c in d["corners"] for truth, b in c["by_truth"].items())
    return table(["motion", "truth", "dt [ms]", "noise [N]", "start", "single named first",
                  "pair both found", "effects on clean files",
                  "half the excess removed", "median excess removed",
                  "base model changed"], rows)


def with_bench_table(page: str, d: dict | None) -> str:
    """`page` (docs/diagnosis.md) with the text between `BENCH_MARKS` replaced by
    `bench_by_truth` of the bench summary `d` (a line saying it is missing for None)."""
    start, end = BENCH_MARKS
    if start not in page or end not in page:
        raise ValueError(f"{DIAGNOSIS_PAGE.name} lacks the bench table's marker lines")
    body = (bench_by_truth(d) if d is not None else
            f"No results: `{SOURCES['diagnosis']}` is missing.")
    head, rest = page.split(start, 1)
    return f"{head}{start}\n{body}\n{end}{rest.split(end, 1)[1]}"


def _bench_command(c: dict) -> str:
    """The command that runs corner `c` of the diagnosis bench (``--only`` subsets, if
    any, are in the JSON's note)."""
    o = c.get("options") or {}
    args = [f"--motions {c.get('motion', 'diagnosis')}", f"--truths {','.join(c['truths'])}",
            f"--rates {c['dt_s']:g}", f"--noises {c['noise_N']:g}"]
    args += [f"--{k} {o[k]:g}" for k in ("jitter", "duration") if k in o]
    if c.get("start", "two-state") != "two-state":
        args.append(f"--start {c['start']}")
    if c.get("runs_diagnosed", 1) > 1:
        args.append(f"--runs {c['runs_diagnosed']}")
    return "python benchmarks/diagnosis_bench.py " + " ".join(args) + " --out ROWS.json"


def _not_acting(corners) -> str:
    """The files whose hidden effects do not all act, named with their corner's motion."""
    files = [f"{' + '.join(h)} on {c.get('motion', 'diagnosis')}" for c in corners
             for h in c.get("not_acting", [])]
    return f": {', '.join(files)}" if files else ""


def section_diagnosis(d: dict) -> list[str]:
    corners = d["corners"]
    targets = d["targets"]

    def total(key):
        return [sum(c[key][i] for c in corners) for i in (0, 1)]

    s, p, h = total("singles"), total("pairs"), total("found_half_excess_removed")
    sl, pl = total("singles_not_absorbed"), total("pairs_not_absorbed")
    clean = sum(c["added_on_clean"] for c in corners)
    files = sum(c["files"] for c in corners)
    goals = [
        ("single hidden effect named first", _ratio(*s), f">= {100 * targets['singles']:.0f} %",
         s[0] >= targets["singles"] * s[1]),
        ("the same, leaving out the absorbed", _ratio(*sl), "", None),
        ("both effects of a pair found", _ratio(*p), f">= {100 * targets['pairs']:.0f} %",
         p[0] >= targets["pairs"] * p[1] if p[1] else None),
        ("the same, leaving out pairs with an effect absorbed alone", _ratio(*pl), "", None),
        ("effects added on clean files", clean, "0", clean == 0),
        ("half the excess error removed when found", _ratio(*h), "every file",
         h[0] == h[1] if h[1] else None),
    ]
    effects = {}
    for c in corners:
        for name, e in c["by_effect"].items():
            acc = effects.setdefault(name, {"files": 0, "named_first": 0, "absorbed": 0,
                                            "instead": {}})
            for k in ("files", "named_first", "absorbed"):
                acc[k] += e[k]
            for other, n in e["instead"].items():
                acc["instead"][other] = acc["instead"].get(other, 0) + n
    per_effect = [[name, f"{e['named_first']} / {e['files']}", e["absorbed"],
                   ", ".join(f"{k} ({n})" for k, n in e["instead"].items()) or "-"]
                  for name, e in effects.items()]
    runs = [r for c in corners for r in c.get("runs", [])]
    dates = sorted({r["date_utc"] for r in runs if r.get("date_utc")})
    cores = sorted({r["cores"] for r in runs if r.get("cores")})
    cpus = sorted({r["cpu"] for r in runs if r.get("cpu")})
    hours = sum(r.get("seconds") or 0 for r in runs) / 3600
    return [
        "`jaxfric diagnose` on synthetic measurements from truths that are not the fitted "
        f"model ({', '.join(sorted({t for c in corners for t in c['truths']}))}), with a "
        "0.05 um encoder, force noise, and one hidden effect, a pair or none. A *corner* is "
        "one sampling interval, noise level, start and motion. An effect is "
        "*absorbed* when it raises "
        f"the baseline's held-out error by less than {100 * d['absorbed_below']:.0f} % over "
        f"the same file without it. A hidden effect without force on its file is not "
        f"counted{_not_acting(corners)}. "
        f"{files} files in {len(corners)} corners.",
        goals_table(goals),
        "Per motion and truth: [Diagnose missing effects](diagnosis.md#how-well-it-works) "
        "(generated from the same JSON).",
        "Per hidden effect, over all corners:",
        table(["hidden effect", "named first", "absorbed", "named first instead"],
              per_effect),
        command("\n".join(dict.fromkeys(_bench_command(c) for c in corners)))
        + f"\n\nThe runs took {hours:.1f} h of wall time in all.",
        f"Machine: {', '.join(cpus) or 'CPU not recorded'}, "
        f"{'/'.join(map(str, cores)) or '?'} cores; runs dated "
        + (" to ".join(dict.fromkeys([dates[0], dates[-1]])) if dates else "(not recorded)")
        + ".",
    ]


def section_generalisation(d: dict) -> list[str]:
    """The diagnosis bench's judged runs: each file's truth and hidden effects on a run the
    diagnosis never saw, predicted by the baseline and by the diagnosed model."""
    rows, files, worse = [], 0, []
    for c in d["corners"]:
        judged = c.get("judged_runs", [])
        files += len(judged)
        ratios = [j["rmse_after"] / j["rmse_before"] for j in judged]
        here = [j for j in judged if j["rmse_after"] > j["rmse_before"]]
        worse += here
        rows.append([f"{1e3 * c['dt_s']:g}", fmt(c["noise_N"]), c.get("motion", "-"),
                     ", ".join(c["truths"]), c.get("runs_diagnosed", 1), len(judged),
                     sum(bool(j["added"]) for j in judged),
                     sum(r < 1 for r in ratios), len(here),
                     fmt(float(sorted(ratios)[len(ratios) // 2]) if ratios else None)])
    body = [
        "Each bench file's truth and hidden effects recorded once more, on a motion the "
        "diagnosis never sees, predicted by the baseline and the diagnosed model.",
        goals_table([("judged runs predicted worse after the diagnosis",
                      f"{len(worse)} / {files}", "0", not worse)]),
        table(["dt [ms]", "noise [N]", "motion", "truths", "runs diagnosed", "files",
               "something added", "judged run better", "worse", "median RMSE after/before"],
              rows)]
    if worse:
        body.append(table(["truth", "hidden", "added", "RMSE before [N]", "after [N]"],
                          [[j["truth"], " + ".join(j["hidden"]) or "(clean)",
                            " + ".join(j["added"]), fmt(j["rmse_before"]),
                            fmt(j["rmse_after"])] for j in worse]))
    body.append(command("python benchmarks/diagnosis_bench.py --quick --runs 2 --out ROWS.json"
                        "\npython benchmarks/diagnosis_bench.py --summarise ROWS.json --summary "
                        "benchmarks/diagnosis_bench_runs.json"))
    runs = [r for c in d["corners"] for r in c.get("runs", [])]
    hours = sum(r.get("seconds") or 0 for r in runs) / 3600
    dates = sorted(r["date_utc"] for r in runs if r.get("date_utc"))
    body.append(f"Machine: {', '.join(sorted({r.get('cpu') or '?' for r in runs}))}, "
                f"{'/'.join(sorted({str(r.get('cores', '?')) for r in runs}))} cores; "
                f"{hours:.1f} h of wall time, run {dates[-1] if dates else '(not recorded)'} "
                "UTC.")
    return body


def _goal_rows(goals: list[dict]) -> list[tuple]:
    """Goals as the benchmark scripts write them: ``goal``, ``measured``, ``target``
    (a number or a text), optional ``unit``, ``n``, and ``met`` (bool) or ``status``."""
    out = []
    for g in goals:
        unit = g.get("unit", "")
        target = g.get("target")
        if not unit and isinstance(target, str) and target.endswith("x"):
            unit = "x"
        name = g["goal"] + (f" (n = {g['n']:.0e})".replace("e+0", "e") if "n" in g else "")
        space = "" if unit in ("", "x") else " "
        target = (f"{target:g}{space}{unit}" if isinstance(target, (int, float))
                  else target)
        met = g["met"] if "met" in g else {"PASS": True, "MISS": False}.get(g.get("status"))
        measured = g.get("measured")
        if measured is not None and isinstance(target, str) and "%" in target:
            measured = f"{100 * measured:+.1g} %"
        elif measured is not None:
            measured = fmt(measured) + space + unit
        out.append((name, measured, target, met))
    return out


def _fit_rows(cells: list[dict]) -> tuple[list[str], list[list]]:
    """The fit-speed table: one row per model and motion, each column's values for every
    size in one cell (``a / b``, sizes ascending, named in the header)."""
    sizes = sorted({c["n"] for c in cells})
    label = " / ".join(f"{n:.0e}".replace("e+0", "e") for n in sizes)
    cols = [lambda c: c["jaxfric"].get("steps"), lambda c: c["scipy"].get("steps"),
            lambda c: fmt(c.get("ratio_warm")) + "x", lambda c: fmt(c.get("ratio_first")) + "x",
            lambda c: f"{100 * c['rmse_rel']:+.2g} %"]
    rows = {}
    for c in cells:
        rows.setdefault((c["model"], c["motion"]), {})[c["n"]] = c
    out = [[model, motion, *(" / ".join(fmt(col(by[n])) if n in by else "-" for n in sizes)
                             for col in cols)] for (model, motion), by in rows.items()]
    heads = ["steps", "scipy steps", "warm x scipy", "first x scipy", "RMSE vs scipy"]
    return ["model", "motion", *(f"{h} ({label})" for h in heads)], out


def section_fit_speed(d: dict) -> list[str]:
    goals = d.get("goals", [])
    if "cells" in d:  # one row per model and motion; the goals' verdicts below it
        missed = [g for g in goals if not g.get("met", True)]
        summary = d.get("summary", {})
        verdict = (f"{summary.get('met', len(goals) - len(missed))} of "
                   f"{summary.get('goals', len(goals))} goals met. Targets: <= 40 steps "
                   "everywhere, RMSE within 1 % of scipy's everywhere; for the two-state "
                   "model at 1e5 samples warm >= 5x and first call >= 2.5x scipy's time.")
        body = [table(*_fit_rows(d["cells"])), verdict]
        if missed:
            body.append(table(["missed", "model", "motion", "samples", "measured", "target"],
                              [[g["goal"], g.get("model"), g.get("motion"),
                                f"{g['n']:.0e}".replace("e+0", "e"), fmt(g.get("measured")),
                                fmt(g.get("target"))] for g in missed]))
    else:
        body = [goals_table(_goal_rows(goals))]
    return [
        "`fitting.fit` against `scipy.optimize.least_squares` (trf, finite differences) "
        "around the same model's simulation (two-state: a Numba loop), same data and start, "
        "side by side; first call: compilation included.",
        *body,
        command(d.get("command", "python benchmarks/fit_speed.py"), SOURCES["fit_speed"]),
        machine_line(d)]


def section_throughput(d: dict) -> list[str]:
    return [
        "The two-state model against a Numba loop of the same algorithm, and compile "
        "times, side by side in one run (medians over interleaved rounds).",
        goals_table(_goal_rows(d.get("goals", []))),
        command(d.get("command", "python benchmarks/throughput.py"), SOURCES["throughput"]),
        machine_line(d)]


def section_montecarlo(d: dict) -> list[str]:
    target = d.get("target", 2.0)
    if d.get("goals"):  # a script that judges its own goals
        goals = _goal_rows(d["goals"])
    else:
        goals = [(f"{r['case']} (B = {r['size']['B']}, n = {r['size']['n']:.0e})"
                  .replace("e+0", "e"), f"{r['ratio']:.2f}x", f">= {target:g}x",
                  r["ratio"] >= target) for r in d.get("rows", [])]
    return [
        "`jaxfric.simulate_many` over parameter sets and trajectories, and `simulate` on one "
        "long trajectory, against a Numba `prange` loop of the same algorithm (ratio = "
        "Numba time / jaxfric time; the forces agree to "
        f"{fmt(max((r['max_abs_diff_N'] for r in d.get('rows', [])), default=None), '.0e')}"
        " N).", goals_table(goals),
        command(d.get("command", "python benchmarks/montecarlo_speed.py"),
                SOURCES["montecarlo"]), machine_line(d)]


def section_real(emps: dict | None, tribo: dict | None) -> list[str]:
    out = []
    if emps is not None:
        b, a = emps["baseline"], emps["after"]
        out += [
            "EMPS positioning stage (24,841 samples at 1 kHz, motor force against position): "
            "`jaxfric diagnose` from the two-state model, in-sample and held-out RMSE before "
            "and after the effects it added.",
            table(["", "RMSE [N]", "held-out RMSE [N]", "relative error"],
                  [["two-state alone", b["rmse"], b["rmse_holdout"],
                    _percent(b["rel_error"], ".1f")],
                   ["+ " + ", ".join(a["added"]), a["rmse"], a["rmse_holdout"],
                    _percent(a["rel_error"], ".1f")]]),
            command("jaxfric diagnose ../shared/data/emps_estimation.csv "
                    "--json docs/figures/emps_diagnosis.json --report docs/figures/emps")]
    if tribo is not None:
        rows = [[name, m["n_params"], m["rmse_fit"], m["rmse_val"], _percent(m["nrmse_val"], ".1f")]
                for name, m in tribo["models"].items()]
        data = tribo.get("data", {})
        out += [
            "Reciprocating tribometer (direct force and position): each model fitted to the "
            f"first {100 * data.get('fit_fraction', 0.7):.0f} % of the record, checked on "
            "the rest (NRMSE: RMSE over the force range).",
            table(["model", "free parameters", "RMSE fit [N]", "RMSE held out [N]",
                   "NRMSE held out"], rows),
            command("python examples/tribometer.py --data ../shared/data/tribometer.csv "
                    "--json docs/figures/tribometer.json --out docs/figures")]
    return out + ["Machine: not recorded in these JSONs."]


def section_c_step(d: dict) -> list[str]:
    target = _find(d, "target_ns") or 100.0
    if d.get("goals"):  # a script that judges its own goals
        goals = _goal_rows(d["goals"])
    else:
        goals = [(f"C step, {r['model']}", f"{r['c_ns_per_step']:.0f} ns", f"<= {target:g} ns",
                  r["c_ns_per_step"] <= target) for r in d["rows"]]
    worst = max(r["c_max_error_rel_to_max_force"] for r in d["rows"])
    return [
        "The exported C step (`jaxfric.export`, `cc -O2`) per sample, called in a C loop as a "
        "controller would call it; its forces equal `jaxfric.simulate`'s to "
        f"{worst:.0e} of the largest force.", goals_table(goals),
        command("python benchmarks/c_step.py"), machine_line(d)]


def section_diagnose_speed(d: dict) -> list[str]:
    goal = d.get("goal_s_at_1e5", 60.0)
    big = [r for r in d["rows"] if r["samples"] >= 0.9e5 and r.get("code", "this") == "this"]
    if d.get("goals"):  # a script that judges its own goals
        goals = _goal_rows(d["goals"])
    else:
        goals = [(f"`jaxfric diagnose`, {r['samples']} samples, {r['cache']} compilation cache",
                  f"{r['wall_s']:.0f} s", f"<= {goal:g} s", r["wall_s"] <= goal) for r in big]
        goals += [(f"the same, {r['cache']} cache, scaled: {r['ratio']:.2f} x the older "
                   f"code's {r['then_s']:.1f} s", f"{r['scaled_s']:.0f} s",
                   f"<= {goal:g} s", r["scaled_s"] <= goal)
                  for r in d.get("ratios", []) if "scaled_s" in r and r["samples"] >= 0.9e5]
    return [
        "Wall time of `jaxfric diagnose` on a synthetic file (one hidden cogging) in a fresh "
        "process, empty compilation cache, then filled (medians of "
        f"{d.get('repeats', '?')} runs)"
        + (", alternating with the older code the goal was set against (commit in the JSON):"
           " the machine's speed varies 1.5x by the hour, so the ratio counts."
           if d.get("ratios") else "."), goals_table(goals),
        command("python benchmarks/diagnose_speed.py" + (
            " --sizes 1e5 --against DIR  # DIR: a worktree of the JSON's 'against'"
            if d.get("ratios") else "")), machine_line(d)]


def section_compiler_options(d: dict) -> list[str]:
    if d.get("goals"):  # a script that judges its own goals
        goals = _goal_rows(d["goals"])
    else:
        goals = [(f"compile time, {r['case']}: XLA defaults / jaxfric",
                  f"{r['ratio compile_s']:.2f}", "> 1", r["ratio compile_s"] > 1)
                 for r in d["rows"]]
    steady = ("Steady runs, XLA defaults / jaxfric: " + "; ".join(
        f"{r['case']} {r['ratio steady_s']:.2f}" for r in d["rows"]) + ". Largest force "
        f"difference between the settings: {max(r['max_dF_N'] for r in d['rows']):.0e} N.")
    return [
        "jaxfric's compiler options (`jaxfric._compile`) against XLA's defaults: compile and "
        "run time of `simulate` and `fit` in fresh processes without a compilation cache "
        "(ratio > 1: jaxfric's options are faster).",
        goals_table(goals), steady, command("python benchmarks/compiler_options.py"),
        machine_line(d)]


SECTIONS = [
    ("Diagnosis bench", ("diagnosis",), section_diagnosis),
    ("Diagnosis bench: another run", ("diagnosis_runs",), section_generalisation),
    ("Fit speed", ("fit_speed",), section_fit_speed),
    ("Throughput", ("throughput",), section_throughput),
    ("Monte-Carlo", ("montecarlo",), section_montecarlo),
    ("Real data", ("emps", "tribometer"), None),
    ("C step", ("c_step",), section_c_step),
    ("Diagnose speed", ("diagnose_speed",), section_diagnose_speed),
    ("Compiler options", ("compiler_options",), section_compiler_options),
]


def render(root: Path = ROOT) -> str:
    def load(key):
        path = root / SOURCES[key]
        return json.loads(path.read_text()) if path.is_file() else None

    parts = ["# Validation", "",
             "What the benchmarks measure and whether each goal is met. The numbers come from "
             "the JSONs the benchmarks write; `python benchmarks/make_validation.py` generates "
             "this page from them. The machine is a shared 2-core one: ratios measured side by "
             "side in one run mean more than absolute times.", ""]
    for title, keys, fn in SECTIONS:
        data = [load(k) for k in keys]
        parts += [f"## {title}", ""]
        if all(x is None for x in data):
            body = [f"No results: `{'`, `'.join(SOURCES[k] for k in keys)}` is missing."]
        else:
            try:
                body = (fn or section_real)(*data)
                # A caveat a JSON carries (e.g. code it measured that has changed since).
                body += [f"**Note:** {x['note']}" for x in data
                         if isinstance(x, dict) and x.get("note")]
            except (KeyError, TypeError, ValueError) as e:
                # A JSON whose layout this page does not know: say so, do not guess.
                body = [f"Cannot read `{'`, `'.join(SOURCES[k] for k in keys)}`: "
                        f"{type(e).__name__} {e}. Update `benchmarks/make_validation.py`."]
        parts += [b for x in body if x for b in (x, "")]
    return "\n".join(parts).rstrip() + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true",
                    help="exit 1 if docs/validation.md differs from the JSONs' page")
    ap.add_argument("--out", type=Path, default=PAGE, help="default: %(default)s")
    args = ap.parse_args(argv)
    text = render()
    bench = ROOT / SOURCES["diagnosis"]
    diag = with_bench_table(DIAGNOSIS_PAGE.read_text(),
                            json.loads(bench.read_text()) if bench.is_file() else None)
    pages = [(args.out, text), (DIAGNOSIS_PAGE, diag)]
    if args.check:
        stale = [p for p, t in pages if not (p.is_file() and p.read_text() == t)]
        for p, _ in pages:
            print(f"{p}: " + ("differs from the JSONs: run python benchmarks/make_validation.py"
                              if p in stale else "up to date"))
        return 1 if stale else 0
    for p, t in pages:
        p.write_text(t)
        print(f"wrote {p} ({len(t.split())} words)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
