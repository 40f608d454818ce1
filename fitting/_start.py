"""Starting models read off a measurement, for fits that begin with no prior knowledge.

A least-squares fit needs a start in the right basin; the paper's values (26 N, 4 um/N) are
useless for a 2 N tribometer. `initial_model` takes the scales from the data:

- Stribeck + viscous: from force levels (``Fc`` the median of ``|F|`` while moving,
  ``Fs = 1.2*Fc``, ``Vs`` a fifth of the 90th percentile of ``|v|``, a small ``sigma2``) or,
  when the data have at least three steady constant-velocity segments, from those
  (`initial_stribeck`): whichever static curve fits the force better.
- Presliding extent ``l1``: from the travel after reversals over which the force rises by
  90 % of ``2*Fs`` (`_estimate_l1`); otherwise 5 % of the median stroke.
- Shape: the paper's shape, rescaled to that ``l1`` (self-similar in normalised coordinates).
- ``C``: the paper's friction-lag time constant ``Fs/C`` (2.4 s) kept.
- GMS: `jaxfric.GMS.from_shape` of that shape; LuGre: ``sigma0 = 1/l1`` (the bristles
  saturate over the same presliding extent), ``sigma1`` critically damped for 1 kg.
"""

import numpy as np

import jaxfric
from jaxfric import NormalizedPaperShape, paper
from jaxfric.data import DataError
from jaxfric.motion import travel_since_reversal, velocity

from ._data import Dataset
from ._staged import _estimate_l1, constant_velocity_segments, initial_stribeck


KINDS = ("two-state", "gms", "lugre", "tustin")


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
    # Two candidate curves; keep the one whose static force s(v) + sigma2*v fits better
    # where the data surely slide: moving, beyond half the median stroke from the last
    # reversal (segment means can be presliding, not sliding, on short strokes).
    sliding = (vel != 0) & (travel_since_reversal(x) > 0.5 * _strokes(x))
    if sliding.sum() < 3:
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

    stribeck, sigma2 = min(candidates, key=static_rss)
    if kind == "tustin":
        return jaxfric.Tustin(stribeck=stribeck, sigma2=sigma2)
    fs = float(stribeck.Fs)
    C = paper.C * fs / float(paper.stribeck().Fs)
    base = NormalizedPaperShape.from_paper(paper.shape(), paper.stribeck().Fs)
    model = jaxfric.TwoState(stribeck=stribeck, shape=base.to_paper(fs), sigma2=sigma2, C=C)
    l1 = _estimate_l1(model, Dataset(t=t, x=x, F=F))
    if l1 is None or not np.isfinite(l1) or l1 <= 0:
        l1 = 0.05 * _strokes(x) / (2.0 * fs)
    shape = NormalizedPaperShape(
        l1=l1, alpha=base.alpha, beta_rel=base.beta_rel, curvature=base.curvature,
        quartic=base.quartic,
    ).to_paper(fs)
    if kind == "two-state":
        return jaxfric.TwoState(stribeck=stribeck, shape=shape, sigma2=sigma2, C=C)
    if kind == "gms":
        return jaxfric.GMS.from_shape(shape, stribeck, sigma2, C, n_elements)
    # The bristles saturate (z -> g/sigma0) over about the presliding extent ``l1*Fs``:
    # sigma0 = 1/l1. (The shape's initial stiffness, tens of times larger for a paper-like
    # curve, makes LuGre slide within a few um of a reversal: on the 60-element GMS truths
    # of `jaxfric.synthetic` that start was about four times further from the data.)
    sigma0 = 1.0 / float(l1)
    return jaxfric.LuGre(stribeck=stribeck, sigma0=sigma0, sigma1=2.0 * sigma0**0.5, sigma2=sigma2)
