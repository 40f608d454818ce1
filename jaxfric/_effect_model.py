"""The machinery of `jaxfric.effects`: what an effect sees (`Signals`), the base class of
every effect (`AbstractEffect`), and a model plus effects (`WithEffects`, ``model + effect``).
`jaxfric.effects` holds the named effects and re-exports these.
"""

import abc
import dataclasses
from typing import Any, ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from ._models._base import AbstractFrictionModel, SimResult
from ._numerics import safe_div, tangent_zeros
from .motion import Motion


class Signals(eqx.Module):
    """What an effect sees per sample: ``t`` (s), ``x`` (m), ``v`` (m/s), ``a`` (m/s^2),
    ``dt`` (s) and ``dx`` (m) since the previous sample (0 at the first), ``t0`` (first
    sample time, s), ``base`` (the base model's force, N) and ``static`` (its Stribeck curve
    ``s(v)`` without the viscous term, N; the base force for a model without one);
    ``load`` (the transmitted load, N or N m, or ``None`` when none was given)."""

    t: Array
    x: Array
    v: Array
    a: Array
    dt: Array
    dx: Array
    t0: Array
    base: Array
    static: Array
    load: Array | None = None


class AbstractEffect(eqx.Module):
    """A named additive force term; see the module docstring for the library."""

    name: ClassVar[str]

    @abc.abstractmethod
    def term(self, s: Signals) -> Array:
        """The effect's force (N) for a whole trajectory (arrays in `s`)."""

    def init_state(self, x0: Array) -> Any:
        """State of a stateful effect at the first sample (None: memoryless)."""
        return None

    def step_term(self, state: Any, s: Signals) -> tuple[Any, Array]:
        """One sample (scalars in `s`): ``(new_state, force)``; memoryless by default."""
        return state, self.term(s)

    def describe(self) -> str:
        """One line with the effect's parameter values and units."""
        return self.name

    @classmethod
    def grid(cls, t, x, v, F) -> list["AbstractEffect"]:
        """Starting instances for a diagnosis's search, from the record (NumPy arrays ``t``
        s, ``x`` m, ``v`` m/s, ``F`` N): one per point of a grid over the effect's nonlinear
        parameters; the search sets the linear ones (``param(..., linear=True)``). Default:
        one instance, for an effect whose parameters are all linear."""
        return [cls()]

    def unphysical(self, t, x, v, F) -> str:
        """Why this fitted instance is not the effect it names on the record (NumPy arrays
        as for `grid`); "" when it is. For a limit that depends on the record (a time
        constant against its duration), where a field's fixed ``physical`` range cannot
        say it. Default: ""."""
        return ""

    def add_to(self, model: AbstractFrictionModel) -> "WithEffects":
        """``model + self``: `model` with this effect appended."""
        return add_effects(model, self)


def static_force(model, v: Array, force: Array) -> Array:
    """`model`'s Stribeck curve ``s(v)`` (N) without viscous term, or `force` if it has none."""
    stribeck = getattr(model, "stribeck", None)
    return stribeck(v) if stribeck is not None else force


def _acceleration(v: Array, dt: Array) -> Array:
    """Backward difference of `v` (m/s^2); 0 at the first sample."""
    dv = jnp.diff(v, prepend=v[:1])
    return safe_div(dv, dt)


def _linear(effect) -> list[str]:
    return [f.name for f in dataclasses.fields(effect) if f.metadata.get("linear")]


@eqx.filter_custom_jvp
def _term(effect: AbstractEffect, s: Signals) -> Array:
    """``effect.term(s)``, with a JVP that skips the signals' tangents where the effect is
    switched off (`_term_jvp`)."""
    return effect.term(s)


@_term.def_jvp
def _term_jvp(primals, tangents):
    # A term is linear in its linear parameters (``param(..., linear=True)``): where all of
    # them are 0, the term is 0 whatever the signals and the other parameters, and its
    # tangent is the linear parameters' alone, ``sum_j dw_j * b_j``. A diagnosis's
    # superset model holds most effects there, and a fit differentiates the signals (the
    # base force, its Stribeck curve) along every free coordinate: a friction lag's
    # recurrence or a drift carried them all at 0 for nothing (the Jacobian of a 20-element
    # GMS with the ten held effects on 9738 samples: 21.7 ms, 15.2 ms without). Equal to
    # the plain JVP wherever that is finite
    # (tests/core/test_effect_terms.py); `lax.cond`, so one branch runs (both under a vmap
    # over effect values).
    effect, s = primals
    t_effect, t_s = (tangent_zeros(p, t) for p, t in zip(primals, tangents))

    def full(_):
        return jax.jvp(lambda e, ss: e.term(ss), (effect, s), (t_effect, t_s))

    names = _linear(effect)
    if not names:
        return full(None)

    def off(_):
        # the other parameters and the signals enter as constants: no tangents for them
        def term(values):
            return eqx.tree_at(lambda e: [getattr(e, n) for n in names], effect,
                               values).term(s)

        return jax.jvp(term, ([getattr(effect, n) for n in names],),
                       ([getattr(t_effect, n) for n in names],))

    zero = jnp.all(jnp.stack([jnp.all(jnp.asarray(getattr(effect, n)) == 0) for n in names]))
    return jax.lax.cond(zero, off, full, None)


class WithEffectsState(eqx.Module):
    base: Any
    effects: tuple
    x_prev: Array
    v_prev: Array
    t: Array


class WithEffects(AbstractFrictionModel):
    """A friction model plus additive effects: ``force = base + sum(effect terms)``.

    Built with ``model + effect`` (or ``model + (e1, e2)``); adding to a `WithEffects`
    appends. `parts` of the full output hold the base model's parts, ``"base"`` and one
    entry per effect name.
    """

    base: AbstractFrictionModel
    effects: tuple[AbstractEffect, ...]

    def __check_init__(self):
        names = [e.name for e in self.effects]
        if len(set(names)) != len(names):
            raise ValueError(f"an effect was added twice: {names}")

    def _simulate(self, motion: Motion) -> SimResult:
        r = self.base._simulate(motion)
        a = _acceleration(motion.v, motion.dt) if motion.a is None else motion.a
        s = Signals(t=motion.t, x=motion.x, v=motion.v, a=a, dt=motion.dt, dx=motion.dx,
                    t0=motion.t[0], base=r.force,
                    static=static_force(self.base, motion.v, r.force), load=motion.load)
        terms = {e.name: _term(e, s) for e in self.effects}
        force = r.force + sum(terms.values())
        return SimResult(force=force, parts={**r.parts, "base": r.force, **terms},
                         overflow=r.overflow)

    def init_state(self, x0: ArrayLike = 0.0) -> WithEffectsState:
        base = self.base.init_state(x0)
        x0 = jnp.asarray(x0, dtype=jnp.asarray(0.0).dtype)
        zero = jnp.zeros_like(x0)
        return WithEffectsState(base=base, effects=tuple(e.init_state(x0) for e in self.effects),
                                x_prev=x0, v_prev=zero, t=zero)

    def step(self, state: WithEffectsState, x, v, dt, load=None):
        """One sample, as the base model's `step`; `load` (N or N m) for the effects
        that read it (`LoadFriction`)."""
        base_state, f = self.base.step(state.base, x, v, dt)
        x, v, dt = jnp.asarray(x), jnp.asarray(v), jnp.asarray(dt)
        t = state.t + dt
        s = Signals(t=t, x=x, v=v, a=safe_div(v - state.v_prev, dt), dt=dt,
                    dx=x - state.x_prev, t0=jnp.zeros_like(t), base=f,
                    static=static_force(self.base, v, f),
                    load=None if load is None else jnp.asarray(load))
        new, total = [], f
        for e, st in zip(self.effects, state.effects):
            st, term = e.step_term(st, s)
            new.append(st)
            total = total + term
        return WithEffectsState(base=base_state, effects=tuple(new), x_prev=x, v_prev=v,
                                t=t), total

    def __add__(self, other):
        return WithEffects(self.base, self.effects + _as_effects(other))

    def without_effects(self) -> AbstractFrictionModel:
        return self.base


def _as_effects(other) -> tuple[AbstractEffect, ...]:
    items = other if isinstance(other, tuple | list) else (other,)
    for e in items:
        if not isinstance(e, AbstractEffect):
            raise TypeError(f"can only add jaxfric effects to a model, not {type(e).__name__}")
    return tuple(items)


def add_effects(model: AbstractFrictionModel, other) -> WithEffects:
    """``model + other`` (`AbstractEffect.add_to` calls this)."""
    if isinstance(model, WithEffects):
        return model + other
    return WithEffects(model, _as_effects(other))
