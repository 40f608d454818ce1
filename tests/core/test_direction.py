"""One direction signal: a velocity column whose sign disagrees with the position steps
(noise) must not drive the hysteresis models out of their Stribeck bounds; the Python
models, their per-sample `step`, the NumPy reference and the reversal bound all agree."""

import warnings

import equinox as eqx
import numpy as np
import pytest

import jaxfric
from jaxfric import paper
from jaxfric._shapes import PowerShape
from jaxfric._stribeck import Stribeck
from jaxfric.motion import consistent_velocity, reversal_bound

from .. import reference
from ..helpers import count_reversals, standstill_motion


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


@pytest.mark.parametrize("quantum", [0.0, 2e-6])
def test_deadband_keeps_noisy_standstill_out_of_the_memory(quantum):
    from jaxfric.motion import estimate_deadband, play

    model = paper.two_state(stack_size=8)
    Fc = float(model.stribeck.Fc)
    t, x, x_true = standstill_motion(7, quantum)
    rests = [((t > lo) & (t < hi), sign) for lo, hi, sign in
             ((1.2, 2.0, 1.0), (3.2, 4.0, -1.0), (5.2, 6.0, 1.0))]
    assert count_reversals(x_true) == 3
    assert count_reversals(x) > 100  # the noise alone makes reversals
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", jaxfric.StackOverflowWarning)
        raw = jaxfric.simulate(model, t, x, full_output=True)
    if not quantum:
        assert int(raw.overflow) > 0  # without a deadband the 8 slots overflow
    f_raw = np.asarray(raw.parts["hysteresis"])
    assert min(np.min(sign * f_raw[w]) for w, sign in rests) < Fc  # fake presliding loops
    b = estimate_deadband(x)
    assert 2e-6 <= b <= 2e-5  # of the order of the noise / encoder step, far below a move
    assert count_reversals(np.asarray(play(x, b))) == 3
    r = jaxfric.simulate(model, t, x, deadband="auto", full_output=True)
    assert int(r.overflow) == 0
    assert int(np.max(np.asarray(r.parts["depth"]))) <= 2
    f_h = np.asarray(r.parts["hysteresis"])
    for w, sign in rests:  # standstills stay on the sliding side: no presliding loop
        assert np.min(sign * f_h[w]) >= Fc
    # with a noisy velocity column the played position still decides alone
    v = np.gradient(x_true, t) + 1e-3 * np.random.default_rng(8).standard_normal(t.size)
    r_v = jaxfric.simulate(model, t, x, v, deadband=b, full_output=True)
    assert int(r_v.overflow) == 0
    f_v = np.asarray(r_v.parts["hysteresis"])
    for w, sign in rests:
        assert np.min(sign * f_v[w]) >= Fc


def test_deadband_zero_changes_nothing_and_bad_values_raise():
    t, x, _ = standstill_motion(9)
    model = paper.two_state(stack_size=64)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", jaxfric.StackOverflowWarning)
        a = np.asarray(jaxfric.simulate(model, t[:3000], x[:3000]))
        b = np.asarray(jaxfric.simulate(model, t[:3000], x[:3000], deadband=0.0))
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="deadband"):
        jaxfric.simulate(model, t, x, deadband=-1e-6)
    with pytest.raises(ValueError, match="deadband"):
        jaxfric.simulate(model, t, x, deadband="noise")


def test_too_small_max_reversals_is_counted_under_jit_and_vmap():
    model = paper.two_state()
    t, x, _ = standstill_motion(3)
    t, x = t[::10], np.interp(t[::10], [0.0, 1.0, 2.0, 3.0, 7.0], [0.0, 1e-3, 0.0, 1e-3, 0.0])
    count = 3

    @eqx.filter_jit
    def run(x):
        return jaxfric.simulate(model, t, x, max_reversals=1, full_output=True)

    r = run(x)
    assert int(r.overflow) == count - 1
    assert np.all(np.isnan(np.asarray(r.force)))
    batched = eqx.filter_vmap(run)(np.stack([x, 0.5 * x]))
    np.testing.assert_array_equal(np.asarray(batched.overflow), [count - 1, count - 1])
    ok = eqx.filter_jit(lambda x: jaxfric.simulate(model, t, x, max_reversals=4,
                                                   full_output=True))(x)
    assert int(ok.overflow) == 0 and np.all(np.isfinite(np.asarray(ok.force)))
    with pytest.warns(jaxfric.StackOverflowWarning, match="max_reversals"):
        jaxfric.simulate(model, t, x, max_reversals=1)
