"""Wall time of ``jaxfric diagnose`` as a user runs it (goal: 1e5 samples in at most 60 s
on the 2-core machine).

Each file is a foreign-truth measurement (`jaxfric.synthetic.measurement`: a two-state
model with a power-law presliding curve, one hidden cogging, a 0.05 um encoder, 0.03 N of
noise, about 97.5 s of motion) sampled so that it has about `--sizes` samples, written as
CSV and diagnosed by the command line in a fresh process, twice: first with an empty
compilation cache (``JAXFRIC_CACHE_DIR`` set to a new folder: what a first run on a new
machine costs, compilation included), then with the cache that run filled (what the next
diagnosis of a file of the same length costs). The time is the whole command's, start-up,
reading, the fits, the cross-validation and the JSON included; the diagnosis's own figure (from its
last line) is given too, and the CPU time the command used (user and system, all its
threads: divided by the wall time, the cores it kept busy). Each pair of runs is repeated
`--repeats` times, each time with a new empty cache; the table gives the medians (the
machine is noisy), the JSON every run.

The same machine runs the same code 1.5x slower at some hours than at others, so a time
alone says little: ``--against DIR`` (a checkout of another commit, e.g.
``git worktree add --detach /tmp/old 6ca9f68``, the code the 60 s goal was set against,
when it took 41-52 s) runs that code's ``jaxfric diagnose`` on the same file beside this
code's, alternately, each with its own new cache, and the table gives the ratio of the
medians, this code's over that code's, and that ratio times the medians that code's own
``benchmarks/diagnose_speed.json`` holds: this code's time at the machine's speed then.
``--summarise JSON`` makes the table and JSON again from a JSON's runs, without running.

    python benchmarks/diagnose_speed.py [--sizes 1e4,1e5] [--repeats 3] [--json OUT.json]
        [--note "what else ran"] [--caches empty,filled] [--against DIR]
        [--summarise JSON]

Prints a table and writes JSON (default benchmarks/diagnose_speed.json).
"""

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from jaxfric.synthetic import measurement


HERE = Path(__file__).resolve().parent
DURATION = 97.5  # s: the motion of `measurement`
GOAL_S = 60.0  # at 1e5 samples


def _file(folder: Path, n: int) -> Path:
    t, x, F = measurement("two_state_power", ("cogging",), noise=0.03, dt=DURATION / n,
                          seed=4)
    path = folder / f"cogging_{n}.csv"
    np.savetxt(path, np.column_stack([t, x, F]), delimiter=",", header="t[s],x[m],F[N]",
               comments="", fmt="%.12g")
    return path


def _run(path: Path, cache: Path, out: Path, code: Path | None = None) -> dict:
    """One ``jaxfric diagnose`` of `path` in a fresh process, with the compilation cache
    `cache`; `code`: a checkout whose ``fitting`` and ``jaxfric`` are run instead of the
    installed ones."""
    env = {**os.environ, "JAXFRIC_CACHE_DIR": str(cache)}
    if code is not None:
        env["PYTHONPATH"] = str(code)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "fitting.cli", "diagnose", str(path), "--json",
                        str(out)], capture_output=True, text=True, env=env, timeout=3600,
                       cwd=code)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if r.returncode != 0:
        raise RuntimeError(f"diagnose failed on {path}:\n{r.stderr}")
    inner = re.findall(r"^\((\d+(?:\.\d+)?) s\)$", r.stdout, flags=re.M)
    added = json.loads(out.read_text())["after"]["added"]
    return {"wall_s": wall, "cpu_s": cpu, "diagnosis_s": float(inner[-1]) if inner else None,
            "added": added}


def _medians(runs: list[dict]) -> list[dict]:
    """One row per size and cache state: the median wall, diagnosis and CPU times of its
    runs, the fastest and slowest wall time, and the effects added (every run must
    agree)."""
    def key_of(r):
        return r["samples"], r["cache"], r.get("code", "this")

    rows = []
    for key in dict.fromkeys(map(key_of, runs)):
        group = [r for r in runs if key_of(r) == key]
        added = {tuple(r["added"]) for r in group}
        if len(added) > 1:
            raise RuntimeError(f"runs of {key[0]} samples added different effects: {added}")
        inner = [r["diagnosis_s"] for r in group if r["diagnosis_s"] is not None]
        walls = [r["wall_s"] for r in group]
        rows.append({"samples": key[0], "cache": key[1], "code": key[2], "runs": len(group),
                     "wall_s": float(np.median(walls)), "wall_min_s": min(walls),
                     "wall_max_s": max(walls),
                     "diagnosis_s": float(np.median(inner)) if inner else None,
                     "cpu_s": float(np.median([r["cpu_s"] for r in group])),
                     "added": group[0]["added"]})
    return rows


def _ratios(rows: list[dict], then: dict | None = None) -> list[dict]:
    """Per size and cache state run by both codes: this code's median wall time over the
    other's; with `then` (`_then`: the other code's own committed medians), that ratio
    times its committed median, ``scaled_s``: this code's time at the machine's speed
    when those were measured."""
    med = {(r["samples"], r["cache"], r["code"]): r["wall_s"] for r in rows}
    out = []
    for n, c, code in med:
        if code != "this" or (n, c, "against") not in med:
            continue
        r = {"samples": n, "cache": c, "ratio": med[(n, c, "this")] / med[(n, c, "against")]}
        if then and (n, c) in then["wall_s"]:
            r |= {"then_s": then["wall_s"][(n, c)],
                  "scaled_s": r["ratio"] * then["wall_s"][(n, c)]}
        out.append(r)
    return out


def _then(code: Path) -> dict | None:
    """The commit of the checkout `code` and the medians its own
    benchmarks/diagnose_speed.json holds (``{(samples, cache): wall_s}``), or None."""
    path = code / "benchmarks" / "diagnose_speed.json"
    if not path.is_file():
        return None
    rows = json.loads(path.read_text())["rows"]
    commit = subprocess.run(["git", "-C", str(code), "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True).stdout.strip()
    return {"commit": commit, "wall_s": {(r["samples"], r["cache"]): r["wall_s"]
                                         for r in rows if r.get("code", "this") == "this"}}


def _measure(args, codes: dict) -> list[dict]:
    """Every run: each size, repeat, code (alternately first, so that a drift of the
    machine's speed hits both) and cache state."""
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for n in [int(float(s)) for s in args.sizes.split(",")]:
            path = _file(folder, n)
            samples = sum(1 for _ in path.open()) - 1
            for k in range(args.repeats):
                for name, code in list(codes.items())[::1 if k % 2 == 0 else -1]:
                    cache = folder / f"cache_{n}_{k}_{name}"
                    for cache_state in args.caches.split(","):
                        print(f"diagnosing {samples} samples with {name} code, compilation "
                              f"cache {cache_state} (run {k + 1} of {args.repeats}) ...",
                              flush=True)
                        r = _run(path, cache, folder / f"d_{n}.json", code)
                        runs.append({"samples": samples, "cache": cache_state, "code": name,
                                     **r})
                        print(f"  {r['wall_s']:.1f} s", flush=True)
    return runs


def _table(rows: list[dict], ratios: list[dict], against) -> None:
    print(f"\n{'samples':>8} {'cache':>7} {'code':>8} {'runs':>5} {'wall [s]':>9} "
          f"{'min..max':>13} {'diagnosis [s]':>14} {'CPU [s]':>8} {'cores':>6}  added")
    for r in rows:
        print(f"{r['samples']:>8} {r['cache']:>7} {r.get('code', 'this'):>8} {r['runs']:>5} "
              f"{r['wall_s']:>9.1f} "
              f"{r['wall_min_s']:>6.1f}..{r['wall_max_s']:<6.1f}"
              f"{r['diagnosis_s'] if r['diagnosis_s'] is not None else float('nan'):>14.1f}"
              f"{r['cpu_s']:>9.1f} {r['cpu_s'] / r['wall_s']:>6.2f}"
              f"  {' + '.join(r['added']) or '-'}")
    for r in ratios:
        print(f"{r['samples']} samples, cache {r['cache']}: this code's median wall time is "
              f"{r['ratio']:.2f} x that of {against}"
              + (f"; times its own committed {r['then_s']:.1f} s: {r['scaled_s']:.1f} s "
                 f"({'met' if r['scaled_s'] <= GOAL_S else 'MISSED'})" if "scaled_s" in r
                 else ""))
    big = [r for r in rows if abs(r["samples"] - 1e5) <= 5e3 and r.get("code") == "this"]
    if big:
        print("\ngoal: 1e5 samples in <= 60 s (median): " + ", ".join(
            f"cache {r['cache']} {r['wall_s']:.0f} s "
            f"({'met' if r['wall_s'] <= GOAL_S else 'MISSED'})" for r in big))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1e4,1e5", help="samples per file (default %(default)s)")
    ap.add_argument("--repeats", type=int, default=3,
                    help="runs of each size and cache state (default %(default)s)")
    ap.add_argument("--json", default=str(HERE / "diagnose_speed.json"))
    ap.add_argument("--note", default="", help="a note kept in the JSON (e.g. the load)")
    ap.add_argument("--caches", default="empty,filled",
                    help="the cache states run, in order (default %(default)s)")
    ap.add_argument("--against", type=Path, default=None,
                    help="a checkout of another commit, run beside this code (module "
                         "docstring)")
    ap.add_argument("--summarise", type=Path, default=None,
                    help="no runs: the table and JSON again from this JSON's runs (with "
                         "--against, the ratios scaled by that checkout's own timings)")
    args = ap.parse_args(argv)
    codes = {"this": None}
    if args.against is not None:
        if not (args.against / "fitting" / "cli").is_dir():
            ap.error(f"--against {args.against}: not a jaxfric checkout (no fitting/cli)")
        codes["against"] = args.against.resolve()
    old = json.loads(args.summarise.read_text()) if args.summarise else {}
    runs = old["runs"] if old else _measure(args, codes)
    then = _then(args.against) if args.against is not None else None
    rows = _medians(runs)
    ratios = _ratios(rows, then)
    _table(rows, ratios, args.against)
    sys.path.insert(0, str(HERE.parent))
    from benchmarks.machine import machine_facts

    command = "python benchmarks/diagnose_speed.py " + " ".join(argv or sys.argv[1:])
    out = {"machine": old.get("machine") or machine_facts(),
           "date_utc": old.get("date_utc") or datetime.now(timezone.utc).strftime(
               "%Y-%m-%d %H:%M"),
           "command": old.get("command", command),
           **({"summarised_by": command} if old else {}),
           "goal_s_at_1e5": GOAL_S, "repeats": old.get("repeats", args.repeats),
           "rows": rows, "runs": runs,
           **({"against": then["commit"] if then else str(args.against),
               "ratios": ratios} if ratios else {}),
           **({"note": args.note or old.get("note")} if args.note or old.get("note") else {}),
           "load_average_end": old.get("load_average_end") or list(os.getloadavg())}
    Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
