"""Which rule for nearly equal candidates names the hidden effect? (`fitting._diagnose.
_closest_call`: of an offset and a direction-dependent level whose refits the held-out
data cannot tell apart, which one to keep.)

From a run of `benchmarks/diagnosis_bench.py` (its JSON: every refit tried, and the
screen's first ranking), for every file where both an offset and an asymmetry were
refitted in the first round, each rule's choice on its own: the higher screen score, the
larger screen ``t``, the lower held-out error after the refit. A choice is right when it
is hidden in the file (both are, in none of the bench's files).

    python benchmarks/closest_calls.py [JSON]   (default benchmarks/diagnosis_bench.json)

The rule before the score (``t``) was set on that run's predecessor:
``git show 3a09733:benchmarks/diagnosis_bench.json > old.json``.
"""

import argparse
import json
import sys
from pathlib import Path


PAIR = ("asymmetry", "offset")
RULES = ("score", "t", "held-out error")


def choices(row: dict) -> dict | None:
    """Each rule's pick for one bench file, or None when the two were not both refitted."""
    refits = {tr["effects"][0]: tr for tr in row["trials"]
              if tr["round"] == 0 and len(tr["effects"]) == 1 and tr["effects"][0] in PAIR}
    screen = {c["name"]: c for c in row["rankings"][0] if c["name"] in PAIR}
    if len(refits) < 2 or len(screen) < 2:
        return None
    return {"score": max(PAIR, key=lambda n: screen[n]["score"]),
            "t": max(PAIR, key=lambda n: screen[n]["t"] or 0.0),
            "held-out error": min(PAIR, key=lambda n: refits[n]["rmse_holdout_after"])}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("json", nargs="?",
                    default=str(Path(__file__).resolve().parent / "diagnosis_bench.json"))
    args = ap.parse_args(argv)
    rows = json.loads(Path(args.json).read_text())["files"]
    right = dict.fromkeys(RULES, 0)
    n = 0
    print(f"{'truth':<16} {'hidden':<32} " + " ".join(f"{r:>15}" for r in RULES))
    for row in rows:
        picks = choices(row)
        if picks is None:
            continue
        n += 1
        for rule, pick in picks.items():
            right[rule] += pick in row["hidden"]
        print(f"{row['truth']:<16} {' + '.join(row['hidden']):<32} "
              + " ".join(f"{picks[r]:>15}" for r in RULES))
    print(f"\nright, of {n} files: " + ", ".join(f"{r} {right[r]}" for r in RULES))
    return 0


if __name__ == "__main__":
    sys.exit(main())
