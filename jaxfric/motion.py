"""The motion ``(t, x[, v])``: derivatives, direction, reversals, and the model inputs.

One place for what every layer derives from a motion: the velocity by backward difference
(what `jaxfric.simulate` uses, and a causal controller can compute) or by a central
difference over a window (smoother, for identification), the direction of motion and its
reversals, and the travel since the last reversal. `make_motion` turns a motion into the
per-sample arrays the models need (`Motion`). Everything here is vectorised over samples;
the models' sequential parts get these arrays. See docs/algorithm.md section 1 for the
rules (one direction signal, backward difference).

Against noisy standstill: `play` (a deadband on the position), `played_velocity`, and the
data-driven decision `deadband_choice` / `auto_deadband` (the command line's default).

The functions on NumPy arrays (`velocity`, `smooth_derivatives`, `reversals`,
`travel_since_reversal`, `estimate_deadband`, `deadband_choice`, `auto_deadband`) are for
data analysis outside compiled code; `backward_velocity`, `play`, `played_velocity`,
`make_motion` and `Motion` are JAX and run under ``jit``/``vmap``/``grad``.
"""

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._numerics import running_max


class Motion(eqx.Module):
    """A motion resampled into what every model needs, one entry per sample.

    - `t`, `x`, `v`: time (s), position (m), velocity (m/s).
    - `dt`: ``t_n - t_{n-1}`` (s), 0 at ``n = 0``.
    - `dx`: ``x_n - x_{n-1}`` (m), 0 at ``n = 0``.
    - `d`: direction ``sign(v_n)`` as a float in {-1, 0, 1}.
    - `last_d`: direction of the last moving sample at or before ``n`` (0 before any motion).
    - `prev_last_d`: the same at ``n - 1`` (0 at ``n = 0``).
    - `x_prev`: ``x_{n-1}`` (``x_0`` at ``n = 0``): the reversal point when one happens at n.
    - `load`: the transmitted load (N, or N m on a rotary axis) that load-dependent
      effects (`jaxfric.effects.LoadFriction`) read, or ``None`` when none was given.
    - `a`: the acceleration (m/s^2) that effects reading it (`jaxfric.effects.Inertia`)
      see, or ``None``: the backward difference of `v`, what a controller's per-sample
      step computes. Identification passes a zero-phase estimate (`fitting._derivatives`).
    - `max_reversals`: a static upper bound on the number of reversals (`reversal` true),
      or ``None`` (up to ``n``). `TwoState` evaluates its reversal terms on a list of this
      size rather than on every sample; `reversal_bound` computes one from concrete data.
    """

    t: Float[Array, " n"]
    x: Float[Array, " n"]
    v: Float[Array, " n"]
    dt: Float[Array, " n"]
    dx: Float[Array, " n"]
    d: Float[Array, " n"]
    last_d: Float[Array, " n"]
    prev_last_d: Float[Array, " n"]
    x_prev: Float[Array, " n"]
    load: Float[Array, " n"] | None = None
    a: Float[Array, " n"] | None = None
    max_reversals: int | None = eqx.field(static=True, default=None)

    @property
    def moving(self) -> Array:
        return self.d != 0

    @property
    def reversal(self) -> Array:
        """True at the first moving sample whose direction differs from the last motion's."""
        return self.moving & (self.prev_last_d != 0) & (self.d != self.prev_last_d)

    def consistent(self) -> "Motion":
        """This motion with `v` replaced by `consistent_velocity` (and the directions
        re-derived): what the models with a memory in position (`TwoState`, `GMS`) use."""
        v = consistent_velocity(self.v, self.dx, self.dt)
        return make_motion(self.t, self.x, v, self.max_reversals, self.load, self.a)


def consistent_velocity(v: Array, dx: Array, dt: Array) -> Array:
    """The velocity (m/s) the hysteresis models take their direction from: `v` where its
    sign agrees with the position step `dx` (m) or either is 0, the step's backward
    difference ``dx / dt`` (0 for ``dt <= 0``) where the two disagree (a noisy velocity
    column). So the direction of motion and the displacement come from one signal
    (docs/algorithm.md section 1) and the hysteresis force stays within the Stribeck
    bounds whatever `v` is given."""
    v, dx, dt = jnp.asarray(v), jnp.asarray(dx), jnp.asarray(dt)
    disagree = v * dx < 0
    ok = dt > 0
    return jnp.where(disagree, jnp.where(ok, dx / jnp.where(ok, dt, 1.0), 0.0), v)


def play(x: Array, deadband) -> Array:
    """The position `x` (m) seen through a play (backlash) of half-width `deadband` (m):
    ``p_0 = x_0``, ``p_n = clip(p_{n-1}, x_n - deadband, x_n + deadband)``. `p` moves only
    when `x` leaves the band around it, so noise and encoder toggling at standstill smaller
    than the band give no motion, no reversal and no presliding loop; a real motion is
    followed with a lag of at most `deadband`. ``deadband = 0`` gives `x` itself.

    A move of `p` by no more than ``1e-9 * deadband`` is not made: with a deadband of one
    encoder count, ``x_n - deadband`` lands on the previous count only up to rounding, and
    those 1e-19 m moves would be reversals of their own."""
    x = jnp.asarray(x)
    b = jnp.asarray(deadband, dtype=x.dtype)

    def body(p, xn):
        c = jnp.clip(p, xn - b, xn + b)
        p = jnp.where(jnp.abs(c - p) <= 1e-9 * b, p, c)
        return p, p

    _, p = jax.lax.scan(body, x[0], x)
    return p


def played_velocity(p: Array, v: Array) -> Array:
    """A velocity column `v` (m/s) made to agree with the played position `p` (m, from
    `play`): 0 where `p` stands and `v` points against the direction `p` last moved in (or
    `p` has not moved yet), `v` elsewhere. So the noise of a measured velocity at
    standstill makes no reversal that the played position does not make, while a slow
    motion between two encoder counts keeps its velocity."""
    p, v = jnp.asarray(p), jnp.asarray(v)
    d = jnp.sign(jnp.diff(p, prepend=p[:1]))
    idx = jnp.arange(d.shape[0], dtype=jnp.int32)
    last = running_max(jnp.where(d != 0, idx, -1))
    last_d = jnp.where(last >= 0, d[jnp.maximum(last, 0)], 0.0)
    return jnp.where((d == 0) & (v * last_d <= 0), 0.0, v)


def estimate_deadband(x) -> float:
    """A deadband (m) for `play` from the position record `x` (concrete): the larger of
    the encoder step (the smallest non-zero position step, when the record is quantised,
    i.e. that step is at least 1 % of the median non-zero step) and six times the
    position noise, estimated robustly from second differences (``1.4826 * median|d2x| /
    sqrt(6)`` for white noise; smooth motion sampled finely adds little to ``d2x``).
    0 for a record without steps."""
    x = np.asarray(x, dtype=np.float64)
    steps = np.abs(np.diff(x))
    steps = steps[steps > 0]
    if steps.size == 0:
        return 0.0
    smallest = float(np.min(steps))
    quantum = smallest if smallest >= 0.01 * float(np.median(steps)) else 0.0
    d2 = np.abs(np.diff(x, 2))
    sigma = 1.4826 * float(np.median(d2)) / np.sqrt(6.0) if d2.size else 0.0
    return float(max(quantum, 6.0 * sigma))


#: Consecutive reversals within the noise band that make `deadband_choice` apply the play:
#: several fake presliding loops in a row, which nest into the memory stack. A clean
#: record has isolated ones at most (a one-count wiggle at a real reversal).
CHATTER_RUN = 4


class DeadbandChoice(NamedTuple):
    """What `deadband_choice` decided and why (positions in m, or rad on a rotary axis).

    - `deadband`: the half-width to play the positions through (`play`), or None.
    - `estimate`: `estimate_deadband` of the positions (the noise band), applied or not.
    - `reversals`: direction reversals of the unplayed motion.
    - `within_band`: those whose stroke since the previous reversal point is within the
      band (at most `estimate`): noise or one encoder count could have made them.
    - `longest_run`: the most such reversals in a row.
    - `reason`: the decision in words, for a log.
    """

    deadband: float | None
    estimate: float
    reversals: int
    within_band: int
    longest_run: int
    reason: str


def _longest_run(mask: np.ndarray) -> int:
    edges = np.diff(np.r_[0, mask.astype(np.int8), 0])
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return int(np.max(ends - starts, initial=0))


def deadband_choice(x, v=None, t=None) -> DeadbandChoice:
    """Decide from the data whether the positions `x` (m or rad; concrete) need a deadband.

    The rule (the command line's default ``--deadband auto``): estimate the noise band
    ``b = estimate_deadband(x)``; find the direction reversals (of ``sign(dx)``, or of the
    consistent velocity when `v`, with `t`, is given: the direction the models use) and
    call a reversal *within the band* when the stroke since the previous reversal point
    is at most ``b``. Apply ``b`` only when `CHATTER_RUN` (4) or more such reversals come
    in a row somewhere: a standstill's noise chatter (most reversals of a noisy
    standstill, hundreds in a row), which nests fake loops into the memory stack.
    Isolated ones (a one-count wiggle at a real reversal: 7 of the
    tribometer's 117, none in a row) are left alone, so a clean file keeps its positions.
    """
    x = np.asarray(x, dtype=np.float64)
    b = estimate_deadband(x)
    dx = np.r_[0.0, np.diff(x)]
    if v is None or t is None:
        d = np.sign(dx)
    else:
        dt = np.r_[0.0, np.diff(np.asarray(t, dtype=np.float64))]
        d = np.sign(np.asarray(consistent_velocity(np.asarray(v, dtype=np.float64), dx, dt)))
    rev, _ = reversals(d)
    points = np.r_[0, np.flatnonzero(rev) - 1]  # x_0, then each reversal point
    strokes = np.abs(np.diff(x[points]))
    within = strokes <= b * (1.0 + 1e-6)  # one count equals b up to rounding
    n, k, run = int(strokes.size), int(np.count_nonzero(within)), _longest_run(within)
    if b == 0:
        return DeadbandChoice(None, b, n, k, run, "the positions do not move")
    if run >= CHATTER_RUN:
        return DeadbandChoice(b, b, n, k, run, f"{k} of {n} reversals were within the "
                              f"position noise band, {run} of them in a row")
    if k == 0:
        why = f"no reversal within the position noise band ({n} reversals)"
    else:
        why = (f"{k} of {n} reversals within the position noise band, at most {run} in a "
               f"row (fewer than {CHATTER_RUN}: no standstill chatter)")
    return DeadbandChoice(None, b, n, k, run, why)


def auto_deadband(x, v=None, t=None) -> float | None:
    """The deadband (m or rad) `deadband_choice` applies to the positions `x`, or None
    when the data show no noise-made reversals: ``deadband="auto"`` of
    `jaxfric.simulate` and the command line's default. To do the same before
    `fitting.fit`: ``b = auto_deadband(x)`` then ``x = play(x, b)`` if ``b`` is not None."""
    return deadband_choice(x, v, t).deadband


def backward_velocity(t: Array, x: Array) -> Array:
    """``v_0 = 0``, ``v_n = (x_n - x_{n-1}) / (t_n - t_{n-1})``: m/s for t in s, x in m."""
    dx = jnp.diff(x, prepend=x[:1])
    dt = jnp.diff(t, prepend=t[:1])
    return jnp.where(dt > 0, dx / jnp.where(dt > 0, dt, 1.0), 0.0)


def velocity(t, x, window_s: float | None = None) -> np.ndarray:
    """Velocity (m/s for t in s, x in m) of concrete arrays.

    Without `window_s`: the backward difference ``v_0 = 0``, ``v_n = (x_n - x_{n-1}) /
    (t_n - t_{n-1})``, as `jaxfric.simulate` derives it. With `window_s` (s): the central
    difference of `x` over ``+-h`` samples, ``h`` = half the window in median sample steps
    (at least 1; one-sided at the ends), which smooths quantised positions before they are
    differentiated again."""
    t, x = np.asarray(t, dtype=np.float64), np.asarray(x, dtype=np.float64)
    if not window_s:
        return np.r_[0.0, np.diff(x) / np.diff(t)]
    return central_difference(t, x, max(1, round(window_s / 2 / float(np.median(np.diff(t))))))


def central_difference(t, x, h: int = 1) -> np.ndarray:
    """``(x_{n+h} - x_{n-h}) / (t_{n+h} - t_{n-h})`` of concrete arrays, one-sided at the
    ends: exactly 0 wherever the position did not change, on any clock (the second-order
    formula of `numpy.gradient` for uneven steps leaves round-off of about 1e-14 m/s there,
    whose sign a ``sign(v)`` term would read as a direction of motion)."""
    t, x = np.asarray(t, dtype=np.float64), np.asarray(x, dtype=np.float64)
    n = t.size
    if n < 2:
        return np.zeros_like(x)
    i = np.arange(n)
    lo, hi = np.clip(i - h, 0, n - 1), np.clip(i + h, 0, n - 1)
    return (x[hi] - x[lo]) / (t[hi] - t[lo])


def smooth_derivatives(t, x, window_s: float, polyorder: int = 3
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Zero-phase velocity (m/s) and acceleration (m/s^2) of concrete arrays: a
    Savitzky-Golay filter (`scipy.signal.savgol_filter`) of order `polyorder` over a window
    of `window_s` seconds (an odd number of samples, at least ``polyorder + 2``), the way
    identification wants them: no lag, quantisation smoothed. For identification only: it
    uses future samples, so a controller's per-sample step cannot compute it (that one uses
    the backward difference).

    Needs uniform sampling (within 1 % of the median interval); otherwise raises
    `ValueError` (use `velocity` with a window instead)."""
    from scipy.signal import savgol_filter

    t, x = np.asarray(t, dtype=np.float64), np.asarray(x, dtype=np.float64)
    dt = np.diff(t)
    h = float(np.median(dt))
    if np.max(np.abs(dt - h)) > 0.01 * h:
        raise ValueError("smooth_derivatives needs uniform sampling (intervals within 1 % "
                         "of their median)")
    n = max(polyorder + 2, round(window_s / h))
    n += 1 - n % 2  # odd
    n = min(n, x.size - (1 - x.size % 2))
    if n <= polyorder:
        raise ValueError(f"too few samples ({x.size}) for a window of order {polyorder}")
    v = savgol_filter(x, n, polyorder, deriv=1, delta=h, mode="interp")
    a = savgol_filter(x, n, polyorder, deriv=2, delta=h, mode="interp")
    return v, a


def reversals(d) -> tuple[np.ndarray, np.ndarray]:
    """``(reversal, start)`` for the direction signal `d` (an array in {-1, 0, 1}, e.g.
    ``np.sign(v)``): `reversal` is true at the first moving sample whose direction differs
    from the last motion's (the rule of `Motion.reversal`, also across rests), and
    ``start[n]`` is the index of the sample before the last reversal at or before `n` (the
    reversal point), 0 before the first reversal."""
    d = np.asarray(d)
    idx = np.arange(d.size)
    last = np.maximum.accumulate(np.where(d != 0, idx, 0))
    dl = d[last]
    rev = np.r_[False, (dl[1:] != dl[:-1]) & (dl[:-1] != 0)]
    start = np.maximum.accumulate(np.where(rev, idx - 1, 0))
    return rev, start


def travel_since_reversal(x, v=None) -> np.ndarray:
    """``|x_n - x_r|`` (m): distance of every sample from the last reversal point ``x_r``
    (from ``x_0`` before the first reversal). The direction is ``sign(v)``, or the sign of
    the position step when `v` is not given."""
    x = np.asarray(x, dtype=np.float64)
    d = np.sign(np.r_[0.0, np.diff(x)] if v is None else np.asarray(v))
    _, start = reversals(d)
    return np.abs(x - x[start])


def reversal_bound(t, x, v=None) -> int:
    """A static bound on the number of reversals of the motion ``(t, x[, v])`` (concrete
    arrays; the same rule as `Motion.reversal`): the count, rounded up to a power of two
    (at least 64, at most ``n``) so that similar motions share one compilation. For
    motions ``(B, n)`` (one per row), the bound of the row with the most reversals."""
    t, x = np.asarray(t), np.asarray(x)
    dt = np.diff(t, axis=-1, prepend=t[..., :1])
    dx = np.diff(x, axis=-1, prepend=x[..., :1])
    if v is None:
        d = np.sign(np.where(dt > 0, dx, 0.0))
    else:
        d = np.sign(np.asarray(consistent_velocity(np.asarray(v), dx, dt)))
    # The direction of the last moving sample (0 before any), and its changes.
    idx = np.arange(d.shape[-1])
    last = np.maximum.accumulate(np.where(d != 0, idx, 0), axis=-1)
    dl = np.take_along_axis(d, last, axis=-1)
    count = int(np.max(np.count_nonzero((dl[..., 1:] != dl[..., :-1]) & (dl[..., :-1] != 0),
                                        axis=-1), initial=0))
    return min(max(64, 1 << count.bit_length()), max(int(t.shape[-1]), 1))


def make_motion(t: Array, x: Array, v: Array | None = None,
                max_reversals: int | None = None, load: Array | None = None,
                a: Array | None = None) -> Motion:
    """Build a `Motion` from 1-D arrays of equal length (shape checks are the caller's);
    `load` (N or N m) and the acceleration `a` (m/s^2; ``None``: the backward difference
    of `v`) are carried for the effects."""
    if v is None:
        v = backward_velocity(t, x)
    d = jnp.sign(v)
    n = d.shape[0]
    idx = jnp.arange(n, dtype=jnp.int32)
    # Index of the last moving sample so far (-1 if none): a running maximum.
    last_idx = running_max(jnp.where(d != 0, idx, -1))
    last_d = jnp.where(last_idx >= 0, d[jnp.maximum(last_idx, 0)], 0.0)
    prev_last_d = jnp.concatenate([jnp.zeros_like(last_d[:1]), last_d[:-1]])
    x_prev = jnp.concatenate([x[:1], x[:-1]])
    return Motion(
        t=t,
        x=x,
        v=v,
        dt=jnp.diff(t, prepend=t[:1]),
        dx=x - x_prev,
        d=d,
        last_d=last_d,
        prev_last_d=prev_last_d,
        x_prev=x_prev,
        load=load,
        a=a,
        max_reversals=max_reversals,
    )
