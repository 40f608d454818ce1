"""The simulation entry points: `simulate` (one model, one motion) and `simulate_many`
(a batch of parameter sets and/or motions, chunked for the CPU's caches)."""

import operator
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from . import _kernel
from ._compile import jit
from ._kernel import forward as _forward_kernel
from ._models._base import AbstractFrictionModel, SimResult
from ._models.two_state import TwoState
from .motion import auto_deadband, make_motion, play, played_velocity, reversal_bound


class StackOverflowWarning(UserWarning):
    """A two-state memory stack was full and its oldest entries were dropped."""


def _as_1d(name: str, a: ArrayLike):
    arr = jnp.asarray(a)
    if arr.ndim != 1:
        raise ValueError(
            f"{name} must be 1-D (one trajectory), got shape {arr.shape}; "
            "use jax.vmap over jaxfric.simulate for a batch"
        )
    if not jnp.issubdtype(arr.dtype, jnp.floating):
        arr = arr.astype(jnp.asarray(0.0).dtype)
    return arr


def _common_float(*arrays):
    """Cast to one floating dtype (the widest given), so float32 times with float64
    positions work under strict dtype promotion too."""
    dtype = max((a.dtype for a in arrays), key=lambda d: d.itemsize)
    return tuple(a.astype(dtype) for a in arrays)


def _strong(leaf):
    """A parameter leaf without the weak-type flag (set by ``eqx.tree_at(..., 2.0)`` or a
    Python-scalar ``jnp.asarray``), which is part of the JIT cache key: without this, an
    edited model would recompile."""
    if eqx.is_inexact_array(leaf) and getattr(leaf, "weak_type", False):
        return jnp.asarray(leaf, dtype=leaf.dtype)
    return leaf


def _check_values(name: str, a) -> None:
    """Raise when concrete `a` has a non-finite value, naming where: ``at index i`` for one
    motion, ``at [row, col]`` for motions ``(B, n)``."""
    if isinstance(a, jax.core.Tracer):
        return
    a = np.asarray(a)
    if np.isfinite(np.sum(a)):  # one pass without a temporary; NaN and inf propagate
        return
    bad = ~np.isfinite(a)
    if bad.any():
        at = np.unravel_index(int(np.argmax(bad)), bad.shape)
        where = f"index {at[0]}" if bad.ndim == 1 else f"[{', '.join(map(str, at))}]"
        raise ValueError(f"{name} has a non-finite value at {where}")


@jit
def _run(model: AbstractFrictionModel, t, x, v, max_reversals=None, load=None,
         a=None, event_pass: str = "auto", parts: bool = True) -> SimResult:
    """`event_pass` (``JAXFRIC_EVENT_KERNEL``, read when tracing; `jaxfric._kernel`) is a
    static argument only so that changing it takes effect at the next call. A `TwoState`
    that runs in the compiled forward kernel gets the motion as given (the kernel derives
    the velocity itself: no XLA pass over the samples before it). Without `parts` the
    result's parts are ``{}``: the kernel then writes the force only."""
    motion = make_motion(t, x, v, max_reversals, load, a)
    if type(model) is TwoState and _forward_kernel.supported(
            model, *(u for u in (t, x, v) if u is not None)):
        # `motion` is unused there, and compiled away.
        force, got, overflow = _forward_kernel.simulate(model, t, x, v, max_reversals)
        return SimResult(force=force, parts=got if parts else {}, overflow=overflow)
    out = model._simulate(motion)
    return out if parts else SimResult(force=out.force, parts={}, overflow=out.overflow)


def _uses_reversal_bound(model, *arrays) -> bool:
    """Whether `model`, or a model inside it (e.g. under added effects), evaluates terms on
    a list of reversals (`AbstractFrictionModel.uses_reversal_bound`), on a motion of
    `arrays` (t, x, v; none: any motion): a `TwoState` that runs in the compiled forward
    kernel (`jaxfric._kernel.forward`) needs no list."""

    def uses(m):
        return getattr(m, "uses_reversal_bound", False) is True

    def needs(m):
        return uses(m) and not (arrays and type(m) is TwoState and _forward_kernel.supported(
            m, *arrays, scalar_params=False))

    return any(needs(m) for m in jax.tree.leaves(model, is_leaf=uses))


def _checked_motion(t, x, v):
    """`t`, `x`, `v` as 1-D float arrays of one shape and dtype, finite, `t` increasing
    (checked where the values are concrete); plain ValueErrors before any tracing."""
    t = _as_1d("t", t)
    x = _as_1d("x", x)
    if x.shape != t.shape:
        raise ValueError(f"t and x must have the same shape, got {t.shape} and {x.shape}")
    if t.shape[0] < 1:
        raise ValueError("need at least one sample")
    if v is not None:
        v = _as_1d("v", v)
        if v.shape != t.shape:
            raise ValueError(f"t and v must have the same shape, got {t.shape} and {v.shape}")
    for name, a in (("t", t), ("x", x), ("v", v)):
        if a is not None:
            _check_values(name, a)
    if v is None:
        t, x = _common_float(t, x)
    else:
        t, x, v = _common_float(t, x, v)
    if not isinstance(t, jax.core.Tracer):
        tn = np.asarray(t)
        back = tn[1:] <= tn[:-1]
        if back.any():
            i = int(np.argmax(back)) + 1
            raise ValueError(f"t must be strictly increasing; t[{i}] <= t[{i - 1}]")
    return t, x, v


def _checked_load(load, t, name="load"):
    """`load` (or another per-sample input `name`) as a 1-D float array of `t`'s shape and
    dtype, finite where concrete; None stays None."""
    if load is None:
        return None
    load = _as_1d(name, load)
    if load.shape != t.shape:
        raise ValueError(f"t and {name} must have the same shape, got {t.shape} and "
                         f"{load.shape}")
    _check_values(name, load)
    return load.astype(t.dtype)


def apply_deadband(x, v, deadband, t=None):
    """``(x, v)`` through the play of half-width `deadband` (m; ``"auto"``: decided from
    concrete `x` (and `v`, `t`) by `jaxfric.motion.auto_deadband`; ``None``/0: unchanged);
    a given `v` is made to agree with the played position (`jaxfric.motion.played_velocity`),
    so the direction comes from the played position alone."""
    if isinstance(deadband, str):
        if deadband != "auto":
            raise ValueError(f"deadband must be a number, None or 'auto', got {deadband!r}")
        if any(isinstance(a, jax.core.Tracer) for a in (x, v, t)):
            raise ValueError("deadband='auto' needs concrete positions; pass a number")
        deadband = auto_deadband(np.asarray(x), None if v is None else np.asarray(v),
                                 None if t is None else np.asarray(t))
    if deadband is None or (not isinstance(deadband, jax.core.Tracer) and float(deadband) == 0):
        return x, v
    if not isinstance(deadband, jax.core.Tracer) and not float(deadband) >= 0:
        raise ValueError(f"deadband must be >= 0, got {deadband}")
    x = play(x, deadband)
    if v is not None:
        v = played_velocity(x, v)
    return x, v


def _max_reversals(model, t, x, v, max_reversals: int | None) -> int | None:
    """The static size of the reversal list: the user's, or counted on concrete data for
    the models that use one (`_uses_reversal_bound`)."""
    if max_reversals is None and not any(isinstance(a, jax.core.Tracer) for a in (t, x, v)) \
            and _uses_reversal_bound(model, *(a for a in (t, x, v) if a is not None)):
        max_reversals = reversal_bound(t, x, v)
    if max_reversals is not None:
        max_reversals = operator.index(max_reversals)
        if max_reversals < 0:
            raise ValueError(f"max_reversals must be >= 0, got {max_reversals}")
    return max_reversals


def simulate(
    model: AbstractFrictionModel,
    t: ArrayLike,
    x: ArrayLike,
    v: ArrayLike | None = None,
    *,
    full_output: bool = False,
    max_reversals: int | None = None,
    deadband: float | str | None = None,
    load: ArrayLike | None = None,
    a: ArrayLike | None = None,
):
    """Friction force of `model` along a motion.

    **Arguments:**

    - `model`: any jaxfric model (`TwoState`, `GMS`, `LuGre`, `Tustin`, ...), starting from
      its zero state at ``x[0]``.
    - `t`: sample times, s, 1-D, strictly increasing (irregular spacing is fine).
    - `x`: positions, m, same shape as `t`.
    - `v`: velocities, m/s, optional. If omitted, ``v`` is the backward difference of `x`
      (``v[0] = 0``), so that its sign always agrees with the step (docs/algorithm.md).
      The direction of motion is ``sign(v)``; pass measured or commanded velocities when
      you have them (a backward difference lags by half a sample).
    - `full_output`: return a `SimResult` (force, named parts, stack overflow count)
      instead of the force array.
    - `max_reversals`: an upper bound on the number of direction reversals in the motion
      (a Python int; static). `TwoState` evaluates its reversal terms on a list of this
      size instead of on every sample. ``None``: computed from the data when they are
      concrete (`jaxfric.reversal_bound`), else ``n`` (inside ``jit``/``vmap``: pass it for
      speed). A bound below the true count gives NaN forces, never silently wrong ones,
      and counts the reversals beyond it in `SimResult.overflow` (a warning outside ``jit``).
    - `deadband`: half-width (m) of a play on the position against noisy standstill
      (`jaxfric.motion.play`, docs/algorithm.md section 1): the models see the played
      position, and a given `v` is 0 where it points against the played motion while the
      played position stands (`jaxfric.motion.played_velocity`). ``"auto"``: estimated from
      `x` and applied only when the data show noise-made reversals
      (`jaxfric.motion.auto_deadband`; concrete data only). ``None`` or 0: none.
    - `load`: the transmitted load, N (N m on a rotary axis), same shape as `t`: the
      signal `jaxfric.effects.LoadFriction` reads (a file's ``load`` column). A model with
      that effect raises `ValueError` without it; other models ignore it.
    - `a`: the acceleration, m/s^2 (rad/s^2), same shape as `t`, that effects reading it
      (`jaxfric.effects.Inertia`) see. ``None``: the backward difference of `v`, what a
      controller's per-sample ``step`` computes. Identification passes a zero-phase
      estimate (`fitting.estimate_derivatives`) or a measured column.

    **Returns:** the friction force, N, one per sample (or a `SimResult`).

    Compiled with ``equinox.filter_jit`` and jaxfric's compiler options (`jaxfric._compile`);
    works under ``jax.vmap`` (over trajectories or over models) and ``jax.grad`` with
    respect to every parameter of `model`. Warns with `StackOverflowWarning` when memory
    entries had to be dropped (only outside traced code).
    """
    t, x, v = _checked_motion(t, x, v)
    load = _checked_load(load, t)
    a = _checked_load(a, t, "a")
    x, v = apply_deadband(x, v, deadband, t)
    model = jax.tree.map(_strong, model)
    max_reversals = _max_reversals(model, t, x, v, max_reversals)
    result = _run(model, t, x, v, max_reversals, load, a, _kernel.mode(), full_output)
    if not isinstance(result.overflow, jax.core.Tracer) and int(result.overflow) > 0:
        warnings.warn(
            f"the memory stack overflowed {int(result.overflow)} time(s); the oldest reversal "
            "points were dropped. Increase the model's stack_size (CLI: --stack-size), or "
            "max_reversals if you gave one (then the forces are NaN), or filter noisy "
            "standstill with a deadband.",
            StackOverflowWarning,
            stacklevel=2,
        )
    return result if full_output else result.force


def _checked_batch_input(u, t, name):
    """A per-sample input of `simulate_many` (`load`, `a`): `t`'s shape and dtype, finite
    where concrete; None stays None."""
    if u is None or t.ndim == 1:
        return _checked_load(u, t, name)
    u = jnp.asarray(u)
    if u.shape != t.shape:
        raise ValueError(f"t and {name} must have the same shape, got {t.shape} and "
                         f"{u.shape}")
    _check_values(name, u)
    return u.astype(t.dtype)


@jit
def _run_many(models, t, x, v, max_reversals, model_axis, chunk, full=True, load=None,
              a=None, event_pass: str = "auto") -> SimResult:
    """`_run` over a batch, `chunk` items at a time (``lax.map`` with ``batch_size``).
    Without `full`, the parts are left out (``{}``): writing four more ``(B, n)`` arrays
    out of the map cost a third more time on the benchmark's Monte-Carlo."""
    B = (t.shape[0] if t.ndim == 2 else
         jax.tree.leaves(eqx.filter(models, eqx.is_array))[0].shape[model_axis])
    params, static = eqx.partition(models, eqx.is_array)
    if model_axis is not None:
        params = jax.tree.map(lambda a: jnp.moveaxis(a, model_axis, 0), params)
    shared = {"t": t, "x": x, "v": v, "load": load, "a": a}
    mapped = {"p": params if model_axis is not None else None,
              **{k: u if u is not None and u.ndim == 2 else None for k, u in shared.items()}}

    def one(item):
        m = eqx.combine(params if item["p"] is None else item["p"], static)
        got = {k: shared[k] if item[k] is None else item[k] for k in shared}
        return _run(m, got["t"], got["x"], got["v"], max_reversals, got["load"], got["a"],
                    parts=full)

    return jax.lax.map(one, mapped, batch_size=max(1, min(chunk, B)))


def _checked_motions(t, x, v):
    """`_checked_motion` for motions ``(B, n)``, one per row, checked all at once."""
    arrays = [a if jnp.issubdtype(a.dtype, jnp.floating) else a.astype(jnp.asarray(0.0).dtype)
              for a in (t, x, v) if a is not None]
    for name, a in zip(("t", "x", "v"), arrays):
        _check_values(name, a)
    arrays = _common_float(*arrays)
    if not isinstance(arrays[0], jax.core.Tracer):
        bad = np.diff(np.asarray(arrays[0]), axis=1) <= 0
        if bad.any():
            row, col = np.unravel_index(int(np.argmax(bad)), bad.shape)
            raise ValueError(f"t must be strictly increasing; t[{row}, {col + 1}] <= "
                             f"t[{row}, {col}]")
    return (*arrays, None) if v is None else tuple(arrays)


def simulate_many(
    models: AbstractFrictionModel,
    t: ArrayLike,
    x: ArrayLike,
    v: ArrayLike | None = None,
    *,
    model_axis: int | None = 0,
    chunk: int | None = None,
    full_output: bool = False,
    max_reversals: int | None = None,
    load: ArrayLike | None = None,
    a: ArrayLike | None = None,
):
    """Friction forces of a batch: many parameter sets (a Monte-Carlo), many motions, or
    both, with the same results as `jax.vmap` over `simulate` but faster on a CPU.

    **Arguments:**

    - `models`: a model whose array leaves have a batch axis `model_axis` (B parameter
      sets, e.g. built with ``jax.vmap`` or ``eqx.tree_at``), or one model with
      ``model_axis=None``.
    - `t`, `x` (and `v`): one motion (1-D, shared by every parameter set: the motion's
      inputs, directions and reversals are then computed once), or B motions ``(B, n)``.
      Units and rules as in `simulate`.
    - `chunk`: how many batch items run together (a ``vmap`` of `chunk` inside a
      ``lax.map`` over the batch). Default: the whole batch where the compiled forward
      kernel runs (one call, its threads sharing the items), else 32, small enough that
      a chunk's arrays stay in the CPU's caches on the JAX path
      (benchmarks/montecarlo_speed.py); on a GPU use the batch size.
    - `full_output`, `max_reversals`: as in `simulate` (the bound is the largest over the
      batch when computed from concrete data).
    - `load`, `a`: the transmitted load (N) and the acceleration (m/s^2) as in `simulate`,
      of the shape of `t` (one per motion for ``(B, n)`` motions).

    **Returns:** forces ``(B, n)`` in N (or a `SimResult` with a leading batch axis).
    Warns with `StackOverflowWarning` as `simulate` does.
    """
    t, x = jnp.asarray(t), jnp.asarray(x)
    v = None if v is None else jnp.asarray(v)
    if t.ndim not in (1, 2) or x.shape != t.shape or (v is not None and v.shape != t.shape):
        raise ValueError(f"t, x (and v) must be 1-D or (B, n) arrays of one shape, got "
                         f"{t.shape} and {x.shape}")
    if model_axis is None and t.ndim == 1:
        raise ValueError("nothing to batch: give a batched model or (B, n) motions")
    if model_axis is not None and t.ndim == 2:
        sizes = {a.shape[model_axis] for a in jax.tree.leaves(eqx.filter(models, eqx.is_array))}
        if sizes != {t.shape[0]}:
            raise ValueError(f"the model's batch axis ({sizes}) and the motions' "
                             f"({t.shape[0]}) differ")
    if t.shape[-1] < 1:
        raise ValueError("need at least one sample")
    t, x, v = _checked_motion(t, x, v) if t.ndim == 1 else _checked_motions(t, x, v)
    load, a = (_checked_batch_input(u, t, name) for u, name in ((load, "load"), (a, "a")))
    models = jax.tree.map(_strong, models)
    max_reversals = _max_reversals(models, t, x, v, max_reversals)
    if chunk is None:
        kernel = type(models) is TwoState and _forward_kernel.supported(
            models, t, x, v, scalar_params=False)
        chunk = (t.shape[0] if t.ndim == 2 else jax.tree.leaves(
            eqx.filter(models, eqx.is_array))[0].shape[model_axis]) if kernel else 32
    result = _run_many(models, t, x, v, max_reversals, model_axis, operator.index(chunk),
                       full_output, load, a, _kernel.mode())
    if not isinstance(result.overflow, jax.core.Tracer) and int(jnp.sum(result.overflow)) > 0:
        warnings.warn(
            f"the memory stack overflowed in {int(jnp.sum(result.overflow > 0))} batch "
            "item(s); the oldest reversal points were dropped. Increase the model's "
            "stack_size, or max_reversals if you gave one (then the forces are NaN).",
            StackOverflowWarning,
            stacklevel=2,
        )
    return result if full_output else result.force
