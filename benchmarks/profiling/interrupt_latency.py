"""How fast does Ctrl-C stop ``jaxfric fit``, and how?

Writes a measurement of `--n` samples (the `jaxfric.examples.excitation` motion repeated,
the paper's two-state model, 0.05 N of noise), then, for each delay, starts
``python -m fitting.cli fit FILE --json OUT`` (compilation cache off, so every run
compiles), waits for its "fitting ..." line plus the delay, sends SIGINT (``--signal
TERM``: SIGTERM) and measures the time to its exit. A row: the delay, the latency, the
exit code (130 expected, 143 for SIGTERM; -11 is a crash), whether stderr is the one line
``jaxfric fit: interrupted`` (or ``terminated``), and whether anything but the input is
left in the folder (a temp file, a JSON).

    python benchmarks/profiling/interrupt_latency.py [--n 100000] [--delays 0.5,2,3,4,5,8]
        [--signal INT|TERM] [--json out.json]

Prints a table (medians and worst at the end) and writes JSON (default
benchmarks/profiling/interrupt_latency.json).
"""

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _measurement(path: Path, n: int) -> None:
    import jaxfric
    from jaxfric import paper
    from jaxfric.examples import excitation

    _, x = excitation(dt=1e-3)
    x = np.concatenate([x] * int(np.ceil(n / x.size)))[:n]
    t = 1e-3 * np.arange(n)
    F = np.asarray(jaxfric.simulate(paper.two_state(), t, x))
    F = F + 0.05 * np.random.default_rng(0).normal(size=n)
    np.savetxt(path, np.column_stack([t, x, F]), delimiter=",", header="t,x,F", comments="",
               fmt="%.10g")


#: ``python -m fitting.cli`` with Ctrl-C as at a terminal, even when this script runs in
#: the background (where the shell starts it with SIGINT ignored, which children inherit).
CLI = ["-c", "import runpy, signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
       "runpy.run_module('fitting.cli', run_name='__main__', alter_sys=True)"]


def _one(path: Path, folder: Path, delay: float, signum: int) -> dict:
    folder.mkdir()
    out = folder / "fit.json"
    proc = subprocess.Popen(
        [sys.executable, *CLI, "fit", str(path), "--max-steps", "1000",
         "--json", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "JAXFRIC_CACHE_DIR": ""})
    while True:
        line = proc.stdout.readline()
        if not line or line.startswith("fitting"):
            break
    time.sleep(delay)
    sent = time.perf_counter()
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=300)
    latency = time.perf_counter() - sent
    left = sorted(p.name for p in folder.iterdir())
    return {"delay_s": delay, "latency_s": latency, "exit": proc.returncode,
            "one_line": err.strip() in ("jaxfric fit: interrupted", "jaxfric fit: terminated"),
            "left": left,
            "stderr": err[-2000:]}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=100_000)
    p.add_argument("--delays", default="0.5,2,3,4,5,8")
    p.add_argument("--signal", default="INT", choices=["INT", "TERM"])
    p.add_argument("--json", default=str(Path(__file__).with_suffix(".json")))
    args = p.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        path = folder / "m.csv"
        _measurement(path, args.n)
        print(f"{'delay [s]':>9}  {'latency [s]':>11}  {'exit':>4}  {'one line':>8}  left")
        for k, delay in enumerate(float(d) for d in args.delays.split(",")):
            r = _one(path, folder / f"run{k}", delay, getattr(signal, f"SIG{args.signal}"))
            rows.append(r)
            print(f"{r['delay_s']:9.1f}  {r['latency_s']:11.2f}  {r['exit']:4d}  "
                  f"{'yes' if r['one_line'] else 'NO':>8}  {', '.join(r['left']) or '-'}")
    lat = [r["latency_s"] for r in rows]
    code = 130 if args.signal == "INT" else 143
    summary = {"median_latency_s": float(np.median(lat)), "worst_latency_s": max(lat),
               "expected_exit": code, "runs_with_expected_exit":
               sum(r["exit"] == code for r in rows), "runs": len(rows)}
    print(f"median {summary['median_latency_s']:.2f} s, worst {summary['worst_latency_s']:.2f} "
          f"s, exit {code} in {summary['runs_with_expected_exit']} of {summary['runs']}")
    Path(args.json).write_text(json.dumps({"meta": {"n": args.n, "signal": args.signal},
                                           "rows": rows,
                                           "summary": summary}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
