"""Motion families for tests, benchmarks and examples: positions ``x`` (m) at given times
``t`` (s), the kinds of motion a friction model meets on real machines.

Every family is a function ``family(t, rng=None, **options) -> x``. With ``rng`` (a
``numpy.random.Generator``) the amplitudes, speeds and phases are drawn around their
defaults (for batches of different motions); without it the motion is fixed. ``t`` need
not be uniform (see `jittered_clock`), but it must increase.

- `sine_strokes`: long sinusoidal strokes with small fast wiggles on top (presliding loops
  inside sliding);
- `point_to_point`: trapezoidal velocity moves between random targets with dwells, short and
  strong accelerations (a pick-and-place axis);
- `jerk_limited`: the same moves with smooth (raised-cosine) accelerations, so that the
  velocity and acceleration are continuous (an S-curve planner);
- `sine_sweep`: a chirp whose frequency rises log-linearly (an identification experiment);
- `robot_log`: band-limited random velocity, reversals at random times (a joint of an arm
  following a task).

`FAMILIES` maps each name to its function. `jittered_clock` turns uniform times into the
times of a logger whose clock jitters.
"""

from collections.abc import Callable

import numpy as np


def _rng_scale(rng, lo=0.8, hi=1.2):
    return 1.0 if rng is None else float(rng.uniform(lo, hi))


def _phase(rng):
    return 0.0 if rng is None else float(rng.uniform(0.0, 2 * np.pi))


def _as_time(t):
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0):
        raise ValueError("t must be a 1-D array of at least two increasing times (s)")
    return t


def sine_strokes(t, rng=None, *, stroke=2e-3, freq=0.1, wiggle=30e-6, wiggle_freq=1.7):
    """Strokes of +-`stroke` m at `freq` Hz with +-`wiggle` m at `wiggle_freq` Hz on top."""
    t = _as_time(t)
    a, w = stroke * _rng_scale(rng), wiggle * _rng_scale(rng)
    return (a * np.sin(2 * np.pi * freq * t + _phase(rng))
            + w * np.sin(2 * np.pi * wiggle_freq * t + _phase(rng)))


def _cumulative(t, v):
    """Position from velocity by the trapezoidal rule, starting at 0."""
    return np.r_[0.0, np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))]


def _moves(t, rng, travel, vmax, accel_time, dwell):
    """Start time, signed distance and duration of each move filling ``t``."""
    rng = np.random.default_rng(0) if rng is None else rng
    moves, now, pos = [], float(t[0]) + dwell, 0.0
    while now < t[-1]:
        target = float(rng.uniform(-travel, travel))
        while abs(target - pos) < 0.1 * travel:
            target = float(rng.uniform(-travel, travel))
        d = target - pos
        speed = vmax * float(rng.uniform(0.3, 1.0))
        # The two ramps never overlap: a short move reaches its speed and leaves it at once.
        duration = max(abs(d) / speed, accel_time) + accel_time
        moves.append((now, d, duration))
        now += duration + dwell * float(rng.uniform(0.5, 1.5))
        pos = target
    return moves


def _move_velocity(t, moves, accel_time, smooth):
    v = np.zeros_like(t)
    for start, d, duration in moves:
        peak = d / (duration - accel_time)
        tau = t - start
        ramp_up = np.clip(tau / accel_time, 0.0, 1.0)
        ramp_down = np.clip((duration - tau) / accel_time, 0.0, 1.0)
        shape = np.minimum(ramp_up, ramp_down)
        if smooth:
            shape = 0.5 - 0.5 * np.cos(np.pi * shape)
        v += peak * shape
    return v


def point_to_point(t, rng=None, *, travel=5e-3, vmax=20e-3, accel_time=0.02, dwell=0.3):
    """Trapezoidal moves between random targets within +-`travel` m, at up to `vmax` m/s,
    reaching their speed in `accel_time` s (short, strong accelerations), with dwells of
    about `dwell` s standing still between them."""
    t = _as_time(t)
    moves = _moves(t, rng, travel, vmax, accel_time, dwell)
    return _cumulative(t, _move_velocity(t, moves, accel_time, smooth=False))


def jerk_limited(t, rng=None, *, travel=5e-3, vmax=20e-3, accel_time=0.08, dwell=0.3):
    """Like `point_to_point`, with raised-cosine speed ramps of `accel_time` s: velocity and
    acceleration are continuous, the jerk is bounded."""
    t = _as_time(t)
    moves = _moves(t, rng, travel, vmax, accel_time, dwell)
    return _cumulative(t, _move_velocity(t, moves, accel_time, smooth=True))


def sine_sweep(t, rng=None, *, amplitude=1e-3, f0=0.05, f1=3.0):
    """A chirp of amplitude `amplitude` m whose frequency rises log-linearly from `f0` to
    `f1` Hz over the record, its amplitude falling as 1/f above 0.5 Hz so that the speed
    stays bounded (large slow strokes, then small fast presliding cycles)."""
    t = _as_time(t)
    span = t[-1] - t[0]
    k = np.log(f1 / f0) / span
    phase = 2 * np.pi * f0 * (np.exp(k * (t - t[0])) - 1.0) / k + _phase(rng)
    f = f0 * np.exp(k * (t - t[0]))
    return amplitude * _rng_scale(rng) * np.minimum(1.0, 0.5 / f) * np.sin(phase)


def robot_log(t, rng=None, *, speed=10e-3, bandwidth=1.0):
    """Band-limited random velocity (RMS about `speed` m/s, content below about
    `bandwidth` Hz), so reversals and slow crossings come at random times."""
    t = _as_time(t)
    rng = np.random.default_rng(1) if rng is None else rng
    # A sum of random sines below the bandwidth, normalised to the RMS speed.
    freqs = rng.uniform(0.02, bandwidth, 12)
    v = sum(rng.normal() * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
            for f in freqs)
    v = speed * v / np.sqrt(np.mean(v**2))
    return _cumulative(t, v)


FAMILIES: dict[str, Callable] = {
    "sine_strokes": sine_strokes,
    "point_to_point": point_to_point,
    "jerk_limited": jerk_limited,
    "sine_sweep": sine_sweep,
    "robot_log": robot_log,
}


def jittered_clock(t, rng, jitter=0.1):
    """The times a logger with a jittering clock records for nominal uniform times `t`:
    each sample is taken up to `jitter` of the interval early or late (uniform), so the
    times stay increasing for ``jitter < 0.5``."""
    t = _as_time(t)
    if not 0.0 <= jitter < 0.5:
        raise ValueError("jitter must be in [0, 0.5) of the sampling interval")
    dt = np.median(np.diff(t))
    return t + jitter * dt * rng.uniform(-1.0, 1.0, t.size)
