"""The benchmark motions and fit data (SI units: t in s, x in m, F in N), shared by the
benchmark scripts without importing the optional Numba baseline."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import jaxfric


UM = 1e-6


def mixed_path(n: int, dt: float = 1e-3, rng: np.random.Generator | None = None):
    """``t`` (s), ``x`` (m) with n samples: a 1 mm, 0.2 Hz sliding sine plus presliding
    sines of 100 um at 1.3 Hz and 20 um at 4.1 Hz. Random phases (and +-20 % amplitudes)
    when `rng` is given, for batches; otherwise fixed phases."""
    t = dt * np.arange(n, dtype=np.float64)
    if rng is None:
        ph, amp = np.array([0.0, 1.0, 2.0]), np.ones(3)
    else:
        ph, amp = rng.uniform(0.0, 2 * np.pi, 3), rng.uniform(0.8, 1.2, 3)
    x = (
        amp[0] * 1e-3 * np.sin(2 * np.pi * 0.2 * t + ph[0])
        + amp[1] * 100 * UM * np.sin(2 * np.pi * 1.3 * t + ph[1])
        + amp[2] * 20 * UM * np.sin(2 * np.pi * 4.1 * t + ph[2])
    )
    return t, x


def perturbed_start(model):
    """The paper model with 7 of its 12 parameters moved by 4-50 % (the fits' start)."""
    st, sh = model.stribeck, model.shape
    return eqx.tree_at(
        lambda m: (m.stribeck.Fs, m.stribeck.Fc, m.stribeck.Vs, m.stribeck.delta, m.sigma2,
                   m.C, m.shape.l1),
        model,
        tuple(jnp.asarray(v) for v in (1.04 * st.Fs, 0.96 * st.Fc, 1.2 * st.Vs,
                                       1.1 * st.delta, 0.9 * model.sigma2, 1.5 * model.C,
                                       1.1 * sh.l1)),
    )


def synthetic_force(model, t, x, rng, noise=0.05):
    """Force of `model` (N) along ``(t, x)`` plus Gaussian noise of `noise` N."""
    return np.asarray(jaxfric.simulate(model, t, x)) + noise * rng.standard_normal(t.shape)
