"""Two runs of `benchmarks/diagnosis_bench.py`, file by file: did a change move any outcome?

For every file in both runs (matched by truth, noise, sampling interval and hidden
effects): the effects added and the first one named in each run, and the held-out error
after the diagnosis (N). A file's outcome is the same when it added the same effects in
the same order; its error moved when the two held-out errors differ by more than
`--rtol` (relative). Files in one run only are listed apart. Also: how far the first
screen's statistics moved (every candidate's score and ``t`` in both runs: the median and
the largest change, and where the largest was). A candidate refitted in the first round of
either run is left out: the diagnosis records its refit's verdict in the ranking (a
confirmed candidate's ``t`` becomes its refit's or its folds'), so its change is not the
screen's.

    python benchmarks/bench_diff.py OLD.json NEW.json [--rtol 1e-3] [--json OUT]

An earlier run from git: ``git show COMMIT:benchmarks/diagnosis_bench.json > old.json``.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def key(row: dict) -> tuple:
    return (row["truth"], row["noise"], row["dt"], tuple(row["hidden"]))


def _file(k: tuple) -> list:
    return [*k[:3], list(k[3])]


def compare(old: list[dict], new: list[dict], rtol: float = 1e-3) -> dict:
    """``{"same", "changed", "error_moved", "only_old", "only_new"}``: lists of file rows
    (``changed``: outcome differs; ``error_moved``: same outcome, held-out error moved
    beyond `rtol`), each with both runs' ``added`` and ``rmse_holdout_after``."""
    a, b = {key(r): r for r in old}, {key(r): r for r in new}
    out = {"same": [], "changed": [], "error_moved": [],
           "only_old": [_file(k) for k in a if k not in b],
           "only_new": [_file(k) for k in b if k not in a]}
    for k in a:
        if k not in b:
            continue
        ra, rb = a[k], b[k]
        ea, eb = ra["rmse_holdout_after"], rb["rmse_holdout_after"]
        row = {"file": _file(k), "added": [ra["added"], rb["added"]],
               "first": [ra["first"], rb["first"]], "rmse_holdout_after": [ea, eb]}
        if ra["added"] != rb["added"]:
            out["changed"].append(row)
        else:
            out["same"].append(row)
            if abs(ea - eb) > rtol * max(abs(ea), abs(eb)):
                out["error_moved"].append(row)
    return out


def screen_changes(old: list[dict], new: list[dict]) -> dict:
    """For ``"score"`` and ``"t"``: the median and largest absolute change of the first
    screen's value of a candidate between the runs (files in both, candidates in both
    rankings and refitted in the first round of neither, ``t`` where both are finite), and
    the ``[file, candidate]`` of the largest."""
    a, b = {key(r): r for r in old}, {key(r): r for r in new}
    out = {}
    for stat in ("score", "t"):
        changes = []
        for k in a.keys() & b.keys():
            tried = {n for r in (a[k], b[k]) for tr in r.get("trials", ())
                     if tr["round"] == 0 for n in tr["effects"]}
            ca = {c["name"]: c[stat] for c in a[k]["rankings"][0]}
            cb = {c["name"]: c[stat] for c in b[k]["rankings"][0]}
            changes += [(abs(ca[n] - cb[n]), _file(k), n)
                        for n in (ca.keys() & cb.keys()) - tried
                        if ca[n] is not None and cb[n] is not None]
        if changes:
            big = max(changes, key=lambda c: c[0])
            out[stat] = {"median": float(np.median([c[0] for c in changes])),
                         "largest": big[0], "where": [big[1], big[2]],
                         "count": len(changes)}
    return out


def _name(file: list) -> str:
    truth, noise, dt, hidden = file
    return f"{truth} {noise:g} N {dt * 1e3:g} ms {' + '.join(hidden) or 'clean'}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--rtol", type=float, default=1e-3)
    ap.add_argument("--json", help="write the comparison here")
    args = ap.parse_args(argv)
    old, new = (json.loads(Path(p).read_text())["files"] for p in (args.old, args.new))
    out = compare(old, new, args.rtol)
    for what in ("changed", "error_moved"):
        for r in out[what]:
            ea, eb = r["rmse_holdout_after"]
            print(f"{what:<11} {_name(r['file']):<58} added {r['added'][0]} -> "
                  f"{r['added'][1]}, held out {ea:.4f} -> {eb:.4f} N")
    for what in ("only_old", "only_new"):
        for f in out[what]:
            print(f"{what:<11} {_name(f)}")
    both = len(out["same"]) + len(out["changed"])
    print(f"\n{both} files in both runs: {len(out['same'])} the same outcome (effects "
          f"added, in order), {len(out['changed'])} changed; of the same, "
          f"{len(out['error_moved'])} with the held-out error moved by more than "
          f"{args.rtol:g}; {len(out['only_old'])} only in the old run, "
          f"{len(out['only_new'])} only in the new")
    moved = screen_changes(old, new)
    for stat, m in moved.items():
        print(f"first screen's {stat} ({m['count']} candidates): median change "
              f"{m['median']:.2g}, largest {m['largest']:.3g} ({_name(m['where'][0])}: "
              f"{m['where'][1]})")
    if args.json:
        Path(args.json).write_text(json.dumps({**out, "screen": moved}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
