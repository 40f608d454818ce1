"""Batch fits and Monte-Carlo refits sharded over 4 CPU devices give the one-device results.

XLA's device count is fixed when JAX starts, so the check runs in a subprocess with
``XLA_FLAGS=--xla_force_host_platform_device_count=4``."""

import os
import subprocess
import sys
import textwrap

import pytest


SCRIPT = textwrap.dedent('''
    import jax, numpy as np
    import jaxfric, fitting
    from jaxfric import paper
    assert len(jax.devices()) == 4, jax.devices()
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 8.0, 800)
    x = 2e-3 * np.sin(2 * np.pi * t / 4) + 1e-3 * np.sin(2 * np.pi * t * 0.75)
    true = paper.tustin()
    F = np.stack([np.asarray(jaxfric.simulate(true, t, x)) + 0.05 * rng.normal(size=t.size)
                  for _ in range(10)])  # 10 datasets: padded to 12 for 4 devices
    T, X = np.broadcast_to(t, F.shape), np.broadcast_to(x, F.shape)
    one = fitting.fit_batch(true, T, X, F)
    many = fitting.fit_batch(true, T, X, F, devices=jax.devices())
    assert len(many.status) == 10 and all(s == "successful" for s in many.status)
    for name in one.names:
        a, b = np.asarray(one.params[name]), np.asarray(many.params[name])
        # The shares are vectorised over 3 datasets instead of 10, which changes rounding,
        # so the iterates differ at 1e-16 and the optima within the solver's stopping
        # tolerance (1e-6 relative): allow 1e-5. A misplaced dataset would be off by %.
        assert np.allclose(a, b, rtol=1e-5, atol=0), (name, a, b)
    assert np.allclose(one.rmse, many.rmse, rtol=1e-5)
    assert np.ptp(np.asarray(many.params["Fc"])) > 0  # ten different fits
    key = jax.random.key(1)
    mc1 = fitting.monte_carlo(true, t, x, key=key, num=8, noise_sigma=0.05)
    mc4 = fitting.monte_carlo(true, t, x, key=key, num=8, noise_sigma=0.05,
                              devices=jax.devices())
    for name in mc1.param_mean:
        assert np.allclose(mc1.param_mean[name], mc4.param_mean[name], rtol=1e-5), name
        assert np.allclose(mc1.param_std[name], mc4.param_std[name], rtol=1e-3), name
    print("OK")
''')


# Slow (about 25 s): a subprocess with four simulated devices compiles everything again.
@pytest.mark.slow
def test_sharded_batch_fit_and_monte_carlo_match_one_device():
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4")
    r = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                       env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.strip().endswith("OK")
