"""Outputs that cannot lose data: checked before the work, written whole or not at all."""

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import equinox as eqx
import numpy as np
import pytest

import jaxfric
from fitting.cli import _output
from jaxfric import _atomic, paper


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


@pytest.mark.parametrize("write", [
    lambda m, folder: jaxfric.save_model(m, folder / "model.json"),
    lambda m, folder: jaxfric.export.to_c(m, folder),
    lambda m, folder: jaxfric.export.to_mujoco(m, folder / "model.xml"),
])
def test_the_librarys_writers_leave_old_files_alone_when_interrupted(tmp_path, monkeypatch,
                                                                      write):
    """`save_model`, `to_c` and `to_mujoco` write through `jaxfric._atomic` too: a write
    cut off before its rename leaves the old files whole and no temporary file behind."""
    write(paper.lugre(), tmp_path)  # the one model every writer takes (MuJoCo: LuGre)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}

    def cut(*_):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", cut)
    with pytest.raises(KeyboardInterrupt):
        write(eqx.tree_at(lambda m: m.sigma0, paper.lugre(), 2 * paper.lugre().sigma0),
              tmp_path)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


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
    assert oct(target.stat().st_mode & 0o777) == oct(0o666 & ~_atomic._umask())


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
    try:  # the file's line ("N samples over ...") comes after loading, before the fit
        lines = [proc.stdout.readline()]
        while lines[-1] and "samples" not in lines[-1] and len(lines) < 5:
            lines.append(proc.stdout.readline())
        assert "samples" in lines[-1], lines
        time.sleep(1.0)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 143, err
    assert "terminated" in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]


# ---- demo: outputs checked first, whole files only ----------------------------------

_DEMO_RUNNER = r"""
import json, os, sys
import fitting.cli.demo as demo
from fitting.cli.main import main

def started(*args, **kw):
    print("the demo started its work", file=sys.stderr)
    raise SystemExit(99)

demo.run = started
if int(sys.argv[2]):  # as root every folder is writable: drop to the user nobody
    os.setgid(65534)
    os.setuid(65534)
sys.exit(main(json.loads(sys.argv[1])))
"""


@pytest.mark.parametrize("case", ["out", "out_parent", "json", "unreachable"])
def test_demo_checks_its_outputs_before_any_work(case):
    """An output the demo cannot write (a folder we may not write in, or not even enter):
    one line, exit 2, before the measurement is even made (`demo.run` is replaced by a
    function that reports that it started)."""
    with tempfile.TemporaryDirectory() as tmp:
        top = Path(tmp)
        os.chmod(top, 0o755)  # nobody may enter the top folder
        locked, free, shut = top / "locked", top / "free", top / "shut"
        for folder, mode in ((locked, 0o555), (free, 0o777), (shut, 0o000)):
            folder.mkdir()
            folder.chmod(mode)  # (mkdir's mode is masked by the umask)
        argv = {"out": ["demo", "--out", str(locked)],
                "out_parent": ["demo", "--out", str(locked / "new" / "report")],
                "json": ["demo", "--out", str(free / "report"), "--json",
                         str(locked / "s.json")],
                "unreachable": ["demo", "--out", str(shut / "report")]}[case]
        try:
            r = subprocess.run([sys.executable, "-c", _DEMO_RUNNER, json.dumps(argv),
                                str(int(os.geteuid() == 0))], capture_output=True,
                               text=True, timeout=120,
                               env={**os.environ, "JAXFRIC_CACHE_DIR": ""})
        finally:
            for folder in (locked, shut):
                folder.chmod(0o755)
        assert r.returncode == 2, r.stderr
        lines = r.stderr.strip().splitlines()
        option = "--json" if case == "json" else "--out"
        assert len(lines) == 1, r.stderr
        assert lines[0].startswith(f"jaxfric demo: error: {option} "), r.stderr
        assert "permission denied" in lines[0] and "Traceback" not in r.stderr
        assert [list(f.iterdir()) for f in (locked, free, shut)] == [[], [], []]


def _small_measurement(seed=0, dt=2e-2):
    t = np.arange(300) * dt
    x = 2e-3 * np.sin(2 * np.pi * t / 3.0)
    return t, x, np.tanh(np.gradient(x, t) / 1e-3), None


def _half_then(exc):
    """A stand-in for `np.savetxt` that writes part of the file, then raises `exc`."""
    def savetxt(f, *args, **kw):
        f.write("t[s],x[m],F[N]\n0,0,0\n0.02,")
        raise exc
    return savetxt


def _diagnosis_raising(exc):
    def diagnose(*args, **kw):
        raise exc
    return diagnose


def _run_demo(out, code, capsys):
    """``jaxfric demo --out OUT`` in-process: exit `code` with the one line, or, for
    ``None``, the work's own error ("solver bug") raised."""
    from fitting.cli.main import main

    argv = ["demo", "--out", str(out), "--quiet"]
    if code is None:
        with pytest.raises(RuntimeError, match="solver bug"):
            main(argv)
    else:
        assert main(argv) == code
        assert capsys.readouterr().err == "jaxfric demo: interrupted\n"


@pytest.mark.parametrize(("where", "exc", "code"), [
    ("example.csv", KeyboardInterrupt, 130),   # Ctrl-C while the measurement is written
    ("fit", KeyboardInterrupt, 130),           # Ctrl-C during the fit
    ("fit", RuntimeError("solver bug"), None),  # the work fails
])
def test_an_interrupted_or_failing_demo_leaves_whole_files_only(tmp_path, monkeypatch, capsys,
                                                               where, exc, code):
    """The folder of an earlier demo: every file is either the old one or a whole new one,
    and no temporary file is left, whether Ctrl-C lands in a write or in the fit, or the fit
    fails."""
    import fitting
    from fitting.cli import demo

    out = tmp_path / "report"
    out.mkdir()
    old = {name: f"old {name}" for name in ("example.csv", "summary.json", "report.html")}
    for name, text in old.items():
        (out / name).write_text(text)
    monkeypatch.setattr(demo, "example_measurement", _small_measurement)
    if where == "example.csv":
        monkeypatch.setattr(demo.np, "savetxt", _half_then(exc))
    else:
        monkeypatch.setattr(fitting, "diagnose", _diagnosis_raising(exc))
    _run_demo(out, code, capsys)
    assert sorted(p.name for p in out.iterdir()) == sorted(old)  # no temp file
    for name, text in old.items():
        if name == "example.csv" and where == "fit":  # written whole before the fit
            t, x, F, _ = _small_measurement()
            back = np.loadtxt(out / name, delimiter=",", skiprows=1)
            np.testing.assert_allclose(back, np.column_stack([t, x, F]), rtol=1e-9)
        else:
            assert (out / name).read_text() == text


@pytest.mark.parametrize(("exc", "code"), [(KeyboardInterrupt, 130),
                                           (RuntimeError("solver bug"), None)])
def test_an_interrupted_or_failing_demo_removes_the_folder_it_made(tmp_path, monkeypatch,
                                                                   capsys, exc, code):
    """A demo into a folder that did not exist (nor its parent): Ctrl-C during the fit, or
    a failing fit, leaves no folder behind (the measurement was already written in it)."""
    import fitting
    from fitting.cli import demo

    out = tmp_path / "new" / "report"
    seen = []

    def diagnose(*args, **kw):
        seen.append(sorted(p.name for p in out.iterdir()))  # the folder, during the work
        raise exc

    monkeypatch.setattr(demo, "example_measurement", _small_measurement)
    monkeypatch.setattr(fitting, "diagnose", diagnose)
    _run_demo(out, code, capsys)
    assert seen == [["example.csv"]]
    assert list(tmp_path.iterdir()) == []


def test_output_folder_keeps_a_folder_that_was_there(tmp_path):
    """Only folders made by `output_folder` are removed: one that existed keeps its old
    files and the whole new ones."""
    out = tmp_path / "report"
    out.mkdir()
    (out / "old.txt").write_text("old")
    with pytest.raises(KeyboardInterrupt), _atomic.output_folder(out) as folder:
        _atomic.write_text(folder / "new.txt", "new")
        raise KeyboardInterrupt
    assert sorted(p.name for p in out.iterdir()) == ["new.txt", "old.txt"]
    with _atomic.output_folder(tmp_path / "a" / "b") as folder:  # finished: kept
        _atomic.write_text(folder / "f.txt", "f")
    assert (tmp_path / "a" / "b" / "f.txt").read_text() == "f"


def test_remove_pending_removes_the_folders_being_filled(tmp_path):
    """A process ended at once (`fitting.cli._interrupt`) does not unwind: `remove_pending`
    removes the folder an unfinished `output_folder` made, with its files, and the
    temporary file of the output being written."""
    filling = _atomic.output_folder(tmp_path / "new" / "report")
    folder = filling.__enter__()
    _atomic.write_text(folder / "example.csv", "t,x,F\n")
    writing = _atomic.atomic_file(folder / "summary.json")
    writing.__enter__().write("{")
    try:
        _atomic.remove_pending()
        assert list(tmp_path.iterdir()) == []
    finally:
        _atomic._pending.clear()
        _atomic._pending_folders.clear()
