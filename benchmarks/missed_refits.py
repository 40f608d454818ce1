"""Could a looser significance rule have found the hidden effects the diagnosis missed,
without adding effects that were not hidden?

From the runs of `benchmarks/diagnosis_bench.py` (their JSONs: every joint refit tried,
`fitting.Diagnosis.trials`), for every refit of a single effect that was hidden in its file
but never added: its share of the held-out SSE removed and its consistency ``t``. Any rule
that grows with both (accept when the share is large enough for the ``t`` it has) and
accepts that refit must also accept every refit with at least its share and at least its
``t``; the script lists those among the refits of effects NOT hidden in their file that
the rule rejected (not added, in a round where nothing was added: not those that lost a
close call to another effect): the false additions such a rule would have made. An empty
list would mean the miss is the rule's; a non-empty one that the bench's refits cannot
tell the hidden effect from model mismatch by these two numbers. (A refit sent to the
three-fold check, `fitting._folds`, was decided on all folds; their numbers are shown.)

    python benchmarks/missed_refits.py [JSON ...]   (default: every
                                                      benchmarks/diagnosis_bench*.json)
"""

import argparse
import json
import sys
from pathlib import Path


HERE = Path(__file__).resolve().parent


def refits(paths) -> list[dict]:
    """Every single-effect refit of the runs in `paths`, with its file and whether the
    effect was hidden there and added in the end."""
    out = []
    for path in paths:
        for row in json.loads(Path(path).read_text())["files"]:
            rounds_added = {tr["round"] for tr in row["trials"] if tr["added"]}
            for tr in row["trials"]:
                if len(tr["effects"]) != 1 or tr["t"] is None:
                    continue
                effect = tr["effects"][0]
                out.append({"run": Path(path).stem, "truth": row["truth"],
                            "file": " + ".join(row["hidden"]) or "(clean)",
                            "start": row.get("start"), "effect": effect,
                            "removed": tr["removed"], "t": tr["t"],
                            "hidden": effect in row["hidden"],
                            "found": effect in row["added"],
                            "rejected": tr["round"] not in rounds_added,
                            "folds": tr.get("folds")})
    return out


def dominating(miss: dict, null: list[dict]) -> list[dict]:
    """The refits of `null` with at least the share removed and the ``t`` of `miss`, the
    closest first."""
    return sorted((r for r in null if r["removed"] >= miss["removed"] and r["t"] >= miss["t"]),
                  key=lambda r: (r["removed"], r["t"]))


def _name(r: dict) -> str:
    start = f", from {r['start']}" if r["start"] else ""
    return f"{r['run']}: {r['truth']} {r['file']}{start}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("json", nargs="*", help="bench runs (default: every "
                    "benchmarks/diagnosis_bench*.json)")
    args = ap.parse_args(argv)
    paths = args.json or sorted(HERE.glob("diagnosis_bench*.json"))
    rows = refits(paths)
    null = [r for r in rows if not r["hidden"] and r["rejected"]]
    misses = [r for r in rows if r["hidden"] and not r["found"] and r["removed"] > 0]
    print(f"{len(rows)} single-effect refits in {len(paths)} runs; {len(null)} of effects "
          f"not hidden, rejected (the null); {len(misses)} of hidden effects never added "
          "that removed anything held out\n")
    clear = 0
    for m in sorted(misses, key=lambda r: (-r["removed"], -r["t"])):
        over = dominating(m, null)
        clear += not over
        print(f"{_name(m)}: {m['effect']} removed {100 * m['removed']:.1f} %, "
              f"t {m['t']:.2f}; rejected not-hidden refits with at least both: {len(over)}")
        if m["folds"]:
            print(f"    (decided on all three folds: {100 * m['folds']['removed']:.1f} %, "
                  f"t {m['folds']['t']:.2f})")
        for r in over[:3]:
            print(f"    {_name(r)}: {r['effect']} {100 * r['removed']:.1f} %, t {r['t']:.2f}")
    print(f"\nmisses a looser rule could take without a false addition: {clear} of "
          f"{len(misses)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
