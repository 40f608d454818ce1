"""Named physical effects that can be added to any friction model: ``model + effect``.

Each effect is a small parameterised force term (N) computed from the motion and, for the
effects that scale friction, from the base model's own force. ``model + effect`` returns a
`WithEffects` model, an ordinary jaxfric model: `jaxfric.simulate`, ``jax.grad``, ``vmap``
and the `fitting` package work on it unchanged, so the effect's parameters are fitted jointly
with the model's.

Memoryless effects:

| name | term (N) | parameters (SI) |
|---|---|---|
| `viscous` | ``c_visc * v`` | c_visc N s/m |
| `quadratic_drag` | ``c_drag * v * abs(v)`` | c_drag N s^2/m^2 |
| `stribeck` | ``dF_str * exp(-(v/v_str)^2) * sign(v)`` | dF_str N, v_str m/s |
| `inertia` | ``mass * a`` | mass kg |
| `offset` | ``offset`` | offset N |
| `asymmetry` | ``asym * abs(F_base)`` | asym (1) |
| `cogging` | ``cog_sin sin(2 pi x/P) + cog_cos cos(...)`` | cog_sin N, cog_cos N, P m |
| `position_dependence` | ``F_base * (pos_1 u + pos_2 u^2)`` | pos_1, pos_2 (1) |
| `position_load` | ``load_1 u + load_2 (u^2 - 1/3)`` | load_1 N, load_2 N |
| `drift` | ``F_base * (drift_level + drift_rate * (t - t_0))`` | drift_rate 1/s, drift_level (1) |
| `ripple` | ``sum_k rip_sin_k sin(2 pi k x/P) + rip_cos_k cos(...)`` | rip_sin, rip_cos N, P m |
| `angle_load` | ``g_sin sin(x) + g_cos cos(x)`` (x an angle, rad) | g_sin N, g_cos N |
| `load_friction` | ``k_load * abs(L) * clip(F_base / abs(s(v)), -1, 1)`` | k_load (1) |

``a`` is the backward difference of ``v`` (the same in `simulate` and `step`), ``u`` the
position normalised to [-1, 1] over the travel given at construction, ``t_0`` the first
sample time, ``L`` the transmitted load (N, or N m on a rotary axis: the ``load`` column
of a file, ``simulate(..., load=...)``). Parameter names are distinct from every model's,
so fitted results keep them apart.

Stateful effects: `presliding` (an elasto-plastic element, ``F_pre`` N and ``k_pre`` N/m,
replacing the Coulomb jump at reversals by a spring) and `friction_lag` (the force follows
the base model's Stribeck curve through a first-order lag: ``lag_gain`` (1), ``tau`` s).
"""

import math
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ._effect_model import (
    _acceleration as _acceleration,
    _as_effects as _as_effects,
    AbstractEffect as AbstractEffect,
    add_effects as add_effects,
    Signals as Signals,
    static_force as static_force,
    WithEffects as WithEffects,
    WithEffectsState as WithEffectsState,
)
from ._fields import param
from ._numerics import linear_recurrence, safe_div


_INF = math.inf

#: The shortest settling time of a drift a diagnosis searches is the record's duration
#: over this (`Drift.grid`).
DRIFT_SPAN_RATIO = 10

#: The most ripples per revolution a diagnosis searches (`Ripple.grid`).
RIPPLE_MAX = 720


def _steps(x) -> np.ndarray:
    dx = np.abs(np.diff(np.asarray(x, float)))
    return dx[dx > 0]


def _shortest_period(x) -> float:
    """The shortest position period (m) a record resolves: 8 of its median position steps,
    and at least 1/2000 of the travel."""
    dx = _steps(x)
    return max(8 * (float(np.median(dx)) if dx.size else 1e-6), float(np.ptp(x)) / 2000)


class Viscous(AbstractEffect):
    """``c_visc * v``: extra linear damping, N s/m."""

    name: ClassVar[str] = "viscous"
    c_visc: Array = param("N s/m", default=0.0, linear=True, physical=(0.0, _INF))

    def term(self, s):
        return self.c_visc * s.v

    def describe(self):
        return f"viscous {float(self.c_visc):.4g} N s/m"


class QuadraticDrag(AbstractEffect):
    """``c_drag * v * |v|``, N s^2/m^2."""

    name: ClassVar[str] = "quadratic_drag"
    c_drag: Array = param("N s^2/m^2", default=0.0, linear=True, physical=(0.0, _INF))

    def term(self, s):
        return self.c_drag * s.v * jnp.abs(s.v)

    def describe(self):
        return f"quadratic drag {float(self.c_drag):.4g} N s^2/m^2"


class StribeckHump(AbstractEffect):
    """``dF_str * exp(-(v/v_str)^2) * sign(v)``: more (or less) friction at low speed."""

    name: ClassVar[str] = "stribeck"
    dF_str: Array = param("N", default=0.0, linear=True, physical=(0.0, _INF))
    v_str: Array = param("m/s", constraint="positive", default=1e-3)

    @classmethod
    def grid(cls, t, x, v, F):  # the speeds the record covers
        speed = np.abs(v[v != 0]) if np.any(v != 0) else np.ones(1)
        vs = np.geomspace(np.quantile(speed, 0.02), np.quantile(speed, 0.98), 24)
        return [cls(v_str=s) for s in vs]

    def term(self, s):
        return self.dF_str * jnp.exp(-(safe_div(s.v, self.v_str) ** 2)) * jnp.sign(s.v)

    def describe(self):
        return (f"Stribeck hump {float(self.dF_str):.4g} N below "
                f"{float(self.v_str) * 1e3:.3g} mm/s")


class Inertia(AbstractEffect):
    """``mass * a``: a force proportional to acceleration (kg): a mass not subtracted from
    a drive force, or a mis-calibrated one."""

    name: ClassVar[str] = "inertia"
    mass: Array = param("kg", default=0.0, linear=True, physical=(0.0, _INF))

    def term(self, s):
        return self.mass * s.a

    def describe(self):
        return f"inertia {float(self.mass):.4g} kg"


class Offset(AbstractEffect):
    """A constant force (N): gravity on an inclined axis, a sensor zero. Fitted to several
    runs, each run has its own (``per_run``): a sensor zero or a gravity compensation is
    set again for every run."""

    name: ClassVar[str] = "offset"
    offset: Array = param("N", default=0.0, linear=True, per_run=True)

    def term(self, s):
        return jnp.broadcast_to(self.offset, s.t.shape)

    def describe(self):
        return f"offset {float(self.offset):.4g} N"


class Asymmetry(AbstractEffect):
    """``asym * |F_base|``: friction higher by ``1 + asym`` in the positive direction and
    lower by ``1 - asym`` in the negative one (dimensionless)."""

    name: ClassVar[str] = "asymmetry"
    asym: Array = param("-", default=0.0, linear=True, physical=(-1.0, 1.0))

    def term(self, s):
        return self.asym * jnp.abs(s.base)

    def describe(self):
        return f"asymmetry {100 * float(self.asym):+.3g} % (positive vs negative direction)"


class Cogging(AbstractEffect):
    """``cog_sin * sin(2 pi x / period) + cog_cos * cos(2 pi x / period)`` (N; period m)."""

    name: ClassVar[str] = "cogging"
    cog_sin: Array = param("N", default=0.0, linear=True)
    cog_cos: Array = param("N", default=0.0, linear=True)
    period: Array = param("m", constraint="positive", default=1e-3)

    @classmethod
    def grid(cls, t, x, v, F):  # from the shortest resolved period to half the travel
        periods = np.geomspace(_shortest_period(x), np.ptp(x) / 2, 160)
        return [cls(period=p) for p in periods]

    def term(self, s):
        phase = 2 * jnp.pi * safe_div(s.x, self.period)
        return self.cog_sin * jnp.sin(phase) + self.cog_cos * jnp.cos(phase)

    def describe(self):
        amp = float(jnp.hypot(self.cog_sin, self.cog_cos))
        return f"cogging {amp:.4g} N amplitude, period {float(self.period) * 1e3:.4g} mm"


def _travel(x: ArrayLike) -> dict[str, float]:
    """``x_mid`` and ``x_half`` (m) of the travel `x`, for the position effects' ``u``."""
    x = jnp.asarray(x)
    lo, hi = float(jnp.min(x)), float(jnp.max(x))
    return {"x_mid": 0.5 * (lo + hi), "x_half": max(0.5 * (hi - lo), 1e-12)}


class PositionDependence(AbstractEffect):
    """``F_base * (pos_1 u + pos_2 u^2)``, ``u = (x - x_mid) / x_half`` in [-1, 1] over the
    travel (`x_mid`, `x_half` in m, fixed at construction: `for_travel`)."""

    name: ClassVar[str] = "position_dependence"
    pos_1: Array = param("-", default=0.0, linear=True)
    pos_2: Array = param("-", default=0.0, linear=True)
    x_mid: float = eqx.field(static=True, default=0.0)
    x_half: float = eqx.field(static=True, default=1.0)

    @classmethod
    def for_travel(cls, x: ArrayLike, **params) -> "PositionDependence":
        return cls(**_travel(x), **params)

    @classmethod
    def grid(cls, t, x, v, F):
        return [cls.for_travel(x)]

    def term(self, s):
        u = (s.x - self.x_mid) / self.x_half
        return s.base * (self.pos_1 * u + self.pos_2 * u**2)

    def describe(self):
        return (f"friction level varies along the travel by {100 * float(self.pos_1):+.3g} % "
                f"(linear) and {100 * float(self.pos_2):+.3g} % (quadratic) at the ends")


class PositionLoad(AbstractEffect):
    """``load_1 u + load_2 (u^2 - 1/3)`` (N): a force that depends on the position but not on
    the friction level, added to it (gravity along an inclined or curved guide, a cable or
    spring load, a counterweight). ``u = (x - x_mid) / x_half`` in [-1, 1] over the travel,
    as for `PositionDependence` (`for_travel`); the quadratic part has no mean over the
    travel, so that it does not stand in for an `Offset`."""

    name: ClassVar[str] = "position_load"
    load_1: Array = param("N", default=0.0, linear=True)
    load_2: Array = param("N", default=0.0, linear=True)
    x_mid: float = eqx.field(static=True, default=0.0)
    x_half: float = eqx.field(static=True, default=1.0)

    @classmethod
    def for_travel(cls, x: ArrayLike, **params) -> "PositionLoad":
        return cls(**_travel(x), **params)

    @classmethod
    def grid(cls, t, x, v, F):
        return [cls.for_travel(x)]

    def term(self, s):
        u = (s.x - self.x_mid) / self.x_half
        return self.load_1 * u + self.load_2 * (u**2 - 1.0 / 3.0)

    def describe(self):
        return (f"position-dependent load {float(self.load_1):+.4g} N (linear) and "
                f"{float(self.load_2):+.4g} N (quadratic) at the ends of the travel")


class Ripple(AbstractEffect):
    """A position ripple with harmonics: ``sum_k rip_sin[k] sin(2 pi (k+1) x / period) +
    rip_cos[k] cos(...)`` (N, or N m on a rotary axis; `period` in m or rad). On a joint the
    period divides a revolution: ``2 pi / i`` for a ripple `i` times per turn (a gear of ratio
    `i` seen on the output, a motor's cogging ``2 pi / (poles i)``); the harmonics (as many as
    the length of `rip_sin`, three by default) shape the ripple that one sine cannot."""

    name: ClassVar[str] = "ripple"
    rip_sin: Array = param("N", default=(0.0, 0.0, 0.0), linear=True)
    rip_cos: Array = param("N", default=(0.0, 0.0, 0.0), linear=True)
    period: Array = param("m", constraint="positive", default=2 * 3.141592653589793)

    @classmethod
    def grid(cls, t, x, v, F):
        """Every integer count ``k`` of ripples per revolution (period ``2 pi / k``) from
        the first whose period fits in the travel to the shortest resolved period, at most
        `RIPPLE_MAX`: a count one off drifts by a whole period over the travel."""
        k_min = max(1, int(np.ceil(2 * np.pi / max(float(np.ptp(x)), 1e-12))))
        k_max = min(RIPPLE_MAX, int(np.floor(2 * np.pi / _shortest_period(x))))
        return [cls(period=2 * np.pi / k) for k in range(k_min, max(k_min, k_max) + 1)]

    def __check_init__(self):
        if jnp.shape(self.rip_sin) != jnp.shape(self.rip_cos) or jnp.ndim(self.rip_sin) < 1:
            raise ValueError("ripple: rip_sin and rip_cos must be vectors of one length "
                             "(one entry per harmonic)")

    def term(self, s):
        k = jnp.arange(1, jnp.shape(self.rip_sin)[-1] + 1, dtype=jnp.result_type(s.x))
        phase = 2 * jnp.pi * safe_div(s.x, self.period)[..., None] * k
        return jnp.sum(self.rip_sin * jnp.sin(phase) + self.rip_cos * jnp.cos(phase), axis=-1)

    def describe(self):
        amps = ", ".join(f"{float(a):.3g}" for a in jnp.hypot(self.rip_sin, self.rip_cos))
        per = float(self.period)
        turn = f" ({2 * math.pi / per:.4g} per 2 pi)" if per < 2 * math.pi + 1e-9 else ""
        return f"ripple {amps} N amplitudes (harmonics 1..), period {per:.4g} m{turn}"


class AngleLoad(AbstractEffect):
    """``g_sin sin(x) + g_cos cos(x)`` with `x` an angle (rad): a torque that depends on the
    joint angle as gravity on a link does (``m g r cos(q + phi)``), or a spring balancer; N m
    on a rotary axis (`position_load` is the polynomial form for a linear travel)."""

    name: ClassVar[str] = "angle_load"
    g_sin: Array = param("N", default=0.0, linear=True)
    g_cos: Array = param("N", default=0.0, linear=True)

    def term(self, s):
        return self.g_sin * jnp.sin(s.x) + self.g_cos * jnp.cos(s.x)

    def describe(self):
        amp = float(jnp.hypot(self.g_sin, self.g_cos))
        phi = math.degrees(math.atan2(float(self.g_sin), float(self.g_cos)))
        return (f"angle load {float(self.g_sin):+.4g} N sin(q) {float(self.g_cos):+.4g} N cos(q) "
                f"(amplitude {amp:.4g} N, its maximum at q = {-phi:.4g} deg)")


class LoadFriction(AbstractEffect):
    """Friction that grows with the transmitted load: ``k_load * |L| * clip(F_base /
    |s(v)|, -1, 1)``, ``L`` the load signal (a file's ``load`` column: a normal force in
    N, or a joint's load or motor torque in N m) and `k_load` dimensionless (load in the
    unit of the friction force: N per N, N m per N m).

    Why this form: Coulomb friction is proportional to the normal force, and in a gear
    (harmonic drive, worm or planetary) the tooth and bearing normal forces grow with the
    transmitted torque, so the Coulomb level of a robot joint grows about linearly with
    ``|load torque|`` (Bittencourt, Wernholt, Sander-Tavallaey and Brogardh, "An extended
    friction model to capture load and temperature effects in robot joints", IROS 2010;
    Hamon, Gautier and Garrec, "Dynamic identification of robots with a dry friction model
    depending on load and velocity", IROS 2010: ``tau_f = (Fc + k |tau_load|) sign(qd) +
    Fv qd``). The sign of the load does not matter, only its size, hence ``|L|``.
    The direction factor is the base model's force over its Stribeck level, clipped to
    [-1, 1]: ``sign(v)`` while sliding, as in those papers, and for a model with presliding
    memory (two-state, GMS, LuGre) the fraction of the level it has reached since the last
    reversal, so the extra friction follows the same hysteresis instead of adding a jump
    at every reversal; at rest it holds. A model simulated without a load signal raises
    `ValueError` (`jaxfric.simulate(..., load=...)`)."""

    name: ClassVar[str] = "load_friction"
    k_load: Array = param("-", default=0.0, linear=True, physical=(0.0, _INF))

    def term(self, s):
        if s.load is None:
            raise ValueError(
                "the load_friction effect needs the load signal: pass "
                "jaxfric.simulate(..., load=L) (a file's 'load' column, N or N m)")
        direction = jnp.clip(safe_div(s.base, jnp.abs(s.static)), -1.0, 1.0)
        return self.k_load * jnp.abs(s.load) * direction

    def describe(self):
        return (f"load-dependent friction: {100 * float(self.k_load):+.3g} % of the "
                "transmitted load |load| added to the friction level")


class Drift(AbstractEffect):
    """``F_base * (drift_level + drift_rate * (t - t0) * phi(drift_decay * (t - t0)))`` with
    ``phi(u) = (1 - exp(-u)) / u`` (``phi(0) = 1``): the friction level changing slowly over
    time, 1/s. With ``drift_decay = 0`` (the default) the change is linear (wear); with
    ``drift_decay = 1/tau > 0`` it starts at `drift_rate` and settles at
    ``drift_rate * tau`` with time constant ``tau`` (a warm-up). A negative decay is an
    accelerating change. `drift_level` (a fraction of ``F_base``) is where the level starts
    in a run (its thermal state, the wear since the last run): one run cannot tell it from
    the base friction, so it is per run relative to the first (``per_run="relative"``,
    `jaxfric._fields.param`): 0 in a fit of one run and for run 1 of several."""

    name: ClassVar[str] = "drift"
    drift_rate: Array = param("1/s", default=0.0, linear=True)
    drift_decay: Array = param("1/s", default=0.0)
    drift_level: Array = param("-", default=0.0, physical=(-1.0, 1.0), per_run="relative")

    @classmethod
    def grid(cls, t, x, v, F):
        """Linear (wear), or settling (a warm-up) over a tenth to twice the record."""
        span = _span(t)
        taus = np.geomspace(span / DRIFT_SPAN_RATIO, 2 * span, 10)
        return [cls(drift_decay=d) for d in (0.0, *(1.0 / taus))]

    def unphysical(self, t, x, v, F):
        """A drift changes slowly: its time constant is at least the shortest of `grid`, a
        tenth of the record. A faster change is confined to one stretch of the record (a
        start-up transient, a base model's mismatch while it first loads), so its
        parameters come from that stretch alone, and a blocked cross-validation holding
        that stretch out cannot judge it."""
        shortest = _span(t) / DRIFT_SPAN_RATIO  # the shortest of `grid`
        decay = abs(float(self.drift_decay))
        if decay * shortest <= 1:
            return ""
        return (f"drift_decay = {float(self.drift_decay):.4g} 1/s: time constant "
                f"{1 / decay:.3g} s, under a tenth of the record ({shortest:.3g} s)")

    def term(self, s):
        elapsed = s.t - s.t0
        return s.base * (self.drift_level
                         + self.drift_rate * elapsed * _settling(self.drift_decay * elapsed))

    def describe(self):
        rate = f"{100 * float(self.drift_rate) * 60:+.3g} % per minute"
        level = float(self.drift_level)
        start = f" from {100 * level:+.3g} %" if level != 0 else ""
        decay = float(self.drift_decay)
        if decay == 0:
            return f"friction level drifts{start} by {rate}"
        if decay > 0:
            return (f"friction level drifts{start} by {rate} at first and settles "
                    f"{100 * float(self.drift_rate) / decay:+.3g} % away with time "
                    f"constant {1 / decay:.3g} s (a warm-up)")
        return (f"friction level drifts{start} by {rate} at first, faster with time "
                f"({1 / -decay:.3g} s)")


def _span(t) -> float:
    """The duration of a record of times `t` (s), which sets a drift's time constants
    (`Drift.grid` and `Drift.unphysical` alike)."""
    return max(float(t[-1] - t[0]), 1e-9)


def _settling(u: Array) -> Array:
    """``(1 - exp(-u)) / u``, 1 at ``u = 0``; its series below ``|u| = 1e-4``, so the value
    and the gradient are finite everywhere."""
    small = jnp.abs(u) < 1e-4
    safe = jnp.where(small, 1.0, u)
    return jnp.where(small, 1.0 - u / 2 + u * u / 6, -jnp.expm1(-safe) / safe)


class Presliding(AbstractEffect):
    """An elasto-plastic element that replaces the Coulomb jump at reversals by a spring:
    ``h_n = clip(h_{n-1} + k_pre * dx_n, -F_pre, F_pre)``, term ``h_n - F_pre * sign(v_n)``.

    In sliding the term is 0; after a reversal it starts at ``2*F_pre`` and fades over
    ``2*F_pre/k_pre`` of travel, so a base model that jumps by ``2*Fc`` (Tustin) gets a
    presliding branch of stiffness `k_pre` (N/m) instead; at rest the element holds its
    force (`F_pre` in N)."""

    name: ClassVar[str] = "presliding"
    F_pre: Array = param("N", constraint="positive", default=1.0)
    k_pre: Array = param("N/m", constraint="positive", default=1e6)

    @classmethod
    def grid(cls, t, x, v, F):
        """Reversal travels ``2 F_pre / k_pre`` from 1e-4 of half the travel to all of it, at
        the median force level."""
        level = float(np.median(np.abs(F))) or 1.0
        dmax = float(np.ptp(x)) / 2
        return [cls(F_pre=level, k_pre=2 * level / d)
                for d in np.geomspace(max(dmax * 1e-4, 1e-9), dmax, 30)]

    def init_state(self, x0):
        return jnp.zeros_like(x0)

    def step_term(self, state, s):
        h = jnp.clip(state + self.k_pre * s.dx, -self.F_pre, self.F_pre)
        return h, h - self.F_pre * jnp.sign(s.v)

    def term(self, s):
        def body(h, dx):
            h = jnp.clip(h + self.k_pre * dx, -self.F_pre, self.F_pre)
            return h, h

        _, h = jax.lax.scan(body, jnp.zeros_like(s.x[0]), s.dx)
        return h - self.F_pre * jnp.sign(s.v)

    def describe(self):
        return (f"presliding spring {float(self.k_pre):.4g} N/m up to {float(self.F_pre):.4g} N "
                f"({2e6 * float(self.F_pre) / float(self.k_pre):.3g} um to reverse)")


class FrictionLag(AbstractEffect):
    """The friction *level* follows the base model's Stribeck curve with a first-order lag
    of time constant `tau` (s), as in Hess and Soom's friction lag: with ``m_n = |s(v_n)|``,
    ``y_n = y_{n-1} + (1 - exp(-dt_n/tau)) (m_n - y_{n-1})`` while moving, held at rest
    (``v_n = 0``), starting at ``m`` of the first moving sample; the term is
    ``lag_gain * sign(v_n) * (y_n - m_n)`` (`lag_gain` dimensionless, 1 = fully lagged).
    The direction follows the motion at once (lagging the signed force would smear every
    reversal, which is presliding's job), and only the Stribeck part lags: lagging the
    viscous term too would act like a (negative) mass and trade off against `inertia`."""

    name: ClassVar[str] = "friction_lag"
    lag_gain: Array = param("-", constraint=("interval", 0.0, 1.0), default=0.0,
                          linear=True, physical=(0.0, 1.0))
    tau: Array = param("s", constraint="positive", default=0.1)

    @classmethod
    def grid(cls, t, x, v, F):  # from one sampling interval to a tenth of the record
        span = float(t[-1] - t[0])
        taus = np.geomspace(max(float(np.median(np.diff(t))), 1e-6), span / 10, 24)
        return [cls(tau=tau) for tau in taus]

    def init_state(self, x0):
        return (jnp.zeros_like(x0), jnp.zeros((), bool))

    def step_term(self, state, s):
        y, started = state
        level = jnp.abs(s.static)
        moving = s.v != 0
        a = jnp.where(moving, jnp.where(started, jnp.exp(-safe_div(s.dt, self.tau)), 0.0), 1.0)
        y = a * y + (1.0 - a) * level
        return (y, started | moving), self.lag_gain * jnp.sign(s.static) * (y - level)

    def term(self, s):
        level = jnp.abs(s.static)
        moving = s.v != 0
        first = moving & (jnp.cumsum(moving) == 1)  # the first moving sample starts y
        a = jnp.where(moving, jnp.where(first, 0.0, jnp.exp(-safe_div(s.dt, self.tau))), 1.0)
        y = linear_recurrence(a, (1.0 - a) * level)
        return self.lag_gain * jnp.sign(s.static) * (y - level)

    def describe(self):
        return (f"friction lag: {100 * float(self.lag_gain):.3g} % of the force lags with "
                f"time constant {float(self.tau) * 1e3:.4g} ms")


#: Every effect by name.
EFFECTS: dict[str, type[AbstractEffect]] = {
    cls.name: cls
    for cls in (Viscous, QuadraticDrag, StribeckHump, Presliding, FrictionLag, Inertia, Offset,
                Asymmetry, Cogging, PositionDependence, PositionLoad, Drift, Ripple, AngleLoad,
                LoadFriction)
}

#: Effects of an angle (rad) that a diagnosis screens on rotary data only: a period that
#: divides a revolution and ``sin(q)``, ``cos(q)`` mean nothing on a travel in metres.
ROTARY_EFFECTS: tuple[str, ...] = ("ripple", "angle_load")

#: Effects that read the load signal: a diagnosis screens them only when the data have one.
LOAD_EFFECTS: tuple[str, ...] = ("load_friction",)
