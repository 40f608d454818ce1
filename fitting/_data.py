"""Measured experiments, their checks, and stacking several of them into one padded array.

Several experiments are fitted together (the staged procedure's joint fit, or a batch) as
arrays of shape ``(D, n)``: shorter ones are padded to the common length ``n`` with samples
of weight 0 that continue the time axis and hold the last position (the model is at rest
there, so padding creates no events). One shape for all stages means one compilation.
"""

import dataclasses

import jax.numpy as jnp
import numpy as np

from jaxfric import _outliers
from jaxfric.data import ABSURD_ROTARY, DataError, Measurement
from jaxfric.motion import velocity


def absurd_sample(name: str, a: np.ndarray, w: np.ndarray | None = None
                  ) -> tuple[int, str] | None:
    """``(i, why)`` if sample ``name[i]`` cannot be a friction measurement in SI, else
    ``None``: beyond
    `jaxfric.data.ABSURD_ROTARY` (the loosest limits: the arrays carry no units), or 1000
    times beyond the rest of its array (`jaxfric._outliers`). Samples of weight 0 (`w`)
    are not judged; for ``F`` the message says to give the sample weight 0."""
    keep = np.ones(a.shape, bool) if w is None else w > 0
    idx = np.flatnonzero(keep)
    vals = a[idx]
    fix = ("give it weight 0 or remove it" if name == "F" else "repair or remove it")
    big = np.abs(vals) > ABSURD_ROTARY[name]
    if big.any():
        i = int(idx[np.argmax(big)])
        return i, (f"{name}[{i}] = {float(a[i]):.6g} is beyond {ABSURD_ROTARY[name]:g} (SI), "
                f"absurd for friction data: a glitch ({fix}) or a unit mistake")
    found = _outliers.relative_outlier(vals)
    if found is not None:
        k, ratio, spread = found
        i = int(idx[k])
        return i, f"{name}[{i}] = {_outliers.message(name, a[i], ratio, spread)}; {fix}"
    return None


#: One experiment for a fit: `jaxfric.data.Measurement` (the same class), constructed as
#: ``Dataset(t, x, F, v=None, weights=None, load=None, a=None, known=None)`` in SI (s, m,
#: N, m/s;
#: weights >= 0, 0 drops a sample, ``None`` for ones; ``v`` ``None`` for the backward
#: difference of ``x``, as `jaxfric.simulate`; ``load`` the transmitted load, N, for
#: `jaxfric.effects.LoadFriction`; ``a`` the acceleration, m/s^2, for
#: `jaxfric.effects.Inertia`, ``None`` for the backward difference of ``v``; ``known`` a
#: known force component in ``F``, N, subtracted before fitting, not fitted).
Dataset = Measurement


def _array(name: str, a, where: str) -> np.ndarray:
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"{where}{name} must be 1-D, got shape {arr.shape}")
    return arr


def check_dataset(data: Dataset, where: str = "", check_force: bool = True) -> Dataset:
    """Validate `data` in NumPy (outside any jit) and return it as float64 arrays.

    Shapes, finite `t`/`x`/`v`, strictly increasing `t`, weights >= 0 raise `ValueError`
    naming the array and the index, and so does an absurd sample of `x`, `v` (`F` when
    `check_force`): see `absurd_sample`. Non-finite `F` raises too when `check_force`;
    otherwise (batches) it is left to the solver, which reports it in that dataset's
    result code.
    Samples of weight 0 may hold anything in `F` (it is zeroed).
    """
    t = _array("t", data.t, where)
    n = t.shape[0]
    if n < 2:
        raise ValueError(f"{where}need at least 2 samples, got {n}")
    out = {"t": t}
    for name in ("x", "F", "v", "weights", "load", "a", "known"):
        a = getattr(data, name)
        if a is None:
            out[name] = None
            continue
        arr = _array(name, a, where)
        if arr.shape != t.shape:
            raise ValueError(f"{where}{name} has shape {arr.shape}, t has {t.shape}")
        out[name] = arr
    w = out["weights"] if out["weights"] is not None else np.ones_like(t)
    for name in ("t", "x", "v", "weights", "load", "a", "known") + (
            ("F",) if check_force else ()):
        a = out[name]
        if name == "F":
            a = np.where(w > 0, a, 0.0)
        if a is not None and not np.all(np.isfinite(a)):
            i = int(np.argmax(~np.isfinite(a)))
            raise DataError(f"{where}{name} has a non-finite value at index {i}")
    bad = np.diff(t) <= 0
    if bad.any():
        i = int(np.argmax(bad)) + 1
        raise DataError(f"{where}t must be strictly increasing; t[{i}] <= t[{i - 1}]")
    if (w < 0).any():
        raise ValueError(f"{where}weights must be >= 0; weights[{int(np.argmax(w < 0))}] < 0")
    if not (w > 0).any():
        raise ValueError(f"{where}all weights are 0")
    _refuse_absurd(out, w, where, ("x", "v") + (("F",) if check_force else ()))
    out["F"] = np.where(w > 0, out["F"], 0.0)
    out["weights"] = w
    return Dataset(**out)


def _refuse_absurd(arrays: dict, w: np.ndarray, where: str, names) -> None:
    for name in names:
        found = None if arrays[name] is None else absurd_sample(name, arrays[name], w)
        if found is not None:
            raise DataError(f"{where}{found[1]}")


def pad(data: Dataset, n: int) -> Dataset:
    """`data` (checked, NumPy) padded to `n` samples of weight 0 (see module docstring)."""
    m = data.t.shape[0]
    if n < m:
        raise ValueError(f"cannot pad {m} samples to {n}")
    k = n - m
    step = data.t[-1] - data.t[-2]
    t = np.concatenate([data.t, data.t[-1] + step * np.arange(1, k + 1)])

    def hold(a, fill):
        return None if a is None else np.concatenate([a, np.full(k, fill)])

    return Dataset(
        t=t,
        x=hold(data.x, data.x[-1]),
        F=hold(data.F, 0.0),
        v=hold(data.v, 0.0),
        weights=hold(data.weights, 0.0),
        load=hold(data.load, data.load[-1] if data.load is not None else 0.0),
        a=hold(data.a, 0.0),
    )


def stack(datasets: list[Dataset], n: int | None = None) -> Dataset:
    """Checked datasets padded to a common length and stacked: arrays of shape ``(D, n)``.

    If some datasets give `v` (or `a`) and others do not, the missing ones get the backward
    difference (what the model would use anyway).
    """
    n = max(d.t.shape[0] for d in datasets) if n is None else n
    any_v = any(d.v is not None for d in datasets)
    any_a = any(d.a is not None for d in datasets)
    with_load = [d.load is not None for d in datasets]
    if any(with_load) and not all(with_load):
        raise ValueError(f"datasets {[i for i, w in enumerate(with_load) if not w]} have no "
                         "load signal and the others do: give all of them one, or none")
    padded = []
    for d in datasets:
        if any_v and d.v is None:
            d = dataclasses.replace(d, v=velocity(d.t, d.x))
        if any_a and d.a is None:  # `velocity` without a window: the backward difference
            d = dataclasses.replace(d, a=velocity(d.t, velocity(d.t, d.x) if d.v is None
                                                  else d.v))
        padded.append(pad(d, n))

    def field(name):
        return jnp.asarray(np.stack([getattr(d, name) for d in padded]))

    return Dataset(
        t=field("t"),
        x=field("x"),
        F=field("F"),
        v=field("v") if any_v else None,
        weights=field("weights"),
        load=field("load") if all(with_load) else None,
        a=field("a") if any_a else None,
    )
