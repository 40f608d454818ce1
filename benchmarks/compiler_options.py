"""jaxfric's compiler options (`jaxfric._compile.COMPILER_OPTIONS`) against XLA's defaults:
compile time and run time of the programs a user waits for, side by side.

Each round runs, for each of the two settings in turn (jaxfric's options, then XLA's
defaults by ``JAXFRIC_XLA_DEFAULTS=1``), a new process without a compilation cache that
times, with JAX's compile log on:

- ``simulate``: `jaxfric.simulate` of the paper's two-state model, of a 5-element GMS and
  of LuGre on the mixed motion (`benchmarks/motions.py`) of `--n` samples: the first call
  (tracing, compiling, one run) and the median of 5 calls after it;
- ``fit``: `fitting.fit` of the two-state model to that motion's force (0.05 N noise) from
  the perturbed start, 50 steps at most: the first call and a second one (compiled).

Reported per case: the XLA compile seconds (from the log), the first call's wall time and
the steady run's, medians over `--rounds`; the ratios defaults / jaxfric (> 1: jaxfric's
options are faster). The two settings' forces are compared too (largest difference, N):
the options change the generated code, not the operations, so only the last bits move.

    python benchmarks/compiler_options.py [--n 100000] [--rounds 3] [--json OUT]

Prints a table and writes JSON (default benchmarks/compiler_options.json).
"""

import argparse
import json
import logging
import os
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np


HERE = Path(__file__).resolve().parent
SETTINGS = {"jaxfric": {}, "XLA defaults": {"JAXFRIC_XLA_DEFAULTS": "1"}}


def _worker(n: int, out: Path) -> None:
    """One process: time every case, write the times and the forces (npz beside)."""
    sys.path.insert(0, str(HERE.parent))
    import jax

    import fitting
    import jaxfric
    from benchmarks.motions import mixed_path, perturbed_start, synthetic_force
    from jaxfric import paper
    from jaxfric._compile import compiler_options

    compiled = []

    class _Log(logging.Handler):
        def emit(self, record):
            msg = record.getMessage()
            if msg.startswith("Finished XLA compilation"):
                compiled.append(float(msg.rsplit(" in ", 1)[-1].split()[0]))

    logger = logging.getLogger("jax")
    logger.addHandler(_Log())
    logger.setLevel(logging.WARNING)
    logger.propagate = False
    jax.config.update("jax_log_compiles", True)

    t, x = mixed_path(n)
    truth = paper.two_state()
    rows, forces = {}, {}

    def timed(name, fn, steady_calls):
        del compiled[:]
        t0 = time.perf_counter()
        first = jax.block_until_ready(fn())
        first_s = time.perf_counter() - t0
        compile_s = sum(compiled)
        runs = []
        for _ in range(steady_calls):
            t0 = time.perf_counter()
            jax.block_until_ready(fn())
            runs.append(time.perf_counter() - t0)
        rows[name] = {"compile_s": compile_s, "first_s": first_s,
                      "steady_s": statistics.median(runs)}
        return first

    for name, model in (("simulate two-state", truth), ("simulate GMS N=5", paper.gms(5)),
                        ("simulate LuGre", paper.lugre())):
        forces[name] = np.asarray(timed(name, lambda m=model: jaxfric.simulate(m, t, x), 5))
    F = synthetic_force(truth, t, x, np.random.default_rng(1))  # (simulate: compiled)
    start = perturbed_start(truth)
    res = timed("fit two-state, 50 steps",
                lambda: fitting.fit(start, t, x, F, max_steps=50).prediction, 1)
    forces["fit two-state, 50 steps"] = np.asarray(res)
    np.savez(out.with_suffix(".npz"), **forces)
    out.write_text(json.dumps({"options": compiler_options(), "rows": rows}))


def _round(n: int, tmp: Path, k: int) -> dict:
    got = {}
    for setting, env in SETTINGS.items():
        out = tmp / f"{k}_{len(got)}.json"
        subprocess.run([sys.executable, __file__, "--worker", str(n), str(out)], check=True,
                       env={**os.environ, "JAXFRIC_CACHE_DIR": "0", **env})
        got[setting] = json.loads(out.read_text())
        got[setting]["forces"] = dict(np.load(out.with_suffix(".npz")))
    return got


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=float, default=1e5, help="samples of the motion")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json", default=str(HERE / "compiler_options.json"))
    ap.add_argument("--worker", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        _worker(int(args.worker[0]), Path(args.worker[1]))
        return
    n = int(args.n)
    with tempfile.TemporaryDirectory() as tmp:
        rounds = [_round(n, Path(tmp), k) for k in range(args.rounds)]
    first = rounds[0]
    options = {s: first[s]["options"] for s in SETTINGS}
    if options["jaxfric"] == options["XLA defaults"]:
        raise RuntimeError(f"both settings compiled with the same options: {options}")
    table = []
    for case in first["jaxfric"]["rows"]:
        row = {"case": case}
        for s in SETTINGS:
            for key in ("compile_s", "first_s", "steady_s"):
                row[f"{s}: {key}"] = statistics.median(r[s]["rows"][case][key] for r in rounds)
        for key in ("compile_s", "first_s", "steady_s"):
            row[f"ratio {key}"] = row[f"XLA defaults: {key}"] / row[f"jaxfric: {key}"]
        row["max_dF_N"] = float(np.max(np.abs(first["jaxfric"]["forces"][case]
                                              - first["XLA defaults"]["forces"][case])))
        table.append(row)
    print(f"jaxfric's compiler options {options['jaxfric']} against XLA's defaults, "
          f"n = {n:g} samples, medians of {args.rounds} rounds (new process each, no cache); "
          "ratio = defaults / jaxfric")
    print(f"{'case':<26} {'compile s':>19} {'ratio':>6} {'first call s':>19} {'ratio':>6} "
          f"{'steady s':>19} {'ratio':>6} {'max |dF| N':>10}")
    for r in table:
        cols = []
        for key in ("compile_s", "first_s", "steady_s"):
            cols.append(f"{r['jaxfric: ' + key]:8.3f} / {r['XLA defaults: ' + key]:8.3f} "
                        f"{r['ratio ' + key]:6.2f}")
        print(f"{r['case']:<26} {' '.join(cols)} {r['max_dF_N']:10.1e}")
    sys.path.insert(0, str(HERE.parent))
    from benchmarks.machine import machine_facts

    Path(args.json).write_text(json.dumps(
        {"machine": machine_facts(),
         "date_utc": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M"), "n": n,
         "rounds": args.rounds, "options": options, "rows": table}, indent=1))
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
