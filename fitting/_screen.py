"""Screening one candidate effect, or two together: one linearised (Gauss-Newton) step of the
joint fit from the baseline optimum, scored by the held-out residual it removes and
tested for consistency where it acts (`fitting._evidence`).
"""

import dataclasses
import itertools

import jax
import jax.numpy as jnp
import numpy as np

import jaxfric
from jaxfric import effects as fx
from jaxfric._compile import jit

from . import _params
from ._candidates import (
    _BOUNDS,
    _code,
    _columns,
    _grid,
    _signals,
    _with_linear,
    Candidate,
)
from ._evidence import convincing, evidence


def _base_jacobian(model, t, x, v, fixed=(), load=None, a=None):
    """d force / d (every parameter of `model` not in `fixed`, natural SI values), columns
    normalised."""
    p0 = _params.natural_vector(model)

    def force(p):
        return jaxfric.simulate(_params.from_natural_vector(p, model), t, x, v, load=load,
                                a=a)

    J = np.asarray(jax.jacfwd(jit(force))(p0))
    J = J[:, [n not in fixed for n in _params.natural_names(model)]]
    J = J[:, np.all(np.isfinite(J), axis=0)]
    norms = np.linalg.norm(J, axis=0)
    return J[:, norms > 0] / norms[norms > 0]


def _base_signals(model, t, x, v, load=None, a=None):
    """The signals effects are built from (`_signals`), at the force of `model` without
    its added effects; `load` (N) for the load-dependent effects, `a` (m/s^2; None: the
    backward difference of `v`) for `jaxfric.effects.Inertia`."""
    base_model = model.without_effects()
    # `load` and `a` change nothing for a model without effects, but given as every fit
    # gives them (`fitting._fit._as_simulated`) the compiled simulation is reused.
    base_force = np.asarray(jaxfric.simulate(base_model, t, x, v, load=load, a=a))
    return _signals(t, x, v, base_force,
                    np.asarray(fx.static_force(base_model, jnp.asarray(v), base_force)), load,
                    a)


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


def _regress_bounded(resid, train, J, blocks):
    """`_regress` on the model's Jacobian `J` and effect `blocks` (``(unit columns, scale,
    name)`` each), with every effect's coefficients held within its physical range
    (`_BOUNDS`: a drag, a mass, a Stribeck hump are not negative), as the single screen
    holds them: coefficients outside are clipped to the bound and fixed there, the rest
    refitted, until none is outside. Without it, two effects regressed together can be
    credited for what one of them does with the wrong sign (a negative drag next to a
    mass error). Returns what is left of `resid` and each block's natural coefficients."""
    held: dict[int, np.ndarray] = {}
    while True:
        free = [k for k in range(len(blocks)) if k not in held]
        r = resid - sum((blocks[k][0] @ (held[k] * blocks[k][1]) for k in held),
                        np.zeros_like(resid))
        new, coef = _regress(r, train, J, *(blocks[k][0] for k in free))
        coef, w = coef[J.shape[1]:], {}
        for k in free:
            q = blocks[k][0].shape[1]
            w[k], coef = coef[:q] / blocks[k][1], coef[q:]
        out = {k: np.clip(w[k], *_BOUNDS[blocks[k][2]]) for k in free
               if blocks[k][2] in _BOUNDS and np.any((w[k] < _BOUNDS[blocks[k][2]][0])
                                                     | (w[k] > _BOUNDS[blocks[k][2]][1]))}
        if not out:
            return new, [held[k] if k in held else w[k] for k in range(len(blocks))]
        held.update(out)


def _normalised_columns(candidates, model, t, x, v, train, load=None, a=None):
    """Each candidate's regression columns at `model`'s base force, scaled to unit norm on
    the training samples: a list of ``(columns, scale)``."""
    s = _base_signals(model, t, x, v, load, a)
    return [_unit_columns(_columns(c.effect, s), train) for c in candidates]


def _joint_check(candidates, model, t, x, v, resid, J, train, test, min_score, min_t,
                 load=None, a=None):
    """Re-test the leading candidates together: with two effects hidden, each one's screen
    sees the other's residual as noise, which can make a real effect look inconsistent. The
    candidates with a score of at least `min_score` (at most three) are regressed jointly
    (with the model's Jacobian); each one's consistency is then that of the held-out
    residual with all of them against the residual without it. A candidate that is
    consistent this way becomes significant (the score, its size, is unchanged)."""
    lead = [c for c in candidates[:3] if c.score >= min_score]
    if len(lead) < 2:
        return
    cols = [(B, scale, c.name) for (B, scale), c in
            zip(_normalised_columns(lead, model, t, x, v, train, load, a), lead)]

    full, _ = _regress_bounded(resid, train, J, cols)
    for i, c in enumerate(lead):
        without, _ = _regress_bounded(resid, train, J, cols[:i] + cols[i + 1:])
        ev = evidence(without, full, test, v)
        if not c.significant and ev.t >= min_t:
            others = ", ".join(o.name for o in lead if o is not c)
            c.significant = True
            c.t_stat = ev.t
            c.evidence += (f"; consistent when fitted together with {others} "
                           f"(t = {ev.t:.1f} over {ev.batches} held-out batches)")


@dataclasses.dataclass
class _Pair:
    """Two candidates regressed together: `score` (held-out SSE share removed by both,
    normalised as a single screen's), `shares` (each one's part: the SSE removed by adding
    it to the other), `effects` (with the joint regression's values)."""

    score: float
    candidates: tuple[Candidate, Candidate]
    shares: tuple[float, float]
    effects: tuple[fx.AbstractEffect, fx.AbstractEffect]


def _pair_screen(candidates, model, t, x, v, resid, J, train, test, load=None, a=None
                 ) -> list[_Pair]:
    """Every pair of screened candidates regressed together with the model's Jacobian (the
    single screens' Gauss-Newton step with two effects), best pair first. Two missing
    effects whose terms are partly alike (an asymmetry and a position dependence along
    strokes that run in one direction over one part of the travel) each screen poorly
    alone, as each one's fit is bent by the other; together they can explain much more
    than either."""
    if len(candidates) < 2:
        return []
    cols = [(B, scale, c.name) for (B, scale), c in
            zip(_normalised_columns(candidates, model, t, x, v, train, load, a),
                candidates)]

    def solve(used):
        return _regress_bounded(resid, train, J, [cols[i] for i in used])

    def sse(r):
        return float(np.sum(r[test] ** 2))

    ref, _ = solve(())
    norm = max(sse(ref), float(np.sum(resid[test] ** 2)), 1e-300)
    alone = [sse(solve((i,))[0]) for i in range(len(candidates))]
    pairs = []
    for i, j in itertools.combinations(range(len(candidates)), 2):
        full, (w_i, w_j) = solve((i, j))
        pairs.append(_Pair(
            score=(sse(ref) - sse(full)) / norm,
            candidates=(candidates[i], candidates[j]),
            shares=((alone[j] - sse(full)) / norm, (alone[i] - sse(full)) / norm),
            effects=(_with_linear(candidates[i].effect, w_i),
                     _with_linear(candidates[j].effect, w_j))))
    pairs.sort(key=lambda p: p.score, reverse=True)
    return pairs


def _screen(name, model, t, x, v, F, resid, J, train, test, min_score, min_t, load=None,
            a=None):
    s = _base_signals(model, t, x, v, load, a)
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
    ev = evidence(ref, new, test, v)
    effect = _with_linear(effect, w)
    significant = bool(gain >= min_score and convincing(gain, ev.t, min_t))
    words = (f"{effect.describe()}; explains {100 * gain:.3g} % of all the held-out residual "
             f"variance; {ev.words()}")
    code = _code(effect)
    return Candidate(name, effect, float(gain), ev.t, significant, words, code)
