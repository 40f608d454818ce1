"""Property tests: random piecewise-linear motions (hypothesis) against laws the models
must obey whatever the motion: finite forces, bounded hysteresis / element forces, the
steady sliding force, odd symmetry, and agreement with the NumPy reference.

Every example has exactly `N_PROP` samples, so each model compiles once per process.
"""

import hypothesis.strategies as st
import jax.numpy as jnp
import numpy as np
from hypothesis import given, HealthCheck, settings

import jaxfric
from jaxfric import paper

from .. import reference as ref
from ..helpers import ref_kwargs


N_PROP = 600
N_REST = 5  # rest samples at the start (the zero state)
N_MOVE = 80  # samples per constant-velocity segment
N_DWELL = 10  # samples per dwell
N_SEGMENTS = 6

FS = 26.1  # paper Stribeck static level, N

# database=None: nothing is written to the working tree; deadline=None: the first example
# of each test includes JAX compilation.
SETTINGS = {"deadline": None, "database": None, "suppress_health_check": [HealthCheck.too_slow]}

# A segment: (log10 amplitude in m, direction code, log10 speed in m/s, dwell after, s).
# Direction code 0 keeps the previous direction (a speed change without reversal); 1-3
# reverse it. Amplitudes 0.1 um .. 2 mm mix deep presliding (2*Fs*l1 = 0.22 mm) and
# sliding; speeds 1 um/s .. 5 mm/s cross the Stribeck velocity (3.1 mm/s).
segment = st.tuples(
    st.floats(-7.0, np.log10(2e-3)),
    st.integers(0, 3),
    st.floats(-6.0, np.log10(5e-3)),
    st.one_of(st.just(0.0), st.floats(1e-3, 1.0)),
)
segments = st.lists(segment, min_size=N_SEGMENTS, max_size=N_SEGMENTS)


def build_motion(segs, n_total=N_PROP):
    """(t, x) with exactly `n_total` samples: rest, the segments (each `N_MOVE` equal steps
    then, if its dwell > 0, `N_DWELL` samples at rest), then rest to the end."""
    t, x = [0.0], [0.0]
    for _ in range(N_REST):
        t.append(t[-1] + 1e-3)
        x.append(0.0)
    direction = 1.0
    for log_amp, code, log_speed, dwell in segs:
        if code != 0:
            direction = -direction
        amp, speed = 10.0**log_amp, 10.0**log_speed
        dt = amp / speed / N_MOVE
        for _i in range(N_MOVE):
            t.append(t[-1] + dt)
            x.append(x[-1] + direction * amp / N_MOVE)
        if dwell > 0:
            for _ in range(N_DWELL):
                t.append(t[-1] + dwell / N_DWELL)
                x.append(x[-1])
    while len(t) < n_total:
        t.append(t[-1] + 1e-2)
        x.append(x[-1])
    assert len(t) == n_total
    return np.asarray(t), np.asarray(x)


motions = segments.map(build_motion)


def _power_two_state():
    return jaxfric.TwoState(
        stribeck=paper.stribeck(), shape=jaxfric.PowerShape(l1=4e-6, n=2.5),
        sigma2=paper.SIGMA2, C=paper.C,
    )


MODELS = {
    "two_state": paper.two_state(),
    "two_state_power": _power_two_state(),
    "gms5": paper.gms5(),
    "gms_from_shape": paper.gms(30),
    "lugre": paper.lugre(),
    "tustin": paper.tustin(),
}

# The hysteresis / element forces are algebraic combinations of Stribeck values and of
# Pi in [0, 1]: rounding only, ~1e-14 N.
BOUND_TOL = 1e-9  # N


@settings(max_examples=30, **SETTINGS)
@given(motions)
def test_forces_finite_bounded_and_odd(motion):
    t, x = motion
    for name, model in MODELS.items():
        out = jaxfric.simulate(model, t, x, full_output=True)
        force = np.asarray(out.force)
        assert np.isfinite(force).all(), name
        if isinstance(model, jaxfric.TwoState):
            # |F_h| <= max|s| = Fs (paper Stribeck curve, Fc < Fs).
            f_h = np.abs(np.asarray(out.parts["hysteresis"]))
            assert f_h.max() <= FS + BOUND_TOL, f"{name}: max |F_h| = {f_h.max()!r}"
            assert int(out.overflow) == 0
        elif isinstance(model, jaxfric.GMS):
            # |F_i| <= nu_i*|s| <= nu_i*Fs for every element, so |sum F_i| <= Fs*sum(nu).
            elements = np.abs(np.asarray(out.parts["elements"]))
            bound = FS * float(jnp.sum(model.nu))
            assert elements.max() <= bound + BOUND_TOL, f"{name}: max = {elements.max()!r}"
        # Odd symmetry: the mirrored motion gives the mirrored force (sign-symmetric
        # Stribeck curve and shapes), to rounding.
        mirrored = np.asarray(jaxfric.simulate(model, t, -x))
        np.testing.assert_allclose(mirrored, -force, rtol=0, atol=1e-9, err_msg=name)


@settings(max_examples=25, **SETTINGS)
@given(
    segments.map(lambda s: s[:4]),
    st.floats(-6.0, np.log10(5e-3)),
    st.booleans(),
)
def test_steady_sliding_force(prefix, log_speed, forward):
    """After any history, a long constant-velocity stroke ends at ``s(v) + sigma2*v``
    (``sum(nu)*s(v)`` for a GMS whose weights do not add up to 1)."""
    t, x = build_motion(prefix, n_total=N_PROP - 100)
    v = (1.0 if forward else -1.0) * 10.0**log_speed
    # Long enough in time for the friction lag (time constant |s|/C <= 2.4 s) to decay by
    # exp(-25) ~ 1e-11, and in distance (>= 5 mm) to leave presliding (0.22 mm) far behind.
    duration = max(60.0, 5e-3 / abs(v))
    dt = duration / 100
    t = np.concatenate([t, t[-1] + dt * np.arange(1, 101)])
    x = np.concatenate([x, x[-1] + v * dt * np.arange(1, 101)])
    s_v = ref.stribeck(v, **ref.PAPER_STRIBECK)
    for name, model in MODELS.items():
        if name == "tustin":
            continue  # static: trivially s(v) + sigma2*v
        weight = float(jnp.sum(model.nu)) if isinstance(model, jaxfric.GMS) else 1.0
        expected = weight * s_v + float(model.sigma2) * v
        force = float(jaxfric.simulate(model, t, x)[-1])
        assert abs(force - expected) < 1e-6, f"{name}: {force!r} != {expected!r} at v = {v}"


@settings(max_examples=12, **SETTINGS)
@given(motions)
def test_two_state_matches_reference(motion):
    t, x = motion
    for model in (MODELS["two_state"], MODELS["two_state_power"]):
        r = ref.two_state(t, x, **ref_kwargs(model))
        out = jaxfric.simulate(model, t, x, full_output=True)
        err = np.max(np.abs(np.asarray(out.force) - r["F"]))
        assert err < 1e-6, f"max |F - F_ref| = {err:.3e} N"
        np.testing.assert_array_equal(np.asarray(out.parts["depth"]), r["depth"])
