"""One direction signal: a velocity column whose sign disagrees with the position steps
(noise) must not drive the hysteresis models out of their Stribeck bounds; the Python
models, their per-sample `step`, the NumPy reference and the reversal bound all agree."""

import equinox as eqx
import numpy as np
import pytest

import jaxfric
from jaxfric import paper
from jaxfric._shapes import PowerShape
from jaxfric._stribeck import Stribeck
from jaxfric.motion import consistent_velocity, reversal_bound

from . import reference


def noisy_motion(seed: int, v_noise: float = 2e-3):
    """A 1 mm, 0.5 Hz sine sampled at 1 ms with a velocity column whose noise (m/s) flips
    its sign against the position steps near every turn and at slow speeds."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 4.0, 1e-3)
    x = 1e-3 * np.sin(np.pi * t) + 2e-6 * rng.standard_normal(t.size)
    v = 1e-3 * np.pi * np.cos(np.pi * t) + v_noise * rng.standard_normal(t.size)
    dx = np.r_[0.0, np.diff(x)]
    assert np.count_nonzero(v * dx < 0) > 200  # the sign really disagrees often
    return t, x, v


def random_two_state(rng) -> jaxfric.TwoState:
    Fs = rng.uniform(5.0, 50.0)
    return jaxfric.TwoState(
        stribeck=Stribeck(Fs=Fs, Fc=Fs * rng.uniform(0.5, 1.0), Vs=rng.uniform(1e-4, 1e-2),
                          delta=rng.uniform(0.5, 2.0)),
        shape=PowerShape(l1=rng.uniform(1e-7, 1e-5), n=rng.uniform(1.5, 4.0)),
        sigma2=0.0, C=rng.uniform(1.0, 50.0), stack_size=16)


def test_paper_two_state_stays_within_stribeck_bounds():
    model = eqx.tree_at(lambda m: m.sigma2, paper.two_state(), 0.0)
    t, x, v = noisy_motion(0)
    r = jaxfric.simulate(model, t, x, v, full_output=True)
    Fs = float(model.stribeck.Fs)
    assert np.max(np.abs(np.asarray(r.parts["hysteresis"]))) <= Fs * (1 + 1e-9)
    assert np.all(np.isfinite(np.asarray(r.force)))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_two_state_stays_within_stribeck_bounds(seed):
    rng = np.random.default_rng(seed)
    model = random_two_state(rng)
    t, x, v = noisy_motion(seed)
    r = jaxfric.simulate(model, t, x, v, full_output=True)
    Fs = float(model.stribeck.Fs)
    assert np.max(np.abs(np.asarray(r.parts["hysteresis"]))) <= Fs * (1 + 1e-9)


def test_gms_stays_within_stribeck_bounds():
    model = eqx.tree_at(lambda m: m.sigma2, paper.gms5(), 0.0)
    t, x, v = noisy_motion(4)
    f = np.asarray(jaxfric.simulate(model, t, x, v))
    assert np.max(np.abs(f)) <= float(model.stribeck.Fs) * (1 + 1e-9)


def test_noisy_velocity_matches_reference_and_step():
    model = paper.two_state()
    t, x, v = noisy_motion(5)
    t, x, v = t[:1500], x[:1500], v[:1500]
    got = np.asarray(jaxfric.simulate(model, t, x, v))
    want = reference.two_state(t, x, v, Fs=26.1, Fc=21.6, Vs=3.1e-3, delta=0.6,
                               sigma2=paper.SIGMA2, C=paper.C)["F"]
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9 * 26.1)
    # the per-sample step takes the same direction
    state = model.init_state(x[0])
    stepped = []
    step = eqx.filter_jit(model.step)
    for n in range(t.size):
        state, f = step(state, x[n], v[n], t[n] - t[n - 1] if n else 0.0)
        stepped.append(float(f))
    np.testing.assert_allclose(stepped, got, rtol=1e-9, atol=1e-9 * 26.1)


def test_consistent_velocity_rule():
    v = np.array([1.0, -1.0, 0.0, 2.0, -3.0])
    dx = np.array([0.0, 0.5, 0.5, -0.1, -0.2])
    dt = np.array([0.0, 0.1, 0.1, 0.1, 0.1])
    np.testing.assert_allclose(np.asarray(consistent_velocity(v, dx, dt)),
                               [1.0, 5.0, 0.0, -1.0, -3.0])


def test_reversal_bound_counts_the_consistent_direction():
    t = np.arange(6.0)
    x = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])  # monotonic: no reversal
    v = np.array([0.0, 1.0, -1.0, 1.0, -1.0, 1.0])  # noise says four
    r = jaxfric.simulate(paper.two_state(), t, x, v, max_reversals=0, full_output=True)
    assert np.all(np.isfinite(np.asarray(r.force)))
    assert reversal_bound(t, x, v) == 6  # min(64, n): counted on the consistent direction
