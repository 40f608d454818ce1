"""The candidate effects a diagnosis screens: for each effect of `jaxfric.effects`, the
instances to try (a grid over its nonlinear parameters), the regression columns of its
linear parameters, their physical bounds, and the `Candidate` a screen returns.
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from jaxfric import effects as fx
from jaxfric._compile import jit


def _signals(t, x, v, base, static, load=None, a=None):
    """The `jaxfric.effects.Signals` of concrete arrays; `a` None: the backward difference
    of `v`, as the model takes it."""
    dt = np.r_[0.0, np.diff(t)]
    if a is None:
        a = np.r_[0.0, np.diff(v) / np.where(dt[1:] > 0, dt[1:], 1.0)]
    return fx.Signals(t=jnp.asarray(t), x=jnp.asarray(x), v=jnp.asarray(v), a=jnp.asarray(a),
                      dt=jnp.asarray(dt), dx=jnp.asarray(np.r_[0.0, np.diff(x)]),
                      t0=jnp.asarray(t[0]), base=jnp.asarray(base),
                      static=jnp.asarray(static),
                      load=None if load is None else jnp.asarray(load))


#: The shortest settling time of a drift is the record's duration over this: the screen's
#: grid starts there, and the diagnosis's refits hold the drift to it (`fitting._diagnose`).
DRIFT_SPAN_RATIO = 10


def _grid(name, t, x, v, F):
    """Instances of effect `name` to screen: unit linear parameters, a grid over the
    nonlinear ones (SI)."""
    speed = np.abs(v[v != 0]) if np.any(v != 0) else np.ones(1)
    level = float(np.median(np.abs(F))) or 1.0
    dx = np.abs(np.diff(x))
    dx = dx[dx > 0]
    if name == "cogging":
        lo = max(8 * (np.median(dx) if dx.size else 1e-6), np.ptp(x) / 2000)
        periods = np.geomspace(lo, np.ptp(x) / 2, 160)
        return [fx.Cogging(cog_sin=1.0, cog_cos=1.0, period=p) for p in periods]
    if name == "stribeck":
        vs = np.geomspace(np.quantile(speed, 0.02), np.quantile(speed, 0.98), 24)
        return [fx.StribeckHump(dF_str=1.0, v_str=s) for s in vs]
    if name == "presliding":
        dmax = np.ptp(x) / 2
        travel = np.geomspace(max(dmax * 1e-4, 1e-9), dmax, 30)  # 2*F_pre/k_pre
        return [fx.Presliding(F_pre=level, k_pre=2 * level / d) for d in travel]
    if name == "drift":  # linear (wear), or settling (a warm-up) over a tenth to twice the record
        span = max(float(t[-1] - t[0]), 1e-9)
        return [fx.Drift(drift_rate=1.0, drift_decay=d)
                for d in (0.0, *(1.0 / np.geomspace(span / DRIFT_SPAN_RATIO, 2 * span, 10)))]
    if name == "friction_lag":
        span = t[-1] - t[0]
        taus = np.geomspace(max(np.median(np.diff(t)), 1e-6), span / 10, 24)
        return [fx.FrictionLag(lag_gain=1.0, tau=tau) for tau in taus]
    if name == "ripple":
        return [fx.Ripple(rip_sin=np.ones(3), rip_cos=np.ones(3), period=2 * np.pi / k)
                for k in _ripple_counts(x, dx)]
    if name == "position_dependence":
        return [fx.PositionDependence.for_travel(x, pos_1=1.0, pos_2=1.0)]
    if name == "position_load":
        return [fx.PositionLoad.for_travel(x, load_1=1.0, load_2=1.0)]
    cls = fx.EFFECTS[name]
    return [cls()]


def _ripple_counts(x, dx) -> np.ndarray:
    """Ripples per revolution to screen (the period ``2 pi / k`` divides a turn): every
    integer `k` from the first whose period fits in the travel (`ptp(x)`) up to the last
    whose period is long against the sampling (8 steps of the median `dx`), at most
    `RIPPLE_MAX` (720: a period of half a degree). Every integer, as a count one off drifts
    by a whole period over as many periods as the travel holds."""
    lo = max(8 * (np.median(dx) if dx.size else 1e-6), np.ptp(x) / 2000)
    k_min = max(1, int(np.ceil(2 * np.pi / max(np.ptp(x), 1e-12))))
    k_max = min(RIPPLE_MAX, int(np.floor(2 * np.pi / lo)))
    return np.arange(k_min, max(k_min, k_max) + 1)


#: The most ripples per revolution a diagnosis screens (`_ripple_counts`).
RIPPLE_MAX = 720


#: Parameters entering the term linearly (the regression's unknowns); effects not listed
#: are scaled as a whole (one column: the term itself).
_LINEAR = {
    "viscous": ("c_visc",), "quadratic_drag": ("c_drag",), "stribeck": ("dF_str",),
    "inertia": ("mass",), "offset": ("offset",), "asymmetry": ("asym",),
    "cogging": ("cog_sin", "cog_cos"), "position_dependence": ("pos_1", "pos_2"),
    "position_load": ("load_1", "load_2"),
    "drift": ("drift_rate",), "friction_lag": ("lag_gain",),
    "ripple": ("rip_sin", "rip_cos"), "angle_load": ("g_sin", "g_cos"),
    "load_friction": ("k_load",),
}


@jit
def _term(effect, s):
    return effect.term(s)


def _columns(effect, s):
    """Effect term's derivative w.r.t. its linear parameters (n, q); for an effect with
    none, the term itself (n, 1). Linear parameters are evaluated at 1."""
    names = _LINEAR.get(effect.name)
    if not names:
        return np.asarray(_term(effect, s))[:, None]
    zero = effect
    for name in names:
        zero = eqx.tree_at(lambda e, n=name: getattr(e, n), zero,
                           jnp.zeros_like(getattr(effect, name)))
    cols = []
    for name in names:  # one column per entry of a vector parameter (ripple's harmonics)
        z = getattr(zero, name)
        for j in range(z.size):
            one = z.ravel().at[j].set(1.0).reshape(z.shape)
            unit = eqx.tree_at(lambda e, n=name: getattr(e, n), zero, one)
            cols.append(np.asarray(_term(unit, s)))
    return np.stack(cols, axis=1)


#: Physical ranges of linear parameters (the lag gain is a fraction of the force).
#: Dissipative terms (viscous, drag) and a Stribeck hump (extra static friction) are not
#: negative: with a negative coefficient they would stand in for model mismatch, not physics.
_BOUNDS = {"friction_lag": (0.0, 1.0), "inertia": (0.0, np.inf),  # a mass is not negative
           "load_friction": (0.0, np.inf),  # friction grows with the load
           "viscous": (0.0, np.inf), "quadratic_drag": (0.0, np.inf), "stribeck": (0.0, np.inf)}


def _with_linear(effect, w):
    names = _LINEAR.get(effect.name)
    if not names:
        if effect.name == "presliding":  # scale the element's force: F_pre * w
            return eqx.tree_at(lambda e: e.F_pre, effect, jnp.abs(effect.F_pre * w[0]))
        return effect
    if effect.name in _BOUNDS:  # strictly inside a finite range (the fit's bounded transform)
        lo, hi = _BOUNDS[effect.name]
        if np.isfinite(hi - lo):
            lo, hi = lo + 1e-3 * (hi - lo), hi - 1e-3 * (hi - lo)
        w = np.clip(w, lo, hi)
    k = 0
    for name in names:
        shape = jnp.shape(getattr(effect, name))
        size = int(np.prod(shape))
        value = jnp.asarray(np.asarray(w[k:k + size], float).reshape(shape))
        effect = eqx.tree_at(lambda e, n=name: getattr(e, n), effect, value)
        k += size
    return effect


def _code(effect) -> str:
    """The one-liner that adds `effect` with its screened values."""
    def value(v):
        a = np.asarray(v, float)
        return f"{float(a):.4g}" if a.ndim == 0 else "(" + ", ".join(f"{u:.4g}" for u in a) + ")"

    args = ", ".join(f"{f.name}={value(getattr(effect, f.name))}"
                     for f in dataclasses.fields(effect))
    return f"model + jaxfric.effects.{type(effect).__name__}({args})"


@dataclasses.dataclass
class Candidate:
    """One screened effect: `effect` (a `jaxfric.effects` instance with the regression's
    values), `score` (fraction of the held-out residual SSE removed), `t_stat` (of the
    share of SSE removed per held-out block), `significant`, `evidence` (plain words),
    `code` (how to add it)."""

    name: str
    effect: fx.AbstractEffect
    score: float
    t_stat: float
    significant: bool
    evidence: str
    code: str

    def to_json(self) -> dict:
        def num(v):  # JSON has no NaN: a candidate not cross-validated has no score
            return float(v) if np.isfinite(v) else None

        return {"effect": self.name, "score": num(self.score), "t_stat": num(self.t_stat),
                "significant": self.significant, "evidence": self.evidence, "code": self.code}
