"""The cost of one `fitting.fit` chunk by chunk: where the steps of a fit go.

Fits the data and start of `benchmarks/fit_speed.py` (default 1e4 samples) once with a
`progress` callback and prints, after every compiled chunk, the steps so far, the cost
``sum(r^2)/2`` (residuals scaled as the solver sees them), its relative decrease over the
chunk and the seconds so far; then the status, why the fit stopped, the RMSE, the condition
number and `FitResult.weakly_determined`. Writes benchmarks/profiling/fit_trace.json
unless ``--json`` says otherwise.

    python benchmarks/profiling/fit_trace.py [--n 10000] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import fitting


try:
    from benchmarks import fit_speed as fs
except ImportError:  # run as a script: benchmarks/profiling/ is sys.path[0]
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import fit_speed as fs


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000)
    ap.add_argument("--json", metavar="OUT",
                    default=str(Path(__file__).with_name("fit_trace.json")))
    args = ap.parse_args(argv)
    t, x, F = fs.make_data(args.n)
    chunks = []
    res = fitting.fit(fs.start_model(fs.start_factors()), t, x, F,
                      progress=lambda p: chunks.append(
                          {"steps": p.steps, "cost": p.cost, "seconds": p.seconds}))
    prev = None
    print("steps | cost | relative decrease | s")
    for c in chunks:
        c["rel_decrease"] = None if prev is None else (prev - c["cost"]) / prev
        prev = c["cost"]
        dec = "-" if c["rel_decrease"] is None else f"{c['rel_decrease']:.2e}"
        print(f"{c['steps']} | {c['cost']:.10g} | {dec} | {c['seconds']:.1f}")
    weak = [list(p) for p in res.weakly_determined()]
    out = {"command": f"python benchmarks/profiling/fit_trace.py --n {args.n}", "n": args.n,
           "chunks": chunks, "status": res.status, "stopped": res.stopped,
           "steps": int(res.num_steps), "rmse": float(res.rmse),
           "condition_number": float(res.condition_number), "weakly_determined": weak}
    print(f"{res.status}: {res.stopped}; RMSE {float(res.rmse):.5f} N; condition number "
          f"{float(res.condition_number):.3g}; weakly determined: {weak}")
    Path(args.json).write_text(json.dumps(out, indent=1))
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
