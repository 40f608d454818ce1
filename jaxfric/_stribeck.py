"""The Stribeck curve ``s(v)`` (paper Eq. 3), without the viscous term."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from ._fields import param
from ._numerics import safe_div


#: ``exp(-exp(w))`` is exactly 0 in float64 for ``w`` above this (``exp(-745.2)`` underflows),
#: so ``(|v|/Vs)**delta`` is not formed there: its derivative overflows (a steep curve,
#: ``delta`` in the hundreds, at a few ``Vs``) and ``inf * 0`` would make the gradient NaN.
_LOG_UNDERFLOW = 6.62

#: The largest Stribeck exponent a fit may reach (the field's constraint: a `Sigmoid` on
#: ``(0, DELTA_MAX)`` in `fitting`); a model given for simulation may have any ``delta > 0``.
#: ``exp(-(|v|/Vs)**delta)`` falls from 90 % to 10 % of its drop between ``|v|/Vs =
#: 0.105**(1/delta)`` and ``2.30**(1/delta)``, a relative span of ``exp(3.09/delta) - 1``:
#: 3 % of ``Vs`` at 100, a step for any physical purpose (measured curves have 0.5-2, the
#: paper 0.6, steep fits some tens). Beyond it only the few samples whose speed falls in
#: that span set the exponent, and a fit that leans on them (a model mismatch in the
#: transients) creeps along the valley towards a step without end. Near the bound the
#: `Sigmoid` flattens, the data stop determining ``delta`` in the fit's coordinates, and
#: the stopping rule (`fitting._stopping`) fires. The price, where the truth is a step and
#: the speeds are exact: an RMSE some 5 % above the noise (tests/fitting/test_delta_bound.py).
DELTA_MAX = 100.0


class Stribeck(eqx.Module):
    """``s(v) = sgn(v) * (Fc + (Fs - Fc) * exp(-(|v|/Vs)**delta))``.

    **Arguments:**

    - `Fs`: static (breakaway) level, N; the v -> 0 limit of ``|s(v)|``.
    - `Fc`: Coulomb level, N.
    - `Vs`: Stribeck velocity, m/s.
    - `delta`: Stribeck shape exponent, dimensionless; a fit keeps it below `DELTA_MAX`.

    ``s(0) = 0``. The friction models use ``rest(D) = D * Fs`` at rest, the v -> 0 limit on
    the side ``D`` of the last motion (see docs/algorithm.md section 2).
    """

    Fs: Array = param("N", constraint="positive", group="stribeck")
    Fc: Array = param("N", constraint="positive", group="stribeck")
    Vs: Array = param("m/s", constraint="positive", group="stribeck")
    delta: Array = param("-", constraint=("interval", 0.0, DELTA_MAX), group="stribeck")

    def magnitude(self, v: ArrayLike) -> Array:
        """``|s(v)|`` in N; equals ``Fs`` at ``v = 0`` (the limit), with finite gradients."""
        u = safe_div(jnp.abs(jnp.asarray(v)), self.Vs)
        pos = u > 0
        w = self.delta * jnp.log(jnp.where(pos, u, 1.0))  # log((|v|/Vs)**delta)
        keep = pos & (w < _LOG_UNDERFLOW)
        decay = jnp.where(keep, jnp.exp(-jnp.exp(jnp.where(keep, w, 0.0))),
                          jnp.where(pos, 0.0, 1.0))
        return self.Fc + (self.Fs - self.Fc) * decay

    def __call__(self, v: ArrayLike) -> Array:
        """``s(v)`` in N (0 at ``v = 0``)."""
        v = jnp.asarray(v)
        return jnp.sign(v) * self.magnitude(v)

    def rest(self, direction: ArrayLike) -> Array:
        """The v -> 0 limit of ``s`` on the side ``direction`` (+1, -1, or 0 for none), N."""
        return jnp.asarray(direction) * self.Fs

    def effective(self, v: ArrayLike, last_direction: ArrayLike) -> Array:
        """``S``: ``s(v)`` while moving, the rest limit of the last motion at ``v = 0``."""
        v = jnp.asarray(v)
        return jnp.where(v != 0, self(v), self.rest(last_direction))
