"""Wall time of ``jaxfric diagnose`` as a user runs it (issue 22, item 5: 1e5 samples in
at most 60 s on the 2-core machine).

Each file is a foreign-truth measurement (`jaxfric.synthetic.measurement`: a two-state
model with a power-law presliding curve, one hidden cogging, a 0.05 um encoder, 0.03 N of
noise, about 97.5 s of motion) sampled so that it has about `--sizes` samples, written as
CSV and diagnosed by the command line in a fresh process, twice: first with an empty
compilation cache (``JAXFRIC_CACHE_DIR`` set to a new folder: what a first run on a new
machine costs, compilation included), then with the cache that run filled (what the next
diagnosis of a file of the same length costs). The time is the whole command's, start-up,
reading, the fits, the screens and the JSON included; the diagnosis's own figure (from its
last line) is given too.

    python benchmarks/diagnose_speed.py [--sizes 1e4,1e5] [--json OUT.json]

Prints a table and writes JSON (default benchmarks/diagnose_speed.json).
"""

import argparse
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
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


def _run(path: Path, cache: Path, out: Path) -> dict:
    env = {**os.environ, "JAXFRIC_CACHE_DIR": str(cache)}
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "fitting.cli", "diagnose", str(path), "--json",
                        str(out)], capture_output=True, text=True, env=env, timeout=3600)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"diagnose failed on {path}:\n{r.stderr}")
    inner = re.findall(r"^\((\d+(?:\.\d+)?) s\)$", r.stdout, flags=re.M)
    added = json.loads(out.read_text())["after"]["added"]
    return {"wall_s": wall, "diagnosis_s": float(inner[-1]) if inner else None,
            "added": added}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1e4,1e5", help="samples per file (default %(default)s)")
    ap.add_argument("--json", default=str(HERE / "diagnose_speed.json"))
    args = ap.parse_args(argv)
    sizes = [int(float(s)) for s in args.sizes.split(",")]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for n in sizes:
            path = _file(folder, n)
            samples = sum(1 for _ in path.open()) - 1
            cache = folder / f"cache_{n}"
            for cache_state in ("empty", "filled"):
                print(f"diagnosing {samples} samples, compilation cache {cache_state} ...",
                      flush=True)
                r = _run(path, cache, folder / f"d_{n}.json")
                rows.append({"samples": samples, "cache": cache_state, **r})
    print(f"\n{'samples':>8} {'cache':>7} {'wall [s]':>9} {'diagnosis [s]':>14}  added")
    for r in rows:
        print(f"{r['samples']:>8} {r['cache']:>7} {r['wall_s']:>9.1f} "
              f"{r['diagnosis_s'] if r['diagnosis_s'] is not None else float('nan'):>14.1f}"
              f"  {' + '.join(r['added']) or '-'}")
    big = [r for r in rows if abs(r["samples"] - 1e5) <= 5e3]
    if big:
        print("\ngoal: 1e5 samples in <= 60 s: " + ", ".join(
            f"cache {r['cache']} {r['wall_s']:.0f} s "
            f"({'met' if r['wall_s'] <= GOAL_S else 'MISSED'})" for r in big))
    out = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                       "python": sys.version.split()[0]},
           "goal_s_at_1e5": GOAL_S, "rows": rows}
    Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
