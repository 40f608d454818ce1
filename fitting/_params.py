"""Parameter properties beside the model, names, and the model <-> flat vector map.

A model's parameters are its inexact-array leaves (`equinox.is_inexact_array`); static
fields such as ``stack_size`` are structure, not parameters. Each leaf is named by the last
attribute on its path (``model.stribeck.Fs`` -> ``"Fs"``, ``model.shape.l1`` -> ``"l1"``),
which gives the paper's symbols for every jaxfric model without a per-model table.

The properties pytree has the structure of ``eqx.filter(model, eqx.is_inexact_array)`` with a
`ParamProps` at every leaf; `default_props` builds it and ``eqx.tree_at`` edits it.
"""

from collections.abc import Iterable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

import jaxfric
from jaxfric import NormalizedPaperShape
from jaxfric._compile import jit
from jaxfric._fields import parameter_info

from ._per_run import run_numbers
from ._transforms import AbstractTransform, Exp, Identity, ParamProps, Sigmoid, Simplex


# Order of the result dictionaries: the paper's (Table 1, then presliding, then C).
_ORDER = ("Fs", "Fc", "Vs", "delta", "sigma0", "sigma1", "sigma2", "a", "b", "c", "alpha",
          "beta", "beta_rel", "curvature", "quartic", "l1", "n", "C", "nu", "k")

def _transform(constraint) -> AbstractTransform:
    """The fit's transform for a parameter's declared constraint (`jaxfric._fields`)."""
    if constraint == "positive":
        return Exp()
    if constraint == "simplex":
        return Simplex()
    if isinstance(constraint, tuple) and constraint[0] == "interval":
        return Sigmoid(constraint[1], constraint[2])
    if isinstance(constraint, tuple) and constraint[0] == "above":
        return Exp(lower=constraint[1])
    return Identity()


def parameters(model) -> tuple[object, object]:
    """``(params, static)`` = ``eqx.partition(model, eqx.is_inexact_array)``."""
    return eqx.partition(model, eqx.is_inexact_array)


def leaf_names(model) -> list[str]:
    """Name of every parameter leaf of `model`, in ``jax.tree.leaves`` order."""
    return [info.name for info in parameter_info(model)]


def default_props(model, free: Iterable[str] | None = None):
    """The default properties pytree for `model` (see the module docstring).

    Each parameter's transform follows the constraint declared on its field: positive
    quantities (Fs, Fc, Vs, sigma0/1/2, C, l1, beta, k_i, ...) get `Exp` (log scale),
    ``alpha`` a `Sigmoid` on (0, 1), ``delta`` one on (0, `jaxfric._stribeck.DELTA_MAX`),
    the GMS weights ``nu`` a `Simplex`, PowerShape's ``n`` `Exp` above 1, unconstrained
    ones `Identity`. Every ``scale`` is left to the starting
    value. `free`: names (or groups declared on the fields: ``"stribeck"``, ``"shape"``) to
    fit; ``None`` frees everything but a scalar ``per_run="relative"`` parameter (a drift's
    starting level: in a fit of one run it cannot be told from the base friction, so it is
    held; a fit to several runs makes it a vector, `fitting._per_run`, and frees it).
    """
    params, _ = parameters(model)
    infos = iter(parameter_info(model))

    def props_of(leaf):
        info = next(infos)
        return ParamProps(_transform(info.constraint), free=not _held_relative(info, leaf))

    props = jax.tree.map(props_of, params)
    return props if free is None else set_free(model, props, free)


def _held_relative(info, leaf) -> bool:
    """A ``per_run="relative"`` parameter of one run: held unless named in ``free=``."""
    return info.per_run == "relative" and jnp.ndim(leaf) == 0


def _is_props(node) -> bool:
    return isinstance(node, ParamProps)


def props_leaves(props) -> list[ParamProps]:
    return jax.tree.leaves(props, is_leaf=_is_props)


def inside_domains(model, props):
    """`model` with each free leaf exactly on a bound of its transform's domain (a fit's
    value pinned there, e.g. a Stribeck exponent at its maximum, then a start of another
    fit) moved just inside it (`AbstractTransform.inside`); any other value unchanged, a
    value beyond a bound refused as before (`make_layout`)."""
    params, static = parameters(model)
    leaves, tree = jax.tree.flatten(params)
    new = [p.transform.inside(leaf) if p.free else leaf
           for leaf, p in zip(leaves, props_leaves(props))]
    return eqx.combine(jax.tree.unflatten(tree, new), static)


def set_free(model, props, free: Iterable[str]):
    """A copy of `props` where exactly the leaves named in `free` are free.

    Raises `ValueError` for a name the model does not have (listing the ones it has).
    """
    if isinstance(free, str):
        free = (free,)
    infos = parameter_info(model)
    names = [i.name for i in infos]
    groups = sorted({i.group for i in infos if i.group is not None})
    wanted = set()
    for item in free:
        hits = [i.name for i in infos if item in (i.name, i.group)]
        if not hits:
            raise ValueError(
                f"{type(model).__name__} has no parameter {item!r}; its parameters are "
                f"{names} (groups: {groups})"
            )
        wanted.update(hits)
    new = [
        ParamProps(p.transform, free=n in wanted, scale=p.scale)
        for p, n in zip(props_leaves(props), names)
    ]
    return jax.tree.unflatten(jax.tree.structure(props, is_leaf=_is_props), new)


class Layout(eqx.Module):
    """How the parameter leaves of one model map onto the solver's flat vector ``y``.

    `transforms` and the shapes/sizes are static structure; `refs` (SI scales) and
    `leaf_free` (one flag per leaf, as an array so that changing the free set does not
    recompile) are data. The vector is assembled leaf by leaf rather than with
    `jax.flatten_util.ravel_pytree`: its ``unravel`` is a new closure at every call, while
    this layout is a stable pytree whose static part keys the compiled solver; and a
    `Simplex` leaf has one coordinate fewer than values.
    """

    transforms: tuple[AbstractTransform, ...]
    refs: tuple[Array, ...]
    leaf_free: Array
    shapes: tuple[tuple[int, ...], ...] = eqx.field(static=True)
    sizes: tuple[int, ...] = eqx.field(static=True)
    names: tuple[str, ...] = eqx.field(static=True)

    def coordinate_mask(self) -> Array:
        """1.0 for coordinates of free leaves, 0.0 otherwise (shape of ``y``)."""
        parts = [jnp.full((s,), self.leaf_free[i]) for i, s in enumerate(self.sizes)]
        return jnp.concatenate(parts).astype(jnp.asarray(0.0).dtype)

    def n_free(self) -> int:
        """The number of free coordinates (concrete flags, on the host: no JAX op)."""
        return int(np.sum(np.repeat(np.asarray(self.leaf_free), self.sizes)))

    def at_bound(self, y: Array) -> Array:
        """One flag per leaf: a free leaf with a coordinate pinned at a bound of its
        transform (`fitting._transforms.PINNED`)."""
        flags, start = [], 0
        for i, (tr, size) in enumerate(zip(self.transforms, self.sizes)):
            flags.append(self.leaf_free[i] & jnp.any(tr.at_bound(y[start:start + size])))
            start += size
        return jnp.stack(flags) if flags else jnp.zeros((0,), bool)

    def coordinate_leaf(self) -> np.ndarray:
        """The index of the leaf of each coordinate of ``y`` (static)."""
        return np.repeat(np.arange(len(self.sizes)), self.sizes)

    def to_vector(self, leaves: list[Array]) -> Array:
        """``y`` for the parameter `leaves`. A held leaf gets the coordinates 0 (its value
        is never read back from ``y``), so that it may sit outside its transform's domain,
        e.g. ``sigma2 = 0`` held under `Exp`."""
        parts = []
        for i, (tr, leaf, ref, size) in enumerate(
            zip(self.transforms, leaves, self.refs, self.sizes)
        ):
            inside = tr.forward(jnp.zeros((size,) if isinstance(tr, Simplex) else leaf.shape,
                                          leaf.dtype), ref)
            safe = jnp.where(self.leaf_free[i], leaf, inside)
            parts.append(jnp.ravel(tr.inverse(safe, ref)))
        return jnp.concatenate(parts)

    def to_leaves(self, y: Array, originals: list[Array]) -> list[Array]:
        """Leaves for ``y``; a fixed leaf keeps its original value exactly (so e.g. GMS
        weights that do not sum to one are not renormalised when held fixed)."""
        out, start = [], 0
        for i, (tr, ref, shape, size) in enumerate(
            zip(self.transforms, self.refs, self.shapes, self.sizes)
        ):
            chunk = y[start:start + size]
            start += size
            if not isinstance(tr, Simplex):
                chunk = chunk.reshape(shape)
            out.append(jnp.where(self.leaf_free[i], tr.forward(chunk, ref), originals[i]))
        return out


def make_layout(model, props) -> Layout:
    """Resolve `props` against `model`'s starting values (checked here, outside any jit)."""
    params, _ = parameters(model)
    leaves = jax.tree.leaves(params)
    plist = props_leaves(props)
    names = leaf_names(model)
    if len(plist) != len(leaves) or not all(_is_props(p) for p in plist):
        raise ValueError(
            "props must have the structure of the model's parameters with a ParamProps at "
            f"every leaf ({len(leaves)} leaves: {names}); build it with default_props(model), "
            "for a PaperShape model with default_props(to_fit_representation(model))"
        )
    refs = []
    for name, leaf, p in zip(names, leaves, plist):
        value = np.asarray(leaf)
        ok = p.transform.in_domain(value)
        if p.free and not np.all(ok):
            raise ValueError(
                f"starting value of {name!r} is {value[~ok].ravel()[0]!r}, outside the domain "
                f"of its transform {type(p.transform).__name__} ({p.transform.domain()})"
            )
        if p.scale is None:
            ref = p.transform.default_ref(jnp.asarray(leaf))
        else:
            ref = jnp.broadcast_to(jnp.asarray(p.scale, dtype=leaf.dtype), leaf.shape)
            if not np.all(np.asarray(ref) > 0):
                raise ValueError(f"scale of {name!r} must be > 0, got {p.scale!r}")
        refs.append(ref)
    return Layout(
        transforms=tuple(p.transform for p in plist),
        refs=tuple(refs),
        leaf_free=jnp.asarray([bool(p.free) for p in plist], dtype=bool),
        shapes=tuple(tuple(leaf.shape) for leaf in leaves),
        sizes=tuple(p.transform.size(tuple(leaf.shape)) for p, leaf in zip(plist, leaves)),
        names=tuple(names),
    )


@jit  # one compiled call instead of some ten small kernels, op by op
def to_vector(model, layout: Layout) -> Array:
    """The unconstrained, scaled vector ``y`` of `model` (free and fixed leaves alike)."""
    params, _ = parameters(model)
    return layout.to_vector(jax.tree.leaves(params))


def from_vector(y: Array, template, layout: Layout):
    """The model with the structure of `template` for the vector `y`; fixed leaves are
    taken from `template`."""
    params, static = parameters(template)
    leaves = jax.tree.leaves(params)
    new = layout.to_leaves(y, leaves)
    return eqx.combine(jax.tree.unflatten(jax.tree.structure(params), new), static)


# ---- the fit representation and the paper's names ------------------------------------


def as_float_arrays(model):
    """Float leaves as strongly typed float arrays.

    Python or NumPy floats put in with ``eqx.tree_at`` (which bypasses the converters)
    would silently not be parameters; a weakly typed array (``jnp.asarray(1.5)``) would be
    a different cache key for the compiled solver and cost a recompilation.
    """
    def conv(leaf):
        if isinstance(leaf, (float, np.floating)) or (
            isinstance(leaf, np.ndarray) and np.issubdtype(leaf.dtype, np.floating)
        ):
            return jnp.asarray(leaf, dtype=jnp.asarray(0.0).dtype)
        if eqx.is_inexact_array(leaf) and leaf.weak_type:
            return jnp.asarray(leaf, dtype=leaf.dtype)
        return leaf

    return jax.tree.map(conv, model)


def two_state_part(model):
    """``get`` with ``get(model)`` the friction model inside `model` that has a presliding
    `shape` (the model itself, or the base of a model with effects), or ``None`` if there
    is none."""
    base = model.without_effects()
    if not isinstance(getattr(base, "shape", None), jaxfric.AbstractShape):
        return None
    return (lambda m: m) if base is model else (lambda m: m.without_effects())


def to_fit_representation(model, reparameterize: bool = True):
    """`model` with a `jaxfric.PaperShape` (of a two-state model, with or without effects)
    replaced by the equivalent `NormalizedPaperShape` (when `reparameterize`); any other
    model unchanged. Float leaves that are not arrays become arrays."""
    model = as_float_arrays(model)
    get = two_state_part(model)
    if reparameterize and get is not None and isinstance(get(model).shape, jaxfric.PaperShape):
        two = get(model)
        shape = NormalizedPaperShape.from_paper(two.shape, two.stribeck.Fs)
        return eqx.tree_at(lambda m: get(m).shape, model, shape)
    return model


def to_user_representation(model, like):
    """Undo `to_fit_representation` when `like` (the user's model) had a `PaperShape`."""
    get = two_state_part(like)
    if (get is not None and isinstance(get(like).shape, jaxfric.PaperShape)
            and two_state_part(model) is not None
            and isinstance(get(model).shape, NormalizedPaperShape)):
        two = get(model)
        return eqx.tree_at(lambda m: get(m).shape, model, two.shape.to_paper(two.stribeck.Fs))
    return model


def _sort_key(item):
    name = item[0]
    return (_ORDER.index(name) if name in _ORDER else len(_ORDER), item[1])


def natural_names(model) -> tuple[str, ...]:
    """Names of `natural_vector`'s entries: leaf names in the paper's order, vector leaves
    expanded as ``name_1 .. name_N`` (GMS: ``nu_i``, ``k_i``)."""
    names, _ = _natural_index(model)
    return names


def _natural_index(model):
    params, _ = parameters(model)
    leaves = jax.tree.leaves(params)
    items = sorted(((n, i) for i, n in enumerate(leaf_names(model))), key=_sort_key)
    numbers = _entry_numbers(model)
    names, index = [], []
    for name, i in items:
        size = int(np.prod(leaves[i].shape))
        if leaves[i].shape == ():
            names.append(name)
            index.append((i, None))
        else:
            for j in range(size):
                names.append(f"{name}_{numbers[i][j]}")
                index.append((i, j))
    return tuple(names), tuple(index)


def _entry_numbers(model) -> list:
    """The numbers of each leaf's entries in their names: 1..N, or for a per-run leaf the
    runs it stores (`fitting._per_run.run_numbers`: a relative one skips its reference
    run, run 1 in a fit of every run)."""
    params, _ = parameters(model)
    return [range(1, int(np.size(leaf)) + 1) if runs is None else runs
            for runs, leaf in zip(run_numbers(model), jax.tree.leaves(params))]


def natural_vector(model) -> Array:
    """All parameter values of `model` (SI) as one vector, in `natural_names` order."""
    params, _ = parameters(model)
    leaves = jax.tree.leaves(params)
    _, index = _natural_index(model)
    return jnp.stack([leaves[i] if j is None else jnp.ravel(leaves[i])[j] for i, j in index])


def from_natural_vector(p: Array, template):
    """Inverse of `natural_vector`: `template` with its parameters taken from `p`."""
    params, static = parameters(template)
    leaves = jax.tree.leaves(params)
    _, index = _natural_index(template)
    new = list(leaves)
    for k, (i, j) in enumerate(index):
        if j is None:
            new[i] = p[k]
        else:
            new[i] = new[i].ravel().at[j].set(p[k]).reshape(leaves[i].shape)
    return eqx.combine(jax.tree.unflatten(jax.tree.structure(params), new), static)


def natural_params(model) -> dict[str, Array]:
    """``{name: value}`` of every parameter of `model` in SI units and the paper's names
    (two-state: Fs, Fc, Vs, delta, sigma2, a, b, c, alpha, beta, l1, C)."""
    return dict(zip(natural_names(model), natural_vector(model)))


def natural_units(model) -> dict[str, str]:
    """``{name: SI unit}`` for `natural_names` (vector entries ``nu_i``, ``k_i`` share their
    leaf's unit), from the units declared on the model's fields."""
    units = {}
    infos = parameter_info(model)
    params, _ = parameters(model)
    for info, leaf, numbers in zip(infos, jax.tree.leaves(params), _entry_numbers(model)):
        if leaf.shape == ():
            units[info.name] = info.unit
        else:
            units.update({f"{info.name}_{n}": info.unit for n in numbers})
    return {name: units[name] for name in natural_names(model)}
