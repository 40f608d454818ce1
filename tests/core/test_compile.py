"""jaxfric's compiler options (`jaxfric._compile`): applied to its own programs, dropped
where XLA does not know them or the user asks for XLA's defaults, and never in the way of
a user's own ``jax.jit``."""

import os
import subprocess
import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfric
from jaxfric import _compile, paper


def _motion(n=400):
    t = 1e-3 * np.arange(n)
    x = 1e-4 * np.sin(2 * np.pi * 2.0 * t) + 2e-5 * np.sin(2 * np.pi * 9.0 * t)
    return t, x


def test_this_xla_takes_the_options():
    # The probe compiles with them here (if a new jaxlib drops an option, this says so).
    assert _compile._probe(_compile.COMPILER_OPTIONS) == _compile.COMPILER_OPTIONS
    assert _compile.compiler_options() in (_compile.COMPILER_OPTIONS, {})


def test_an_option_xla_does_not_know_is_left_out():
    assert _compile._probe({"xla_cpu_no_such_option_for_jaxfric": True}) == {}


def test_the_environment_asks_for_xla_defaults(monkeypatch):
    monkeypatch.setattr(_compile, "_accepted", None)
    monkeypatch.setenv("JAXFRIC_XLA_DEFAULTS", "1")
    assert _compile.compiler_options() == {}
    monkeypatch.setattr(_compile, "_accepted", None)
    monkeypatch.setenv("JAXFRIC_XLA_DEFAULTS", "0")
    assert _compile.compiler_options() == _compile._probe(_compile.COMPILER_OPTIONS)


def test_jaxfric_programs_get_the_options(monkeypatch):
    made, real = [], eqx.filter_jit

    def fake_filter_jit(fun, **kwargs):
        made.append(kwargs)
        return real(fun)

    monkeypatch.setattr(_compile.eqx, "filter_jit", fake_filter_jit)
    monkeypatch.setattr(_compile, "_accepted", {"some_option": 1})
    f = _compile.jit(lambda u: u * 2.0)
    assert float(f(jnp.asarray(3.0))) == 6.0
    assert made == [{"compiler_options": {"some_option": 1}}]


def test_inside_a_users_jit_and_scan_the_results_agree():
    # JAX refuses compiler options on a program nested in another: there the plain
    # filter_jit runs (the outer program's options apply).
    model = paper.two_state()
    t, x = _motion()
    top = np.asarray(jaxfric.simulate(model, t, x, max_reversals=20))
    inner = np.asarray(jax.jit(lambda m: jaxfric.simulate(m, t, x, max_reversals=20))(model))

    def body(carry, scale):
        return carry, jaxfric.simulate(model, t, scale * x, max_reversals=20)

    _, scanned = jax.lax.scan(body, 0.0, jnp.asarray([1.0]))
    np.testing.assert_allclose(inner, top, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(scanned[0]), top, rtol=0, atol=1e-12)


def test_an_error_inside_the_program_is_not_swallowed():
    @_compile.jit
    def bad(u):
        raise ValueError("a model's own complaint")

    with pytest.raises(ValueError, match="a model's own complaint"):
        bad(jnp.zeros(()))
    with pytest.raises(ValueError, match="a model's own complaint"):
        jax.jit(bad)(jnp.zeros(()))


def test_a_new_process_with_xla_defaults_gives_the_same_forces(tmp_path):
    # Only the generated code differs: the forces agree to round-off.
    model = paper.two_state()
    t, x = _motion()
    ours = np.asarray(jaxfric.simulate(model, t, x))
    out = tmp_path / "f.npy"
    code = ("import numpy as np, jaxfric; from jaxfric import paper, _compile; "
            "assert _compile.compiler_options() == {}; "
            "t = 1e-3 * np.arange(400); "
            "x = 1e-4 * np.sin(2 * np.pi * 2.0 * t) + 2e-5 * np.sin(2 * np.pi * 9.0 * t); "
            f"np.save({str(out)!r}, np.asarray(jaxfric.simulate(paper.two_state(), t, x)))")
    subprocess.run([sys.executable, "-c", code], check=True,
                   env={**os.environ, "JAXFRIC_XLA_DEFAULTS": "1"})
    np.testing.assert_allclose(np.load(out), ours, rtol=1e-12, atol=1e-12)
