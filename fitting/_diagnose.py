"""Diagnosis: where a fitted model fails, which physical effect is missing, and the error
falling as effects are added.

**Per-regime errors** (`regimes`, `compare`): RMSE overall and in presliding (within a
travel window after a reversal), reversal windows (a time window around each reversal),
sliding by speed band, and acceleration phases.

**Ranking effects** (`diagnose`). The data are cut into `blocks` contiguous time blocks;
every third block is held out, the rest is the training set (interleaved, so that a slow
drift or a position dependence is seen in both). The model is fitted on the training set.
Then, for every candidate effect of `jaxfric.effects`:

1. its nonlinear parameters (cogging period, Stribeck velocity, presliding stiffness, lag
   time constant) are searched on a grid, and for each grid point the residual of the
   training set is regressed, by linear least squares, on the effect's columns *together
   with* the Jacobian columns of the model's own parameters: one Gauss-Newton step of the
   joint fit from the baseline optimum, so an effect only scores for what the model's own
   parameters cannot absorb;
2. the **score** is the fraction of the held-out residual sum of squares that this step
   removes beyond the same step without the effect (a flexible term that only fits noise
   removes nothing from held-out data);
3. it is **significant** when the score is at least `min_score` and the held-out
   improvement is consistent across held-out blocks: the ``t`` statistic of the share of
   each held-out block's SSE that it removes is at least `min_t`. With two effects
   missing, each one's screen sees the other as noise; so the leading candidates (score
   at least `min_score`, at most three) are also regressed together, and one whose
   contribution is consistent in that joint step is significant too.

The best significant effect is added (``model + effect``, starting from the regression's
values), everything is refitted jointly on the training set (twice: from the fitted model,
and from the starting model with the effects, which is not bent by the missing effect; the
better training fit is kept, and a fit that stops at its step limit is restarted while
that still lowers its error by more than 1 %, up to five times),
and the ranking repeats on the new residual until nothing significant is left. The
held-out RMSE after each addition is reported; an addition whose refit removes less than
``min_score/2`` of the held-out SSE is undone and marked not significant, and the next
significant candidate is tried. When nothing is significant but the best score is at least
``4*min_score`` (a large effect whose screen a second missing effect made inconsistent),
that candidate is tried too, and kept only if the refit's held-out improvement is
consistent block by block (``t`` at least `min_t`).

When no single effect holds up, two missing effects may each be hiding the other (each
one's screen fits the other's residual with the wrong term). Every pair of candidates is
then regressed together in the same linearised step; the best pairs (at most `_PAIRS`)
that remove at least ``4*min_score`` of the held-out SSE, and ``min_score`` more than the
best single effect, are each added together and refitted, with the same checks; of those
that hold up, the one with the lower held-out error is kept, as one step. Each of the two
is then ranked by its share within the pair (the held-out SSE it removes when added to the
other), and the evidence says so.
"""

import dataclasses
import itertools
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxfric
from jaxfric import effects as fx

from . import _params
from ._fit import fit, FitResult


# ---- regimes ---------------------------------------------------------------------------


def _reversals(x, v):
    d = np.sign(v)
    idx = np.arange(d.size)
    last = np.maximum.accumulate(np.where(d != 0, idx, 0))
    dl = d[last]
    rev = np.r_[False, (dl[1:] != dl[:-1]) & (dl[:-1] != 0)]
    start = np.maximum.accumulate(np.where(rev, idx - 1, 0))
    return rev, start


def regimes(t, x, v=None, *, presliding_travel=None, window_s=None, speed_bands=None):
    """Boolean masks (one per sample) of the regimes of a motion, SI units.

    - ``presliding``: travel since the last reversal below `presliding_travel` (m; default
      a tenth of the median stroke) while not at rest;
    - ``reversal window``: within `window_s` (s; default 2 % of the record) of a reversal;
    - ``sliding |v| < ...`` bands: outside presliding, by speed (`speed_bands`, m/s;
      default the terciles of |v| there);
    - ``accelerating``: outside presliding and |a| above its 80th percentile there;
    - ``rest``: v = 0.
    """
    t, x = np.asarray(t, float), np.asarray(x, float)
    v = np.r_[0.0, np.diff(x) / np.diff(t)] if v is None else np.asarray(v, float)
    rev, start = _reversals(x, v)
    travel = np.abs(x - x[start])
    if presliding_travel is None:
        turns = np.r_[x[0], x[start[rev]], x[-1]]
        strokes = np.abs(np.diff(turns))
        strokes = strokes[strokes > 0]
        presliding_travel = 0.1 * (np.median(strokes) if strokes.size else np.ptp(x))
    moving = v != 0
    pre = moving & (travel < presliding_travel) & (start > 0)
    if window_s is None:
        window_s = 0.02 * (t[-1] - t[0])
    rev_t = t[rev]
    if rev_t.size:
        k = np.searchsorted(rev_t, t)
        near = np.minimum(np.abs(t - rev_t[np.clip(k - 1, 0, rev_t.size - 1)]),
                          np.abs(t - rev_t[np.clip(k, 0, rev_t.size - 1)]))
        window = near <= window_s
    else:
        window = np.zeros(t.size, bool)
    slide = moving & ~pre
    speed = np.abs(v)
    out = {"presliding": pre, "reversal window": window}
    if slide.any():
        if speed_bands is None:
            speed_bands = list(np.quantile(speed[slide], [1 / 3, 2 / 3]))
        edges = [0.0, *speed_bands, np.inf]
        for lo, hi in itertools.pairwise(edges):
            label = (f"sliding |v| < {hi * 1e3:.3g} mm/s" if lo == 0 else
                     f"sliding |v| >= {lo * 1e3:.3g} mm/s" if hi == np.inf else
                     f"sliding {lo * 1e3:.3g}-{hi * 1e3:.3g} mm/s")
            out[label] = slide & (speed >= lo) & (speed < hi)
        a = np.r_[0.0, np.diff(v) / np.diff(t)]
        out["accelerating"] = slide & (np.abs(a) > np.quantile(np.abs(a[slide]), 0.8))
    out["rest"] = ~moving
    return out


def regime_errors(residual, masks) -> dict[str, dict[str, float]]:
    """``{regime: {"rmse": N, "samples": n, "share": fraction of the total SSE}}``, with
    ``"all"`` first."""
    r = np.asarray(residual, float)
    total = float(np.sum(r**2)) or 1.0
    out = {"all": {"rmse": float(np.sqrt(np.mean(r**2))), "samples": int(r.size), "share": 1.0}}
    for name, m in masks.items():
        if m.any():
            out[name] = {"rmse": float(np.sqrt(np.mean(r[m] ** 2))), "samples": int(m.sum()),
                         "share": float(np.sum(r[m] ** 2)) / total}
    return out


# ---- candidates ------------------------------------------------------------------------


def _signals(t, x, v, base, static):
    dt = np.r_[0.0, np.diff(t)]
    a = np.r_[0.0, np.diff(v) / np.where(dt[1:] > 0, dt[1:], 1.0)]
    return fx.Signals(t=jnp.asarray(t), x=jnp.asarray(x), v=jnp.asarray(v), a=jnp.asarray(a),
                      dt=jnp.asarray(dt), dx=jnp.asarray(np.r_[0.0, np.diff(x)]),
                      t0=jnp.asarray(t[0]), base=jnp.asarray(base),
                      static=jnp.asarray(static))


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
    if name == "friction_lag":
        span = t[-1] - t[0]
        taus = np.geomspace(max(np.median(np.diff(t)), 1e-6), span / 10, 24)
        return [fx.FrictionLag(lag_gain=1.0, tau=tau) for tau in taus]
    if name == "position_dependence":
        return [fx.PositionDependence.for_travel(x, pos_1=1.0, pos_2=1.0)]
    cls = fx.EFFECTS[name]
    return [cls()]


#: Parameters entering the term linearly (the regression's unknowns); effects not listed
#: are scaled as a whole (one column: the term itself).
_LINEAR = {
    "viscous": ("c_visc",), "quadratic_drag": ("c_drag",), "stribeck": ("dF_str",),
    "inertia": ("mass",), "offset": ("offset",), "asymmetry": ("asym",),
    "cogging": ("cog_sin", "cog_cos"), "position_dependence": ("pos_1", "pos_2"),
    "drift": ("drift_rate",), "friction_lag": ("lag_gain",),
}


@eqx.filter_jit
def _term(effect, s):
    return effect.term(s)


def _columns(effect, s):
    """Effect term's derivative w.r.t. its linear parameters (n, q); for an effect with
    none, the term itself (n, 1). Linear parameters are evaluated at 1."""
    names = _LINEAR.get(effect.name)
    if not names:
        return np.asarray(_term(effect, s))[:, None]
    cols = []
    for name in names:
        unit = eqx.tree_at(lambda e, n=name: getattr(e, n), effect, jnp.asarray(1.0))
        others = [n for n in names if n != name]
        for other in others:
            unit = eqx.tree_at(lambda e, o=other: getattr(e, o), unit, jnp.asarray(0.0))
        cols.append(np.asarray(_term(unit, s)))
    return np.stack(cols, axis=1)


#: Physical ranges of linear parameters (the lag gain is a fraction of the force).
_BOUNDS = {"friction_lag": (0.0, 1.0), "inertia": (0.0, np.inf)}  # a mass is not negative


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
    for name, value in zip(names, w):
        effect = eqx.tree_at(lambda e, n=name: getattr(e, n), effect, jnp.asarray(float(value)))
    return effect


# ---- the ranking -----------------------------------------------------------------------


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
        return {"effect": self.name, "score": self.score, "t_stat": self.t_stat,
                "significant": self.significant, "evidence": self.evidence, "code": self.code}


@dataclasses.dataclass
class Step:
    """After adding `added` and refitting: the fit, RMSE on all data and held out (N)."""

    added: list[str]
    fit: FitResult
    rmse: float
    rmse_holdout: float
    regimes: dict
    rel_error: float = float("nan")  # rmse / RMS of the measured force


@dataclasses.dataclass
class Diagnosis:
    """Outcome of `diagnose`: `baseline` and `steps` (one `Step` per added effect),
    `rankings` (the candidate list before each step; `rankings[0]` on the baseline), the
    held-out mask, and the final model."""

    baseline: Step
    steps: list[Step]
    rankings: list[list[Candidate]]
    holdout: np.ndarray
    model: object
    model_name: str

    @property
    def candidates(self) -> list[Candidate]:
        return self.rankings[0]

    @property
    def final(self) -> Step:
        return self.steps[-1] if self.steps else self.baseline

    def to_json(self) -> dict:
        return {
            "baseline": {"model": self.model_name, "rmse": self.baseline.rmse,
                         "rmse_holdout": self.baseline.rmse_holdout,
                         "rel_error": self.baseline.rel_error,
                         "regimes": self.baseline.regimes},
            "candidates": [c.to_json() for c in self.candidates],
            "after": {"added": self.final.added, "rmse": self.final.rmse,
                      "rmse_holdout": self.final.rmse_holdout,
                      "rel_error": self.final.rel_error,
                      "regimes": self.final.regimes,
                      "steps": [{"added": s.added, "rmse": s.rmse,
                                 "rmse_holdout": s.rmse_holdout} for s in self.steps]},
        }

    def summary(self) -> str:
        lines = [f"baseline {self.model_name}: RMSE {self.baseline.rmse:.4g} N "
                 f"(held out {self.baseline.rmse_holdout:.4g} N, "
                 f"{100 * self.baseline.rel_error:.3g} % of the RMS force)", "candidate effects:"]
        for c in self.candidates:
            mark = "*" if c.significant else " "
            lines.append(f" {mark} {c.name:<20} score {c.score:7.3f}  t {c.t_stat:6.1f}  "
                         f"{c.evidence}")
        for before, s in zip([self.baseline, *self.steps], self.steps):
            new = " + ".join(s.added[len(before.added):])
            lines.append(f"+ {new:<20} RMSE {s.rmse:.4g} N (held out "
                         f"{s.rmse_holdout:.4g} N, {100 * s.rel_error:.3g} %)")
        if not self.steps:
            lines.append("nothing significant to add")
        return "\n".join(lines)


def holdout_mask(t, blocks: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """Every third of `blocks` contiguous time blocks (the 3rd, 6th, ...) as a mask, and
    the block index of every sample."""
    t = np.asarray(t, float)
    b = np.minimum((blocks * (t - t[0]) / (t[-1] - t[0])).astype(int), blocks - 1)
    return (b % 3) == 2, b


def _base_jacobian(model, t, x, v, fixed=()):
    """d force / d (every parameter of `model` not in `fixed`, natural SI values), columns
    normalised."""
    p0 = _params.natural_vector(model)

    def force(p):
        return jaxfric.simulate(_params.from_natural_vector(p, model), t, x, v)

    J = np.asarray(jax.jacfwd(eqx.filter_jit(force))(p0))
    J = J[:, [n not in fixed for n in _params.natural_names(model)]]
    J = J[:, np.all(np.isfinite(J), axis=0)]
    norms = np.linalg.norm(J, axis=0)
    return J[:, norms > 0] / norms[norms > 0]


def _consistency(ref, new, test, blocks) -> tuple[float, int]:
    """How consistently residual `new` improves on `ref` over the held-out blocks: the
    ``t`` statistic (against zero) of the share of each block's SSE removed, one number per
    block (relative, so that blocks of large and small residual weigh alike and one block
    cannot carry the verdict), and the number of blocks."""
    per_block = []
    for b in np.unique(blocks[test]):
        in_b = test & (blocks == b)
        ref_b = float(np.sum(ref[in_b] ** 2))
        if ref_b > 0:
            per_block.append((ref_b - float(np.sum(new[in_b] ** 2))) / ref_b)
    per_block = np.asarray(per_block)
    if per_block.size < 2:
        return 0.0, int(per_block.size)
    sem = per_block.std(ddof=1) / np.sqrt(per_block.size)
    mean = per_block.mean()
    t_stat = float(mean / sem) if sem > 0 else (np.inf if mean > 0 else 0.0)
    return t_stat, int(per_block.size)


def _base_signals(model, t, x, v):
    """The signals effects are built from (`_signals`), at the force of `model` without
    its added effects."""
    base_model = model.base if isinstance(model, fx.WithEffects) else model
    base_force = np.asarray(jaxfric.simulate(base_model, t, x, v))
    return _signals(t, x, v, base_force,
                    np.asarray(fx.static_force(base_model, jnp.asarray(v), base_force)))


def _unit_columns(B, train):
    """`B` with each column scaled to unit norm on the training samples, and the scales."""
    scale = np.linalg.norm(B[train], axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    return B / scale, scale


def _regress(resid, train, *blocks):
    """The linearised step every screen takes: least squares of `resid` on the columns of
    `blocks` (the model's Jacobian, effect columns) over the training samples. Returns
    what is left of `resid` on all samples, and the coefficients."""
    A = np.concatenate(blocks, axis=1)
    coef, *_ = np.linalg.lstsq(A[train], resid[train], rcond=1e-10)
    return resid - A @ coef, coef


def _normalised_columns(candidates, model, t, x, v, train):
    """Each candidate's regression columns at `model`'s base force, scaled to unit norm on
    the training samples: a list of ``(columns, scale)``."""
    s = _base_signals(model, t, x, v)
    return [_unit_columns(_columns(c.effect, s), train) for c in candidates]


def _joint_check(candidates, model, t, x, v, resid, J, train, test, blocks, min_score, min_t):
    """Re-test the leading candidates together: with two effects hidden, each one's screen
    sees the other's residual as noise, which can make a real effect look inconsistent
    across blocks. The candidates with a score of at least `min_score` (at most three) are
    regressed jointly (with the model's Jacobian); each one's consistency is then that of
    the held-out residual with all of them against the residual without it. A candidate
    that is consistent this way becomes significant (the score, its size, is unchanged)."""
    lead = [c for c in candidates[:3] if c.score >= min_score]
    if len(lead) < 2:
        return
    cols = [B for B, _ in _normalised_columns(lead, model, t, x, v, train)]

    full, _ = _regress(resid, train, J, *cols)
    for i, c in enumerate(lead):
        without, _ = _regress(resid, train, J, *cols[:i], *cols[i + 1:])
        t_joint, n_blocks = _consistency(without, full, test, blocks)
        if not c.significant and t_joint >= min_t:
            others = ", ".join(o.name for o in lead if o is not c)
            c.significant = True
            c.t_stat = t_joint
            c.evidence += (f"; consistent when fitted together with {others} "
                           f"(t = {t_joint:.1f} over {n_blocks} held-out blocks)")


@dataclasses.dataclass
class _Pair:
    """Two candidates regressed together: `score` (held-out SSE share removed by both,
    normalised as a single screen's), `shares` (each one's part: the SSE removed by adding
    it to the other), `effects` (with the joint regression's values)."""

    score: float
    candidates: tuple[Candidate, Candidate]
    shares: tuple[float, float]
    effects: tuple[fx.AbstractEffect, fx.AbstractEffect]


def _pair_screen(candidates, model, t, x, v, resid, J, train, test) -> list[_Pair]:
    """Every pair of screened candidates regressed together with the model's Jacobian (the
    single screens' Gauss-Newton step with two effects), best pair first. Two missing
    effects whose terms are partly alike (an asymmetry and a position dependence along
    strokes that run in one direction over one part of the travel) each screen poorly
    alone, as each one's fit is bent by the other; together they can explain much more
    than either."""
    if len(candidates) < 2:
        return []
    cols = _normalised_columns(candidates, model, t, x, v, train)

    def solve(used):
        new, coef = _regress(resid, train, J, *(cols[i][0] for i in used))
        return new, coef[J.shape[1]:]

    def sse(r):
        return float(np.sum(r[test] ** 2))

    ref, _ = solve(())
    norm = max(sse(ref), float(np.sum(resid[test] ** 2)), 1e-300)
    alone = [sse(solve((i,))[0]) for i in range(len(candidates))]
    pairs = []
    for i, j in itertools.combinations(range(len(candidates)), 2):
        full, coef = solve((i, j))
        q = cols[i][0].shape[1]
        w_i, w_j = coef[:q] / cols[i][1], coef[q:] / cols[j][1]
        pairs.append(_Pair(
            score=(sse(ref) - sse(full)) / norm,
            candidates=(candidates[i], candidates[j]),
            shares=((alone[j] - sse(full)) / norm, (alone[i] - sse(full)) / norm),
            effects=(_with_linear(candidates[i].effect, w_i),
                     _with_linear(candidates[j].effect, w_j))))
    pairs.sort(key=lambda p: p.score, reverse=True)
    return pairs


def _screen(name, model, t, x, v, F, resid, J, train, test, blocks, min_score, min_t):
    s = _base_signals(model, t, x, v)
    best = None
    base_test = resid[test]
    # The model's own parameters alone (one Gauss-Newton step): the reference.
    ref, _ = _regress(resid, train, J)
    sse_base = max(float(np.sum(base_test**2)), 1e-300)
    bounds = _BOUNDS.get(name)
    for effect in _grid(name, t, x, v, F):
        B = _columns(effect, s)
        if not np.all(np.isfinite(B)) or not np.any(B[train]):
            continue
        unit, scale = _unit_columns(B, train)
        new, coef = _regress(resid, train, J, unit)
        w = coef[J.shape[1]:] / scale
        if bounds is not None and np.any((w < bounds[0]) | (w > bounds[1])):
            # Outside its physical range: hold it at the bound, refit the model's part.
            w = np.clip(w, *bounds)
            new, _ = _regress(resid - B @ w, train, J)
        # Held-out SSE removed beyond what the model's own parameters do in the same
        # linearised step, as a fraction of the larger of the two reference SSEs (<= 1).
        sse_new, sse_ref = float(np.sum(new[test] ** 2)), float(np.sum(ref[test] ** 2))
        gain = (sse_ref - sse_new) / max(sse_ref, sse_base)
        if best is None or gain > best[0]:
            best = (gain, effect, w, new)
    if best is None:
        return None
    gain, effect, w, new = best
    t_stat, n_blocks = _consistency(ref, new, test, blocks)
    effect = _with_linear(effect, w)
    significant = bool(gain >= min_score and t_stat >= min_t)
    evidence = (f"{effect.describe()}; explains {100 * gain:.3g} % of the held-out residual "
                f"variance (consistent over {n_blocks} held-out blocks: t = {t_stat:.1f})")
    code = _code(effect)
    return Candidate(name, effect, float(gain), t_stat, significant, evidence, code)


def _code(effect) -> str:
    """The one-liner that adds `effect` with its screened values."""
    args = ", ".join(f"{f.name}={float(getattr(effect, f.name)):.4g}"
                     for f in dataclasses.fields(effect))
    return f"model + jaxfric.effects.{type(effect).__name__}({args})"


#: Most warm restarts of a refit that stops at its step limit (see `_step`).
_RESTARTS = 5

#: Most pairs of effects tried together when no single effect holds up (see `diagnose`).
_PAIRS = 2


def _step(model, added, t, x, v, F, train, test, masks, log, max_steps, fixed=(),
          restart=False):
    names = _params.leaf_names(_params.to_fit_representation(model))
    free = [n for n in names if n not in fixed] if fixed else None
    res = fit(model, t, x, F, v, weights=train.astype(float), max_steps=max_steps, free=free)
    # A refit with a new effect starts from the screen's values, often far from its
    # optimum; a warm restart (fresh damping) gets it unstuck more often than more steps.
    # Restart while the fit stops at its step limit and each restart still lowers the
    # training RMSE by more than 1 % (slow but steady fits, e.g. a friction lag of twice
    # the nominal size, need about five rounds of 300 steps), at most `_RESTARTS` times.
    for _ in range(_RESTARTS if restart else 0):
        if bool(res.converged):
            break
        again = fit(res.model, t, x, F, v, weights=train.astype(float), max_steps=max_steps,
                    free=free)
        progress = float(again.rmse) < 0.99 * float(res.rmse)
        if float(again.rmse) <= float(res.rmse):
            res = again
        if not progress:
            break
    resid = np.asarray(res.prediction) - F
    return Step(
        added=list(added), fit=res,
        rmse=float(np.sqrt(np.mean(resid**2))),
        rmse_holdout=float(np.sqrt(np.mean(resid[test] ** 2))),
        regimes=regime_errors(resid, masks),
        rel_error=float(np.sqrt(np.mean(resid**2) / np.mean(F**2))),
    ), -resid


def diagnose(
    model,
    t,
    x,
    F,
    v=None,
    *,
    effects: Sequence[str] | None = None,
    blocks: int = 24,
    min_score: float = 0.05,
    min_t: float = 3.0,
    max_added: int = 4,
    max_steps: int = 300,
    fixed: Sequence[str] = (),
    model_name: str | None = None,
    log: Callable[[str], None] | None = None,
) -> Diagnosis:
    """Fit `model` to ``(t, x, F[, v])`` (SI), rank the missing effects, add the significant
    ones one at a time with a joint refit after each (see the module docstring).

    `effects`: names from `jaxfric.effects.EFFECTS` to consider (default all not already in
    the model). `fixed`: parameter names of `model` held at their values in every fit
    (e.g. ``("sigma2",)`` with ``sigma2 = 0`` for a model without viscous friction); the
    screening then does not let them absorb an effect either. `max_steps`: per fit.
    Returns a `Diagnosis`; its models are in the fit representation
    (`fitting.to_fit_representation`: a `PaperShape` appears as the equivalent
    `NormalizedPaperShape`, finite where the paper's ``a`` would overflow).
    """
    fixed = tuple(fixed)
    # Work in the fit representation throughout (a `PaperShape` as a `NormalizedPaperShape`):
    # a round trip through the paper's symbols is singular for a nearly straight shape.
    model = _params.to_fit_representation(model)
    unknown = set(fixed) - set(_params.leaf_names(model))
    if unknown:
        raise ValueError(f"fixed: {type(model).__name__} has no parameter(s) "
                         f"{sorted(unknown)}; it has {_params.leaf_names(model)}")
    log = log or (lambda *_: None)
    t, x, F = (np.asarray(a, dtype=np.float64) for a in (t, x, F))
    v_arr = np.r_[0.0, np.diff(x) / np.diff(t)] if v is None else np.asarray(v, np.float64)
    test, block = holdout_mask(t, blocks)
    train = ~test
    masks = regimes(t, x, v_arr)
    present = {e.name for e in getattr(model, "effects", ())}
    names = [n for n in (effects or fx.EFFECTS) if n not in present]
    log(f"fitting the baseline model on {int(train.sum())} of {t.size} samples "
        f"({int(test.sum())} held out in {blocks // 3} blocks) ...")
    baseline, resid = _step(model, [], t, x, v, F, train, test, masks, log, max_steps, fixed)
    current, added, steps, rankings = baseline.fit.model, [], [], []
    best_holdout = baseline.rmse_holdout
    while True:
        J = _base_jacobian(current, t, x, v, fixed)
        ranking = []
        for name in names:
            if name in added:
                continue
            c = _screen(name, current, t, x, v_arr, F, resid, J, train, test, block,
                        min_score, min_t)
            if c is not None:
                ranking.append(c)
        ranking.sort(key=lambda c: c.score, reverse=True)
        _joint_check(ranking, current, t, x, v_arr, resid, J, train, test, block,
                     min_score, min_t)
        rankings.append(ranking)
        for c in ranking[:3]:
            log(f"  {c.name}: score {c.score:.3f}, t {c.t_stat:.1f}"
                + ("  (significant)" if c.significant else ""))
        if len(added) >= max_added:
            break
        accepted = None
        tries = [c for c in ranking if c.significant]
        if ranking and not ranking[0].significant and ranking[0].score >= 4 * min_score:
            # The largest score, but inconsistent across blocks: often a second missing
            # effect confounding the linear screen. Try it first; the refit must confirm
            # it block by block.
            tries = [ranking[0], *tries]
        def refit(new_effects, names_new, current=current, resid=resid,
                  best_holdout=best_holdout):
            """Add `new_effects`, refit (from the fitted model and from the starting model
            with the effects; the better training fit is kept). Returns the step, its
            residual, whether it removed enough held-out SSE, and its consistency."""
            trial, trial_resid = _step(current + new_effects, [*added, *names_new], t, x,
                                       v, F, train, test, masks, log, max_steps, fixed,
                                       restart=True)
            # The fitted model can sit where it compensated for the missing effect (a
            # distorted Stribeck curve, say), a poor start for the refit: also refit from
            # the starting model with the effects, and keep the better training fit.
            effects = tuple(getattr(current, "effects", ()))
            plain = model.base if isinstance(model, fx.WithEffects) else model
            fresh, fresh_resid = _step(plain + (*effects, *new_effects),
                                       [*added, *names_new], t, x, v, F, train, test, masks,
                                       log, max_steps, fixed, restart=True)
            if float(fresh.fit.rmse) < float(trial.fit.rmse):
                trial, trial_resid = fresh, fresh_resid
            # The refit must remove at least half the screening threshold of held-out SSE,
            # and an effect not yet shown consistent must now be so, block by block.
            enough = trial.rmse_holdout**2 < (1.0 - 0.5 * min_score) * best_holdout**2
            t_refit, n_blocks = _consistency(resid, trial_resid, test, block)
            return trial, trial_resid, enough, t_refit, n_blocks

        for chosen in tries:
            log(f"adding {chosen.name} and refitting ...")
            trial, trial_resid, enough, t_refit, n_blocks = refit((chosen.effect,),
                                                                  [chosen.name])
            if enough and (chosen.significant or t_refit >= min_t):
                if not chosen.significant:
                    chosen.significant, chosen.t_stat = True, t_refit
                    chosen.evidence += (f"; confirmed by the joint refit, consistent over "
                                        f"{n_blocks} held-out blocks (t = {t_refit:.1f})")
                accepted = [chosen]
                break
            log(f"  {chosen.name} did not lower the held-out error enough, or not "
                "consistently; not added")
            chosen.significant = False
        if accepted is None and len(added) + 2 <= max_added:
            # No single effect holds up: two effects can each be hidden by the other. Try
            # the best pairs that explain clearly more together than any one alone.
            best_single = max((c.score for c in ranking), default=0.0)
            pairs = [p for p in _pair_screen(ranking, current, t, x, v_arr, resid, J,
                                             train, test)[:_PAIRS]
                     if p.score >= 4 * min_score and p.score >= best_single + min_score]
            tried = []
            for pair in pairs:
                names_pair = [c.name for c in pair.candidates]
                log(f"adding {' and '.join(names_pair)} together (they explain "
                    f"{100 * pair.score:.3g} % of the held-out residual jointly) and "
                    "refitting ...")
                out = refit(pair.effects, names_pair)
                log(f"  held-out RMSE {out[0].rmse_holdout:.4g} N (was {best_holdout:.4g} "
                    f"N), consistency over the held-out blocks t = {out[3]:.1f}")
                if out[2] and out[3] >= min_t:
                    tried.append((out, pair))
            if tried:
                # Of the pairs that hold up (two effects with partly alike terms can
                # compete, e.g. an offset and an asymmetry), keep the lower held-out error.
                (trial, trial_resid, _, t_refit, n_blocks), pair = min(
                    tried, key=lambda o: o[0][0].rmse_holdout)
                alone = [(c.score, c.t_stat) for c in pair.candidates]
                for c, share, (score, t_stat), (other_score, _), other, effect in zip(
                        pair.candidates, pair.shares, alone, alone[::-1],
                        pair.candidates[::-1], pair.effects):
                    c.evidence = (
                        f"{effect.describe()}; found together with {other.name}: both "
                        f"explain {100 * pair.score:.3g} % of the held-out residual "
                        f"variance, {other.name} alone {100 * other_score:.3g} %, so adding "
                        f"{c.name} to it removes {100 * share:.3g} % (alone "
                        f"{100 * score:.3g} %, t = {t_stat:.1f}); confirmed by the joint "
                        f"refit of both, consistent over {n_blocks} held-out blocks "
                        f"(t = {t_refit:.1f})")
                    c.effect, c.code = effect, _code(effect)
                    c.score, c.significant, c.t_stat = float(share), True, t_refit
                ranking.sort(key=lambda c: c.score, reverse=True)
                accepted = sorted(pair.candidates, key=lambda c: c.score, reverse=True)
                trial.added = [*added, *(c.name for c in accepted)]
        if accepted is None:
            break
        steps.append(trial)
        added.extend(c.name for c in accepted)
        current, resid, best_holdout = trial.fit.model, trial_resid, trial.rmse_holdout
    return Diagnosis(baseline=baseline, steps=steps, rankings=rankings, holdout=test,
                     model=current, model_name=model_name or type(model).__name__)
