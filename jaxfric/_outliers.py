"""Absurd outliers: one sample many orders of magnitude beyond the rest of its column.

A sensor glitch or a corrupted cell (a force of 1e154 N among forces of 1 N, a position
jump of 1e10 m) would dominate a least-squares fit (its square alone can overflow to
infinity) and leave the solver at its start values. Such a sample cannot be friction, so
it is refused with its place and value rather than fitted or silently dropped (a dropped
sample would change the data the user believes was fitted). Two rules, both on one column:

- absolute: beyond the SI limits of `jaxfric.data.ABSURD` (files; `fitting` uses the
  rotary limits, the loosest, for arrays given without units);
- relative (`relative_outlier`): farther from the column's median than `OUTLIER_FACTOR`
  times the column's spread: the distance from the median that all but the farthest
  ``max(1, n // 100)`` samples keep to (about the 99th percentile of the distances,
  never the glitch itself in a short record). It is the spread of the column's own signal
  whatever up to 1 % of glitches do: a sample is
  refused only when it is 1000 times farther out than 99 % of the data, which friction
  data, whose force and motion fill more than 1 % of a record, do not produce. (A record
  at rest for over 99 % of its samples, with its motion 1000 times the resting noise,
  would be refused: not an identification experiment.) A column constant over 99 % of
  its samples has no spread to compare with and is not judged.

Moderate outliers (`spikes`: a force sample 10 to 50 times the noise away from its
neighbours, where the motion is steady) are possible in real data (an impact) and are not
refused: `jaxfric.data.load` warns (`DataWarning`) naming their rows and lines, and they
are fitted as given. A friction peak sampled once (a breakaway, a stop, a speed change, a
ripple sampled a few times per period) looks like a spike to the force column alone, so
the rules also look at the motion and at the residuals around (see `spikes`); they find
none in the demo's data, in synthetic records with cogging or inertia sampled coarsely,
in the measured records of ../shared/data, nor in 1.9e5 samples of Gaussian noise on
strokes (tests/cli/test_reliability.py).
"""

import numpy as np


#: A sample farther from the median than this many times the column's spread is refused.
OUTLIER_FACTOR = 1e3
#: Share of samples the spread may leave out (at least one).
SPREAD_EXCLUDES = 0.01


def spread(values: np.ndarray) -> float:
    """Distance from the median that all but the farthest ``max(1, n * SPREAD_EXCLUDES)``
    finite samples of `values` keep to."""
    a = np.asarray(values, dtype=np.float64)
    a = a[np.isfinite(a)]
    dist = np.abs(0.5 * a - 0.5 * np.median(a))  # halved: no overflow near 1e308
    m = max(1, int(a.size * SPREAD_EXCLUDES))
    return 2.0 * float(np.partition(dist, a.size - 1 - m)[a.size - 1 - m])


def relative_outlier(values) -> tuple[int, float, float] | None:
    """``(index, ratio, spread)`` of the sample farthest from the median of `values` (1-D)
    if its distance is more than `OUTLIER_FACTOR` times the column's `spread`; else
    ``None``. Non-finite values are skipped (they are refused elsewhere)."""
    a = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(a)
    if finite.sum() < 10:
        return None
    # Halved: a - median can overflow for values near the float64 limit.
    half = 0.5 * np.median(a[finite])
    dist = np.where(finite, np.abs(0.5 * a - half), 0.0)
    ref = 0.5 * spread(a)
    i = int(np.argmax(dist))
    if ref == 0 or dist[i] <= OUTLIER_FACTOR * ref:
        return None
    return i, float(dist[i] / ref), 2.0 * ref


def message(name: str, value: float, ratio: float, spread: float) -> str:
    """The body of a refusal: what the value is against the rest of its column."""
    return (f"{float(value):.6g} is {ratio:.2g} times farther from the median than 99 % of "
            f"the samples of {name!r} (within {spread:.3g} of it): a glitch, not a "
            "measurement")


#: A force sample is a spike when it is farther than this many times the noise from what
#: its four neighbours predict (and see `spikes`).
SPIKE_NOISE = 8.0
#: ... and farther than this share of the column's `spread` (noise-free data have no noise
#: to compare with).
SPIKE_FLOOR = 0.01
#: More spikes than this share of the samples are the signal's own character (stick-slip,
#: a quantised sensor), not isolated glitches: not reported.
SPIKE_MOST = 0.01
# The residual of the cubic through the four neighbours has sqrt(1 + 2 (1 + 16) / 36)
# times the noise's standard deviation.
_RESIDUAL_GAIN = float(np.sqrt(1.0 + 34.0 / 36.0))


#: A speed changing by more than this factor within two samples of a sample (or a change
#: of direction there) is a motion event: a spike there is not reported.
SPIKE_EVENT_RATIO = 1.25


def motion_events(t, x, idx=None) -> np.ndarray:
    """Whether samples `idx` (default: all) are within two of a change of direction or of
    a speed change by more than `SPIKE_EVENT_RATIO` (central-difference velocity): where
    friction itself can peak for one sample (a breakaway, a stop), so a spike there is not
    a glitch for sure."""
    t, x = np.asarray(t, dtype=np.float64), np.asarray(x, dtype=np.float64)
    last = t.size - 1
    idx = np.arange(t.size) if idx is None else np.asarray(idx)
    v = []
    for k in range(-2, 3):
        j = np.clip(idx + k, 0, last)
        lo, hi = np.maximum(j - 1, 0), np.minimum(j + 1, last)
        v.append((x[hi] - x[lo]) / (t[hi] - t[lo]))
    v = np.array(v)
    speed = np.abs(v)
    turning = np.sign(v).min(axis=0) != np.sign(v).max(axis=0)
    return turning | (speed.max(axis=0) > SPIKE_EVENT_RATIO * speed.min(axis=0))


def _residuals(a: np.ndarray) -> np.ndarray:
    """``r[j]``: sample ``j + 2`` less the cubic through its two neighbours on each side,
    computed in place (one array: `jaxfric.data.load` keeps its peak memory low)."""
    r = a[1:-3] + a[3:-1]
    r *= 4.0
    r -= a[:-4]
    r -= a[4:]
    r /= -6.0
    r += a[2:-2]
    return r


def _noise(r: np.ndarray) -> float:
    """The standard deviation of the noise from the median absolute deviation of the
    residuals `r` (one scratch array)."""
    work = r.copy()
    k = work.size // 2
    work.partition(k)
    np.subtract(r, work[k], out=work)
    np.abs(work, out=work)
    work.partition(k)
    return 1.4826 * float(work[k]) / _RESIDUAL_GAIN


def _abs_at(r: np.ndarray, j: np.ndarray, offsets) -> np.ndarray:
    """The largest ``|r|`` at ``j + k`` for the `offsets` k (0 beyond the ends)."""
    out = np.zeros(j.size)
    for k in offsets:
        jj = j + k
        ok = (jj >= 0) & (jj < r.size)
        out[ok] = np.maximum(out[ok], np.abs(r[jj[ok]]))
    return out


def spikes(values, t=None, x=None) -> tuple[np.ndarray, np.ndarray, float]:
    """``(indices, sizes, noise)`` of the isolated spikes of `values` (1-D, finite): sizes
    in units of `noise`, the standard deviation of the column's sample-to-sample noise.
    With the motion (`t`, `x`), spikes at `motion_events` are not reported.

    Sample ``i`` (not among the first or last two) is a spike when its residual ``r`` from
    the cubic through samples ``i-2, i-1, i+1, i+2`` exceeds `SPIKE_NOISE` times the noise
    and `SPIKE_FLOOR` times the column's `spread`; when it stands out from both neighbours
    ``i-1`` and ``i+1`` by more than ``|r|/2`` on the side of ``r`` (a step, as a reversal
    sampled coarsely makes, stands out on one side only); and when those neighbours agree
    to within ``|r|/2`` (a peak sampled once on a slope, such as a breakaway peak between a
    rise and a plateau, has neighbours far apart); and when the residuals three and four
    samples away are below ``|r|/2`` (a ripple sampled a few times per period is not
    isolated), those two away below ``|r|`` and those one away below ``1.25 |r|`` (a
    spike's neighbours have 1/6 and 2/3 of its residual: so only the spike itself is
    named, not a neighbour). The noise is the median absolute deviation of the residuals (robust to
    the spikes themselves), so a smooth signal's curvature does not count. None are
    reported when more than `SPIKE_MOST` of the samples would be (or ten times that many
    pass the first rule)."""
    a = np.asarray(values, dtype=np.float64)
    none = (np.zeros(0, int), np.zeros(0), 0.0)
    if a.size < 20 or not np.isfinite(a).all():
        return none
    floor = SPIKE_FLOOR * spread(a)
    r = _residuals(a)
    noise = _noise(r)
    limit = max(SPIKE_NOISE * noise, floor)
    j = np.flatnonzero((r > limit) | (r < -limit))
    if j.size == 0 or j.size > 10 * SPIKE_MOST * a.size:
        return none
    i = j + 2
    size = np.abs(r[j])
    s = np.sign(r[j])
    found = ((s * (a[i] - a[i - 1]) > size / 2) & (s * (a[i] - a[i + 1]) > size / 2)
             & (np.abs(a[i + 1] - a[i - 1]) < size / 2)
             & (_abs_at(r, j, (-4, -3, 3, 4)) < size / 2)
             & (_abs_at(r, j, (-1, 1)) < 1.25 * size) & (_abs_at(r, j, (-2, 2)) < size))
    if t is not None and x is not None:
        found &= ~motion_events(t, x, i)
    if not found.any() or found.sum() > SPIKE_MOST * a.size:
        return none
    sizes = size[found] / noise if noise > 0 else np.full(int(found.sum()), np.inf)
    return i[found], sizes, noise
