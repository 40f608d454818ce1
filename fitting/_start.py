"""Starting models read off a measurement, for fits that begin with no prior knowledge.

A least-squares fit needs a start in the right basin; the paper's values (26 N, 4 um/N) are
useless for a 2 N tribometer. `initial_model` reads every family's parameters off the data:

- **Presliding range**: the travel after a reversal at which the force has swung by 90 % of
  that branch's whole rise (`swing_travel`; the median over the branches that rise by at
  least 60 % of the largest rise, i.e. full reversals). Sliding starts beyond twice that.
- **Steady-state curve** (Stribeck ``Fs, Fc, Vs`` and ``sigma2``, ``delta`` held at
  `START_DELTA`; for the hysteretic starts one curve per exponent of `LAG_DELTAS`,
  settled by the data below): fitted to the median force of the steady sliding samples
  per speed bin (`fitting._steady`); with fewer
  than 3 speed bins, from force levels (``Fc`` the median of ``|F|`` while moving,
  ``Fs = 1.2*Fc``, ``Vs`` a fifth of the 90th percentile of ``|v|``, a small ``sigma2``)
  or the steady constant-velocity segments (`initial_stribeck`): for Tustin whichever
  static curve fits the moving samples better; for the hysteretic starts both, settled
  with the uncertain values below. (Where the presliding range is most of a stroke, few
  or no samples slide steadily, and a static curve judged on moving samples that are
  mostly presliding can be far off: a segment line with ``Fc`` 5 % of ``Fs`` and a huge
  ``sigma2``, from which the two-state start was 15 N RMS off the data where a start
  with the level curve is 2 N off: tests/fitting/test_start.py.)
- **Presliding extent and stiffness**: two-state ``l1`` from the swing travel scaled by the
  paper shape's own ``Pi^-1(0.9)`` (`fitting._staged._estimate_l1`), the shape the paper's
  rescaled to it; GMS the elements of that shape (`jaxfric.GMS.from_shape`); LuGre
  ``sigma0 = ln(10)*Fs/x90`` (its force swings as ``2*Fs*(1 - exp(-sigma0*x/Fs))`` after a
  reversal: 90 % at the swing travel ``x90``), ``sigma1`` critically damped for 1 kg.
- **Records that never slide** (`MIN_SLIDING`): the Stribeck velocity far beyond the
  data's speeds (`NEVER_SLIDING`), ``sigma2`` at the steady curve's floor.
- **Friction lag** ``C`` (two-state, GMS): the lag time constant ``Fs/C`` is not measurable
  before the presliding and the curve are known, so it is one of the uncertain values below.
  The diagnosis's base fit also starts from the fastest of `LAG_TIMES` (`lag_starts`).
- **Uncertain values, settled by the data**: the presliding extent (x0.5, x1, x2 of the
  estimate), the lag time constant (`LAG_TIMES`) and the curve's exponent (`LAG_DELTAS`;
  without speed bins, the static curves) are tried
  together: every candidate is simulated on the measurement (one compiled
  `jaxfric.simulate` for all) and the one with the smallest sum of squared errors is the
  start. (LuGre: ``sigma0`` x0.5, x1, x2 with each curve, no lag.)
  Then, for every hysteretic start, larger viscous terms (`VISCOUS_SHARES`), the same way
  (`_viscous`).
"""

import itertools

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import jaxfric
from jaxfric import NormalizedPaperShape, paper
from jaxfric.data import DataError
from jaxfric.motion import velocity

from ._data import Dataset
from ._staged import _estimate_l1, constant_velocity_segments, initial_stribeck
from ._steady import fit_steady_curve, steady_curve, steady_sliding, steady_weights


KINDS = ("two-state", "gms", "lugre", "tustin")
#: Lag time constants ``Fs/C`` (s) tried for the two-state and GMS starts: the paper's
#: (2.4 s), and a tenth and a hundredth of it.
LAG_TIMES = (2.4, 0.24, 0.024)
#: The start's Stribeck exponent. The bins determine ``delta`` least of the curve's
#: parameters, and where a friction lag has not settled in them they look like a steep step:
#: a start there (``delta`` 2.5 or more) sent a two-state fit to ``delta`` ~300, where its
#: next fits could not move (tests/diagnosis/test_folds.py); the fit determines it from 1.
START_DELTA = 1.0
#: The exponents of the steady-state curves tried for the hysteretic starts (two-state,
#: GMS, LuGre). One fixed exponent can put the whole level into the exponential and the
#: viscous term (``Fc`` ~ 0): where the bins hold a friction lag that has not settled (a lag
#: time ``|s|/C`` of seconds against strokes of a fraction of one), which bends them, and
#: where the bins end before the curve flattens (a LuGre truth's bins up to 10 mm/s,
#: ``Fc`` 20 N: with ``delta`` 1, ``Fc`` 0.026 N and ``sigma2`` 1174 N s/m, a start the
#: fit cannot leave, as ``Fc`` then moves no sample). From there a fit lands in another
#: optimum (the demo's data: RMSE 0.60 N instead of 0.45 N; that LuGre file: 0.155 N
#: instead of 0.046 N). The simulation of each candidate settles the choice.
LAG_DELTAS = (0.5, START_DELTA, 2.0)
#: A record with fewer steady sliding samples than this (`fitting._steady.steady_sliding`)
#: never slides: the hysteretic start's Stribeck velocity is then `NEVER_SLIDING` times its
#: largest speed, where the curve is flat over the data (to 0.01 % of its drop with ``delta``
#: 1). Inside the data's speeds (a fifth of the 90th percentile, as for sliding records
#: without speed bins) it bends the presliding plateau, and a fit that holds the curve's
#: undetermined parameters at their start then fits far worse than the free fit
#: (tests/fitting/test_honest_fits.py).
MIN_SLIDING = 10
NEVER_SLIDING = 1e4
#: Factors on the presliding estimate tried for every hysteretic start.
SPREAD = (0.5, 1.0, 2.0)
#: Viscous forces at the 90th percentile of the speed, as fractions of ``Fc``, tried for
#: ``sigma2`` where the start's is smaller (`_viscous`): a decade apart.
VISCOUS_SHARES = (0.01, 0.1)


def _level_stribeck(F, vel):
    moving = vel != 0
    if moving.sum() < 3:
        raise DataError("no motion in the data: cannot estimate a friction level")
    fc = float(np.median(np.abs(F[moving])))
    if fc <= 0:
        raise DataError("the force is zero wherever the data move")
    v90 = float(np.quantile(np.abs(vel[moving]), 0.9))
    stribeck = jaxfric.Stribeck(Fs=1.2 * fc, Fc=fc, Vs=max(0.2 * v90, 1e-12), delta=1.0)
    return stribeck, 0.01 * fc / max(v90, 1e-12)


def _strokes(x) -> float:
    """Median travel between reversals, m."""
    dx = np.diff(x)
    d = np.sign(dx)
    keep = d != 0
    d, xs = d[keep], x[1:][keep]
    turns = np.nonzero(d[1:] != d[:-1])[0]
    points = np.r_[x[0], xs[turns], x[-1]]
    travel = np.abs(np.diff(points))
    travel = travel[travel > 0]
    return float(np.median(travel)) if travel.size else float(np.ptp(x))


def swing_travel(x, F, level: float = 0.9) -> float | None:
    """The travel (m) after a reversal at which the force has covered `level` of the
    branch's whole rise: the median over the branches rising by at least 60 % of the largest
    rise (full reversals, not inner loops or noise). ``None`` without such a branch."""
    x, F = np.asarray(x, float), np.asarray(F, float)
    direction = np.sign(np.diff(x))
    moving = np.nonzero(direction)[0]
    if moving.size < 2:
        return None
    rev = moving[1:][direction[moving[1:]] != direction[moving[:-1]]]
    branches = []
    for k in rev:
        d, end = direction[k], k + 1
        while end < direction.size and direction[end] in (d, 0):
            end += 1
        rise, travel = d * (F[k:end + 1] - F[k]), d * (x[k:end + 1] - x[k])
        branches.append((float(rise.max()), rise, travel))
    if not branches:
        return None
    top = max(b[0] for b in branches)
    travels = [tr[np.argmax(r >= level * total)] for total, r, tr in branches
               if total >= 0.6 * top and total > 0]
    travels = [t for t in travels if t > 0]
    return float(np.median(travels)) if travels else None


def _static_curve(t, x, F, v, vel, presliding, deltas=(START_DELTA,), every=False):
    """``[(stribeck, sigma2), ...]``: the steady-state curve read off the data (module
    docstring), one per exponent of `deltas` when the bins are fitted; else the static
    curve that fits the moving samples best, or with `every` each reading, that one
    first (for a hysteretic start, whose simulation settles the choice: `_best`)."""
    curve = steady_curve(t, x, F, vel, presliding)
    if len(curve) >= 3:
        return [fit_steady_curve(curve, deltas=(d,))[:2] for d in deltas]
    sliding = vel != 0
    candidates = [_level_stribeck(F, vel)]
    segments = constant_velocity_segments(t, x, F, v)
    if len(segments) >= 3:
        try:
            candidates.append(initial_stribeck(segments))
        except ValueError:
            pass

    def static_rss(candidate):
        tustin = jaxfric.Tustin(stribeck=candidate[0], sigma2=candidate[1])
        static = np.asarray(jaxfric.simulate(tustin, t, x, v))
        return float(np.sum(((static - F)[sliding]) ** 2))

    ranked = sorted(candidates, key=static_rss)
    return ranked if every else ranked[:1]


def _best(models, t, x, F, v):
    """The model of `models` (same structure) whose simulation on the measurement has the
    smallest sum of squared errors (a non-finite one never wins). One compiled simulation
    serves them all (their parameters are arrays of one shape)."""
    if len(models) == 1:
        return models[0]
    sse = [float(np.sum((np.asarray(jaxfric.simulate(m, t, x, v)) - F) ** 2)) for m in models]
    return models[int(np.argmin(np.where(np.isfinite(sse), sse, np.inf)))]


def initial_model(kind: str, t, x, F, v=None, *, n_elements: int = 5):
    """A starting model of `kind` (``"two-state"``, ``"gms"``, ``"lugre"``, ``"tustin"``)
    scaled to the measurement ``(t, x, F[, v])`` in SI (s, m, N, m/s); see the module
    docstring for how each parameter is estimated. `n_elements` is the GMS size."""
    if kind not in KINDS:
        raise ValueError(f"unknown model {kind!r}; choose one of {', '.join(KINDS)}")
    t = np.asarray(t, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    F = np.asarray(F, dtype=np.float64)
    vel = velocity(t, x) if v is None else np.asarray(v, dtype=np.float64)
    if (vel != 0).sum() < 3:
        raise DataError("no motion in the data: cannot estimate a friction level")
    x90 = swing_travel(x, F)
    presliding = 2.0 * x90 if x90 is not None else 0.1 * _strokes(x)
    if kind == "tustin":
        stribeck, sigma2 = _static_curve(t, x, F, v, vel, presliding)[0]
        return jaxfric.Tustin(stribeck=stribeck, sigma2=sigma2)
    curves = _static_curve(t, x, F, v, vel, presliding,
                           LAG_DELTAS,
                           every=True)
    if steady_sliding(t, x, vel, presliding).sum() < MIN_SLIDING:
        # Never sliding: no velocity weakening in the data, so none in the start, and a
        # viscous term as small as the steady curve's floor (`fitting._steady`).
        vmax = float(np.max(np.abs(vel)))
        curves = [(eqx.tree_at(lambda s: s.Vs, st, jnp.asarray(NEVER_SLIDING * vmax)),
                   1e-3 * float(np.max(np.abs(F))) / vmax) for st, _ in curves]
    stribeck, sigma2 = curves[0]
    fs = float(stribeck.Fs)
    if kind == "lugre":
        travel = x90 if x90 is not None else 0.05 * _strokes(x)
        lugres = []
        for f, (stribeck, sigma2) in itertools.product(SPREAD, curves):
            sigma0 = f * np.log(10.0) * float(stribeck.Fs) / travel
            lugres.append(jaxfric.LuGre(stribeck=stribeck, sigma0=sigma0,
                                        sigma1=2.0 * sigma0**0.5, sigma2=sigma2))
        best = _best(lugres, t, x, F, v)
        return _viscous(best, t, x, F, v, vel)
    base = NormalizedPaperShape.from_paper(paper.shape(), paper.stribeck().Fs)
    probe = jaxfric.TwoState(stribeck=stribeck, shape=base.to_paper(fs), sigma2=sigma2,
                             C=paper.C)
    l1 = _estimate_l1(probe, Dataset(t=t, x=x, F=F))
    if l1 is None or not np.isfinite(l1) or l1 <= 0:
        l1 = 0.05 * _strokes(x) / (2.0 * fs)
    candidates = []
    for f, lag, (stribeck, sigma2) in itertools.product(SPREAD, LAG_TIMES, curves):
        fs = float(stribeck.Fs)
        shape = NormalizedPaperShape(
            l1=f * l1, alpha=base.alpha, beta_rel=base.beta_rel, curvature=base.curvature,
            quartic=base.quartic,
        ).to_paper(fs)
        C = fs / lag
        if kind == "two-state":
            candidates.append(jaxfric.TwoState(stribeck=stribeck, shape=shape, sigma2=sigma2,
                                               C=C))
        else:
            candidates.append(jaxfric.GMS.from_shape(shape, stribeck, sigma2, C, n_elements))
    return _viscous(_best(candidates, t, x, F, v), t, x, F, v, vel)


def _viscous(model, t, x, F, v, vel):
    """`model`, or the same with a larger ``sigma2`` (`VISCOUS_SHARES`) if one fits the
    measurement better (`_best`). The bins fix the viscous term poorly where the friction
    lag has not settled in them (it bends the curve like a Stribeck drop) or where they
    span a narrow range of speeds; a fit then finds ``sigma2 = 0``, whose floor (0.1 % of
    the largest force at the largest speed) is decades below a viscous term of a few
    percent, and climbing those decades on the log scale took two of the two-state fits
    of tests/fitting/test_fit_properties.py (seeds 12 and 20) 36 and 34 steps instead of
    21 and 19. Only larger values are tried: a smaller ``sigma2`` than the bins' is no better
    supported."""
    v90 = float(np.quantile(np.abs(vel[vel != 0]), 0.9))
    fc = float(model.stribeck.Fc)
    share = float(model.sigma2) * v90 / fc
    more = [eqx.tree_at(lambda m: m.sigma2, model, jnp.asarray(k * fc / v90))
            for k in VISCOUS_SHARES if k > share]
    return _best([model, *more], t, x, F, v) if more else model


def lag_starts(model, fixed=()) -> list[tuple[str, object]]:
    """``[(label, model)]``: the starts a base fit from `model` races (the better training
    fit wins: `fitting._refits.Fitter.race`): `model` itself (``"given start"``) and, for a
    model with a friction lag (a ``C`` and a Stribeck curve: two-state, GMS; with or
    without effects), the same with the fastest lag time ``Fs/C`` of `LAG_TIMES`
    (``"fast-lag start"``) where its own is slower. `initial_model` picks the lag by the
    SSE of crude simulations, before any fit; from a slow lag (seconds) a fit can settle in
    an optimum where the lag acts as a memory of the motion (``sigma2`` -> 0, a flat
    curve), far off the fit from a fast lag, whose held-out predictions are far worse
    (tests/diagnosis/test_lag_race.py). Any other model, or ``C`` among the parameters
    held at their values (`fixed`): `model` alone."""
    base = model.without_effects()
    C, stribeck = getattr(base, "C", None), getattr(base, "stribeck", None)
    if C is None or stribeck is None or "C" in fixed:
        return [("given start", model)]
    fast_C = float(stribeck.Fs) / min(LAG_TIMES)  # as `initial_model` sets it
    if float(C) >= fast_C:
        return [("given start", model)]
    get = (lambda m: m.C) if base is model else (lambda m: m.without_effects().C)
    faster = eqx.tree_at(get, model, jnp.asarray(fast_C, jnp.asarray(C).dtype))
    return [("given start", model), ("fast-lag start", faster)]


def steady_sliding_weights(t, x, F, v=None) -> np.ndarray:
    """Weights for fitting a static model (`jaxfric.Tustin`) where it can represent the
    data: 1 on the steady sliding samples (`fitting._steady.steady_sliding`, beyond twice
    the `swing_travel` of a reversal, or a tenth of the median stroke without one), 0
    elsewhere; all ones when fewer than 10 samples slide steadily. (s, m, N, m/s.)"""
    t, x, F = (np.asarray(a, dtype=np.float64) for a in (t, x, F))
    vel = velocity(t, x) if v is None else np.asarray(v, dtype=np.float64)
    x90 = swing_travel(x, F)
    return steady_weights(t, x, vel, 2.0 * x90 if x90 is not None else 0.1 * _strokes(x))


def gms_like(model, n_elements: int):
    """A GMS with `n_elements` elements that starts where a fitted two-state `model` (any
    presliding shape family) is: its virgin curve interpolates the model's presliding curve
    (`jaxfric.GMS.from_shape`), with the model's Stribeck curve, ``sigma2`` and friction lag
    ``C``. None for a model without a presliding shape (a GMS, LuGre or Tustin model),
    and for a curve that is not concave at the breakpoints (a GMS element of negative
    stiffness). A richer base model started here starts near the fitted one, instead of
    in an optimum of its own read off the data."""
    shape = getattr(model, "shape", None)
    if shape is None or not isinstance(model, jaxfric.TwoState):
        return None
    gms = jaxfric.GMS.from_shape(shape, model.stribeck, model.sigma2, model.C, n_elements)
    return gms if bool(np.all(np.asarray(gms.k) > 0)) else None
