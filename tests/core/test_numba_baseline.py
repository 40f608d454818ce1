"""The Numba baseline of the benchmarks computes the same model as jaxfric.

`benchmarks/numba_two_state.py` is a hand-written float64 loop of docs/algorithm.md
section 4; a speed comparison only means something if it gives the same forces as
`jaxfric.simulate(paper.two_state(), ...)`. Its ``--check`` mode compares them (< 1e-9 N on
the built-in identification motion with nested loops and strokes, and on an irregularly
sampled motion with a given velocity; with a 3-entry stack that overflows, the same
overflow counts; its analytic shape against `jaxfric.PaperShape`; the prange batch against
one trajectory at a time). Run as a script, so the tests never import the benchmarks.
"""

import subprocess
import sys
from pathlib import Path


ROOT = Path(__file__).resolve().parents[2]


def test_numba_baseline_agrees_with_jaxfric():
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "numba_two_state.py"),
                          "--check"], capture_output=True, text=True, timeout=900, cwd=ROOT)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "all agree" in run.stdout
    assert run.stdout.count("max |F_numba - F_jaxfric|") == 4
