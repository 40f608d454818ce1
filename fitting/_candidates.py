"""The candidate effects of a diagnosis: which effects can be switched on in the superset
model (`switchable`: those with a linear parameter, ``param(..., linear=True)``), where a
refit of one starts (`start_effect`, from its `grid` and a regression on the residual),
whether its fitted values are physical (`physical`, ``param(..., physical=(lo, hi))``),
what a diagnosis reports of each option it fitted (`Candidate`), and the one-liner that
adds an effect with its fitted values (`_code`).
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import jaxfric
from jaxfric import effects as fx
from jaxfric._compile import jit

from ._per_run import mean_effect, plain_effect, run_model


@dataclasses.dataclass
class Data:
    """The record every fit uses (SI arrays; `a` and `load` may be None): one run, or
    several runs concatenated in order, run ``i`` being ``lengths[i]`` samples (None: one
    run). Each run is simulated from its own zero state at its own first sample."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    F: np.ndarray
    a: np.ndarray | None = None
    load: np.ndarray | None = None
    lengths: tuple[int, ...] | None = None

    @property
    def n_runs(self) -> int:
        return 1 if self.lengths is None else len(self.lengths)

    def slices(self) -> list[slice]:
        """The samples of each run."""
        if self.lengths is None:
            return [slice(0, self.t.size)]
        ends = np.cumsum(self.lengths)
        return [slice(int(e - n), int(e)) for n, e in zip(self.lengths, ends)]

    def runs(self) -> list["Data"]:
        """Each run on its own."""
        if self.lengths is None:
            return [self]
        return [Data(*(None if arr is None else arr[sl] for arr in
                       (self.t, self.x, self.v, self.F, self.a, self.load)))
                for sl in self.slices()]

    def longest(self) -> "Data":
        return max(self.runs(), key=lambda d: d.t.size)

    def every(self, k: int) -> tuple["Data", np.ndarray]:
        """One sample in `k` of each run, and their indices into this record's samples."""
        return self.take(np.concatenate([np.arange(sl.start, sl.stop, k)
                                         for sl in self.slices()]))

    def take(self, idx) -> tuple["Data", np.ndarray]:
        """The samples `idx` (indices into this record, sorted and made unique; each run
        keeps its own), and those indices."""
        idx = np.unique(np.asarray(idx, int))
        lengths = None if self.lengths is None else tuple(
            int(np.count_nonzero((idx >= sl.start) & (idx < sl.stop))) for sl in self.slices())
        return Data(*(None if arr is None else arr[idx] for arr in
                      (self.t, self.x, self.v, self.F, self.a, self.load)), lengths), idx

    def simulate(self, model, fitted=None) -> np.ndarray:
        """`model`'s force on every run: run ``i`` by `fitting.run_model` ``(model, i)``
        when `fitted` (run indices; default all) holds ``i``, else with its per-run
        parameters at their mean over the `fitted` runs (a run not fitted has no value of
        its own)."""
        fitted = range(self.n_runs) if fitted is None else list(fitted)
        out = []
        for i, d in enumerate(self.runs()):
            m = run_model(model, i) if i in fitted else run_model(model, None, among=fitted)
            out.append(np.asarray(jaxfric.simulate(m, d.t, d.x, d.v, load=d.load, a=d.a)))
        return np.concatenate(out)

    def grid(self, name: str) -> list:
        """The starting grid of effect `name` (`AbstractEffect.grid`), on the longest run."""
        d = self.longest()
        return fx.EFFECTS[name].grid(d.t, d.x, d.v, d.F)


def _linear(effect) -> list[str]:
    effect = plain_effect(effect)
    return [f.name for f in dataclasses.fields(effect) if f.metadata.get("linear")]


def switchable(name: str) -> bool:
    """Whether effect `name` can sit in the superset (it has a linear parameter)."""
    return bool(_linear(fx.EFFECTS[name]))


def _set(effect, values: dict):
    for k, val in values.items():
        effect = eqx.tree_at(lambda e, k=k: getattr(e, k), effect,
                             jnp.asarray(val, float).reshape(jnp.shape(getattr(effect, k))))
    return effect


def _off(effect):
    return _set(effect, {k: np.zeros(np.shape(getattr(effect, k))) for k in _linear(effect)})


@jit
def _term(effect, s):
    return effect.term(s)


def _columns(effect, s) -> np.ndarray:
    """The term's derivative w.r.t. each entry of its linear parameters, (n, q); `s`: the
    signals, or a list of them (one per run, rows concatenated)."""
    if isinstance(s, list):
        return np.concatenate([_columns(effect, one) for one in s])
    zero, cols = _off(effect), []
    for k in _linear(effect):
        z = np.zeros(np.shape(getattr(effect, k)))
        for j in range(z.size):
            one = z.ravel().copy()
            one[j] = 1.0
            cols.append(np.asarray(_term(_set(zero, {k: one.reshape(z.shape)}), s)))
    return np.stack(cols, axis=1)


def _signals(data: Data, base_model):
    """The signals of `base_model` on `data` (`jaxfric.effects.Signals`; a list of them,
    one per run, for several runs)."""
    if data.n_runs > 1:
        return [_signals(d, base_model) for d in data.runs()]
    base = np.asarray(jaxfric.simulate(base_model, data.t, data.x, data.v, load=data.load,
                                       a=data.a))
    dt = np.r_[0.0, np.diff(data.t)]
    a = data.a if data.a is not None else np.r_[0.0, np.diff(data.v) / np.where(
        dt[1:] > 0, dt[1:], 1.0)]
    return fx.Signals(t=jnp.asarray(data.t), x=jnp.asarray(data.x), v=jnp.asarray(data.v),
                      a=jnp.asarray(a), dt=jnp.asarray(dt),
                      dx=jnp.asarray(np.r_[0.0, np.diff(data.x)]), t0=jnp.asarray(data.t[0]),
                      base=jnp.asarray(base),
                      static=jnp.asarray(fx.static_force(base_model, jnp.asarray(data.v),
                                                         jnp.asarray(base))),
                      load=None if data.load is None else jnp.asarray(data.load))


def start_effect(name: str, data: Data, base_model, resid: np.ndarray, s=None,
                 weights=None):
    """Effect `name` at the grid point whose term best regresses `resid` (N, measured minus
    model) on the samples of weight > 0 (`weights`; default all), its linear parameters at
    that regression's values (clipped to their physical range). `s`: the signals of
    `base_model` on `data`, if already computed."""
    s = _signals(data, base_model) if s is None else s
    keep = slice(None) if weights is None else np.asarray(weights) > 0
    resid = resid[keep]
    best, best_gain = None, -np.inf
    for e in data.grid(name):
        X = _columns(e, s)[keep]
        w, *_ = np.linalg.lstsq(X, resid, rcond=None)
        gain = float(resid @ resid - np.sum((resid - X @ w) ** 2))
        if gain > best_gain:
            best, best_gain, best_w = e, gain, w
    values, k = {}, 0
    for f in dataclasses.fields(best):
        if not f.metadata.get("linear"):
            continue
        size = int(np.size(getattr(best, f.name)))
        lo, hi = f.metadata.get("physical") or (-np.inf, np.inf)
        values[f.name] = np.clip(best_w[k:k + size], lo, hi)
        k += size
    return _set(best, values)


def physical(effect, data: Data) -> str:
    """Why `effect`'s fitted values are not physical ("" when they are), from each
    field's ``physical`` range (of every run's value, for a per-run parameter), then
    from the effect's own limits on `data`'s longest run (`AbstractEffect.unphysical`)."""
    wrapped, effect = effect, plain_effect(effect)
    for f in dataclasses.fields(effect):
        rng = f.metadata.get("physical")
        if rng is None:
            continue
        # every run's value: a relative per-run leaf stores all runs' but its reference's
        val = np.asarray(wrapped.values(f.name) if f.name in getattr(wrapped, "fields", ())
                         else getattr(effect, f.name), float)
        if np.any(val < rng[0]) or np.any(val > rng[1]):
            return f"{f.name} = {np.round(val, 6).tolist()} outside [{rng[0]}, {rng[1]}]"
    d = data.longest()
    return effect.unphysical(d.t, d.x, d.v, d.F)



def _code(effect) -> str:
    """The one-liner that adds `effect` with its screened values (a per-run parameter at
    its mean over the runs)."""
    effect = mean_effect(effect)
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
