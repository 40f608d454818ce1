"""Synthetic measurements made the way a sensor records them, from truths that are NOT the
models jaxfric fits: the data of `benchmarks/diagnosis_bench.py` and of the diagnosis's slow
tests from other truths.

- **truths** (`truth`): a 60-element GMS whose virgin curve is another family (a power law)
  with its own Stribeck curve (``gms_power``); a LuGre model with stiff bristles
  (``lugre``); a two-state model with a `PowerShape` presliding curve
  (``two_state_power``); and, not a jaxfric model at all, true stiction (``stiction``,
  `stiction_force`: a stiff stuck spring that breaks away above the sliding curve and drops
  to it, stick-slip at every start);
- **motion**: `jaxfric.examples.diagnosis_motion` with its velocity steps turned into
  ramps of 0.1 s (`finite_acceleration`), so that a mass has something to act on; or any
  family of `jaxfric.trajectories` (``motion="point_to_point"``, ...), optionally recorded
  by a jittering clock (``jitter``);
- **physics on a fine grid**: the truth is simulated at a tenth of the sampling interval
  with the fine grid's own central-difference velocity, and the hidden effects are computed
  there with formulas written here (`hidden_force`), not with `jaxfric.effects`;
- **sensors** (`measurement`): the position is sampled and quantised to a 0.05 um encoder,
  the force gets white noise; the file holds t, x, F only, so whoever fits it has to
  derive the velocity;
- **a load** (`load_signal`): a transmitted load (N) that varies independently of the
  motion, for the hidden load-dependent friction (`HIDDEN_LOAD`; `measurement` with
  ``load=True`` also returns the sampled load, with its own sensor noise).
"""

import numpy as np


FINE = 10  # the truth runs on a grid this many times finer than the sampling
RAMP = 0.1  # s: the stage changes its velocity over this time (a finite acceleration)
ENCODER = 0.05e-6  # m per count
REST = 1e-7  # m/s: slower than this the truth is at rest (a hundredth of a count per ms)
TRUTHS = ("gms_power", "lugre", "two_state_power")
#: Truths that no jaxfric model family is (`stiction_force`).
FOREIGN_TRUTHS = ("stiction",)
HIDDEN = ("quadratic_drag", "asymmetry", "inertia", "cogging", "drift", "offset",
          "position_dependence", "position_load", "stribeck", "friction_lag")
#: Hidden effects of a joint angle: for rotary files (`measurement` with `rotary`).
HIDDEN_ROTARY = ("ripple", "angle_load")
ROTARY_SCALE = 300.0  # rad per m: the rotary files' angle is the linear motion times this
GEAR = 50  # the ripple's count per revolution (a gear of ratio 50 seen on the output)
#: Hidden effects of the transmitted load: for files with a load column (`load_signal`).
HIDDEN_LOAD = ("load_friction",)
LOAD_NOISE = 0.2  # N: white noise of the recorded load


def load_signal(t):
    """The transmitted load (N) at times `t` (s): 5..95 N, two swings of 3.1 s and 1.3 s
    that share no period with the motion (a payload and a process force), always pushing
    one way: faster than the diagnosis's held-out blocks, so every block sees it vary."""
    t = np.asarray(t, dtype=np.float64)
    return (50.0 + 30.0 * np.sin(2 * np.pi * t / 3.1 + 0.4)
            + 15.0 * np.sin(2 * np.pi * t / 1.3 + 1.3))


def truth(name: str):
    """The true model `name` (one of `TRUTHS`)."""
    from . import GMS, LuGre, PowerShape, Stribeck

    if name == "gms_power":
        stribeck = Stribeck(Fs=30.0, Fc=22.0, Vs=4e-3, delta=2.0)
        shape = PowerShape(l1=4e-6, n=2.5)
        return GMS.from_shape(shape, stribeck, sigma2=80.0, C=15.0, n=60)
    if name == "lugre":
        stribeck = Stribeck(Fs=26.0, Fc=20.0, Vs=3e-3, delta=1.2)
        return LuGre(stribeck=stribeck, sigma0=2e6, sigma1=2.0 * 2e6**0.5, sigma2=60.0)
    if name == "two_state_power":
        from .examples import diagnosis_truth

        return diagnosis_truth()
    raise ValueError(name)


def _stribeck_level(v, Fs=24.0, Fc=20.0, Vs=3e-3):
    return Fc + (Fs - Fc) * np.exp(-((v / Vs) ** 2))


def stiction_force(t, x, v, *, breakaway=27.0, stiffness=1e7, sigma2=60.0):
    """True stiction (N) on the motion ``(t, x, v)`` (s, m, m/s; a fine grid): while stuck
    the contact is a stiff spring (`stiffness` N/m from where it stuck) until its force
    exceeds `breakaway` N, above the sliding curve's peak (24 N); then it slips and the
    force drops at once to the sliding curve ``sign(v) s(v) + sigma2 v`` (Stribeck 24 ->
    20 N, 3 mm/s). It sticks again where the velocity reverses or stops, with the force
    it had (no jump). No jaxfric family has this breakaway-and-drop: their presliding
    curves rise smoothly to the sliding level."""
    f = np.empty_like(x)
    stuck, anchor = True, x[0]
    for i in range(x.size):
        if stuck:
            f[i] = stiffness * (x[i] - anchor)
            if abs(f[i]) > breakaway and v[i] != 0:
                stuck = False
        if not stuck:
            f[i] = np.sign(v[i]) * _stribeck_level(v[i]) + sigma2 * v[i]
            if v[i] == 0 or (i + 1 < x.size and v[i + 1] * v[i] <= 0):
                stuck, anchor = True, x[i] - f[i] / stiffness
    return f


def _central(t, y):
    return np.gradient(y, t)


def _travel_force(name: str, u, base):
    """The hidden effects of the position `u` in [-1, 1] over the travel."""
    if name == "position_dependence":  # level +-5 % at the ends of the travel, quadratic
        return base * (0.04 * u + 0.03 * (u**2 - 1 / 3))
    # position_load: a spring-like load along the travel, +-0.9 N at the ends
    return 0.9 * np.tanh(1.5 * u) / np.tanh(1.5)


def _joint_force(name: str, q, dq):
    """The hidden effects of a joint angle (`HIDDEN_ROTARY`): `q` (rad), `dq` the angle from
    mid-travel."""
    if name == "ripple":  # a gear's ripple, 50 per turn, with a 4th harmonic no fit has
        phase = GEAR * q
        return (0.5 * np.sin(phase + 0.3) + 0.25 * np.sin(2 * phase + 1.2)
                + 0.12 * np.cos(3 * phase - 0.5) + 0.06 * np.sin(4 * phase))
    # gravity on a link, m g r cos(q + phi) of 1.4 N m, and a spring balancer that is not
    # of that form (3 % of it, linear in the angle)
    return 1.4 * np.cos(q + 0.7) + 0.03 * 1.4 * dq


def _load_force(t, v):
    """The hidden load friction: the Coulomb level grows by 3 % of ``|load|``, with
    ``sign(v)`` (Hamon et al.'s static form: a jump at each reversal, where jaxfric's
    effect follows the base model's presliding)."""
    return 0.03 * np.abs(load_signal(t)) * np.sign(v)


def hidden_force(name: str, t, x, v, a, base, level, static=None):
    """The hidden effect's force (N) on the fine grid; `level` is the sliding friction
    level (N) of the truth, `base` its force, `static` its Stribeck level ``|s(v)|`` (N;
    ``Fs`` at rest). (``load_friction``, of the load rather than the motion:
    `_load_force`.)"""
    travel_mid, travel_half = 0.5 * (x.min() + x.max()), 0.5 * np.ptp(x)
    if name in HIDDEN_ROTARY:
        return _joint_force(name, x, x - travel_mid)
    if name in ("position_dependence", "position_load"):
        return _travel_force(name, (x - travel_mid) / travel_half, base)
    if name == "quadratic_drag":  # 1.5 N at 20 mm/s, nothing below 5 mm/s
        excess = np.maximum(np.abs(v) - 5e-3, 0.0)
        return 1.5 * np.sign(v) * (excess / 15e-3) ** 2
    if name == "asymmetry":  # the friction force 6 % larger where it points toward +x
        # Proportional to the friction force, as a direction-dependent friction level is,
        # and continuous: a stop holds the force it had, raised too (a force cannot change
        # while nothing moves). A constant step, ``c * (v > 0)``, would be ``c/2`` of
        # offset plus ``c/2`` more symmetric friction, sample for sample in sliding: no
        # data could tell it from an offset.
        return 0.06 * np.maximum(base, 0.0)
    if name == "inertia":  # a mass error: 2 N at the 90th percentile of |a| while accelerating
        typical = np.quantile(np.abs(a)[np.abs(a) > 0.01 * np.abs(a).max()], 0.9)
        return 2.0 / typical * a
    if name == "cogging":  # two harmonics of a 1.3 mm pitch
        phase = 2 * np.pi * x / 1.3e-3
        return 0.5 * np.sin(phase + 0.4) + 0.2 * np.sin(2 * phase + 1.1)
    if name == "drift":  # warm-up: the friction level rises 6 % with a 40 s time constant
        return 0.06 * base * (1 - np.exp(-(t - t[0]) / 40.0))
    if name == "offset":
        return np.full_like(t, 0.8)
    if name == "stribeck":  # an extra hump of 2 N below about 1 mm/s
        return 2.0 * np.sign(v) * np.exp(-((np.abs(v) / 1e-3) ** 2))
    if name == "friction_lag":  # 35 % of the friction level follows speed changes, tau 0.6 s
        # The level is the truth's Stribeck curve |s(v)| (a speed-dependent level lagging
        # behind the speed, as Hess and Soom measured), held while at rest. `static` is Fs
        # at rest: a level of 0 there would start the record with a transient of -Fs*0.35
        # decaying over tau, a start-up artefact that dominated this effect's energy.
        target = 0.35 * static
        y = np.empty_like(target)
        y[0] = target[0]
        alpha = 1 - np.exp(-np.diff(t) / 0.6)
        for i in range(1, t.size):
            y[i] = y[i - 1] + (alpha[i - 1] * (target[i] - y[i - 1]) if v[i] != 0 else 0.0)
        return np.sign(v) * (y - target)
    raise ValueError(name)


def finite_acceleration(t, x, ramp: float):
    """The motion `x` (m) at uniform times `t` (s) with its velocity averaged over `ramp`
    seconds (causally): every velocity step becomes a ramp, as a real stage accelerates."""
    h = float(t[1] - t[0])
    k = max(1, round(ramp / h))
    v = np.diff(x) / h
    v = np.convolve(v, np.ones(k) / k)[: v.size]
    return x[0] + np.r_[0.0, np.cumsum(v) * h]


def measurement(truth_name: str, hidden: tuple[str, ...] = (), noise: float = 0.03,
                dt: float = 1e-2, seed: int = 0, rotary: bool = False, load: bool = False,
                motion: str | None = None, duration: float = 100.0, jitter: float = 0.0):
    """``(t, x, F)`` (s, m, N) as a sensor would record them: the `diagnosis_motion` of
    `seed` through truth `truth_name` plus the `hidden` effects, sampled every `dt`, the
    position quantised to `ENCODER`, the force with `noise` N of white noise.

    `rotary`: a joint instead (s, rad, N m): the angle is the motion times `ROTARY_SCALE`
    (a 10 mm travel becomes 3.2 rad, the encoder 15 urad, about 2^18.7 counts per turn),
    the truth's friction is the same function of the motion (its speeds and presliding
    lengths scale with the angle), and the hidden effects (`HIDDEN_ROTARY` among them) are
    functions of the angle.

    `load`: return ``(t, x, F, L)`` with the transmitted load `L` (`load_signal`, N or N m,
    with `LOAD_NOISE` of white noise) that the hidden ``load_friction`` reads.

    `motion`: a family of `jaxfric.trajectories` (its `FAMILIES`) over `duration` s,
    drawn with `seed`, instead of the diagnosis motion. `jitter`: the logger's clock takes
    each sample up to this fraction of `dt` early or late (below 0.5; on the fine grid,
    so the recorded ``t`` is when the sample was really taken)."""
    from . import simulate, trajectories
    from .examples import diagnosis_motion

    if motion is None:
        t_fine, x_fine = diagnosis_motion(dt=dt / FINE, seed=seed, separable=True)
        x_fine = finite_acceleration(t_fine, x_fine, RAMP)
    else:
        t_fine = np.arange(0.0, duration, dt / FINE)
        x_fine = trajectories.FAMILIES[motion](t_fine, np.random.default_rng(seed))
    v = _central(t_fine, x_fine)
    a = _central(t_fine, v)
    # At rest: the fine grid's central difference leaves round-off on a dwell (about 1e-16
    # m/s), and a hidden effect with sign(v) (a Stribeck hump, a friction lag) would act
    # there with a random sign. Below `REST` the truth is at rest.
    v = np.where(np.abs(v) < REST, 0.0, v)
    if truth_name == "stiction":
        base = stiction_force(t_fine, x_fine, v)
        static = _stribeck_level(v)
    else:
        model = truth(truth_name)
        base = np.asarray(simulate(model, t_fine, x_fine, v))
        static = np.asarray(model.stribeck.magnitude(v))  # |s(v)|, Fs at rest (s(0) is 0)
    # The sliding level the hidden effects scale with: above 5 mm/s, or on the fastest
    # tenth of the samples when the motion never reaches it (a slow sine sweep).
    fast = np.abs(v) > 5e-3
    if not fast.any():
        fast = np.abs(v) >= np.quantile(np.abs(v), 0.9)
    level = float(np.median(np.abs(base[fast])))
    k = ROTARY_SCALE if rotary else 1.0
    force = base + sum((_load_force(t_fine, v) if h in HIDDEN_LOAD else
                        hidden_force(h, t_fine, k * x_fine, k * v, k * a, base, level, static)
                        for h in hidden), np.zeros_like(base))
    rng = np.random.default_rng(1000 + seed)
    if not 0.0 <= jitter < 0.5:
        raise ValueError("jitter must be in [0, 0.5) of the sampling interval")
    keep = np.arange(0, t_fine.size, FINE)
    j = round(jitter * FINE)
    if j:
        keep = np.clip(keep + rng.integers(-j, j + 1, keep.size), 0, t_fine.size - 1)
    t = t_fine[keep]
    x = np.round(x_fine[keep] / ENCODER) * ENCODER * k
    F = force[keep] + noise * rng.standard_normal(t.size)
    if load:
        return t, x, F, load_signal(t) + LOAD_NOISE * rng.standard_normal(t.size)
    return t, x, F
