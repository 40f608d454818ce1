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
the rules also look at the motion and at the residuals around (see `spikes`); they found
none in the demo's data, the synthetic measurements of `jaxfric.synthetic` and
`jaxfric.examples`, the measured records of ../shared/data, nor in 1.9e5 samples of
Gaussian noise on strokes (tests/test_reliability.py).
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


def motion_events(t, x) -> np.ndarray:
    """Samples within two of a change of direction or of a speed change by more than
    `SPIKE_EVENT_RATIO` (central-difference velocity): where friction itself can peak for
    one sample (a breakaway, a stop), so a spike there is not a glitch for sure."""
    v = np.gradient(np.asarray(x, dtype=np.float64), np.asarray(t, dtype=np.float64))
    windows = np.lib.stride_tricks.sliding_window_view(np.pad(v, 2, mode="edge"), 5)
    low, high = np.abs(windows).min(axis=1), np.abs(windows).max(axis=1)
    turning = np.sign(windows).min(axis=1) != np.sign(windows).max(axis=1)
    return turning | (high > SPIKE_EVENT_RATIO * low)


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
    samples away are below ``|r|/2.5`` (a ripple sampled a few times per period is not
    isolated) and those one and two away below ``|r|``. The noise is the median absolute
    deviation of the residuals (robust to the spikes themselves), so a smooth signal's
    curvature does not count. None are reported when more than `SPIKE_MOST` of the samples
    would be."""
    a = np.asarray(values, dtype=np.float64)
    none = (np.zeros(0, int), np.zeros(0), 0.0)
    if a.size < 20 or not np.isfinite(a).all():
        return none
    left2, left, mid, right, right2 = a[:-4], a[1:-3], a[2:-2], a[3:-1], a[4:]
    r = mid - (4.0 * (left + right) - left2 - right2) / 6.0
    noise = 1.4826 * float(np.median(np.abs(r - np.median(r)))) / _RESIDUAL_GAIN
    size = np.abs(r)
    s = np.sign(r)
    found = ((size > SPIKE_NOISE * noise) & (size > SPIKE_FLOOR * spread(a))
             & (s * (mid - left) > size / 2) & (s * (mid - right) > size / 2)
             & (np.abs(right - left) < size / 2))
    if t is not None and x is not None:
        found &= ~motion_events(t, x)[2:-2]
    # Isolated: the residuals three and four samples away (beyond the reach of a spike's
    # own) are small; a ripple sampled a few times per period (cogging at speed) is not.
    far = np.pad(size, 4)
    around = np.max([far[k:k + size.size] for k in (0, 1, 7, 8)], axis=0)
    found &= around < size / 2.5
    # The largest residual within two samples: a spike's neighbours have 2/3 of its own.
    near = np.max([far[k:k + size.size] for k in (2, 3, 5, 6)], axis=0)
    found &= size > near
    idx = np.flatnonzero(found)
    if idx.size == 0 or idx.size > SPIKE_MOST * a.size:
        return none
    sizes = size[idx] / noise if noise > 0 else np.full(idx.size, np.inf)
    return idx + 2, sizes, noise
