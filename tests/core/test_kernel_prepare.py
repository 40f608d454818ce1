"""`jaxfric._kernel.prepare`: the command line builds the C++ kernels in a background
thread as it starts, so that the first compiled program does not wait for the compiler."""

import threading

import pytest

from jaxfric import _kernel as K


def test_prepare_decides_in_a_thread_of_its_own(monkeypatch):
    seen = []
    monkeypatch.setattr(K, "_state", {})
    monkeypatch.setattr(K, "available", lambda: seen.append(threading.current_thread().name))
    monkeypatch.delenv(K.ENV, raising=False)
    thread = K.prepare()
    thread.join(timeout=10)
    assert seen == ["jaxfric-kernels"]


def test_prepare_keeps_a_failure_for_the_first_use(monkeypatch):
    """A failed build raises where the kernels are used (``kernel`` mode), not in the
    thread."""
    def fail():
        raise RuntimeError("no compiler")

    monkeypatch.setattr(K, "_state", {})
    monkeypatch.setattr(K, "available", fail)
    monkeypatch.setenv(K.ENV, "kernel")
    failed = []
    monkeypatch.setattr(threading, "excepthook", lambda args: failed.append(args))
    K.prepare().join(timeout=10)
    assert failed == []


@pytest.mark.parametrize("value, state", [("jax", {}), ("auto", {"ok": True}),
                                          ("neither", {})])
def test_prepare_starts_nothing_when_there_is_nothing_to_build(monkeypatch, value, state):
    monkeypatch.setattr(K, "_state", state)
    monkeypatch.setattr(K, "available", lambda: pytest.fail("nothing to build"))
    monkeypatch.setenv(K.ENV, value)
    assert K.prepare() is None


@pytest.mark.parametrize("argv, builds", [
    (["diagnose", "run.csv", "--model", "tustin"], True),  # a diagnosis tries a GMS
    (["fit", "run.csv"], True),
    (["fit", "run.csv", "--model", "gms"], True),
    (["fit", "run.csv", "--model", "tustin"], False),
    (["compare", "run.csv", "--models", "lugre,tustin"], False),
    (["compare", "run.csv", "--models", "lugre,gms"], True),
    (["compare", "run.csv"], True),
])
def test_the_command_line_prepares_the_kernels_where_it_uses_them(monkeypatch, tmp_path,
                                                                  argv, builds):
    import importlib

    cli = importlib.import_module("fitting.cli.main")

    (tmp_path / "run.csv").write_text("t,x,F\n0,0,0\n1,1,1\n")
    monkeypatch.chdir(tmp_path)
    seen = []
    monkeypatch.setattr(K, "prepare", lambda: seen.append("prepare"))
    for name in ("_fit", "_diagnose", "_compare"):
        monkeypatch.setattr(cli, name, lambda args: 0)
    monkeypatch.setenv("JAXFRIC_CACHE_DIR", "")
    assert cli.main(argv) == 0
    assert seen == (["prepare"] if builds else [])
