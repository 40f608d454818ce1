"""What every friction model provides."""

import abc
from typing import Any, ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from ..motion import Motion


class SimResult(eqx.Module):
    """Full output of `jaxfric.simulate`.

    - `force`: total friction force, N, one per sample.
    - `parts`: the named contributions (N) that add up to `force`, e.g. ``"hysteresis"``,
      ``"lag"``, ``"viscous"`` for `TwoState`; plus model diagnostics (e.g. ``"depth"``,
      the number of memory-stack entries in use).
    - `overflow`: how many memory entries were dropped because the stack was full (an int;
      0 for models without a stack). Nonzero means the result may deviate from the model's
      exact memory behaviour: raise ``stack_size``. For `TwoState` it also counts the
      reversals beyond a `max_reversals` bound given too small (the forces are then NaN),
      so that a traced caller (``jit``/``vmap``) sees why.
    """

    force: Array
    parts: dict[str, Array]
    overflow: Array


class AbstractFrictionModel(eqx.Module):
    """A friction model: a pytree of parameters plus ``init_state``/``step``.

    ``step`` is the per-sample update used in closed loops (a mass plus a controller in the
    user's own ``lax.scan``); ``_simulate`` is the whole-trajectory path that
    `jaxfric.simulate` uses. Models whose smooth parts can be vectorised override
    ``_simulate``; the default scans ``step``. Both give the same numbers (tested).

    ``uses_reversal_bound``: whether ``_simulate`` evaluates terms on a list of
    ``Motion.max_reversals`` slots (`jaxfric.simulate` then computes the bound from
    concrete data).
    """

    uses_reversal_bound: ClassVar[bool] = False

    @abc.abstractmethod
    def init_state(self, x0: ArrayLike = 0.0) -> Any:
        """The zero state at initial position `x0` (m): no force, no memory."""

    @abc.abstractmethod
    def step(self, state: Any, x: ArrayLike, v: ArrayLike, dt: ArrayLike) -> tuple[Any, Array]:
        """Advance one sample to position `x` (m) with velocity `v` (m/s) after `dt` (s).

        Returns ``(new_state, force)`` with force in N. The direction of motion is
        ``sign(v)`` (docs/algorithm.md section 1): give a `v` consistent with the motion.
        """

    def __add__(self, effect):
        """``model + effect`` (or a tuple of effects): the model with additive physical
        effects (`jaxfric.effects`), fitted jointly by the `fitting` package.

        Each effect adds itself through its ``add_to(model)`` method, so this layer needs
        no import of the effects module (which builds on it)."""
        model = self
        for e in effect if isinstance(effect, tuple | list) else (effect,):
            add_to = getattr(e, "add_to", None)
            if add_to is None:
                raise TypeError(f"can only add jaxfric effects to a model, not {type(e).__name__}")
            model = add_to(model)
        return model

    def without_effects(self) -> "AbstractFrictionModel":
        """The friction model itself, without added effects (`jaxfric.effects`): this
        model, or the base of a model with effects."""
        return self

    def _simulate(self, motion: Motion) -> SimResult:
        state = self.init_state(motion.x[0])

        def body(state, inp):
            return self.step(state, *inp)

        _, force = jax.lax.scan(body, state, (motion.x, motion.v, motion.dt))
        return SimResult(force=force, parts={}, overflow=jnp.zeros((), jnp.int32))
