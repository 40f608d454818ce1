"""Where a model fails: the regimes of a motion and the error in each.

**Per-regime errors** (`regimes`, `compare`): RMSE overall and in presliding (within a
travel window after a reversal), reversal windows (a time window around each reversal),
sliding by speed band, and acceleration phases.
"""

import itertools

import numpy as np

from jaxfric.motion import reversals


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
    rev, start = reversals(np.sign(v))
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

