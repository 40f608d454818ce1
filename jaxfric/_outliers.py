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

Moderate outliers (a spike of 10 or 100 times the force) are left to the user: they are
possible in real data (impacts), and the fit's residuals show them.
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
