"""Ctrl-C and SIGTERM stop the command line within a second or two, with one line, the
documented exit code (130, 143) and no file left half-written (`fitting.cli._interrupt`).
Each test runs the command as a process, as a user does."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from fitting.cli import _interrupt


#: ``python -c`` arguments that run ``python -m fitting.cli`` with Ctrl-C as at a terminal,
#: even when pytest itself was started in the background with SIGINT ignored.
CLI = ["-c", "import runpy, signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
       "runpy.run_module('fitting.cli', run_name='__main__', alter_sys=True)"]

#: A command whose main thread never stops by itself once it has an output half-written:
#: it swallows every KeyboardInterrupt (as Python does with one raised in a finaliser).
_STUCK = r"""
import signal, sys, time
from pathlib import Path
signal.signal(signal.SIGINT, signal.default_int_handler)
from fitting.cli import _interrupt, _output
signal.signal(signal.SIGTERM, _interrupt.terminate)
_interrupt.arm("fit")
writing = _output.atomic_file(Path(sys.argv[1]) / "fit.json")
f = writing.__enter__()
f.write('{"half": ')
f.flush()
announced = False
while True:
    try:  # (announced inside: a signal that comes at once is swallowed too)
        if not announced:
            announced = True
            print("writing", flush=True)
        time.sleep(60)
    except KeyboardInterrupt:
        pass
"""


def _latency(proc, signum) -> tuple[float, str]:
    assert proc.poll() is None, "over before the signal: the test would prove nothing"
    sent = time.perf_counter()
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    return time.perf_counter() - sent, err


@pytest.mark.parametrize(("signum", "code", "word"), [(signal.SIGINT, 130, "interrupted"),
                                                      (signal.SIGTERM, 143, "terminated")])
def test_the_watcher_stops_a_command_that_does_not_stop(tmp_path, signum, code, word):
    """The main thread goes on after the signal (here it swallows it; in a fit it is busy
    in compiled code): the watcher ends the process `GRACE` seconds later, with the one
    line and the exit code, and removes the temporary file of the output being written."""
    proc = subprocess.Popen([sys.executable, "-c", _STUCK, str(tmp_path)], text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout.readline() == "writing\n"
    assert len(list(tmp_path.iterdir())) == 1  # the temporary file
    latency, err = _latency(proc, signum)
    assert proc.returncode == code, err
    assert err == f"jaxfric fit: {word}\n"
    assert _interrupt.GRACE <= latency < _interrupt.GRACE + 2.0
    assert list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def long_fit_file(tmp_path_factory):
    """A measurement whose two-state fit runs for tens of seconds (1e5 samples, 0.05 N
    of noise)."""
    import jaxfric
    from jaxfric import paper
    from jaxfric.examples import excitation

    n = 100_000
    _, x = excitation(dt=1e-3)
    x = np.concatenate([x] * int(np.ceil(n / x.size)))[:n]
    t = 1e-3 * np.arange(n)
    F = np.asarray(jaxfric.simulate(paper.two_state(), t, x))
    F = F + 0.05 * np.random.default_rng(0).normal(size=n)
    path = tmp_path_factory.mktemp("long") / "m.csv"
    np.savetxt(path, np.column_stack([t, x, F]), delimiter=",", header="t,x,F", comments="",
               fmt="%.10g")
    return path


# Slow: about 10 s per case (loading 1e5 samples, then compiling) plus the file.
@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.5, 2.5, 5.0])  # compiling, first chunks, running
def test_ctrl_c_stops_a_long_fit_within_two_seconds(long_fit_file, tmp_path, delay):
    out = tmp_path / "fit.json"
    proc = subprocess.Popen([sys.executable, *CLI, "fit", str(long_fit_file), "--max-steps",
                             "1000", "--json", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "JAXFRIC_CACHE_DIR": ""})
    while not proc.stdout.readline().startswith("fitting"):
        assert proc.poll() is None, proc.stderr.read()
    time.sleep(delay)
    latency, err = _latency(proc, signal.SIGINT)
    assert proc.returncode == 130, err
    assert err == "jaxfric fit: interrupted\n"
    assert latency < 2.0
    assert list(tmp_path.iterdir()) == []  # no JSON, no temporary file
