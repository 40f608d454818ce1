"""Two fits side by side in threads (as the diagnosis runs its fits, `fitting._refits.Fitter.map`)
against one after the other, with the BLAS limited to one thread per fit only (each
`fitting.fit` holds `fitting._blas.single_threaded_blas` while it runs) and with one such
limit held around the pair as well (what `fitting.diagnose` does).

After a first call of each case (compiling it), each round times two identical fits
(`fitting.fit` from the same start, `--steps` steps at most) one after the other, then the
same two in two threads at once, under each setting in turn (the settings alternate within
a round: the machine's speed drifts). Per case and setting: the wall time of the pair each
way, their ratio (in turn / side by side: above 1, the threads gain) and the process's CPU
time (user and system, every thread) per fit. Medians over `--rounds`. The cases:

- ``two-state``: the paper's two-state model from the perturbed start, fitted to its own
  force with 0.05 N of noise along the mixed motion (`benchmarks/motions.py`);
- ``GMS N=10``: the paper's 10-element GMS fitted to that force.

    python benchmarks/profiling/parallel_fits.py [--n 10000] [--steps 40] [--rounds 5] [--json OUT]

Prints a table and writes JSON (default benchmarks/profiling/parallel_fits.json).
"""

import argparse
import contextlib
import json
import resource
import statistics
import sys
import threading
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np


HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))  # run as a script: the repository's root

SETTINGS = ("a limit per fit", "one limit around both")


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _pair(one, threads: bool, around: bool) -> tuple[float, float]:
    """Wall time (s) and CPU time per fit (s) of two calls of `one`."""
    from fitting._blas import single_threaded_blas

    with single_threaded_blas() if around else contextlib.nullcontext():
        c0, t0 = _cpu(), time.perf_counter()
        if threads:
            errors: list = []
            workers = [threading.Thread(target=lambda: _guarded(one, errors)) for _ in range(2)]
            for w in workers:
                w.start()
            for w in workers:
                w.join()
            if errors:
                raise errors[0]
        else:
            one(), one()
        return time.perf_counter() - t0, (_cpu() - c0) / 2


def _guarded(one, errors: list) -> None:
    try:
        one()
    except Exception as e:  # raised in the caller
        errors.append(e)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=float, default=1e4, help="samples of the motion")
    ap.add_argument("--steps", type=int, default=40, help="solver steps per fit at most")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--json", default=str(HERE / "parallel_fits.json"))
    args = ap.parse_args(argv)
    import fitting
    from benchmarks.machine import machine_facts
    from benchmarks.motions import mixed_path, perturbed_start, synthetic_force
    from jaxfric import paper

    n = int(args.n)
    t, x = mixed_path(n)
    truth = paper.two_state()
    F = synthetic_force(truth, t, x, np.random.default_rng(1))
    cases = {"two-state": perturbed_start(truth), "GMS N=10": paper.gms(10)}
    table = []
    for name, start in cases.items():
        def one(start=start):
            return fitting.fit(start, t, x, F, max_steps=args.steps)

        one()  # compiles
        got = {(s, way): [] for s in SETTINGS for way in ("in turn", "side by side")}
        for _ in range(args.rounds):
            for s in SETTINGS:
                for way in ("in turn", "side by side"):
                    got[s, way].append(_pair(one, way == "side by side",
                                             s == "one limit around both"))
        row = {"case": name}
        for (s, way), runs in got.items():
            row[f"{s}: {way} wall_s"] = statistics.median(r[0] for r in runs)
            row[f"{s}: {way} cpu_per_fit_s"] = statistics.median(r[1] for r in runs)
        for s in SETTINGS:
            row[f"{s}: gain"] = row[f"{s}: in turn wall_s"] / row[f"{s}: side by side wall_s"]
        table.append(row)
    print(f"two fits in turn against side by side (2 threads), n = {n:g}, at most "
          f"{args.steps} steps, medians of {args.rounds} rounds; gain = in turn / side by side")
    print(f"{'case':<10} {'BLAS limit':<22} {'in turn s':>9} {'side by side s':>14} "
          f"{'gain':>5} {'CPU/fit in turn s':>17} {'CPU/fit side by side s':>22}")
    for r in table:
        for s in SETTINGS:
            print(f"{r['case']:<10} {s:<22} {r[f'{s}: in turn wall_s']:9.3f} "
                  f"{r[f'{s}: side by side wall_s']:14.3f} {r[f'{s}: gain']:5.2f} "
                  f"{r[f'{s}: in turn cpu_per_fit_s']:17.3f} "
                  f"{r[f'{s}: side by side cpu_per_fit_s']:22.3f}")
    Path(args.json).write_text(json.dumps(
        {"machine": machine_facts(),
         "date_utc": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M"), "n": n,
         "steps": args.steps, "rounds": args.rounds, "rows": table}, indent=1))
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
