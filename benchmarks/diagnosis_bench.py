"""Diagnosis bench: does `jaxfric diagnose` name the missing effect on data it did not make?

    python benchmarks/diagnosis_bench.py [--quick] [--jobs 2] [--json OUT.json]

Every file is made the way a measurement would be, from truths that are NOT the model being
fitted (a two-state model with the paper's presliding shape):

- **truths**: a 60-element GMS whose virgin curve is another family (a power law,
  ``1 - (1 - u)**2.5``) with its own Stribeck curve (``gms_power``); a LuGre model with
  stiff bristles (``lugre``); a two-state model with a `PowerShape` presliding curve
  (``two_state_power``);
- **physics on a fine grid**: the truth is simulated at a tenth of the sampling interval
  and the hidden effects are computed there, from the fine grid's own central-difference
  velocity and acceleration, with formulas written in `jaxfric.synthetic` (not
  `jaxfric.effects`);
- **sensors**: the position is sampled and quantised to a 0.05 um encoder; the force gets
  white noise (two levels); two sampling intervals; the file holds t, x, F only, so the
  diagnosis derives the velocity itself;
- **hidden effects**: one at a time (regime-confined ones included: a drag that matters
  only at high speed, an asymmetry in one direction only, an acceleration (mass) term,
  a two-harmonic position ripple, a warm-up drift, an offset, a friction level that
  changes along the travel, a spring-like load along the travel, a Stribeck hump, a
  friction lag), pairs, and clean files.

For each file the bench records which effect the diagnosis added first and all it added,
and the RMSE before and after. The summary prints a confusion table (hidden -> named
first), the share of single-effect files whose effect was named first, of pairs with both
found, the number of effects added on clean files, and the share of the excess error over
the same file without its hidden effects (same motion and noise) removed when the effect
was found (targets: >= 90 %, >= 80 %, 0, >= 50 %). A hidden effect that raises the
baseline's held-out error by less than 10 % over that clean twin is marked "absorbed" (the
base model's own viscous term or lag took it up; little is left to find), and the share
named first is also given without those files (and the share of pairs with both found
without the pairs holding an effect absorbed in its own single file).
JSON with every file's outcome goes to ``benchmarks/diagnosis_bench.json`` (or --json);
``--update JSON`` re-runs only the files selected (``--only``, ``--truths``) into an
earlier run, for a change that can only affect those (its ``"rerun"`` lists them).
The full bench (3 truths x 2 noise levels x 2 rates x 16 files) takes hours on two cores;
``--quick`` runs one truth, one noise level and one rate (16 files). The files are made by
`jaxfric.synthetic.measurement`. ``--start gms`` (or lugre, tustin) diagnoses from another
model than the two-state one (`fitting.initial_model`): do the effects found depend on it?
(Each row then says ``"start"``.)
"""

import argparse
import json
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from jaxfric.synthetic import HIDDEN, measurement, TRUTHS


HERE = Path(__file__).resolve().parent
SINGLES = HIDDEN
#: The first three kinds of pair, then two added so that every hidden effect is in one
#: (their seeds follow: the files of the first three are unchanged).
PAIRS = (("asymmetry", "position_dependence"), ("inertia", "cogging"),
         ("quadratic_drag", "drift"), ("stribeck", "position_load"),
         ("friction_lag", "offset"))
NOISES = (0.03, 0.08)  # N
RATES = (1e-2, 5e-3)  # s


def run_case(case: dict) -> dict:
    import fitting

    t0 = time.perf_counter()
    t, x, F = measurement(case["truth"], tuple(case["hidden"]), case["noise"], case["dt"],
                          case["seed"])
    kind = case.get("start", "two-state")
    start = fitting.initial_model(kind, t, x, F, fitting.estimate_velocity(t, x))
    d = fitting.diagnose(start, t, x, F, model_name=kind)
    ranked = [c.name for c in sorted(d.candidates, key=lambda c: -c.score)]
    return {**case, "samples": int(t.size), "added": list(d.final.added),
            "rmse_holdout_clean": clean_holdout(case, start, d.holdout),
            "first": d.final.added[0] if d.final.added else None,
            "top_score": ranked[0] if ranked else None,
            "rmse_before": d.baseline.rmse, "rmse_after": d.final.rmse,
            "rmse_holdout_before": d.baseline.rmse_holdout,
            "rmse_holdout_after": d.final.rmse_holdout,
            "seconds": time.perf_counter() - t0, "summary": d.summary(),
            "trials": d.trials,
            "rankings": [[{"name": c.name, "score": c.score,
                           "t": c.t_stat if np.isfinite(c.t_stat) else None,
                           "significant": c.significant} for c in ranking]
                         for ranking in d.rankings]}


def clean_holdout(case: dict, start, holdout) -> float:
    """Held-out RMSE (N) of the baseline model fitted to the same file without its hidden
    effects (same motion, encoder and noise: `measurement` seeds them by file), on the
    diagnosis's training/held-out split: the error the baseline would have if nothing were
    missing. A hidden effect that raises the baseline's held-out error by less than
    `ABSORBED` of this is absorbed by the base model's own parameters (a drag by the
    viscous term, a friction lag by the lag state): there is then little left to find."""
    import fitting

    if not case["hidden"]:
        return float("nan")
    t, x, F = measurement(case["truth"], (), case["noise"], case["dt"], case["seed"])
    v = fitting.estimate_velocity(t, x)
    res = fitting.fit(start, t, x, F, v, weights=(~holdout).astype(float), max_steps=300)
    err = np.asarray(res.prediction) - F
    return float(np.sqrt(np.mean(err[holdout] ** 2)))


#: A hidden effect whose baseline held-out RMSE exceeds the clean file's by less than this
#: fraction is counted as absorbed by the base model (`clean_holdout`).
ABSORBED = 0.1


def absorbed(row: dict) -> bool:
    clean = row.get("rmse_holdout_clean", float("nan"))
    return bool(row["hidden"]) and row["rmse_holdout_before"] < (1 + ABSORBED) * clean


def cases(quick: bool, truths=None, rates=None, noises=None, start="two-state"
          ) -> list[dict]:
    truths = truths or (TRUTHS[:1] if quick else TRUTHS)
    rates = rates or (RATES[:1] if quick else RATES)
    noises = noises or (NOISES[:1] if quick else NOISES)
    hidden = [()] + [(h,) for h in SINGLES] + list(PAIRS)
    out = []
    for truth in truths:
        for noise in noises:
            for dt in rates:
                for k, h in enumerate(hidden):
                    out.append({"truth": truth, "noise": noise, "dt": dt, "hidden": list(h),
                                "seed": k, **({} if start == "two-state" else
                                              {"start": start})})
    return out


def wrong_refits(rows: list[dict]) -> list[dict]:
    """Every joint refit (`fitting.Diagnosis.trials`) of an effect that was not hidden in
    its file, with the file's hidden effects: the null evidence the significance rule must
    reject (on a clean file all refits are of this kind)."""
    return [{**tr, "hidden": r["hidden"]} for r in rows for tr in r.get("trials", ())
            if not set(tr["effects"]) <= set(r["hidden"])]


def _null_summary(rows: list[dict]) -> dict:
    """The largest held-out share removed by a refit of an effect not hidden, on clean
    files and on any file, and how many such refits the rule let through."""
    wrong = wrong_refits(rows)
    clean = [w for w in wrong if not w["hidden"]]
    return {
        "wrong_refits": len(wrong),
        "wrong_refits_added": sum(w["added"] for w in wrong),
        "largest_share_removed_by_wrong_refit_clean": max(
            (w["removed"] for w in clean), default=None),
        "largest_share_removed_by_wrong_refit": max((w["removed"] for w in wrong),
                                                    default=None),
    }


def _groups(rows: list[dict]):
    """``(singles, pairs, left, findable)``: the single-effect and pair files, the singles
    not absorbed, and the pairs without an effect its base model absorbs alone (same truth,
    noise and rate): those have only one effect to find."""
    singles = [r for r in rows if len(r["hidden"]) == 1]
    pairs = [r for r in rows if len(r["hidden"]) == 2]
    left = [r for r in singles if not absorbed(r)]
    gone = {(r["truth"], r["noise"], r["dt"], r["hidden"][0]) for r in singles if absorbed(r)}
    findable = [r for r in pairs
                if not any((r["truth"], r["noise"], r["dt"], h) in gone for h in r["hidden"])]
    return singles, pairs, left, findable


def summarise(rows: list[dict]) -> dict:
    clean = {(r["truth"], r["noise"], r["dt"]): r for r in rows if not r["hidden"]}
    singles, pairs, left, findable = _groups(rows)
    right = [r for r in singles if r["first"] == r["hidden"][0]]
    both = [r for r in pairs if set(r["hidden"]) <= set(r["added"])]
    removed = []
    for r in right + both:
        # The excess over the same file without its hidden effects (same motion and noise).
        excess = r["rmse_holdout_before"] - r["rmse_holdout_clean"]
        if excess > 0:
            removed.append((r["rmse_holdout_before"] - r["rmse_holdout_after"]) / excess)
    return {
        "single_right_first": len(right) / max(len(singles), 1),
        "singles": len(singles),
        "singles_absorbed_by_base": [r["hidden"][0] for r in singles if absorbed(r)],
        "single_right_first_not_absorbed": (
            sum(r["first"] == r["hidden"][0] for r in left) / max(len(left), 1)),
        "pairs_both_found": len(both) / max(len(pairs), 1),
        "pairs": len(pairs),
        "pairs_both_found_not_absorbed": (
            sum(set(r["hidden"]) <= set(r["added"]) for r in findable)
            / max(len(findable), 1)),
        "pairs_not_absorbed": len(findable),
        "clean_files": len(clean),
        "effects_added_on_clean": sum(len(r["added"]) for r in clean.values()),
        "median_excess_removed_when_found": float(np.median(removed)) if removed else None,
        "found_with_half_excess_removed": (float(np.mean(np.asarray(removed) >= 0.5))
                                           if removed else None),
        **_null_summary(rows),
    }


def print_table(rows: list[dict], summary: dict) -> None:
    print(f"\n{'truth':<16} {'noise':>5} {'dt':>6}  {'hidden':<34} {'added (in order)':<40} "
          f"{'RMSE before -> after (held out), N':>34}")
    for r in rows:
        hidden = " + ".join(r["hidden"]) or "(clean)"
        added = " + ".join(r["added"]) or "-"
        if len(r["hidden"]) == 2:
            ok = "ok" if set(r["hidden"]) <= set(r["added"]) else "MISS"
        else:
            ok = ("ok" if (r["hidden"] and r["first"] in r["hidden"]) or
                  (not r["hidden"] and not r["added"]) else "MISS")
        if absorbed(r):
            ok += f" (absorbed: clean {r['rmse_holdout_clean']:.4f})"
        print(f"{r['truth']:<16} {r['noise']:>5.2f} {r['dt'] * 1e3:>4.0f}ms  {hidden:<34} "
              f"{added:<40} {r['rmse_holdout_before']:>10.4f} -> {r['rmse_holdout_after']:.4f}"
              f"  {ok}")
    names = sorted({h for r in rows for h in r["hidden"]})
    print("\nconfusion (single hidden effect -> first named), counts:")
    named = sorted({r["first"] or "-" for r in rows if len(r["hidden"]) == 1})
    print(f"{'hidden':<22}" + "".join(f"{n[:10]:>11}" for n in named))
    for h in names:
        sel = [r for r in rows if r["hidden"] == [h]]
        if sel:
            print(f"{h:<22}" + "".join(
                f"{sum((r['first'] or '-') == n for r in sel):>11}" for n in named))
    wrong = wrong_refits(rows)
    if wrong:
        print("\nrefits of effects not hidden in their file (what the rule must reject):")
        for w in sorted(wrong, key=lambda w: -w["removed"]):
            t = "inf" if w["t"] is None else f"{w['t']:.1f}"
            print(f"  {' + '.join(w['hidden']) or '(clean)':<34} {' + '.join(w['effects']):<34}"
                  f" removed {100 * w['removed']:6.1f} %  t {t:>5}"
                  f"  {'ADDED' if w['added'] else 'rejected'}")
    print("\nsummary:")
    for k, v in summary.items():
        print(f"  {k:<36} {v if not isinstance(v, float) else round(v, 3)}")


def _verdict(r: dict) -> str:
    if len(r["hidden"]) == 2:
        found = [h for h in r["hidden"] if h in r["added"]]
        ok = "ok" if len(found) == 2 else f"**miss** ({len(found)} of 2)"
    elif r["hidden"]:
        ok = "ok" if r["first"] == r["hidden"][0] else "**miss**"
    else:
        ok = "ok" if not r["added"] else "**miss**"
    return ok + (" (absorbed)" if absorbed(r) else "")


def markdown(rows: list[dict]) -> str:
    """The per-file table as Markdown, for docs/diagnosis.md."""
    lines = ["| truth | noise [N] | dt [ms] | hidden | named (in order) | held-out RMSE "
             "before -> after [N] | clean twin [N] | |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        clean = r.get("rmse_holdout_clean", float("nan"))
        lines.append(
            f"| {r['truth']} | {r['noise']:g} | {r['dt'] * 1e3:g} | "
            f"{' + '.join(r['hidden']) or '(clean)'} | {', '.join(r['added']) or 'nothing'} | "
            f"{r['rmse_holdout_before']:.3f} -> {r['rmse_holdout_after']:.3f} | "
            f"{'' if np.isnan(clean) else f'{clean:.3f}'} | {_verdict(r)} |")
    return "\n".join(lines)


def markdown_by_truth(rows: list[dict]) -> str:
    """One row per hidden effect(s), one column per truth: what was named (in order), and
    the held-out RMSE before -> after; for docs/diagnosis.md."""
    truths = list(dict.fromkeys(r["truth"] for r in rows))
    keys = list(dict.fromkeys(tuple(r["hidden"]) for r in rows))
    lines = ["| hidden | " + " | ".join(truths) + " |", "|---" * (len(truths) + 1) + "|"]
    for key in keys:
        cells = []
        for truth in truths:
            r = next((r for r in rows if r["truth"] == truth and tuple(r["hidden"]) == key),
                     None)
            cells.append("" if r is None else
                         f"{', '.join(r['added']) or 'nothing'} "
                         f"({r['rmse_holdout_before']:.3f} -> {r['rmse_holdout_after']:.3f}) "
                         f"{_verdict(r)}")
        lines.append(f"| {' + '.join(key) or '(clean)'} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _counts(rows: list[dict]) -> dict:
    """The targets' numerators and denominators (as `summarise`, in counts)."""
    singles, pairs, left, findable = _groups(rows)
    s = summarise(rows)
    return {
        "singles": (sum(r["first"] == r["hidden"][0] for r in singles), len(singles)),
        "singles_left": (sum(r["first"] == r["hidden"][0] for r in left), len(left)),
        "pairs": (sum(set(r["hidden"]) <= set(r["added"]) for r in pairs), len(pairs)),
        "pairs_left": (sum(set(r["hidden"]) <= set(r["added"]) for r in findable),
                       len(findable)),
        "clean": s["effects_added_on_clean"], "half": s["found_with_half_excess_removed"],
        "median": s["median_excess_removed_when_found"]}


def markdown_targets(rows: list[dict]) -> str:
    """The targets, per truth and over all, as Markdown for docs/diagnosis.md: counts, and
    over all the share and whether it is met."""
    truths = list(dict.fromkeys(r["truth"] for r in rows))
    per = [_counts([r for r in rows if r["truth"] == t]) for t in truths]
    every = _counts(rows)

    def frac(key, c):
        k, n = c[key]
        return f"{k} of {n}"

    def total(key, goal):
        k, n = every[key]
        share = k / max(n, 1)
        return (f"{k} of {n} ({100 * share:.0f} %): "
                + ("met" if share >= goal else "**missed**"))

    def half(c):
        if c["half"] is None:
            return "none found"
        return ("all" if c["half"] == 1 else f"{100 * c['half']:.0f} %") + (
            f" (median {100 * c['median']:.0f} %)")

    lines = ["| target | " + " | ".join(truths) + " | all |", "|---" * (len(truths) + 2) + "|"]
    for label, key, goal in (
            ("single hidden effect named first (>= 90 %)", "singles", 0.9),
            ("the same, leaving out the absorbed", "singles_left", 0.9),
            ("both effects of a pair found (>= 80 %)", "pairs", 0.8),
            ("the same, leaving out pairs with an effect absorbed alone", "pairs_left", 0.8)):
        lines.append(f"| {label} | " + " | ".join(frac(key, c) for c in per)
                     + f" | {total(key, goal)} |")
    lines.append("| effects added on the clean file (0) | " + " | ".join(
        str(c["clean"]) for c in per) + f" | {every['clean']}: "
        + ("met" if every["clean"] == 0 else "**missed**") + " |")
    lines.append("| half the excess error removed when found | " + " | ".join(
        half(c) for c in per) + f" | {half(every)}: "
        + ("met" if every["half"] in (None, 1.0) else "**missed**") + " |")
    return "\n".join(lines)


def _replaced(files: list[dict], new: list[dict]) -> list[dict]:
    """`files` with the rows of the same file (truth, hidden, noise, sampling) as in `new`
    replaced by those, and the rows of files it did not have (a kind of file added to the
    bench) after them."""
    def key(r):
        return r["truth"], tuple(r["hidden"]), r["noise"], r["dt"], r.get("start")

    fresh = {key(r): r for r in new}
    old = {key(r) for r in files}
    return [fresh.get(key(r), r) for r in files] + [r for r in new if key(r) not in old]


def _exactly(todo: list[dict], spec: str) -> list[dict]:
    """The cases of `todo` named in `spec` (``TRUTH:HIDDEN,...``, see --files)."""
    wanted = set()
    for item in spec.split(","):
        truth, sep, hidden = item.strip().partition(":")
        if not sep or truth not in TRUTHS:
            raise SystemExit(f"--files: {item!r} is not TRUTH:HIDDEN with TRUTH one of "
                             f"{', '.join(TRUTHS)}")
        names = () if hidden == "clean" else tuple(hidden.split("+"))
        if any(n not in SINGLES for n in names):
            raise SystemExit(f"--files: {hidden!r} is not 'clean' or effects of "
                             f"{', '.join(SINGLES)} joined by '+'")
        wanted.add((truth, names))
    out = [c for c in todo if (c["truth"], tuple(c["hidden"])) in wanted]
    missing = wanted - {(c["truth"], tuple(c["hidden"])) for c in out}
    if missing:
        raise SystemExit("--files: not among the bench's files (with these --truths, "
                         f"--rates, --noises): {sorted(missing)}")
    return out


def _reruns(base: dict) -> list[dict]:
    """The earlier re-runs recorded in `base` (one dict before they were a list)."""
    rerun = base.get("rerun", [])
    return [rerun] if isinstance(rerun, dict) else list(rerun)


def _commit() -> str | None:
    """The short commit of the checkout the bench runs from, if it is a git one."""
    import subprocess

    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=HERE,
                             capture_output=True, text=True, timeout=10)
    except OSError:
        return None
    return (out.stdout.strip() or None) if out.returncode == 0 else None


def _by_truth(files: list[dict]) -> dict:
    return {truth: summarise([r for r in files if r["truth"] == truth])
            for truth in dict.fromkeys(r["truth"] for r in files)}


def _print_all(out: dict) -> None:
    rows = out["files"]
    print_table(rows, out["summary"])
    if len(out["by_truth"]) > 1:
        for truth, part in out["by_truth"].items():
            print(f"\n{truth}: " + ", ".join(
                f"{k} {round(v, 3) if isinstance(v, float) else v}" for k, v in part.items()
                if k in ("single_right_first", "single_right_first_not_absorbed",
                         "pairs_both_found", "pairs_both_found_not_absorbed",
                         "effects_added_on_clean")))
    print("\n" + markdown(rows))
    if len(out["by_truth"]) > 1:
        print("\n" + markdown_by_truth(rows))
    print("\n" + markdown_targets(rows))


def _resummarise(path: Path) -> int:
    out = json.loads(path.read_text())
    out["summary"], out["by_truth"] = summarise(out["files"]), _by_truth(out["files"])
    tmp = path.with_suffix(".json.partial")
    tmp.write_text(json.dumps(out, indent=2) + "\n")
    tmp.replace(path)
    _print_all(out)
    print(f"\nsummaries recomputed in {path}")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="one truth, noise level and rate")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    ap.add_argument("--json", default=str(HERE / "diagnosis_bench.json"),
                    help="output JSON (default: %(default)s)")
    ap.add_argument("--only", help="comma-separated hidden effects to run (and clean)")
    ap.add_argument("--files", help="comma-separated files to run, exactly: TRUTH:HIDDEN, "
                    "HIDDEN an effect, a pair joined by '+', or 'clean' (e.g. "
                    "gms_power:clean,gms_power:asymmetry+position_dependence); with "
                    "--rates, --noises, --start")
    ap.add_argument("--truths", help=f"comma-separated truths (default: {', '.join(TRUTHS)}; "
                    "--quick: the first)")
    ap.add_argument("--rates", help="comma-separated sampling intervals in s (default: "
                    f"{', '.join(map(str, RATES))}; --quick: the first). Records of 2e4 "
                    "samples or more (1e-3: 97.5k) are searched on a copy of 1e4 "
                    "(fitting._search_copy)")
    ap.add_argument("--noises", help="comma-separated force noise levels in N (default: "
                    f"{', '.join(map(str, NOISES))}; --quick: the first)")
    ap.add_argument("--start", default="two-state",
                    choices=("two-state", "gms", "lugre", "tustin"),
                    help="the model the diagnosis starts from (fitting.initial_model; "
                    "default %(default)s): do the effects found depend on it?")
    ap.add_argument("--update", metavar="JSON",
                    help="re-run only these files (with --only, --truths) and write JSON: the "
                    "run in this JSON with their rows replaced, summaries recomputed, and "
                    "'rerun' saying which files (for a change that can only affect some)")
    ap.add_argument("--resummarise", metavar="JSON",
                    help="run nothing: recompute the summaries of an earlier run in place "
                    "(after a change to the summary's measures) and print its tables")
    args = ap.parse_args(argv)
    if args.resummarise:
        return _resummarise(Path(args.resummarise))

    def floats(text):
        return [float(v) for v in text.split(",")] if text else None

    todo = cases(args.quick, args.truths.split(",") if args.truths else None,
                 floats(args.rates), floats(args.noises), args.start)
    if args.only:
        keep = set(args.only.split(","))
        todo = [c for c in todo if not c["hidden"] or set(c["hidden"]) & keep]
    if args.files:
        todo = _exactly(todo, args.files)
    print(f"{len(todo)} files; each is fitted and diagnosed ({args.jobs} worker(s))",
          flush=True)
    rows, t0 = [], time.perf_counter()

    base = json.loads(Path(args.update).read_text()) if args.update else None

    def save(complete: bool) -> dict:
        # Written after every file ("complete": false until the end), so that a run cut
        # off (a crashed worker, a machine shut down) keeps what it had done.
        files = rows if base is None else _replaced(base["files"], rows)
        out = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                           "python": sys.version.split()[0]},
               "quick": args.quick if base is None else base["quick"], "complete": complete,
               "seconds": time.perf_counter() - t0, "summary": summarise(files),
               "by_truth": _by_truth(files), "files": files}
        if base is not None:
            out["seconds"] = base["seconds"]
            out["rerun"] = [*_reruns(base), {
                "commit": _commit(), "files": [[r["truth"], r["hidden"]] for r in rows],
                "seconds": time.perf_counter() - t0}]
        tmp = Path(args.json).with_suffix(".json.partial")
        tmp.write_text(json.dumps(out, indent=2) + "\n")
        tmp.replace(args.json)
        return out

    # A fresh worker for every file: each diagnosis compiles its own functions (about a
    # hundred), and a worker that kept them all ran out of memory maps ("LLVM ERROR: Unable
    # to allocate section memory") after about 14 files.
    with ProcessPoolExecutor(max_workers=args.jobs, max_tasks_per_child=1) as pool:
        for k, row in enumerate(pool.map(run_case, todo), start=1):
            rows.append(row)
            print(f"[{k}/{len(todo)} {time.perf_counter() - t0:6.0f} s] {row['truth']} "
                  f"{' + '.join(row['hidden']) or '(clean)'}: added "
                  f"{' + '.join(row['added']) or 'nothing'}", flush=True)
            save(complete=False)
    _print_all(save(complete=True))
    print(f"\nwrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
