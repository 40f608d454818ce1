"""Property test of fits (issue 36, "done when"): many random truths, each fitted from a
start read off its own data (`fitting.initial_model`), converge in at most 40 steps, down
to the noise.

Truths are drawn (seeded) in plausible ranges around the paper's values; the motion is one
fixed record (long strokes with small wiggles at 1 kHz, `jaxfric.trajectories`), so each
model family compiles once. The default run fits a few truths per family; ``-m slow`` many.
"""

import functools

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import fitting
import jaxfric
from jaxfric import NormalizedPaperShape, paper, trajectories


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
        # the paper's, scaled with Fs*l1 through the normalised shape. (The paper's a, b, c
        # with another l1 would evaluate its saw-tooth polynomial, fitted on 0.22 mm, out
        # to 2*Fs*l1: beyond 0.5 mm the virgin curve turns negative, the force growing
        # against the new motion for 0.2 mm before it jumps; at 0.35 mm it saturates
        # within a fifth of its range.)
        base = NormalizedPaperShape.from_paper(paper.shape(), paper.stribeck().Fs)
        l1 = _factor(rng, 2e-6, 8e-6)
        shape = eqx.tree_at(lambda s: s.l1, base, jnp.asarray(l1)).to_paper(m.stribeck.Fs)
        pi = np.asarray(shape.pi(jnp.linspace(0.0, l1, 101), m.stribeck.Fs))
        assert np.all(np.diff(pi) >= 0) and pi[-1] == pytest.approx(1.0)  # a virgin curve
        return eqx.tree_at(lambda m: (m.shape, m.C), m,
                           (shape, jnp.asarray(_factor(rng, 3.0, 30.0))))
    if kind == "lugre":
        m = _stribeck(rng, paper.lugre())
        s0 = _factor(rng, 1e6, 1e7)
        # Damping between 0.2 and 1 of critical for a 1 kg mass.
        return eqx.tree_at(lambda m: (m.sigma0, m.sigma1), m,
                           (jnp.asarray(s0), jnp.asarray(rng.uniform(0.4, 2.0) * np.sqrt(s0))))
    if kind == "tustin":
        return _stribeck(rng, paper.tustin())
    raise ValueError(kind)


@functools.cache
def _fit_many(kind: str, seeds: tuple) -> list[tuple]:
    """``(seed, converged, steps, rmse, stopped)`` of a fit of each seed's random truth
    (cached: the convergence and the step-count tests read the same fits)."""
    t, x = _motion()
    out = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        truth = _truth(kind, rng)
        F = np.asarray(jaxfric.simulate(truth, t, x)) + NOISE * rng.standard_normal(N)
        start = fitting.initial_model(kind, t, x, F)
        res = fitting.fit(start, t, x, F, max_steps=256)
        out.append((seed, bool(res.converged), int(res.num_steps), float(res.rmse),
                    res.stopped))
    return out


def _converged(kind: str, fits) -> None:
    bad = [f"{kind} seed {s}: converged {c}, RMSE {r:.4g} N ({why})"
           for s, c, n, r, why in fits if not (c and r < 1.1 * NOISE)]
    assert not bad, "\n".join(bad)


def _within_steps(kind: str, fits) -> None:
    slow = [f"{kind} seed {s}: {n} steps ({why})" for s, c, n, r, why in fits
            if n > MAX_STEPS]
    assert not slow, "\n".join(slow)


# Seeds 3-22 (``-m slow``), measured on the loaded 2-core machine: every two-state truth
# converges to the noise in 10-28 steps from its start (0.1-1.7 N RMS off the data),
# including the longest presliding ranges, ``l1*Fs`` 0.27-0.32 mm on strokes of +-1 mm,
# which the start reads within 25 %. LuGre (at most 24) and Tustin (at most 26) are
# within 40.
KINDS = ["two-state", "lugre", "tustin"]
FEW, MANY = tuple(range(3)), tuple(range(3, 23))


@pytest.mark.parametrize("kind", KINDS)
def test_random_truths_converge_to_the_noise(kind):
    _converged(kind, _fit_many(kind, FEW))


@pytest.mark.parametrize("kind", KINDS)
def test_random_truths_converge_in_40_steps(kind):
    _within_steps(kind, _fit_many(kind, FEW))


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_many_random_truths_converge_to_the_noise(kind):
    _converged(kind, _fit_many(kind, MANY))


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_many_random_truths_converge_in_40_steps(kind):
    _within_steps(kind, _fit_many(kind, MANY))
