"""Property test of fits (issue 36, "done when"): many random truths, each fitted from a
start read off its own data (`fitting.initial_model`), converge in at most 40 steps, down
to the noise.

Truths are drawn (seeded) in plausible ranges around the paper's values; the motion is one
fixed record (long strokes with small wiggles at 1 kHz, `jaxfric.trajectories`), so each
model family compiles once. The default run fits a few truths per family; ``-m slow`` many.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import fitting
import jaxfric
from jaxfric import paper, trajectories


N = 4000  # samples at 1 kHz
NOISE = 0.05  # N
MAX_STEPS = 40


def _motion():
    t = 1e-3 * np.arange(N, dtype=np.float64)
    return t, trajectories.sine_strokes(t, stroke=1e-3, freq=0.5, wiggle=20e-6,
                                        wiggle_freq=3.0)


def _factor(rng, lo, hi):
    """Log-uniform in [lo, hi]."""
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def _stribeck(rng, model):
    """The Stribeck curve and viscous term of `model` drawn around the paper's: Fs 5-60 N,
    Fc/Fs 0.6-0.95, Vs 0.5-8 mm/s, delta 0.5-2, sigma2 10-150 N s/m."""
    fs = _factor(rng, 5.0, 60.0)
    return eqx.tree_at(
        lambda m: (m.stribeck.Fs, m.stribeck.Fc, m.stribeck.Vs, m.stribeck.delta, m.sigma2),
        model,
        tuple(jnp.asarray(v) for v in (fs, fs * rng.uniform(0.6, 0.95),
                                       _factor(rng, 0.5e-3, 8e-3), _factor(rng, 0.5, 2.0),
                                       _factor(rng, 10.0, 150.0))))


def _truth(kind: str, rng):
    if kind == "two-state":
        m = _stribeck(rng, paper.two_state())
        # Presliding: the range l1 (m/N) and the friction lag C drawn; the shape's form is
        # the paper's (scaled with Fs*l1 through the normalised shape).
        return eqx.tree_at(lambda m: (m.shape.l1, m.C), m,
                           (jnp.asarray(_factor(rng, 2e-6, 8e-6)),
                            jnp.asarray(_factor(rng, 3.0, 30.0))))
    if kind == "lugre":
        m = _stribeck(rng, paper.lugre())
        s0 = _factor(rng, 1e6, 1e7)
        # Damping between 0.2 and 1 of critical for a 1 kg mass.
        return eqx.tree_at(lambda m: (m.sigma0, m.sigma1), m,
                           (jnp.asarray(s0), jnp.asarray(rng.uniform(0.4, 2.0) * np.sqrt(s0))))
    if kind == "tustin":
        return _stribeck(rng, paper.tustin())
    raise ValueError(kind)


def _fit_many(kind: str, seeds) -> list[str]:
    t, x = _motion()
    bad = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        truth = _truth(kind, rng)
        F = np.asarray(jaxfric.simulate(truth, t, x)) + NOISE * rng.standard_normal(N)
        start = fitting.initial_model(kind, t, x, F)
        res = fitting.fit(start, t, x, F, max_steps=256)
        steps, rmse = int(res.num_steps), float(res.rmse)
        if not (bool(res.converged) and steps <= MAX_STEPS and rmse < 1.1 * NOISE):
            bad.append(f"{kind} seed {seed}: {res.status}, {steps} steps, RMSE {rmse:.4g} N "
                       f"({res.stopped})")
    return bad


@pytest.mark.parametrize("kind", ["two-state", "lugre", "tustin"])
def test_random_truths_converge_in_40_steps(kind):
    bad = _fit_many(kind, range(3))
    assert not bad, "\n".join(bad)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["two-state", "lugre", "tustin"])
def test_many_random_truths_converge_in_40_steps(kind):
    bad = _fit_many(kind, range(3, 23))
    assert not bad, "\n".join(bad)
