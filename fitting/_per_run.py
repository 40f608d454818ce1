"""Per-run nuisance parameters of a fit to several runs.

An effect's parameter declared ``param(..., per_run=True)`` (`jaxfric._fields`; the offset
of `jaxfric.effects.Offset`) belongs to one run, not to the machine: a sensor zero or a
gravity compensation is set again for every run. `fitting.fit_datasets` then fits one value
of it per run and shares every other parameter. One declared ``per_run="relative"`` (the
starting level of `jaxfric.effects.Drift`) cannot be told from the machine's parameters
within one run, so one run is the reference, held at its value, and the others are
fitted: run 1 in a fit of every run, the first run fitted in a fit that leaves runs out
(a leave-one-run-out fold without run 1: were run 1 the reference, a common shift of the
fitted runs' levels would be the base friction's scale, and the fit ill-posed).

**How.** The effect is wrapped in `_PerRunEffect`, whose per-run leaves carry one value per
run (a vector leaf, so the result names them ``offset_1 .. offset_D`` in run order, with a
standard error each); a relative leaf carries the values of every run but the reference
run's (``drift_level_2 .. drift_level_D`` with run 1 the reference; the names skip the
reference run, `run_numbers`), that one being static (`_PerRunEffect.reference`), so no
per-element free mask is needed. `rereferenced` moves the reference to another run and
keeps every run's model (a warm start from a fit of every run into a fold without run 1).
Which run a simulation is of is told by its first sample time (`jaxfric.effects.Signals.t0`):
the fit shifts run ``i``'s time axis to start at ``i`` seconds (`shifted`), which changes
nothing else, since every model and effect reads time only through its steps and its
distance from the first sample. The plain model of one run is `run_model`; `mean_model` is
the model for a run not fitted (each per-run value at its mean over the runs).
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxfric._effect_model import AbstractEffect, WithEffects
from jaxfric._fields import _child


def per_run_fields(effect) -> tuple[str, ...]:
    """The fields of `effect` declared ``per_run`` (`jaxfric._fields.param`)."""
    return tuple(f.name for f in dataclasses.fields(effect)
                 if f.metadata.get("per_run", False))


class _PerRunEffect(AbstractEffect):
    """`effect` with its `fields` holding one value per run (leading axis), those also in
    `relative` the values of every run but run `reference_run` (0-based; its values are
    `reference`, in `relative`'s order); the run of a simulation is the number of `starts`
    (after the first) at or before its first sample."""

    effect: AbstractEffect
    fields: tuple[str, ...] = eqx.field(static=True)
    starts: tuple[float, ...] = eqx.field(static=True)
    relative: tuple[str, ...] = eqx.field(static=True, default=())
    reference: tuple[float, ...] = eqx.field(static=True, default=())
    reference_run: int = eqx.field(static=True, default=0)

    @property
    def name(self) -> str:  # the wrapped effect's: results and terms keep its name
        return self.effect.name

    def values(self, field: str):
        """Every run's value of per-run `field` (the reference run's inserted for a
        relative one)."""
        stored = getattr(self.effect, field)
        if field not in self.relative:
            return stored
        ref = jnp.asarray(self.reference[self.relative.index(field)], stored.dtype)
        k = self.reference_run
        return jnp.concatenate([stored[:k], ref[None], stored[k:]])

    def run_numbers(self, field: str) -> tuple[int, ...]:
        """The runs (numbered from 1) whose values the leaf of per-run `field` stores."""
        runs = range(1, len(self.starts) + 1)
        return tuple(r for r in runs if field not in self.relative
                     or r != self.reference_run + 1)

    def rereferenced(self, k: int) -> "_PerRunEffect":
        """This effect with run `k` (0-based) the reference of its relative fields: every
        run's value unchanged (the values must be concrete)."""
        if k == self.reference_run or not self.relative:
            return self
        if not 0 <= k < len(self.starts):
            raise ValueError(f"{self.name}: reference run {k} not in 0..{len(self.starts) - 1}")
        every = [np.asarray(self.values(f)) for f in self.relative]
        stored = [jnp.asarray(np.delete(v, k)) for v in every]
        effect = eqx.tree_at(lambda e: [getattr(e, f) for f in self.relative], self.effect,
                             stored)
        return dataclasses.replace(self, effect=effect,
                                   reference=tuple(float(v[k]) for v in every),
                                   reference_run=k)

    def with_values(self, values: list):
        """The plain effect with `fields` set to `values` (one scalar each)."""
        return eqx.tree_at(lambda e: [getattr(e, f) for f in self.fields], self.effect,
                           values)

    def of_run(self, k) -> AbstractEffect:
        """The plain effect of run `k` (an int or a traced index)."""
        return self.with_values([self.values(f)[k] for f in self.fields])

    def term(self, s):
        k = jnp.sum(s.t0 >= jnp.asarray(self.starts[1:]))
        return self.of_run(k).term(s)

    def describe(self) -> str:
        return f"{self.effect.name}, one value per run of {', '.join(self.fields)}"


def has_per_run(model) -> bool:
    """`model` has effects with per-run parameters."""
    return isinstance(model, WithEffects) and any(per_run_fields(e) for e in model.effects)


def with_runs(model, runs: int, reference: int | None = None):
    """`model` with every per-run parameter repeated for `runs` runs (run ``i`` starting at
    ``i`` seconds, see `shifted`), run `reference` (0-based; default 0) the reference of a
    relative one; `model` itself when it has none. An effect already wrapped keeps its
    values, and its reference unless `reference` is given (then moved there,
    `rereferenced`; the effect must be wrapped for `runs` runs)."""
    if runs < 2 or not isinstance(model, WithEffects):
        return model
    starts = tuple(float(i) for i in range(runs))

    def wrap(e):
        if isinstance(e, _PerRunEffect):
            if reference is None:
                return e
            if len(e.starts) != runs:
                raise ValueError(f"{e.name}: per-run values of {len(e.starts)} runs, "
                                 f"fitted to {runs}")
            return e.rereferenced(reference)
        fields = per_run_fields(e)
        if not fields:
            return e
        for f in fields:
            if jnp.ndim(getattr(e, f)) != 0:
                raise ValueError(f"{e.name}: per-run parameter {f!r} must be a scalar")
        relative = tuple(f.name for f in dataclasses.fields(e)
                         if f.metadata.get("per_run") == "relative")
        k = 0 if reference is None else reference
        if not 0 <= k < runs:
            raise ValueError(f"reference run {k} not in 0..{runs - 1}")
        rep = eqx.tree_at(lambda x: [getattr(x, f) for f in fields], e,
                          [jnp.full(runs - (f in relative), getattr(e, f)) for f in fields])
        return _PerRunEffect(rep, fields, starts, relative,
                             tuple(float(getattr(e, f)) for f in relative), k)

    if not any(isinstance(e, _PerRunEffect) or per_run_fields(e) for e in model.effects):
        return model
    return WithEffects(model.base, tuple(wrap(e) for e in model.effects))


def rereferenced(model, k: int):
    """`model` (wrapped by `with_runs`) with run `k` (0-based) the reference of every
    relative per-run parameter: the stored values are every run's but run `k`'s, which is
    held static; every run's model (`run_model`) is unchanged. Any other model unchanged."""
    if not isinstance(model, WithEffects):
        return model
    return WithEffects(model.base, tuple(e.rereferenced(k) if isinstance(e, _PerRunEffect)
                                         else e for e in model.effects))


def run_numbers(model) -> list[tuple[int, ...] | None]:
    """For each parameter leaf of `model` (``jax.tree.leaves`` order of its inexact
    arrays): the runs (numbered from 1) a per-run leaf stores, ``None`` for any other."""
    params = eqx.filter(model, eqx.is_inexact_array)
    out = []
    for path, _ in jax.tree_util.tree_flatten_with_path(params)[0]:
        owner, numbers = model, None
        for key in path[:-1]:
            owner = _child(owner, key)
            if isinstance(owner, _PerRunEffect):
                field = getattr(path[-1], "name", None)
                numbers = owner.run_numbers(field) if field in owner.fields else None
        out.append(numbers)
    return out


def shifted(datasets, runs=None):
    """Checked datasets with run ``i``'s time axis starting at ``i`` seconds; `runs`: the
    run number of each dataset (default 0, 1, ...; a fit that leaves runs out)."""
    runs = range(len(datasets)) if runs is None else runs
    return [dataclasses.replace(d, t=d.t - d.t[0] + float(i)) for i, d in zip(runs, datasets)]


def plain_effect(e):
    """The effect a `_PerRunEffect` wraps (values per run); any other effect unchanged."""
    return e.effect if isinstance(e, _PerRunEffect) else e


def mean_effect(e):
    """A `_PerRunEffect` with its per-run values at their mean (the effect for a run not
    fitted); any other effect unchanged."""
    if not isinstance(e, _PerRunEffect):
        return e
    return e.with_values([jnp.mean(e.values(f)) for f in e.fields])


def run_model(model, k: int | None, among=None):
    """The plain model of run `k` of a model fitted with per-run parameters (``None``: the
    mean over the runs `among`, default all, the model for a run not fitted); any other
    model unchanged."""
    if not isinstance(model, WithEffects) or not any(
            isinstance(e, _PerRunEffect) for e in model.effects):
        return model

    def plain(e):
        if not isinstance(e, _PerRunEffect):
            return e
        if k is not None:
            return e.of_run(k)
        pick = slice(None) if among is None else np.asarray(list(among), int)
        return e.with_values([jnp.mean(e.values(f)[pick]) for f in e.fields])

    return WithEffects(model.base, tuple(plain(e) for e in model.effects))


def per_run_values(model) -> list[dict[str, float]]:
    """``[{name: value}]`` per run of the per-run parameters of a fitted model (empty when
    it has none)."""
    if not isinstance(model, WithEffects):
        return []
    out: list[dict[str, float]] = []
    for e in model.effects:
        if isinstance(e, _PerRunEffect):
            for f in e.fields:
                values = np.asarray(e.values(f))
                out += [{} for _ in range(len(values) - len(out))]
                for i, val in enumerate(values):
                    out[i][f] = float(val)
    return out


def mean_model(model):
    """`run_model` of no run: per-run parameters at their mean."""
    return run_model(model, None)
