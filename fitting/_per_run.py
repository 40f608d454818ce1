"""Per-run nuisance parameters of a fit to several runs.

An effect's parameter declared ``param(..., per_run=True)`` (`jaxfric._fields`; the offset
of `jaxfric.effects.Offset`) belongs to one run, not to the machine: a sensor zero or a
gravity compensation is set again for every run. `fitting.fit_datasets` then fits one value
of it per run and shares every other parameter. One declared ``per_run="relative"`` (the
starting level of `jaxfric.effects.Drift`) cannot be told from the machine's parameters
within one run, so run 1 is the reference, held at its value, and runs 2..D are fitted.

**How.** The effect is wrapped in `_PerRunEffect`, whose per-run leaves carry one value per
run (a vector leaf, so the result names them ``offset_1 .. offset_D`` in run order, with a
standard error each); a relative leaf carries the values of runs 2..D only
(``drift_level_2 .. drift_level_D``), run 1's being static (`_PerRunEffect.reference`), so
no per-element free mask is needed. Which run a simulation is of is told by its first
sample time (`jaxfric.effects.Signals.t0`): the fit shifts run ``i``'s time axis to start
at ``i`` seconds (`shifted`), which changes nothing else, since every model and effect reads
time only through its steps and its distance from the first sample. The plain model of one
run is `run_model`; `mean_model` is the model for a run not fitted (each per-run value at
its mean over the runs).
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from jaxfric._effect_model import AbstractEffect, WithEffects


def per_run_fields(effect) -> tuple[str, ...]:
    """The fields of `effect` declared ``per_run`` (`jaxfric._fields.param`)."""
    return tuple(f.name for f in dataclasses.fields(effect)
                 if f.metadata.get("per_run", False))


class _PerRunEffect(AbstractEffect):
    """`effect` with its `fields` holding one value per run (leading axis), those also in
    `relative` the values of runs 2..D (run 1's is `reference`, in `relative`'s order); the
    run of a simulation is the number of `starts` (after the first) at or before its first
    sample."""

    effect: AbstractEffect
    fields: tuple[str, ...] = eqx.field(static=True)
    starts: tuple[float, ...] = eqx.field(static=True)
    relative: tuple[str, ...] = eqx.field(static=True, default=())
    reference: tuple[float, ...] = eqx.field(static=True, default=())

    @property
    def name(self) -> str:  # the wrapped effect's: results and terms keep its name
        return self.effect.name

    def values(self, field: str):
        """Every run's value of per-run `field` (run 1's reference prepended for a
        relative one)."""
        stored = getattr(self.effect, field)
        if field not in self.relative:
            return stored
        ref = jnp.asarray(self.reference[self.relative.index(field)], stored.dtype)
        return jnp.concatenate([ref[None], stored])

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


def with_runs(model, runs: int):
    """`model` with every per-run parameter repeated for `runs` runs (run ``i`` starting at
    ``i`` seconds, see `shifted`); `model` itself when it has none."""
    if runs < 2 or not has_per_run(model):
        return model
    starts = tuple(float(i) for i in range(runs))

    def wrap(e):
        fields = per_run_fields(e)
        if not fields:
            return e
        for f in fields:
            if jnp.ndim(getattr(e, f)) != 0:
                raise ValueError(f"{e.name}: per-run parameter {f!r} must be a scalar")
        relative = tuple(f.name for f in dataclasses.fields(e)
                         if f.metadata.get("per_run") == "relative")
        rep = eqx.tree_at(lambda x: [getattr(x, f) for f in fields], e,
                          [jnp.full(runs - (f in relative), getattr(e, f)) for f in fields])
        return _PerRunEffect(rep, fields, starts, relative,
                             tuple(float(getattr(e, f)) for f in relative))

    return WithEffects(model.base, tuple(wrap(e) for e in model.effects))


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
