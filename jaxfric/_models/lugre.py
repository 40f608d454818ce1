"""The LuGre model (Canudas de Wit et al. 1995; docs/algorithm.md section 6)."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from .._fields import param
from .._numerics import linear_recurrence
from .._stribeck import Stribeck
from ..motion import Motion
from ._base import AbstractFrictionModel, SimResult


class LuGreState(eqx.Module):
    z: Array


class LuGre(AbstractFrictionModel):
    """``dz/dt = v - sigma0*|v|*z/g(v)``, ``F = sigma0*z + sigma1*dz/dt + sigma2*v``,
    with ``g(v) = |s(v)|`` from a `Stribeck` curve (``g(0) = Fs``).

    **Arguments:** `stribeck`; `sigma0` bristle stiffness (N/m); `sigma1` bristle damping
    (N s/m); `sigma2` viscous coefficient (N s/m).

    The bristle state is updated exactly for a velocity held constant over each sample, which
    makes the whole trajectory a linear recurrence in z (no sequential loop).
    """

    stribeck: Stribeck
    sigma0: Array = param("N/m", constraint="positive", role="presliding")
    sigma1: Array = param("N s/m", constraint="positive", role="presliding")
    sigma2: Array = param("N s/m", constraint="positive")

    def _coefficients(self, v, dt):
        g = self.stribeck.magnitude(v)
        a = jnp.exp(-self.sigma0 * jnp.abs(v) * dt / g)
        return a, (1.0 - a) * jnp.sign(v) * g / self.sigma0, g

    def _force(self, z, v, g):
        zdot = v - self.sigma0 * jnp.abs(v) * z / g
        return self.sigma0 * z + self.sigma1 * zdot + self.sigma2 * v

    def init_state(self, x0: ArrayLike = 0.0) -> LuGreState:
        return LuGreState(z=jnp.zeros((), self.sigma0.dtype))

    def step(self, state: LuGreState, x, v, dt):
        v, dt = jnp.asarray(v), jnp.asarray(dt)
        a, b, g = self._coefficients(v, dt)
        z = a * state.z + b
        return LuGreState(z=z), self._force(z, v, g)

    def _simulate(self, motion: Motion) -> SimResult:
        a, b, g = self._coefficients(motion.v, motion.dt)
        z = linear_recurrence(a, b)
        return SimResult(
            force=self._force(z, motion.v, g),
            parts={"bristle": self.sigma0 * z, "viscous": self.sigma2 * motion.v},
            overflow=jnp.zeros((), jnp.int32),
        )
