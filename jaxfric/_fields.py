"""Parameter fields: what each parameter is, declared where the parameter is declared.

Every parameter of a model, shape or effect is a field made by `param`, which records its SI
unit, its constraint and its group in the field's metadata. `parameter_info` reads them
back for any model (effects included) in the order of the model's parameter leaves, so the
fitting side (transforms, ``free=`` groups, unit columns of tables and reports) needs no
table of names of its own.

Constraints are plain data, mapped to transforms by `fitting`:

- ``None``: any real value;
- ``"positive"``: > 0 (fitted on a log scale);
- ``("interval", lo, hi)``: strictly between `lo` and `hi`;
- ``("above", lo)``: > `lo`;
- ``"simplex"``: a vector of weights > 0 that sum to one.
"""

import dataclasses
from typing import Any, NamedTuple

import equinox as eqx
import jax

from ._numerics import as_param


_MISSING = dataclasses.MISSING


def param(unit: str, *, constraint: Any = None, group: str | None = None,
          role: str | None = None, default: Any = _MISSING, linear: bool = False,
          physical: tuple[float, float] | None = None, per_run: bool | str = False) -> Any:
    """A parameter field (an `equinox.field` with the `as_param` converter): `unit` is its
    SI unit as text (``"N"``, ``"m/s"``, ``"N s/m"``, ``"-"`` for none), `constraint` one of
    the module docstring's, `group` a name that ``free=`` accepts for several parameters
    (``"stribeck"``, ``"shape"``), `role` the part of the friction it describes where the
    staged fit needs to know (``"presliding"``: the memory of the presliding curve;
    ``"lag"``: the friction lag). For an effect's parameters (`jaxfric.effects`), what a
    diagnosis needs: `linear` when the term is linear in it (0 switches the effect off),
    `physical` the ``(lo, hi)`` range a fitted value must fall in to be physical (a mass
    is not negative), checked after the fit rather than imposed by a transform.
    `per_run`: a nuisance parameter that belongs to one run rather than to the machine (a
    sensor zero, a gravity-compensation offset): a fit to several runs
    (`fitting.fit_datasets`) gives it one value per run and shares every other parameter.
    ``per_run="relative"``: a per-run value that one run cannot tell from the machine's
    parameters (a drift's starting level against the base friction), so it is relative to
    the first run: held at its value in a fit of one run and for run 1, free for runs
    2..D."""
    metadata = {"unit": unit, "constraint": constraint, "group": group, "role": role,
                "linear": linear, "physical": physical, "per_run": per_run}
    if default is _MISSING:
        return eqx.field(converter=as_param, metadata=metadata)
    return eqx.field(converter=as_param, default=default, metadata=metadata)


class ParamInfo(NamedTuple):
    """What `param` recorded for one parameter leaf, with the leaf's name."""

    name: str
    unit: str
    constraint: Any
    group: str | None
    role: str | None
    per_run: bool | str = False


def _key_name(key) -> str:
    for attr in ("name", "key", "idx"):
        if hasattr(key, attr):
            return str(getattr(key, attr))
    return str(key)


def _child(node, key):
    if hasattr(key, "name"):
        return getattr(node, key.name)
    if hasattr(key, "idx"):
        return node[key.idx]
    return node[key.key]


def parameter_info(model) -> list[ParamInfo]:
    """`ParamInfo` of every parameter leaf of `model` (its inexact-array leaves), in
    ``jax.tree.leaves`` order. A leaf whose field was not made by `param` gets unit
    ``"?"`` and no constraint, group or role."""
    params = eqx.filter(model, eqx.is_inexact_array)
    out = []
    for path, _ in jax.tree_util.tree_flatten_with_path(params)[0]:
        owner = model
        for key in path[:-1]:
            owner = _child(owner, key)
        name = _key_name(path[-1])
        fields = {f.name: f for f in dataclasses.fields(owner)} if dataclasses.is_dataclass(
            owner) else {}
        meta = fields[name].metadata if name in fields else {}
        out.append(ParamInfo(name, meta.get("unit", "?"), meta.get("constraint"),
                             meta.get("group"), meta.get("role"), meta.get("per_run", False)))
    return out
