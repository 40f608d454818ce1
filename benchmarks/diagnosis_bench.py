"""Diagnosis bench: does `jaxfric diagnose` name the missing effect on data it did not make?

    python benchmarks/diagnosis_bench.py [--quick] [--jobs 2] [--out ROWS.json]
    python benchmarks/diagnosis_bench.py --motions point_to_point,jerk_limited,sine_sweep \
        --truths gms_power,stiction --noises 0.1 --rates 0.002 --jitter 0.1 --duration 30

Every file is made the way a measurement would be (`jaxfric.synthetic.measurement`), from
truths that are NOT the model being fitted (a two-state model with the paper's presliding
shape):

- **truths**: a 60-element GMS whose virgin curve is another family (a power law) with its
  own Stribeck curve (``gms_power``); a LuGre model with stiff bristles (``lugre``); a
  two-state model with a `PowerShape` presliding curve (``two_state_power``); true
  stiction, a breakaway force and a stiff spring at rest, which none of jaxfric's families
  is (``stiction``, `jaxfric.synthetic.stiction_force`);
- **motions**: the diagnosis motion (``diagnosis``, `jaxfric.examples.diagnosis_motion`)
  or a family of `jaxfric.trajectories` (``--motions``: trapezoidal point-to-point moves
  with short strong accelerations, jerk-limited moves, sine sweeps) over ``--duration``
  seconds, with a logger clock that takes each sample up to ``--jitter`` of the interval
  early or late;
- **physics on a fine grid**: the truth is simulated at a tenth of the sampling interval
  and the hidden effects are computed there, with formulas written in `jaxfric.synthetic`
  (not `jaxfric.effects`);
- **sensors**: the position is quantised to a 0.05 um encoder, the force gets white noise;
  the file holds t, x, F only, so the diagnosis derives the velocity itself;
- **hidden effects**: none (a clean file), each of `SINGLES` alone, and the `PAIRS`.

A *corner* is one sampling interval, noise level, starting model and motion; each corner
has one file per truth and hidden effect(s). The summary counts each corner over all, per
truth, and per hidden effect with what was named first instead (a confusion row). For
each file the bench records what the diagnosis added (in order), the held-out RMSE before
and after, and the same baseline's cross-validated held-out RMSE on the file's clean twin
(same motion and noise, nothing hidden). A hidden effect that exerts no force on the file
(`acting_effects`: a drag felt above 5 mm/s on a sine sweep slower than that) is not
counted: the file hides the others (``not_acting`` lists such files). Targets: a single
hidden effect the first effect added in >= 90 % of files, both effects of a pair found in
>= 80 %, no effect added on clean files, and at least half the excess error over the clean
twin removed on every file where the effect was found. A base-model change (a GMS or a
LuGre instead of the two-state model: "the base model is the limit here") is not an effect:
the truths are of other families, where it is a right finding; the summary counts the files
with one (``base_model_changed``). A hidden effect that raises the baseline's held-out error
by less than `ABSORBED` over the clean twin is counted as *absorbed* by the base model
(little is left to find); the shares are also given without those files.

**Generalisation.** Each file is also judged on a run it was not fitted on: the same truth
and hidden effects on another motion (`measurement` with another seed, `OTHER_RUN`); its
RMSE by the baseline and by the diagnosed model (``judged_run_rmse_before/after``; the
summary counts the files where the diagnosis made it worse, ``judged_run_worse``). With
``--runs 2`` the diagnosis gets the file and one other run together (leave one run out,
`fitting.diagnose` with several runs) and is judged on a third.

A run writes every file's row (what was added, the rankings, every refit tried, the
diagnosis summary) to ``--out`` (default: in the system's temporary folder, not the
repository), and a summary of counts per corner (`summary`) to ``--summary`` (default
``benchmarks/diagnosis_bench.json``, the file docs/validation.md is generated from): the
corners the run covered replace theirs there, the others are kept. A ``--quick``,
``--only`` or ``--files`` run writes its summary next to ``--out`` instead.
``--summarise ROWS.json ...`` runs nothing: it summarises earlier runs' rows into
``--summary`` (a file in a later run replaces the same file in an earlier one).

The default run (3 truths x 2 noise levels x 2 sampling intervals x 16 files) takes about
3 hours on the 2-core machine; ``--quick`` runs one truth, noise level and interval (16
files, 10 to 15 minutes). To add a truth, an effect or a pair, add it to
`jaxfric.synthetic` or to the constants below; keyword arguments of `measurement` for a
new kind of file go in a case's ``"options"`` (they are part of its corner).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from jaxfric.synthetic import HIDDEN, measurement, TRUTHS


HERE = Path(__file__).resolve().parent
SUMMARY = HERE / "diagnosis_bench.json"
SINGLES = HIDDEN
#: Pairs of hidden effects; every effect is in one. A new pair goes at the end: a file's
#: motion and noise are seeded by its place in the list (`cases`).
PAIRS = (("asymmetry", "position_dependence"), ("inertia", "cogging"),
         ("quadratic_drag", "drift"), ("stribeck", "position_load"),
         ("friction_lag", "offset"))
NOISES = (0.03, 0.08)  # N
RATES = (1e-2, 5e-3)  # s
#: The truths of `jaxfric.synthetic.measurement`: its families, and true stiction.
BENCH_TRUTHS = (*TRUTHS, "stiction")
MOTIONS = ("diagnosis", "point_to_point", "jerk_limited", "sine_sweep")
STARTS = ("two-state", "gms", "lugre", "tustin")
#: A hidden effect whose baseline held-out RMSE exceeds the clean twin's by less than this
#: fraction is counted as absorbed by the base model (`clean_holdout`).
ABSORBED = 0.1
TARGETS = {"singles": 0.9, "pairs": 0.8}


def cases(quick: bool = False, truths=None, rates=None, noises=None, start="two-state",
          options: dict | None = None) -> list[dict]:
    """One case per file: every truth x noise x rate x (clean, singles, pairs); the seed
    is the hidden effects' place in that list, so the same effects get the same motion and
    noise in every corner."""
    truths = truths or (BENCH_TRUTHS[:1] if quick else BENCH_TRUTHS)
    rates = rates or (RATES[:1] if quick else RATES)
    noises = noises or (NOISES[:1] if quick else NOISES)
    hidden = [()] + [(h,) for h in SINGLES] + list(PAIRS)
    return [{"truth": truth, "noise": noise, "dt": dt, "hidden": list(h), "seed": k,
             "start": start, **({"options": options} if options else {})}
            for truth in truths for noise in noises for dt in rates
            for k, h in enumerate(hidden)]


def _measure(case: dict, hidden) -> tuple:
    return measurement(case["truth"], tuple(hidden), case["noise"], case["dt"], case["seed"],
                       **case.get("options", {}))


#: The seed of a file's other runs is its own plus this times the run's number: the same
#: truth and hidden effects on another motion (and other noise).
OTHER_RUN = 1000


def _other_run(case: dict, k: int):
    """Run `k` (1, 2, ...) of the file after its own: `measurement` of the same truth and
    hidden effects with another seed, so another motion."""
    import fitting

    other = {**case, "seed": case["seed"] + OTHER_RUN * k}
    t, x, F = _measure(other, case["hidden"])
    v, a = fitting.estimate_derivatives(t, x)  # as the diagnosis derives them
    return fitting.Dataset(t=t, x=x, F=F, v=v, a=a)


def _judged(model, d) -> float:
    """RMSE (N) of `model`'s prediction of run `d`, not fitted on it."""
    import jaxfric

    pred = np.asarray(jaxfric.simulate(model, d.t, d.x, d.v, a=d.a))
    return float(np.sqrt(np.mean((pred - d.F) ** 2)))


def run_case(case: dict) -> dict:
    """Diagnose the file (with ``case["runs"] == 2``: the file and its first other run
    together, leave one run out), then judge the baseline and the diagnosed model on a run
    they were not fitted on (`_other_run`): generalisation."""
    import fitting

    t0 = time.perf_counter()
    t, x, F = _measure(case, case["hidden"])
    acting = acting_effects(case)
    kind = case.get("start", "two-state")
    start = fitting.initial_model(kind, t, x, F, fitting.estimate_velocity(t, x))
    n_runs = case.get("runs", 1)
    if n_runs > 1:
        v, a = fitting.estimate_derivatives(t, x)
        runs = [fitting.Dataset(t=t, x=x, F=F, v=v, a=a)]
        runs += [_other_run(case, k) for k in range(1, n_runs)]
        d = fitting.diagnose(start, runs, model_name=kind)
    else:
        d = fitting.diagnose(start, t, x, F, model_name=kind)
    judge = _other_run(case, n_runs)
    base = fitting.run_model(d.baseline.fit.fit_model, None)
    judged = [c for c in d.candidates if np.isfinite(c.score)]
    return {**case, "acting": acting, "samples": int(t.size), "added": list(d.final.added),
            "folds": d.folds,
            "judged_run_rmse_before": _judged(base, judge),
            "judged_run_rmse_after": _judged(d.model, judge),
            "rmse_holdout_clean": clean_holdout(case, start),
            "first": d.final.added[0] if d.final.added else None,
            "top_score": judged[0].name if judged else None, "finding": d.finding,
            "rmse_before": d.baseline.rmse, "rmse_after": d.final.rmse,
            "rmse_holdout_before": d.baseline.rmse_holdout,
            "rmse_holdout_after": d.final.rmse_holdout,
            "seconds": time.perf_counter() - t0, "summary": d.summary(),
            "trials": d.trials,
            "rankings": [[{"name": c.name,
                           "score": c.score if np.isfinite(c.score) else None,
                           "t": c.t_stat if np.isfinite(c.t_stat) else None,
                           "significant": c.significant} for c in ranking]
                         for ranking in d.rankings]}


def acting_effects(case: dict) -> list[str]:
    """The file's hidden effects that exert a force on it: the same file with that effect
    alone differs from its clean twin (same motion, clock and noise) on some sample. A drag
    felt only above 5 mm/s does not act on a sine sweep that never reaches that speed."""
    clean = _measure(case, ())[2]
    return [h for h in case["hidden"] if np.any(_measure(case, [h])[2] != clean)]


def hidden(row: dict) -> list[str]:
    """What the file hides in fact (`acting_effects`; rows made before it was recorded:
    every hidden effect): a file whose one hidden effect does not act is a clean file,
    a pair with one that does not a single."""
    return row.get("acting", row["hidden"])


def clean_holdout(case: dict, start) -> float:
    """Held-out RMSE (N) of the baseline model on the file's clean twin (same motion,
    encoder and noise: `measurement` seeds them by file), cross-validated as the diagnosis
    cross-validates its baseline (its search copy of a long record, blocks and folds):
    the error the baseline would have if nothing were missing."""
    import fitting
    from fitting._base_options import base_model_starts, default_base_models
    from fitting._diagnose import _record, _search_copy, SEARCH_SAMPLES
    from fitting._folds import time_block_folds

    if not case["hidden"]:
        return float("nan")
    full, _ = _record(*_measure(case, ()), None, None, None, "central", None)
    start = _raced_start(start, full)
    copy = full
    if full.t.size >= 2 * SEARCH_SAMPLES:
        fitted = fitting.fit(start, full.t, full.x, full.F, full.v, a=full.a,
                             max_steps=150).fit_model
        tried = base_model_starts(default_base_models(start, full), fitted)
        copy, _, _ = _search_copy(full, fitted, SEARCH_SAMPLES, lambda *_: None, tried)
    rules = fitting.DiagnosisRules()
    sse = 0.0
    for train, test in time_block_folds(copy.t, rules.blocks, rules.folds):
        res = fitting.fit(start, copy.t, copy.x, copy.F, copy.v, a=copy.a, weights=train,
                          max_steps=150)
        sse += float(np.sum(((np.asarray(res.prediction) - copy.F) ** 2)[test > 0]))
    return float(np.sqrt(sse / copy.t.size))


def _raced_start(start, d):
    """The start of `start`'s lag starts whose fit on `d` the diagnosis's base fit keeps
    (`fitting._start.lag_starts`, `Fitter.race`)."""
    from fitting._params import to_fit_representation
    from fitting._refits import Fitter
    from fitting._start import lag_starts

    starts = lag_starts(to_fit_representation(start))
    won = Fitter(d, (), 150).race(starts, frozenset())[2]
    return dict(starts).get(won, start)


def absorbed(row: dict) -> bool:
    clean = row.get("rmse_holdout_clean", float("nan"))
    return bool(hidden(row)) and row["rmse_holdout_before"] < (1 + ABSORBED) * clean


def effects_added(row: dict) -> list[str]:
    """What the diagnosis added to the file, in order, that is an effect of
    `jaxfric.effects`; the rest are base-model changes ("the base model is the limit
    here", a GMS or a LuGre instead of the two-state model), the finding the diagnosis should make
    on a truth of another family, not an effect the file hides."""
    from jaxfric.effects import EFFECTS

    return [n for n in row["added"] if n in EFFECTS]


def base_changed(row: dict) -> bool:
    return len(effects_added(row)) < len(row["added"])


def first_effect(row: dict) -> str | None:
    e = effects_added(row)
    return e[0] if e else None


def found(row: dict) -> bool:
    """A single effect the first effect added (a base-model change may come before it),
    both effects of a pair added."""
    if len(hidden(row)) == 1:
        return first_effect(row) == hidden(row)[0]
    return set(hidden(row)) <= set(row["added"])


def file_key(row: dict) -> tuple:
    return (row["truth"], tuple(row["hidden"])) + corner_key(row)


def motion(row: dict) -> str:
    return row.get("options", {}).get("motion") or "diagnosis"


def corner_key(row: dict) -> tuple:
    return (row["dt"], row["noise"], row.get("start", "two-state"),
            json.dumps(row.get("options", {}), sort_keys=True), row.get("runs", 1))


def counts(rows: list[dict]) -> dict:
    """The targets' numerators and denominators (``[found, files]``) for `rows`."""
    singles = [r for r in rows if len(hidden(r)) == 1]
    pairs = [r for r in rows if len(hidden(r)) == 2]
    clean = [r for r in rows if not hidden(r)]
    gone = {(r["truth"],) + corner_key(r) + (hidden(r)[0],) for r in singles if absorbed(r)}
    left = [r for r in singles if not absorbed(r)]
    findable = [r for r in pairs if not any(
        (r["truth"],) + corner_key(r) + (h,) in gone for h in hidden(r))]
    removed = []
    for r in singles + pairs:
        excess = r["rmse_holdout_before"] - r["rmse_holdout_clean"]
        if found(r) and excess > 0:
            removed.append((r["rmse_holdout_before"] - r["rmse_holdout_after"]) / excess)

    judged = [r for r in rows if r.get("judged_run_rmse_before") is not None]

    def share(sel):
        return [sum(found(r) for r in sel), len(sel)]

    return {"not_acting": [r["hidden"] for r in rows if hidden(r) != r["hidden"]],
            "singles": share(singles), "singles_not_absorbed": share(left),
            "pairs": share(pairs), "pairs_not_absorbed": share(findable),
            "clean_files": len(clean),
            "added_on_clean": sum(len(effects_added(r)) for r in clean),
            "not_hidden_added": sum(len(set(effects_added(r)) - set(hidden(r)))
                                    for r in rows),
            "base_model_changed": [sum(map(base_changed, rows)), len(rows)],
            "found_half_excess_removed": [sum(s >= 0.5 for s in removed), len(removed)],
            # generalisation: the run not used, predicted worse after the diagnosis
            "judged_run_worse": [sum(r["judged_run_rmse_after"] > r["judged_run_rmse_before"]
                                     for r in judged), len(judged)],
            "judged_run_worse_with_added": [
                sum(r["judged_run_rmse_after"] > r["judged_run_rmse_before"]
                    for r in judged if r["added"]), sum(bool(r["added"]) for r in judged)],
            "median_excess_removed": float(np.median(removed)) if removed else None}


def summarise_corner(rows: list[dict]) -> dict:
    """A corner's summary: its counts, over all and per truth, and per hidden effect (single
    files): how many, named first, absorbed, and what was named first instead."""
    r0 = rows[0]
    by_effect = {}
    for h in dict.fromkeys(h for r in rows if len(hidden(r)) == 1 for h in hidden(r)):
        sel = [r for r in rows if hidden(r) == [h]]
        instead = [first_effect(r) or "nothing" for r in sel if not found(r)]
        by_effect[h] = {"files": len(sel), "named_first": sum(map(found, sel)),
                        "absorbed": sum(map(absorbed, sel)),
                        "instead": {n: instead.count(n) for n in sorted(set(instead))}}
    by_pair = {}
    for r in rows:
        if len(hidden(r)) == 2:
            p = by_pair.setdefault(" + ".join(hidden(r)), {"files": 0, "both_found": 0})
            p["files"] += 1
            p["both_found"] += found(r)
    truths = list(dict.fromkeys(r["truth"] for r in rows))
    return {"dt_s": r0["dt"], "noise_N": r0["noise"], "start": r0.get("start", "two-state"),
            "runs_diagnosed": r0.get("runs", 1),
            **({"options": r0["options"]} if r0.get("options") else {}),
            "motion": motion(r0), "truths": truths, "files": len(rows), **counts(rows),
            "by_truth": {t: counts([r for r in rows if r["truth"] == t]) for t in truths},
            "by_effect": by_effect, "by_pair": by_pair,
            "judged_runs": [{"truth": r["truth"], "hidden": r["hidden"], "added": r["added"],
                             "rmse_before": r["judged_run_rmse_before"],
                             "rmse_after": r["judged_run_rmse_after"]}
                            for r in rows if "judged_run_rmse_before" in r]}


def summary(rows: list[dict], runs: list[dict], previous: dict | None = None) -> dict:
    """The summary JSON: one entry per corner of `rows` (with the runs that made it:
    machine, date, seconds), after the corners of `previous` that `rows` does not cover."""
    corners = {}
    for r in rows:
        corners.setdefault(corner_key(r), []).append(r)
    fresh = []
    for sel in corners.values():
        entry = summarise_corner(sel)
        names = {r["_run"] for r in sel}
        entry["runs"] = [{k: v for k, v in run.items() if k != "name"} for run in runs
                         if run["name"] in names]
        fresh.append(entry)
    kept = [c for c in (previous or {}).get("corners", [])
            if _entry_key(c) not in {_entry_key(c) for c in fresh}]
    order = {s: k for k, s in enumerate(STARTS)}
    every = sorted(kept + fresh, key=lambda c: (order.get(c["start"], 99), -c["dt_s"],
                                                c["noise_N"]))
    return {"benchmark": "diagnosis bench", "command": "python benchmarks/diagnosis_bench.py",
            "targets": {**TARGETS, "added_on_clean": 0, "found_half_excess_removed": 1.0},
            "absorbed_below": ABSORBED, "corners": every}


def _entry_key(c: dict) -> tuple:
    return (c["dt_s"], c["noise_N"], c["start"],
            json.dumps(c.get("options", {}), sort_keys=True), c.get("runs_diagnosed", 1))


def _git_date(path: Path) -> str | None:
    """The date of the last commit of `path` (runs made before the rows held their date)."""
    try:
        out = subprocess.run(["git", "log", "-1", "--format=%cd", "--date=format:%Y-%m-%d",
                              "--", path.name], cwd=path.parent, capture_output=True,
                             text=True, timeout=10)
    except OSError:
        return None
    return out.stdout.strip() or None


def _run_facts(name: str, data: dict, path: Path | None = None) -> dict:
    m = data.get("machine", {})
    date = data.get("date_utc") or (path is not None and _git_date(path)) or None
    return {"name": name, "cpu": m.get("cpu"),
            "cores": m.get("usable_cores") or m.get("cpus") or m.get("logical_cores"),
            "date_utc": date, "seconds": data.get("seconds"), "quick": data.get("quick")}


def load_rows(paths: list[Path]) -> tuple[list[dict], list[dict]]:
    """The rows of earlier runs (a file in a later run replaces it in an earlier one) and
    the facts of each run."""
    rows, runs = {}, []
    for path in paths:
        data = json.loads(path.read_text())
        runs.append(_run_facts(path.name, data, path))
        for r in data["files"]:
            rows[file_key(r)] = {**r, "_run": path.name}
    return list(rows.values()), runs


def write_summary(path: Path, rows: list[dict], runs: list[dict], note: str | None = None
                  ) -> dict:
    previous = json.loads(path.read_text()) if path.is_file() else None
    out = summary(rows, runs, previous)
    if note:
        out["note"] = note
    path.write_text(json.dumps(out, indent=1) + "\n")
    return out


def print_table(rows: list[dict]) -> None:
    print(f"\n{'truth':<16} {'motion':<15} {'noise':>5} {'dt':>6}  {'hidden':<34} "
          f"{'added (in order)':<40} held-out RMSE before -> after, N; run not used")
    for r in rows:
        ok = "ok" if (found(r) if hidden(r) else not effects_added(r)) else "MISS"
        if hidden(r) != r["hidden"]:
            ok += f" (acting: {' + '.join(hidden(r)) or 'none'})"
        if absorbed(r):
            ok += f" (absorbed: clean {r['rmse_holdout_clean']:.4f})"
        print(f"{r['truth']:<16} {motion(r):<15} {r['noise']:>5.2f} {r['dt'] * 1e3:>4.0f}ms  "
              f"{' + '.join(r['hidden']) or '(clean)':<34} "
              f"{' + '.join(r['added']) or '-':<40} {r['rmse_holdout_before']:>10.4f} -> "
              f"{r['rmse_holdout_after']:.4f}  {ok}"
              + (f"  judged run {r['judged_run_rmse_before']:.4f} -> "
                 f"{r['judged_run_rmse_after']:.4f}" if "judged_run_rmse_before" in r else ""))


def print_summary(out: dict) -> None:
    for c in out["corners"]:
        print(f"\ncorner dt {c['dt_s'] * 1e3:g} ms, noise {c['noise_N']:g} N, start "
              f"{c['start']}, motion {c.get('motion', 'diagnosis')} "
              f"({', '.join(c['truths'])}; {c['files']} files):")
        for k in ("singles", "singles_not_absorbed", "pairs", "pairs_not_absorbed",
                  "found_half_excess_removed", "judged_run_worse"):
            if k in c:
                print(f"  {k:<28} {c[k][0]} of {c[k][1]}")
        print(f"  {'added_on_clean':<28} {c['added_on_clean']} ({c['clean_files']} files)")
        for h, e in c["by_effect"].items():
            print(f"  {h:<22} named first {e['named_first']} of {e['files']}"
                  + (f", instead {e['instead']}" if e["instead"] else ""))


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="one truth, noise level and rate")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    ap.add_argument("--out", default=str(Path(tempfile.gettempdir())
                                         / "diagnosis_bench_rows.json"),
                    help="every file's row, JSON (default: %(default)s)")
    ap.add_argument("--summary", help=f"the summary JSON (default: {SUMMARY}; with --quick "
                    "or --only: next to --out)")
    ap.add_argument("--files", help="comma-separated files, each named by its hidden "
                    "effects joined by '+' ('clean' for none): run exactly those (a corner's "
                    "files that a change can touch; --summarise merges them with a full run)")
    ap.add_argument("--only", help="comma-separated hidden effects: run the files whose "
                    "hidden effects are all among them (and the clean files)")
    ap.add_argument("--truths", help="comma-separated truths (default: "
                    f"{', '.join(BENCH_TRUTHS)}; "
                    "--quick: the first)")
    ap.add_argument("--rates", help="comma-separated sampling intervals in s (default: "
                    f"{', '.join(map(str, RATES))}; --quick: the first)")
    ap.add_argument("--noises", help="comma-separated force noise levels in N (default: "
                    f"{', '.join(map(str, NOISES))}; --quick: the first)")
    ap.add_argument("--start", default="two-state", choices=STARTS,
                    help="the model the diagnosis starts from (fitting.initial_model; "
                    "default %(default)s)")
    ap.add_argument("--motions", default="diagnosis",
                    help=f"comma-separated motions, of {', '.join(MOTIONS)} (default: "
                    "%(default)s)")
    ap.add_argument("--duration", type=float, default=30.0,
                    help="seconds of a trajectories motion (default: %(default)s)")
    ap.add_argument("--jitter", type=float, default=0.0,
                    help="clock jitter, fraction of the interval (default: %(default)s)")
    ap.add_argument("--runs", type=int, default=1, choices=(1, 2),
                    help="runs diagnosed together: 1 (the file; its time blocks are the "
                    "folds) or 2 (the file and a run of another motion, leave one run out); "
                    "either is judged on one more run (default: %(default)s)")
    ap.add_argument("--note", help="a note saved in the summary (e.g. what subset ran)")
    ap.add_argument("--summarise", nargs="+", metavar="ROWS", type=Path,
                    help="run nothing: summarise the rows of earlier runs into --summary")
    return ap


def _share_cores(jobs: int) -> None:
    """The files are the parallel work: with several worker processes, each diagnosis
    runs its fits on its share of the cores (``JAXFRIC_WORKERS``,
    `fitting._refits.default_workers`), not on all; a value given is kept."""
    if jobs > 1 and "JAXFRIC_WORKERS" not in os.environ:
        os.environ["JAXFRIC_WORKERS"] = str(max(1, (os.cpu_count() or 1) // jobs))


def main(argv=None) -> int:
    ap = _parser()
    args = ap.parse_args(argv)
    out = Path(args.out)
    summary_path = Path(args.summary) if args.summary else (
        out.with_name(out.stem + "_summary.json") if args.quick or args.only or args.files
        else SUMMARY)
    if args.summarise:
        rows, runs = load_rows(args.summarise)
        print_summary(write_summary(summary_path, rows, runs, args.note))
        print(f"\nwrote {summary_path}")
        return 0

    def floats(text):
        return [float(v) for v in text.split(",")] if text else None

    todo = []
    for m in args.motions.split(","):
        if m not in MOTIONS:
            ap.error(f"--motions: {m!r} is not one of {', '.join(MOTIONS)}")
        options = ({} if m == "diagnosis" else {"motion": m, "duration": args.duration})
        if args.jitter:
            options["jitter"] = args.jitter
        todo += cases(args.quick, args.truths.split(",") if args.truths else None,
                      floats(args.rates), floats(args.noises), args.start, options or None)
    if args.runs > 1:
        todo = [{**c, "runs": args.runs} for c in todo]
    if args.only:
        keep = set(args.only.split(","))
        todo = [c for c in todo if set(c["hidden"]) <= keep]
    if args.files:
        wanted = set(args.files.split(","))
        todo = [c for c in todo if ("+".join(c["hidden"]) or "clean") in wanted]
    print(f"{len(todo)} files; each is fitted and diagnosed ({args.jobs} worker(s))",
          flush=True)
    rows, t0 = [], time.perf_counter()
    try:
        from machine import machine_facts
    except ImportError:
        from benchmarks.machine import machine_facts
    facts = {"machine": machine_facts(),
             "date_utc": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M")}

    def save(complete: bool) -> dict:
        # Written after every file, so that a run cut off keeps what it had done.
        data = {**facts, "quick": args.quick, "complete": complete,
                "seconds": time.perf_counter() - t0, "files": rows}
        tmp = out.with_suffix(".json.partial")
        tmp.write_text(json.dumps(data, indent=1) + "\n")
        tmp.replace(out)
        return data

    _share_cores(args.jobs)
    # A fresh worker for every file: each diagnosis compiles its own functions (about a
    # hundred), and a worker that kept them all would run out of memory maps.
    with ProcessPoolExecutor(max_workers=args.jobs, max_tasks_per_child=1) as pool:
        for k, row in enumerate(pool.map(run_case, todo), start=1):
            rows.append(row)
            print(f"[{k}/{len(todo)} {time.perf_counter() - t0:6.0f} s] {row['truth']} "
                  f"{' + '.join(row['hidden']) or '(clean)'}: added "
                  f"{' + '.join(row['added']) or 'nothing'}", flush=True)
            save(complete=False)
    data = save(complete=True)
    print_table(rows)
    run = _run_facts(out.name, data)
    print_summary(write_summary(summary_path, [{**r, "_run": out.name} for r in rows], [run],
                                args.note))
    print(f"\nwrote {out} (every file) and {summary_path} (the summary)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
