"""The steady-state friction curve read off the sliding parts of a measurement.

A start for a fit (`fitting.initial_model`) and the samples a static model is fitted on
(`steady_weights`): where the motion slides steadily, the force of every jaxfric model is
its steady-state curve ``s(v) + sigma2*v`` (Stribeck curve plus viscous term).

- **Steady sliding samples** (`steady_sliding`): moving, further from the last reversal
  than `presliding` (the travel over which the force swings after a reversal; twice the
  travel at which the swing reaches 90 %), and with a velocity that has stayed within
  ``rel_tol`` of its present value over the last `settle` seconds (``|a| * settle`` small
  against ``|v|``). The friction lag's own settling (``|s|/C``, unknown before a fit) is
  not waited for: the median over a speed bin and both directions is what is read.
- **The curve** (`steady_curve`): those samples binned by speed (log bins, `per_decade`
  of them per decade, each direction), the median force per bin; the level of a bin is the
  mean of the two directions' magnitudes where both are there, and their mean is the
  offset (an asymmetric force shows as that offset).
- **The fit** (`fit_steady_curve`): ``Fc + (Fs - Fc)*exp(-(v/Vs)**delta) + sigma2*v`` is
  linear in ``Fc, Fs - Fc, sigma2`` once ``Vs, delta`` are given: a grid over ``Vs`` (the
  speeds the data visit, widened by 3 both ways) and ``delta`` (0.5 .. 2.5), non-negative
  least squares (`scipy.optimize.nnls`, weighted by the square root of each bin's count)
  for the three linear parameters; the best grid point is polished by a bounded
  `scipy.optimize.least_squares` of all five on the bins (a handful of points).
"""

import dataclasses

import numpy as np
from scipy.ndimage import maximum_filter1d, minimum_filter1d
from scipy.optimize import least_squares, nnls

import jaxfric
from jaxfric.motion import travel_since_reversal


#: ``delta`` values of the grid (the Stribeck exponent).
DELTAS = (0.5, 0.75, 1.0, 1.5, 2.0, 2.5)


@dataclasses.dataclass(frozen=True)
class SteadyCurve:
    """The measured steady-state friction curve (NumPy arrays, one entry per speed bin).

    - `speed`: the median ``|v|`` of each bin, m/s, increasing.
    - `force`: the friction level ``|F|`` of each bin, N (both directions' mean where both
      are there, the offset removed).
    - `count`: samples in the bin (both directions).
    - `offset`: the mean of the two directions' forces, N (0 with one direction only).
    - `mask`: the steady sliding samples (a boolean per sample of the measurement).
    """

    speed: np.ndarray
    force: np.ndarray
    count: np.ndarray
    offset: float
    mask: np.ndarray

    def __len__(self) -> int:
        return int(self.speed.shape[0])


def _held_velocity(v: np.ndarray, t: np.ndarray, settle: float, rel_tol: float) -> np.ndarray:
    """True where ``v`` has stayed within ``rel_tol*|v|`` of its present value over the
    last `settle` seconds (at least two samples back; never within them of the start)."""
    n = v.size
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    k = max(2, round(settle / dt))
    # Running max and min over the trailing window [i - k, i].
    hi = maximum_filter1d(v, size=k + 1, origin=k // 2, mode="nearest")
    lo = minimum_filter1d(v, size=k + 1, origin=k // 2, mode="nearest")
    held = np.maximum(hi - v, v - lo) <= rel_tol * np.abs(v)
    held[:k] = False
    return held


def steady_sliding(t, x, v, presliding: float, *, settle: float | None = None,
                   rel_tol: float = 0.1) -> np.ndarray:
    """Boolean mask of the steady sliding samples (module docstring). `t`, `x`, `v` in s,
    m, m/s; `presliding` (m): the travel after a reversal that is not yet sliding;
    `settle` (s): how long the velocity must have held (default 5 % of the record, at most
    0.2 s, at least two samples)."""
    t, x, v = (np.asarray(a, dtype=np.float64) for a in (t, x, v))
    if settle is None:
        settle = min(0.2, 0.05 * float(t[-1] - t[0]))
    moving = v != 0
    beyond = travel_since_reversal(x) > presliding
    return moving & beyond & _held_velocity(v, t, settle, rel_tol)


def steady_curve(t, x, F, v, presliding: float, *, per_decade: int = 4,
                 min_count: int = 5, **options) -> SteadyCurve:
    """The measured steady-state curve (module docstring); `options` go to
    `steady_sliding`."""
    F = np.asarray(F, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    mask = steady_sliding(t, x, v, presliding, **options)
    speed = np.abs(v)
    empty = SteadyCurve(np.zeros(0), np.zeros(0), np.zeros(0, int), 0.0, mask)
    if mask.sum() < min_count:
        return empty
    lo, hi = np.log10(speed[mask].min()), np.log10(speed[mask].max())
    edges = 10.0 ** np.linspace(lo, hi, max(2, int(np.ceil((hi - lo) * per_decade)) + 1))
    edges[0], edges[-1] = 0.0, np.inf
    which = np.digitize(speed, edges) - 1
    rows = []
    for b in range(edges.size - 1):
        sides = {}
        for d in (1, -1):
            m = mask & (which == b) & (np.sign(v) == d)
            if m.sum() >= min_count:
                sides[d] = (float(np.median(F[m])), float(np.median(speed[m])), int(m.sum()))
        if sides:
            rows.append(sides)
    both = [r for r in rows if len(r) == 2]
    offset = float(np.mean([0.5 * (r[1][0] + r[-1][0]) for r in both])) if both else 0.0
    out = []
    for r in rows:
        level = np.mean([d * (f - offset) for d, (f, _, _) in r.items()])
        vm = np.mean([s for _, s, _ in r.values()])
        out.append((vm, level, sum(c for _, _, c in r.values())))
    if not out:
        return empty
    out.sort()
    sp, level, count = (np.asarray(c) for c in zip(*out, strict=True))
    return SteadyCurve(sp, level, count.astype(int), offset, mask)


def _stribeck_columns(speed, vs, delta):
    return np.column_stack([np.ones_like(speed), np.exp(-((speed / vs) ** delta)), speed])


def fit_steady_curve(curve: SteadyCurve, *, deltas=DELTAS, n_vs: int = 24
                     ) -> tuple[jaxfric.Stribeck, float, float]:
    """``(stribeck, sigma2, rms)``: the Stribeck curve and viscous term (N s/m) whose
    steady state ``s(v) + sigma2*v`` fits the bins of `curve` best (module docstring), and
    the weighted RMS misfit (N). `deltas`: the exponents tried (one value holds it; the
    polish keeps it within their range). Needs 3 bins or more (`ValueError` otherwise)."""
    if len(curve) < 3:
        raise ValueError(f"need 3 speed bins of steady sliding for a steady-state curve, got "
                         f"{len(curve)}")
    speed, force = curve.speed, curve.force
    w = np.sqrt(curve.count / curve.count.mean())
    grid = np.geomspace(speed[0] / 3.0, speed[-1] * 3.0, n_vs)
    best = None
    for vs in grid:
        for delta in deltas:
            A = _stribeck_columns(speed, vs, delta)
            coef, res = nnls(A * w[:, None], force * w)
            if best is None or res < best[0]:
                best = (res, vs, delta, coef)
    res, vs, delta, (fc, dfs, sigma2) = best
    # Polish from the grid's best (bounded: non-negative levels, Vs within the grid, delta
    # within `deltas`).
    free_delta = min(deltas) < max(deltas)

    def unpack(p):
        return np.exp(p[0]), (p[1] if free_delta else delta), p[-3:]

    def residual(p):
        vs_, delta_, lin = unpack(p)
        return (_stribeck_columns(speed, vs_, delta_) @ lin - force) * w

    scale = max(float(force.max()), 1e-12)
    keep = [True, free_delta, True, True, True]
    p0 = np.array([np.log(vs), delta, fc, dfs, sigma2])[keep]
    lo = np.array([np.log(grid[0]), min(deltas), 0.0, 0.0, 0.0])[keep]
    hi = np.array([np.log(grid[-1]), max(deltas), 10.0 * scale, 10.0 * scale, np.inf])[keep]
    polished = least_squares(residual, np.clip(p0, lo, hi), bounds=(lo, hi), x_scale="jac")
    if polished.success and np.linalg.norm(polished.fun) < res:
        res = float(np.linalg.norm(polished.fun))
        vs, delta, (fc, dfs, sigma2) = unpack(polished.x)
    if fc <= 0:  # the whole level in the exponential: no sliding plateau in the data
        fc, dfs = fc + dfs, 0.0
    fc = max(fc, 1e-3 * max(float(force.max()), 1e-12))
    # Likewise a viscous term of at least 0.1 % of the largest force at the largest speed:
    # 0 is outside the log scale sigma2 is fitted on, and a start of 1e-17 would take the
    # fit dozens of steps to leave.
    sigma2 = max(sigma2, 1e-3 * max(float(force.max()), 1e-12) / speed[-1])
    stribeck = jaxfric.Stribeck(Fs=fc + dfs, Fc=fc, Vs=vs, delta=float(delta))
    return stribeck, float(sigma2), float(res / np.sqrt(np.sum(w**2)))


def steady_weights(t, x, v, presliding: float, **options) -> np.ndarray:
    """Weights (1 on the steady sliding samples, 0 elsewhere) for fitting a static model
    (`jaxfric.Tustin`) where it can represent the data; all ones when fewer than 10
    samples slide steadily."""
    mask = steady_sliding(t, x, v, presliding, **options)
    return mask.astype(np.float64) if mask.sum() >= 10 else np.ones(mask.size)
