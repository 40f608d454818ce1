"""Built-in example motions and synthetic measurements (seeded, SI units)."""

import numpy as np

from .motion import velocity


def _segment(x0, x1, speed, dt):
    n = max(round(abs(x1 - x0) / speed / dt), 1)
    return np.linspace(x0, x1, n + 1)[1:]


def excitation(dt: float = 1e-3, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A realistic identification motion: positions (m) sampled every `dt` seconds.

    Three parts, like the experiments of the paper's Sec. 5: slow saw-tooth reversals
    inside presliding with nested inner loops (+-20 .. 100 um at 20 um/s), strokes of 2 mm
    at several speeds (0.1 .. 20 mm/s) with small loops at the turning points, and a
    sinusoidally varying positive velocity (friction lag). Returns ``(t, x)``.
    """
    rng = np.random.default_rng(seed)
    um = 1e-6
    xs = [np.zeros(50)]
    pos = 0.0

    def go(target, speed):
        nonlocal pos
        xs.append(_segment(pos, target, speed, dt))
        pos = target

    # presliding: nested loops with slightly random turning points
    for amp in (100, 60, 30):
        jitter = rng.uniform(-5, 5)
        go((amp + jitter) * um, 20 * um)
        go((-amp + 0.4 * amp) * um, 20 * um)
        go((0.7 * amp) * um, 20 * um)
        go((-amp - jitter) * um, 20 * um)
    # sliding strokes at several speeds, with a small loop at each end
    for speed in (1e-4, 5e-4, 2e-3, 5e-3, 2e-2):
        go(pos + 2e-3, speed)
        go(pos - 40 * um, 20 * um)
        go(pos + 25 * um, 20 * um)
        go(pos - 2e-3, speed)
    # varying positive velocity: v = 2 mm/s * (1 + 0.8 sin(2 pi 1 Hz t)) for 4 s
    t_var = np.arange(1, int(4.0 / dt) + 1) * dt
    v_var = 2e-3 * (1 + 0.8 * np.sin(2 * np.pi * t_var))
    xs.append(pos + np.cumsum(v_var) * dt)
    x = np.concatenate(xs)
    return dt * np.arange(x.size), x


def diagnosis_motion(dt: float = 1e-2, seed: int = 0, *,
                     separable: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """A motion for diagnosing missing effects (about 9700 samples at `dt` = 10 ms): slow
    presliding loops (+-50 and +-100 um at 40 um/s, nested), 4 mm strokes at 1..20 mm/s in
    both directions over different parts of a 10 mm travel, each ending with a slow 0.6 mm
    approach (0.2 mm/s) and small loops at the turning point, and a varying-velocity
    segment. Returns ``(t, x)`` in s, m.

    By default each speed is used for one stroke cycle (out and back), at one place and one
    time, and the varying-velocity segment comes last and runs 12 mm beyond the strokes'
    travel: a friction level that changes with time or position is then confounded with
    the Stribeck curve (a fitted model absorbs most of it). `separable` = True returns the
    same kind of motion, as long, in which speed, position and time *can* be told apart:
    the return stroke of each cycle uses another cycle's speed (so every speed is used twice,
    in both directions, at two places and times), and the varying-velocity segment (3 s out
    and 3 s back) sits in the middle of the record, inside the travel."""
    rng = np.random.default_rng(seed)
    um = 1e-6
    approach = 2e-4  # m/s: each stroke ends with 0.6 mm at 0.2 mm/s, as a stage settles
    xs = [np.zeros(20)]
    pos = 0.0

    def go(target, speed):
        nonlocal pos
        xs.append(_segment(pos, target, speed, dt))
        pos = target

    def varying(seconds, direction):
        nonlocal pos
        t_var = np.arange(1, int(seconds / dt) + 1) * dt
        v_var = 2e-3 * (1 + 0.8 * np.sin(2 * np.pi * 0.5 * t_var))
        xs.append(pos + direction * np.cumsum(v_var) * dt)
        pos = float(xs[-1][-1])

    for amp in (100, 50):
        jitter = rng.uniform(-5, 5)
        go((amp + jitter) * um, 40 * um)
        go(-0.6 * amp * um, 40 * um)
        go(0.7 * amp * um, 40 * um)
        go((-amp - jitter) * um, 40 * um)
    speeds = rng.permutation([1e-3, 2e-3, 5e-3, 1e-2, 2e-2, 3e-3])
    for k, speed in enumerate(speeds):
        lo = (k % 3) * 3e-3 + rng.uniform(0, 5e-4)
        if separable and k == 3:  # the varying-velocity segment, mid-record, mid-travel
            go(1.5e-3, 1e-2)
            varying(3.0, +1)
            varying(3.0, -1)
        back = speeds[(k + 2) % speeds.size] if separable else speed
        go(lo, 1e-2)
        go(lo + 3.4e-3, speed)
        go(lo + 4e-3, approach)
        go(lo + 4e-3 - 60 * um, 40 * um)
        go(lo + 4e-3 - 20 * um, 40 * um)
        go(lo + 0.6e-3, back)
        go(lo, approach)
    if not separable:
        varying(6.0, +1)
    x = np.concatenate(xs)
    return dt * np.arange(x.size), x


#: Effects `hidden_effect_measurement` can hide; see there for sizes and fitted models.
HIDDEN_EFFECTS = ("viscous", "quadratic_drag", "stribeck", "presliding", "friction_lag",
                  "inertia", "offset", "asymmetry", "cogging", "position_dependence", "drift")


def diagnosis_truth(C: float = 9.0, l1: float = 3e-6):
    """The "true" friction of `hidden_effect_measurement`: a two-state model with a
    `PowerShape` presliding curve (``1 - (1 - xi/l1)**1.8``, l1 m/N; 144 um of presliding
    travel at l1 = 3 um/N) and Stribeck 24/19 N, 2.5 mm/s, delta 1.5; sigma2 50 N s/m, lag
    attraction `C` N/s (lag time constant ``|s|/C``, about 2.2 s at 9 N/s)."""
    from . import PowerShape, Stribeck, TwoState

    return TwoState(stribeck=Stribeck(Fs=24.0, Fc=19.0, Vs=2.5e-3, delta=1.5),
                    shape=PowerShape(l1=l1, n=1.8), sigma2=50.0, C=C)


def _typical_acceleration(t, x) -> float:
    """The median of ``|a|`` (m/s^2) where it exceeds 1 % of its maximum (backward
    differences): the size of the motion's velocity changes."""
    a = np.abs(velocity(t, velocity(t, x)))
    return float(np.median(a[a > 0.01 * a.max()]))


def _hidden_term(name: str, m: float, t, x):
    """The `jaxfric.effects` term of hidden effect `name` at magnitude `m` (sizes in
    `hidden_effect_measurement`)."""
    from . import effects as fx

    phase = 0.6  # rad, of the cogging
    make = {
        "viscous": lambda: fx.Viscous(c_visc=75.0 * m),
        "quadratic_drag": lambda: fx.QuadraticDrag(c_drag=11250.0 * m),
        "presliding": lambda: fx.Presliding(F_pre=19.0, k_pre=2 * 19.0 / (100e-6 * m)),
        "friction_lag": lambda: fx.FrictionLag(lag_gain=0.4 * m, tau=1.0),
        "stribeck": lambda: fx.StribeckHump(dF_str=2.0 * m, v_str=1.5e-3),
        "inertia": lambda: fx.Inertia(mass=2.0 * m / _typical_acceleration(t, x)),
        "offset": lambda: fx.Offset(offset=1.0 * m),
        "asymmetry": lambda: fx.Asymmetry(asym=0.05 * m),
        "cogging": lambda: fx.Cogging(cog_sin=0.7 * m * np.cos(phase),
                                      cog_cos=0.7 * m * np.sin(phase), period=1.7e-3),
        "position_dependence": lambda: fx.PositionDependence.for_travel(x, pos_1=0.05 * m,
                                                                        pos_2=0.0),
        "drift": lambda: fx.Drift(drift_rate=0.05 * m / (t[-1] - t[0])),
    }
    return make[name]()


def hidden_effect_measurement(effect=None, magnitude: float = 1.0, seed: int = 0,
                              noise: float = 0.05, dt: float = 1e-2):
    """A synthetic measurement on `diagnosis_motion` whose truth is *not* the model that
    will be fitted to it, plus hidden effect(s) at a realistic size.

    The truth is `diagnosis_truth`: a two-state model whose presliding curve is a
    `PowerShape`, which a fitted `PaperShape` two-state cannot reproduce exactly (fitted to
    the clean measurement at `dt` = 20 ms it leaves 0.09 N RMS with 0.05 N of noise), so the
    diagnosis is tested against a model mismatch, not only noise. (A 100-element GMS truth
    would be a harder mismatch: the two-state's reversal rule and lag formulation differ
    from GMS, leaving 0.36 N that `presliding`, `friction_lag` and `cogging` partly
    explain; a clean truth must leave nothing significant, so that mismatch is the wrong
    baseline here.)

    `effect`: ``None`` (clean), a name of `HIDDEN_EFFECTS` or a sequence of names. Sizes at
    `magnitude` = 1 (everything scales linearly with `magnitude`, unless said otherwise):

    - ``viscous``: 75 N s/m (1.5 N at 20 mm/s); note that every jaxfric model has a
      viscous ``sigma2`` that absorbs it;
    - ``quadratic_drag``: 11250 N s^2/m^2 (4.5 N at 20 mm/s, of which the fitted viscous
      and Stribeck terms absorb all but about 0.17 N RMS);
    - ``stribeck``: a hump of 2 N below 1.5 mm/s (``v_str``);
    - ``presliding``: an elasto-plastic presliding spring (`jaxfric.effects.Presliding`)
      of 19 N that takes 100 um to reverse (`magnitude` scales the travel), on a static
      truth (`jaxfric.Tustin` with the Stribeck curve and viscous term of
      `diagnosis_truth`): fit a static model. This is the one case where the truth, with
      the effect added, is the fitted model's family: the two-state model's own presliding
      is not an elasto-plastic spring, and on 20 ms samples its reversal differs from
      Tustin's for one sample;
    - ``friction_lag``: 40 % of the friction level lagging with a time constant of 1 s
      (`jaxfric.effects.FrictionLag`), on a truth whose own lag is negligible (24 us): fit
      a model without lag (the two-state model with ``C`` held at 1e6 N/s);
    - ``inertia``: a mass giving 2 N at the typical acceleration of the motion's velocity
      changes (the median of ``|a|`` where it exceeds 1 % of its maximum; about 2 kg at
      `dt` = 10 ms, as the velocity steps make ``a`` scale with ``1/dt``);
    - ``offset``: 1 N;
    - ``asymmetry``: 5 % (friction 5 % higher in the positive direction, lower in the
      negative);
    - ``cogging``: 0.7 N amplitude, period 1.7 mm;
    - ``position_dependence``: friction level +-5 % at the ends of the travel (linear);
    - ``drift``: friction level rising 5 % over the record.

    Gaussian noise of `noise` N is added (seeded by `seed`, which also seeds the motion).
    Returns ``(t, x, F, truth)``: times (s), positions (m), forces (N) and the true model
    (`diagnosis_truth` plus the hidden effects as `jaxfric.effects` terms).
    """
    from . import simulate

    names = () if effect is None else (effect,) if isinstance(effect, str) else tuple(effect)
    unknown = set(names) - set(HIDDEN_EFFECTS)
    if unknown:
        raise ValueError(f"unknown effects {sorted(unknown)}; choose from {HIDDEN_EFFECTS}")
    t, x = diagnosis_motion(dt=dt, seed=seed, separable=True)
    C = 1e6 if "friction_lag" in names else 9.0  # 1e6 N/s: a lag of 24 us, negligible
    terms = [_hidden_term(name, float(magnitude), t, x) for name in names]
    truth = diagnosis_truth(C=C)
    if "presliding" in names:  # a static truth: presliding comes only from the effect
        from . import Tustin

        truth = Tustin(stribeck=truth.stribeck, sigma2=truth.sigma2)
    if terms:
        truth = truth + tuple(terms)
    F = np.asarray(simulate(truth, t, x))
    F = F + noise * np.random.default_rng(seed + 12345).standard_normal(t.size)
    return t, x, F, truth
