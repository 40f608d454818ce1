"""What did the three-fold confirmation decide, and was it right? (`fitting._folds`: a
refit with a large held-out gain, inconsistent on the one split, refitted with each of the
other two folds held out.)

From runs of `benchmarks/diagnosis_bench.py` (their JSONs hold every refit tried, with
``"folds"`` when it went to the three folds), every such refit: the file's truth and
hidden effects, the effects refitted, the share of the held-out SSE removed on the one
split and on all folds, the all-fold ``t``, the shares where the effects' terms are large
in the three folds, and whether it was added. A refit is of hidden effects when all its
effects are hidden in the file, of effects not hidden when none is, else mixed.

    python benchmarks/fold_checks.py [JSON ...]
        (default: every benchmarks/diagnosis_bench*.json diagnosed from the two-state
        model, i.e. without "start" in its rows)
"""

import argparse
import json
import sys
from collections import Counter
from pathlib import Path


HERE = Path(__file__).resolve().parent
KINDS = ("hidden", "not hidden", "mixed")


def kind(effects, hidden) -> str:
    effects, hidden = set(effects), set(hidden)
    if effects <= hidden:
        return "hidden"
    return "not hidden" if not effects & hidden else "mixed"


def checks(rows: list[dict]):
    """``(row, trial)`` for every refit of `rows` that went to the three folds."""
    for row in rows:
        for trial in row["trials"]:
            if trial.get("folds"):
                yield row, trial


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("json", nargs="*", help="bench JSONs (default: see above)")
    args = ap.parse_args(argv)
    paths = [Path(p) for p in args.json] or sorted(HERE.glob("diagnosis_bench*.json"))
    counts = Counter()
    print(f"{'run':<34} {'truth':<16} {'hidden':<32} {'refitted':<30} {'split':>6} "
          f"{'folds':>6} {'t':>5}  {'where large (3 folds)':<22} added")
    for path in paths:
        rows = json.loads(path.read_text())["files"]
        if not args.json and any(r.get("start") for r in rows):
            continue
        for row, trial in checks(rows):
            folds = trial["folds"]
            k = kind(trial["effects"], row["hidden"])
            counts[k, trial["added"]] += 1
            shares = " ".join(f"{100 * s:4.0f}" for s in folds.get("shares_where_it_acts", []))
            t = "-" if folds["t"] is None else f"{folds['t']:.1f}"
            print(f"{path.stem:<34} {row['truth']:<16} "
                  f"{' + '.join(row['hidden']) or '(clean)':<32} "
                  f"{' + '.join(trial['effects']):<30} {100 * trial['removed']:5.1f}% "
                  f"{100 * folds['removed']:5.1f}% {t:>5}  {shares:<22} "
                  f"{'ADDED' if trial['added'] else '-'}")
    total = sum(counts.values())
    print(f"\n{total} refits went to the three folds: " + "; ".join(
        f"{k}: {counts[k, True]} added, {counts[k, False]} rejected" for k in KINDS))
    return 0


if __name__ == "__main__":
    sys.exit(main())
