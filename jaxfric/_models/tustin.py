"""Tustin's static model: the Stribeck curve plus viscous friction."""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from .._fields import param
from .._stribeck import Stribeck
from ..motion import Motion
from ._base import AbstractFrictionModel, SimResult


class Tustin(AbstractFrictionModel):
    """``F = s(v) + sigma2*v`` (N): no state, so no presliding, lag or memory; 0 at v = 0.

    **Arguments:** `stribeck`; `sigma2` viscous coefficient (N s/m).
    """

    stribeck: Stribeck
    sigma2: Array = param("N s/m", constraint="positive")

    def _force(self, v):
        return self.stribeck(v) + self.sigma2 * v

    def init_state(self, x0: ArrayLike = 0.0) -> tuple:
        return ()

    def step(self, state, x, v, dt):
        return state, self._force(jnp.asarray(v))

    def _simulate(self, motion: Motion) -> SimResult:
        viscous = self.sigma2 * motion.v
        return SimResult(
            force=self._force(motion.v),
            parts={"stribeck": self.stribeck(motion.v), "viscous": viscous},
            overflow=jnp.zeros((), jnp.int32),
        )
