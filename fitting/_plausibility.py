"""Is a fitted model plausible for the right reasons? Three checks run on the base model (its
added effects removed: its presliding and lag are what could take effects up), by
simulation (so they hold for every model kind), against the scale of the measured motion:

- **presliding range**: from steady sliding at the typical speed, the motion reverses; the
  travel after which the force has covered 90 % of its swing to the new sliding level.
  Flagged when it exceeds half a long stroke (`_strokes`): the model then treats most of each stroke
  as presliding, and its hysteresis can take up what sliding effects (drag, position
  dependence, a load) should explain.
- **lag time**: a step between two sliding speeds (the 25th and 75th percentiles of the
  measured sliding speed); the time the force takes to cover 63 % of its change. Flagged
  when it exceeds half the duration of that stroke: the lag then acts as a memory of
  the motion, able to take up slow effects (drift, warm-up, a position-dependent load).
- **steady state**: where the measurement slides at a nearly constant speed, the model's
  own prediction against its steady state at that speed (`steady_state`). Flagged when they
  differ by more than 10 % of the sliding force level: the fit then relies on a state that
  never settles instead of on its friction curve.

- **friction curve**: a Stribeck curve whose level at rest ``Fs`` is below 90 % of its
  sliding level ``Fc`` rises with speed. Flagged: over the measured speeds it can stand in
  for viscous friction or a drag (on the EMPS record a two-state fit once traded a viscous
  coefficient of 203 N s/m for ``Fs`` 10.9 N, ``Fc`` 59.8 N; docs/diagnosis.md), unless the
  contact is velocity-strengthening.
- **sliding level beyond the data**: at the fastest measured speed the Stribeck curve has
  covered less than half of its way from ``Fs`` to ``Fc``. Not wrong, but ``Fc`` (and the
  curve above the measured speeds) is then extrapolation, not measurement (on the EMPS
  record: ``Vs`` 128 mm/s, the fastest speed 127.8 mm/s, ``Fc`` 0.0003 N).

`steady_state` is also the static curve a report can draw: the force the whole model
(effects included, e.g. an offset) reaches after sliding at constant speed.
"""

import numpy as np

import jaxfric
from jaxfric.motion import reversals


def _strokes(t, x, v):
    """A long stroke of the motion (m) and its duration (s): the stroke between reversals
    at the 90th percentile of their lengths. A model whose presliding or lag spans even the
    long strokes has taken up more than presliding and lag."""
    rev, _ = reversals(np.sign(v))
    idx = np.r_[0, np.flatnonzero(rev), t.size - 1]
    lengths = np.abs(np.diff(x[idx]))
    durations = np.diff(t[idx])
    keep = lengths > 0
    if not keep.any():
        return float(np.ptp(x)) or 1e-3, float(t[-1] - t[0]) or 1.0
    lengths, durations = lengths[keep], durations[keep]
    k = int(np.argsort(lengths)[int(0.9 * (lengths.size - 1))])
    return float(lengths[k]), float(durations[k])


def _sliding_speeds(v):
    speed = np.abs(v[v != 0])
    if speed.size == 0:
        return 1e-3, 1e-3, 1e-3
    lo, mid, hi = np.quantile(speed, [0.25, 0.5, 0.75])
    return float(lo), float(mid), float(hi)


#: Samples of every simulated motion here: one length, one compiled simulation.
SAMPLES = 4000


def _simulate(model, t, x, v):
    """`jaxfric.simulate` at zero transmitted load (`jaxfric.effects.LoadFriction` adds
    nothing), as every motion here is simulated (one compiled program per model)."""
    return np.asarray(jaxfric.simulate(model, t, x, v, load=np.zeros_like(t)))


def steady_state(model, speeds, duration: float, samples: int = SAMPLES,
                 at: float = 0.0) -> np.ndarray:
    """The force (N) `model` reaches after sliding at each of `speeds` (m/s, signed) for
    `duration` seconds from rest, arriving at position `at` (m; where position-dependent
    effects are evaluated), at zero transmitted load (`jaxfric.effects.LoadFriction`
    adds nothing there)."""
    t = np.linspace(0.0, duration, samples)
    out = []
    for s in np.asarray(speeds, float):
        x = at + s * (t - duration)
        v = np.full_like(t, s)
        out.append(float(_simulate(model, t, x, v)[-1]))
    return np.asarray(out)


def _presliding_range(model, speed, stroke, samples=SAMPLES):
    """Travel (m) after a reversal until the force has covered 90 % of its swing."""
    n1 = samples // 2
    t = np.linspace(0.0, 4 * stroke / speed, samples)
    dt = t[1]
    v = np.r_[np.full(n1, -speed), np.full(samples - n1, speed)]
    x = np.cumsum(np.r_[0.0, v[1:] * dt])
    f = _simulate(model, t, x, v)
    after = f[n1 - 1:]
    swing = after[-1] - after[0]
    if swing == 0:
        return 0.0
    reached = np.flatnonzero((after - after[0]) / swing >= 0.9)
    travel = np.abs(x[n1 - 1:] - x[n1 - 1])
    return float(travel[reached[0]]) if reached.size else float(travel[-1])


def _lag_time(model, v_lo, v_hi, settle):
    """Time (s) for the force to cover 63 % of its change after a speed step from `v_lo` to
    `v_hi` (held `settle` s each); the change is the one between the model's steady states
    (reached after 10^4 `settle`), so a lag too slow to move within the window is measured
    as at least the window."""
    t = np.linspace(0.0, 2 * settle, SAMPLES)
    v = np.where(t < settle, v_lo, v_hi)
    x = np.cumsum(np.r_[0.0, v[1:] * t[1]])
    f = _simulate(model, t, x, v)
    k = int(np.searchsorted(t, settle))
    lo, hi = steady_state(model, [v_lo, v_hi], 1e4 * settle)
    change = hi - f[k - 1]
    if abs(hi - lo) < 1e-9 * max(abs(hi), 1.0) or abs(change) < 1e-12:
        return 0.0
    reached = np.flatnonzero((f[k - 1:] - f[k - 1]) / change >= 1 - np.exp(-1))
    return float(t[k - 1 + reached[0]] - t[k - 1]) if reached.size else float(t[-1] - t[k - 1])


def plausibility(model, t, x, v, F, *, a=None, load=None) -> list[str]:
    """Plain-words warnings about `model` fitted to ``(t, x, v, F)`` (SI) with its
    prediction: see the module docstring. Empty when nothing is implausible. The
    checks are on the base model (its added effects removed): its presliding and lag are
    what could take up effects. `a` and `load` change nothing for the base model, but
    given as the fit had them, its compiled simulation is reused."""
    t, x, v, F = (np.asarray(arr, np.float64) for arr in (t, x, v, F))
    model = model.without_effects()
    pred = np.asarray(jaxfric.simulate(model, t, x, v, a=a, load=load))
    stroke, stroke_time = _strokes(t, x, v)
    lo, mid, hi = _sliding_speeds(v)
    level = float(np.median(np.abs(F[np.abs(v) >= mid]))) if np.any(np.abs(v) >= mid) else 1.0
    flags = []
    reach = _presliding_range(model, mid, stroke)
    if reach > 0.5 * stroke:
        flags.append(
            f"presliding range {1e6 * reach:.4g} um (90 % of the force swing after a reversal) "
            f"is {100 * reach / stroke:.3g} % of a long stroke ({1e6 * stroke:.4g} um): the "
            "model treats most of each stroke as presliding and its hysteresis can take up "
            "sliding effects")
    tau = _lag_time(model, lo, hi, max(stroke_time, 10 * float(np.median(np.diff(t)))))
    if tau > 0.5 * stroke_time:
        flags.append(
            f"lag time {tau:.3g} s is {100 * tau / stroke_time:.3g} % of a long stroke's "
            f"duration ({stroke_time:.3g} s): the lag acts as a memory of the motion and can "
            "take up slow effects (drift, warm-up, a position-dependent load)")
    flags += _steady_flags(model, t, x, v, pred, level, stroke)
    return flags + _curve_flags(model) + _extrapolation_flags(model, v)


def _curve_flags(model) -> list[str]:
    """A Stribeck curve that rises with speed (module docstring)."""
    curve = getattr(model, "stribeck", None)
    if curve is None or not hasattr(curve, "Fs") or not hasattr(curve, "Fc"):
        return []
    Fs, Fc = float(curve.Fs), float(curve.Fc)
    if not Fs < 0.9 * Fc:
        return []
    sigma2 = getattr(model, "sigma2", None)
    viscous = "" if sigma2 is None else f" (its viscous coefficient: {float(sigma2):.4g} N s/m)"
    return [f"the friction curve rises with speed (Fs {Fs:.4g} N at rest, Fc {Fc:.4g} N "
            f"sliding): over the measured speeds it can stand in for viscous friction or a "
            f"drag{viscous}; read its values with care unless the contact is "
            "velocity-strengthening"]


def _extrapolation_flags(model, v) -> list[str]:
    """A sliding level the data do not reach (module docstring)."""
    curve = getattr(model, "stribeck", None)
    if curve is None or not hasattr(curve, "Fs") or not hasattr(curve, "Fc") or not v.size:
        return []
    Fs, Fc = float(curve.Fs), float(curve.Fc)
    fastest = float(np.max(np.abs(v)))
    drop = Fs - Fc
    if fastest == 0 or abs(drop) <= 0.1 * max(abs(Fs), abs(Fc)):
        return []
    covered = (Fs - float(curve(np.asarray(fastest)))) / drop
    if covered >= 0.5:
        return []
    return [f"the Stribeck curve's sliding level Fc ({Fc:.4g} N) lies beyond the data: at "
            f"the fastest measured speed ({1e3 * fastest:.4g} mm/s) the curve has covered "
            f"{100 * max(covered, 0.0):.3g} % of its way from Fs ({Fs:.4g} N); Fc and the "
            "curve above that speed are extrapolation"]


def _steady_flags(model, t, x, v, pred, level, stroke):
    """Model prediction vs its own steady state where the measurement slides steadily: the
    speed changes by less than 5 % over 50 samples, in the second half of a stroke."""
    dt = np.r_[np.diff(t), np.diff(t)[-1:]]
    a = np.gradient(v, t)
    speed = np.abs(v)
    _, start = reversals(np.sign(v))
    far = np.abs(x - x[start]) > 0.5 * stroke
    steady = (speed > 0) & far & (np.abs(a) * 50 * dt < 0.05 * speed)
    if steady.sum() < 20:
        return []
    grid = np.quantile(v[steady], np.linspace(0.02, 0.98, 15))
    grid = grid[grid != 0]
    if grid.size == 0:
        return []
    curve = steady_state(model, grid, float(t[-1] - t[0]))
    order = np.argsort(grid)
    expected = np.interp(v[steady], grid[order], curve[order])
    gap = float(np.median(np.abs(pred[steady] - expected)))
    if gap > 0.1 * level:
        return [f"in steady sliding the model's force differs from its own steady state by "
                f"{gap:.3g} N (median; the sliding force is about {level:.3g} N): the fit "
                "relies on a state that does not settle (a long lag or presliding memory) "
                "rather than on its friction curve"]
    return []
