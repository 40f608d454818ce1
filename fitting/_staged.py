"""The paper's staged parameter determination (Sec. 5), then a joint fit.

1. **Stribeck curve and viscous term** from constant-velocity sliding: steady segments are
   found automatically from the velocity, the end of each is averaged, and
   ``s(v) + sigma2*v`` is fitted to the segment means (a `jaxfric.Tustin` fit, so the
   standard errors come with it).
2. **Presliding shape** (two-state: ``l1`` and the shape coordinates; GMS: ``nu, k``;
   LuGre: ``sigma0, sigma1``) from low-speed reversal data, with stage 1 held.
3. **Attraction parameter C** (two-state, GMS) from sliding at varying velocity, with the
   rest held. The paper differentiates ``F_l = F - F_h - sigma2*v`` and fits Eq. 27; fitting
   the simulated force instead uses the same information without differentiating noise.
4. **Joint fit** of every parameter on all the data, started from the staged values.

Stages 2-4 simulate the three experiments stacked into one padded array and switch
experiments off with zero weights, so all of them reuse one compiled solver.
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import jaxfric
from jaxfric._fields import parameter_info

from . import _fit, _params
from ._data import check_dataset, Dataset, stack
from ._problem import _problem_from_fit
from ._result import FitResult


@dataclasses.dataclass(frozen=True)
class Segments:
    """Steady constant-velocity segments (NumPy arrays, one entry per segment).

    - `start`, `stop`: sample range ``[start, stop)`` that was averaged (the settled end
      of each steady run).
    - `v`: mean velocity over that range, m/s (displacement over time).
    - `F`: mean measured force, N; `sem`: its standard error, N; `count`: samples.
    """

    start: np.ndarray
    stop: np.ndarray
    v: np.ndarray
    F: np.ndarray
    sem: np.ndarray
    count: np.ndarray

    def __len__(self) -> int:
        return int(self.v.shape[0])


def _smoothed_velocity(t, x, window: int) -> np.ndarray:
    """Centred difference over `window` samples (m/s): the slope that a noisy position
    signal supports, with the ends using the nearest full window."""
    n = t.shape[0]
    h = max(window // 2, 1)
    lo = np.clip(np.arange(n) - h, 0, n - 1)
    hi = np.clip(np.arange(n) + h, 0, n - 1)
    return (x[hi] - x[lo]) / (t[hi] - t[lo])


def constant_velocity_segments(
    t,
    x,
    F,
    v=None,
    *,
    rel_tol: float = 0.05,
    window: int = 5,
    settle: float = 0.5,
    min_samples: int = 10,
) -> Segments:
    """Find runs of (nearly) constant, nonzero velocity and average their settled ends.

    **Arguments:**

    - `t`, `x`, `F`, `v`: one experiment (s, m, N, optional m/s). Without `v` the velocity is
      the slope of `x` over `window` samples.
    - `rel_tol`: a run ends where the velocity leaves ``+-rel_tol`` of the run's mean.
    - `settle`: fraction of each run's *duration* discarded at its start. The force is
      steady only once the presliding transition (``2*Fs*l1`` of travel) and the friction
      lag (time constant ``|s(v)|/C``, 2.4 s with the paper's values) have died out: runs
      must last several of those time constants.
    - `min_samples`: shortest averaged range kept.

    **Returns:** `Segments`.
    """
    t = np.asarray(t, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    F = np.asarray(F, dtype=np.float64)
    if v is None:
        vel = _smoothed_velocity(t, x, window)
        # The direction comes from the step itself (one signal, as in jaxfric): a window
        # straddling a reversal would otherwise carry the old direction into the new stroke.
        direction = np.sign(np.concatenate([[0.0], np.diff(x)]))
    else:
        vel = np.asarray(v, dtype=np.float64)
        direction = np.sign(vel)
    n = vel.shape[0]
    runs, start, total = [], 0, vel[0]
    for i in range(1, n):
        mean = total / (i - start)
        same_direction = direction[i] != 0 and direction[i] == np.sign(mean)
        if same_direction and abs(vel[i] - mean) <= rel_tol * abs(mean):
            total += vel[i]
        else:
            runs.append((start, i))
            start, total = i, vel[i]
    runs.append((start, n))
    out = {k: [] for k in ("start", "stop", "v", "F", "sem", "count")}
    for a, b in runs:
        if not np.any(vel[a:b]):
            continue  # at rest
        a_keep = a + int(np.searchsorted(t[a:b], t[a] + settle * (t[b - 1] - t[a])))
        count = b - a_keep
        if count < max(min_samples, 2):
            continue
        seg_v = (x[b - 1] - x[a_keep]) / (t[b - 1] - t[a_keep])
        if seg_v == 0:
            continue
        f = F[a_keep:b]
        out["start"].append(a_keep)
        out["stop"].append(b)
        out["v"].append(seg_v)
        out["F"].append(f.mean())
        out["sem"].append(f.std(ddof=1) / np.sqrt(count))
        out["count"].append(count)
    return Segments(**{k: np.asarray(val) for k, val in out.items()})


def _slope(speed, force) -> float:
    """The least-squares slope of `force` over `speed`, and 0 when the speeds are one speed
    up to round-off (spread below 1e-9 of their size: segment speeds of one commanded
    speed differ in their last bits, and a line through them is noise, which `np.polyfit`
    only warns about)."""
    if speed.size < 2 or np.ptp(speed) <= 1e-9 * np.max(np.abs(speed)):
        return 0.0
    ds = speed - speed.mean()
    return float(ds @ (force - force.mean()) / (ds @ ds))


def initial_stribeck(segments: Segments) -> tuple[jaxfric.Stribeck, float]:
    """A rough starting Stribeck curve and ``sigma2`` (N s/m) from segment means.

    Uses ``|F|`` against ``|v|`` (odd symmetry): ``sigma2`` from a line through the fastest third,
    ``Fs`` from the slowest, ``Fc`` the lowest level once the viscous part is removed,
    ``Vs`` where the excess over ``Fc`` has fallen to ``1/e`` of ``Fs - Fc``, ``delta = 1``.
    """
    if len(segments) < 3:
        raise ValueError(f"need at least 3 steady segments for the Stribeck curve, got "
                         f"{len(segments)}")
    speed = np.abs(segments.v)
    force = segments.F * np.sign(segments.v)
    order = np.argsort(speed)
    speed, force = speed[order], force[order]
    # Slope over the fastest third (at least two distinct speeds), where s(v) ~ Fc.
    fast = speed >= np.quantile(speed, 2.0 / 3.0)
    if np.unique(speed[fast]).size < 2:
        fast = speed >= np.unique(speed)[-2] if np.unique(speed).size >= 2 else fast
    sigma2 = _slope(speed[fast], force[fast])
    sigma2 = max(sigma2, 1e-6 * abs(force[-1]) / speed[-1])
    level = force - sigma2 * speed
    fs = max(level[0], 1e-9)
    fc = float(np.clip(level.min(), 0.05 * fs, 0.98 * fs))
    excess = (level - fc) / (fs - fc)
    below = np.nonzero(excess < np.exp(-1.0))[0]
    vs = speed[below[0]] if below.size else speed[-1]
    vs = max(vs, speed[0])
    return jaxfric.Stribeck(Fs=fs, Fc=fc, Vs=vs, delta=1.0), float(sigma2)


def _names_with_role(model, role: str) -> tuple[str, ...]:
    """Names of `model`'s parameters whose field declares `role` (``"presliding"``,
    ``"lag"``; see `jaxfric._fields.param`)."""
    return tuple(i.name for i in parameter_info(model) if i.role == role)


def _estimate_l1(model: jaxfric.TwoState, data: Dataset, level: float = 0.9) -> float | None:
    """``l1`` (m/N) from reversal branches: the travel after a reversal at which the force
    has covered `level` of the branch's whole rise, divided by what the model's shape needs
    for that (``2*Fs*l1*u`` with ``Pi(u*l1) = level``); the median over the branches that
    rise by at least 60 % of ``2*Fs`` (full reversals, not small inner loops). Relative
    to each branch's own rise, so a start ``Fs`` that is too high (or friction lag, which
    lowers the level after a reversal) does not bias it. ``None`` if no branch qualifies."""
    fs = float(model.stribeck.Fs)
    dx = np.diff(data.x)
    direction = np.sign(dx)
    moving = np.nonzero(direction)[0]
    if moving.size < 2:
        return None
    rev = moving[1:][direction[moving[1:]] != direction[moving[:-1]]]
    travels = []
    for k in rev:  # branch starts at sample k (position x[k]) and runs while direction holds
        d = direction[k]
        end = k + 1
        while end < dx.shape[0] and direction[end] in (d, 0):
            end += 1
        rise = d * (data.F[k:end + 1] - data.F[k])
        travel = d * (data.x[k:end + 1] - data.x[k])
        total = float(rise.max())
        if total < 0.6 * 2.0 * fs:
            continue
        travels.append(travel[np.argmax(rise >= level * total)])
    if not travels:
        return None
    grid = np.linspace(0.0, 1.0, 2001)
    pi = np.asarray(model.shape.pi(jnp.asarray(grid) * model.shape.l1, model.stribeck.Fs))
    u_level = grid[np.argmax(pi >= level)]
    if u_level <= 0:
        return None
    return float(np.median(travels)) / (2.0 * fs * u_level)


@dataclasses.dataclass(frozen=True)
class StagedResult:
    """The outcome of `fit_staged`.

    - `model`: the final model (the joint fit's, or the last stage's with ``joint=False``).
    - `stages`: ``{"stribeck": ..., "presliding": ..., "lag": ..., "joint": ...}``, a
      `FitResult` for each stage that ran. The ``"stribeck"`` one is a `jaxfric.Tustin` fit
      to the segment means (its `prediction`/`residuals` are per segment).
    - `segments`: the `Segments` used in stage 1.
    """

    model: object
    stages: dict[str, FitResult]
    segments: Segments


def fit_staged(
    model,
    sliding: Dataset,
    presliding: Dataset | None = None,
    lag: Dataset | None = None,
    *,
    joint: bool = True,
    stribeck_init: str = "data",
    estimate_l1: bool = True,
    segment_options: dict | None = None,
    solver=None,
    max_steps: int = 256,
) -> StagedResult:
    """The paper's staged identification (module docstring), then a joint fit.

    **Arguments:**

    - `model`: the starting model (its type and structure: shape family, stack size,
      number of GMS elements; its values start the stages that have no data-based start).
    - `sliding`: constant-velocity sliding at several speeds, both directions (stage 1).
    - `presliding`: low-speed motion with reversals, beyond and within presliding
      (stage 2); ``None`` skips the stage.
    - `lag`: sliding at varying velocity without reversals (stage 3); ``None`` skips it.
    - `joint`: finish with a joint fit, on all the data given, of every parameter that a
      stage determined (all of them when the three experiments are given).
    - `stribeck_init`: ``"data"`` starts stage 1 from `initial_stribeck` (the segment
      means), ``"model"`` from `model`'s Stribeck curve and ``sigma2``.
    - `estimate_l1`: (two-state) start stage 2 with ``l1`` read off the reversal branches:
      the travel at which the force has risen by 90 % of ``2*Fs``, scaled by the starting
      shape's own ``Pi^-1(0.9)``.
    - `segment_options`: keyword arguments for `constant_velocity_segments`.
    - `solver`, `max_steps`: as for `fit`.

    **Returns:** a `StagedResult`.
    """
    given = {"sliding": sliding, "presliding": presliding, "lag": lag}
    checked = {k: check_dataset(d, where=f"{k}: ") for k, d in given.items() if d is not None}
    stages = {}

    # Stage 1: Stribeck curve + sigma2 from the means of steady segments.
    s = checked["sliding"]
    segments = constant_velocity_segments(s.t, s.x, s.F, s.v, **(segment_options or {}))
    if len(segments) < 5:
        raise ValueError(f"stage 1 needs at least 5 steady segments (4 Stribeck parameters "
                         f"and sigma2), found {len(segments)} in the sliding data")
    if stribeck_init == "data":
        st0, sigma2_0 = initial_stribeck(segments)
    elif stribeck_init == "model":
        st0, sigma2_0 = model.stribeck, model.sigma2
    else:
        raise ValueError(f"stribeck_init must be 'data' or 'model', got {stribeck_init!r}")
    # Segment means as a "trajectory" for Tustin (its force depends on v only): t is a
    # dummy increasing axis. A mean of `count` samples has variance noise^2/count, so
    # weights proportional to `count` (the noise level itself comes out of the residuals).
    n_seg = len(segments)
    stages["stribeck"] = _fit.fit(
        jaxfric.Tustin(stribeck=st0, sigma2=sigma2_0),
        np.arange(n_seg, dtype=np.float64), np.zeros(n_seg), segments.F, segments.v,
        weights=segments.count / segments.count.mean(), solver=solver, max_steps=max_steps,
    )
    tustin = stages["stribeck"].model
    # The stages hand the model on in the fit representation (a `NormalizedPaperShape` for
    # a `PaperShape`): a round trip through the paper's symbols is singular where the
    # exponential is straight (curvature 0: a -> inf).
    paper_shape = isinstance(getattr(model, "shape", None), jaxfric.PaperShape)
    current = _params.to_fit_representation(model)
    current = eqx.tree_at(lambda m: (m.stribeck, m.sigma2), current,
                          (tustin.stribeck, tustin.sigma2))

    # Stages 2-4 share one stacked data array (sliding, presliding, lag: those given) and
    # switch experiments off with zero weights: one compiled solver for all of them.
    keys = list(checked)
    data = stack([checked[k] for k in keys])

    def run(start, free, use):
        on = jnp.asarray([[1.0 if k in use else 0.0] for k in keys])
        stage_data = eqx.tree_at(lambda d: d.weights, data, data.weights * on)
        problem, y0 = _problem_from_fit(start, None, free, paper_shape)
        return _fit._fit_stacked(problem, y0, [checked[k] for k in keys], stage_data,
                                 solver, max_steps)

    joint_free = ["stribeck", "sigma2"]
    names = _names_with_role(current, "presliding")
    if "presliding" in checked and names:
        if estimate_l1 and hasattr(current, "shape"):  # a presliding curve with l1
            l1 = _estimate_l1(current, checked["presliding"])
            if l1 is not None:
                current = eqx.tree_at(lambda m: m.shape.l1, current, jnp.asarray(l1))
        stages["presliding"], current = run(current, names, {"presliding"})
        joint_free += names
    names = _names_with_role(current, "lag")
    if "lag" in checked and names:
        stages["lag"], current = run(current, names, {"lag"})
        joint_free += names
    if joint:
        # Everything a stage determined, on all the data (a parameter no experiment
        # informs, e.g. C without lag data, stays held rather than drifting).
        stages["joint"], current = run(current, joint_free, set(keys))
    final = _params.to_user_representation(current, like=model)
    return StagedResult(model=final, stages=stages, segments=segments)


