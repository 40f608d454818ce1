"""Outputs that cannot lose data: checked before the work, written whole or not at all."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import jaxfric
from fitting.cli import _output
from jaxfric import paper


def _run(*args, **kw):
    return subprocess.run([sys.executable, "-m", "fitting.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=600, **kw)


@pytest.fixture
def measurement(tmp_path):
    t = np.linspace(0.0, 6.0, 1201)
    x = 2e-3 * np.sin(2 * np.pi * t / 3.0)
    F = np.asarray(jaxfric.simulate(paper.tustin(), t, x))
    path = tmp_path / "m.csv"
    np.savetxt(path, np.column_stack([t, x, F]), delimiter=",", header="t,x,F", comments="")
    return path


@pytest.mark.parametrize(("command", "option", "make"), [
    ("fit", "--json", lambda tmp: tmp),                                   # a folder
    ("fit", "--json", lambda tmp: tmp / "missing" / "f.json"),            # no such folder
    ("fit", "--plot", lambda tmp: tmp),
    ("diagnose", "--json", lambda tmp: tmp),
    ("diagnose", "--report", lambda tmp: tmp / "m.csv"),                  # a file
    ("compare", "--json", lambda tmp: tmp / "nope" / "c.json"),
    ("simulate", "--out", lambda tmp: tmp),
])
def test_bad_output_is_refused_before_any_work(measurement, tmp_path, command, option, make):
    target = make(tmp_path)
    r = _run(command, measurement, option, target, "--model", "tustin")
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"jaxfric {command}: error: {option}"), r.stderr
    assert "fitting" not in r.stdout and "samples" not in r.stdout  # nothing was done


def test_demo_refuses_an_output_folder_that_is_a_file(tmp_path):
    f = tmp_path / "file"
    f.write_text("keep")
    r = _run("demo", "--out", f)
    assert r.returncode == 2 and "is a file" in r.stderr
    assert f.read_text() == "keep"


def test_atomic_file_leaves_the_target_alone_when_interrupted(tmp_path):
    target = tmp_path / "result.json"
    target.write_text("old")
    with pytest.raises(KeyboardInterrupt), _output.atomic_file(target) as f:
        f.write("half of the new")
        raise KeyboardInterrupt
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.json"]  # no temp file left


def test_writes_do_not_follow_a_planted_symlink(tmp_path):
    victim = tmp_path / "victim"
    victim.write_text("precious")
    target = tmp_path / "out.json"
    # The old scheme wrote to a predictable name: plant links at every such name.
    for pid in range(os.getpid() - 5, os.getpid() + 5):
        (tmp_path / f".out.json.tmp{pid}").symlink_to(victim)
    _output.write_json(target, {"a": 1.0})
    assert victim.read_text() == "precious"
    assert json.loads(target.read_text()) == {"a": 1.0}
    assert oct(target.stat().st_mode & 0o777) == oct(0o666 & ~_output._umask())


def test_json_is_rfc8259_with_null_for_undefined_values(tmp_path):
    target = tmp_path / "r.json"
    _output.write_json(target, {"a": float("inf"), "b": [1.0, float("nan")], "c": "x"})
    text = target.read_text()
    json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in JSON"))
    assert json.loads(text) == {"a": None, "b": [1.0, None], "c": "x"}


@pytest.mark.slow
def test_sigterm_during_a_fit_cleans_up_and_writes_nothing(measurement, tmp_path):
    out = tmp_path / "fit.json"
    proc = subprocess.Popen(
        [sys.executable, "-m", "fitting.cli", "fit", str(measurement), "--model", "gms",
         "--elements", "10", "--json", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "JAXFRIC_CACHE_DIR": ""})
    line = proc.stdout.readline()  # the first line comes after loading, before the fit
    assert "samples" in line, line
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    assert "terminated" in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]
