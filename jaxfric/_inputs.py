"""Turning a measured or commanded motion ``(t, x[, v])`` into model inputs.

Everything here is vectorised over samples; the models' sequential parts get these arrays.
See docs/algorithm.md section 1 for the rules (one direction signal, backward difference).
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._numerics import running_max


class Motion(eqx.Module):
    """A motion resampled into what every model needs, one entry per sample.

    - `t`, `x`, `v`: time (s), position (m), velocity (m/s).
    - `dt`: ``t_n - t_{n-1}`` (s), 0 at ``n = 0``.
    - `dx`: ``x_n - x_{n-1}`` (m), 0 at ``n = 0``.
    - `d`: direction ``sign(v_n)`` as a float in {-1, 0, 1}.
    - `last_d`: direction of the last moving sample at or before ``n`` (0 before any motion).
    - `prev_last_d`: the same at ``n - 1`` (0 at ``n = 0``).
    - `x_prev`: ``x_{n-1}`` (``x_0`` at ``n = 0``): the reversal point when one happens at n.
    - `max_reversals`: a static upper bound on the number of reversals (`reversal` true),
      or ``None`` (up to ``n``). `TwoState` evaluates its reversal terms on a list of this
      size rather than on every sample; `reversal_bound` computes one from concrete data.
    """

    t: Float[Array, " n"]
    x: Float[Array, " n"]
    v: Float[Array, " n"]
    dt: Float[Array, " n"]
    dx: Float[Array, " n"]
    d: Float[Array, " n"]
    last_d: Float[Array, " n"]
    prev_last_d: Float[Array, " n"]
    x_prev: Float[Array, " n"]
    max_reversals: int | None = eqx.field(static=True, default=None)

    @property
    def moving(self) -> Array:
        return self.d != 0

    @property
    def reversal(self) -> Array:
        """True at the first moving sample whose direction differs from the last motion's."""
        return self.moving & (self.prev_last_d != 0) & (self.d != self.prev_last_d)


def backward_velocity(t: Array, x: Array) -> Array:
    """``v_0 = 0``, ``v_n = (x_n - x_{n-1}) / (t_n - t_{n-1})``: m/s for t in s, x in m."""
    dx = jnp.diff(x, prepend=x[:1])
    dt = jnp.diff(t, prepend=t[:1])
    return jnp.where(dt > 0, dx / jnp.where(dt > 0, dt, 1.0), 0.0)


def reversal_bound(t, x, v=None) -> int:
    """A static bound on the number of reversals of the motion ``(t, x[, v])`` (concrete
    arrays; the same rule as `Motion.reversal`): the count, rounded up to a power of two
    (at least 64, at most ``n``) so that similar motions share one compilation."""
    t, x = np.asarray(t), np.asarray(x)
    if v is None:
        dt = np.diff(t, prepend=t[:1])
        dx = np.diff(x, prepend=x[:1])
        d = np.sign(np.where(dt > 0, dx, 0.0))
    else:
        d = np.sign(np.asarray(v))
    moving = d[d != 0]
    count = int(np.count_nonzero(moving[1:] != moving[:-1]))
    return min(max(64, 1 << count.bit_length()), max(int(t.shape[0]), 1))


def make_motion(t: Array, x: Array, v: Array | None = None,
                max_reversals: int | None = None) -> Motion:
    """Build a `Motion` from 1-D arrays of equal length (shape checks are the caller's)."""
    if v is None:
        v = backward_velocity(t, x)
    d = jnp.sign(v)
    n = d.shape[0]
    idx = jnp.arange(n, dtype=jnp.int32)
    # Index of the last moving sample so far (-1 if none): a running maximum.
    last_idx = running_max(jnp.where(d != 0, idx, -1))
    last_d = jnp.where(last_idx >= 0, d[jnp.maximum(last_idx, 0)], 0.0)
    prev_last_d = jnp.concatenate([jnp.zeros_like(last_d[:1]), last_d[:-1]])
    x_prev = jnp.concatenate([x[:1], x[:-1]])
    return Motion(
        t=t,
        x=x,
        v=v,
        dt=jnp.diff(t, prepend=t[:1]),
        dx=x - x_prev,
        d=d,
        last_d=last_d,
        prev_last_d=prev_last_d,
        x_prev=x_prev,
        max_reversals=max_reversals,
    )
