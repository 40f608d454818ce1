"""The least-squares problem of a fit: the model <-> vector map, the simulated forces of
stacked experiments, and the residual vector with its Jacobian.

**Residual.** ``r = sqrt(w) * (simulate(model) - F) / scale`` with ``scale`` the standard
deviation of the measured force: dimensionless residuals of order one, so the solver's
tolerances mean the same thing for a 2 N tribometer and a 30 N linear guide.

**Unknowns.** The solver sees the unconstrained, scaled vector ``y`` of *all* parameter leaves
(see `_transforms`); a held leaf keeps its value and so has a zero Jacobian column, which
the damped QR step leaves at zero. The free set is therefore data, not structure: stages of
a staged fit with different free parameters share one compilation.
"""

import dataclasses
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

import jaxfric
from jaxfric import NormalizedPaperShape

from . import _params
from ._data import Dataset


class _Problem(eqx.Module):
    """What the jitted solve needs besides the data: the starting model in the fit
    representation, how its leaves map to ``y``, and whether to report a `PaperShape`."""

    template: Any
    layout: _params.Layout
    paper_shape: bool = eqx.field(static=True)
    max_reversals: int | None = eqx.field(static=True, default=None)
    #: None: the Jacobian has a column for every coordinate of ``y`` (the free set changes
    #: nothing compiled). An int: only the free coordinates' columns are computed, in this
    #: many slots (at least the number of free coordinates; `narrowed`).
    width: int | None = eqx.field(static=True, default=None)

    def narrowed(self) -> "_Problem":
        """This problem with its Jacobian computed over the free coordinates only, in
        slots of 8 (`width`: one compilation per width), when that is at most two thirds
        of all coordinates; else unchanged. For a model most of whose parameters are held
        (a diagnosis's superset of effects), where each held column costs as much as a free
        one to compute and is then multiplied by 0."""
        free = self.layout.n_free()
        total = int(sum(self.layout.sizes))
        width = 8 * -(-free // 8)
        return dataclasses.replace(self, width=width) if 3 * width <= 2 * total else self

    def bounded(self, data: Dataset) -> "_Problem":
        """This problem with a static bound on the reversals of `data` (stacked, concrete
        arrays ``(..., n)``), which the two-state simulation uses to evaluate its reversal
        terms on a short list (`jaxfric.simulate`, ``max_reversals``)."""
        t, x = np.asarray(data.t), np.asarray(data.x)
        v = None if data.v is None else np.asarray(data.v)
        t2, x2 = t.reshape(-1, t.shape[-1]), x.reshape(-1, x.shape[-1])
        v2 = None if v is None else v.reshape(-1, v.shape[-1])
        bound = max(jaxfric.reversal_bound(t2[i], x2[i], None if v2 is None else v2[i])
                    for i in range(t2.shape[0]))
        return dataclasses.replace(self, max_reversals=bound)

    def model(self, y):
        return _params.from_vector(y, self.template, self.layout)

    def user_model(self, y):
        model = self.model(y)
        if self.paper_shape:
            get = _params.two_state_part(model)
            two = get(model)
            model = eqx.tree_at(lambda m: get(m).shape, model,
                                two.shape.to_paper(two.stribeck.Fs))
        return model


def _simulate_stack(model, data: Dataset, max_reversals: int | None = None):
    """Force (N) and stack-overflow count for stacked datasets, arrays ``(D, n)``.

    `lax.map` (a loop), not `vmap`, over the D experiments of one fit: the simulation and
    its Jacobian are then compiled once, unbatched, which compiles several times faster
    than their batched version and runs as fast on CPU.
    """
    model_ = model

    def one(d):
        t, x, v, load, a = d
        out = jaxfric.simulate(model_, t, x, v, full_output=True,
                               max_reversals=max_reversals, load=load, a=a)
        return out.force, out.overflow

    force, overflow = jax.lax.map(one, (data.t, data.x, data.v, data.load, data.a))
    return force, jnp.sum(overflow)


def _force_scale(data: Dataset) -> Array:
    """Weighted standard deviation of the measured force (N); 1 if it is 0."""
    w = data.weights
    mean = jnp.sum(w * data.F) / jnp.sum(w)
    std = jnp.sqrt(jnp.sum(w * (data.F - mean) ** 2) / jnp.sum(w))
    return jnp.where(std > 0, std, 1.0)


def _forces(y, problem: _Problem, data: Dataset):
    """Model force ``(D, n)`` for the vector `y`, and the stack-overflow count (as a float,
    so that it can ride along through the custom JVP below)."""
    force, overflow = _simulate_stack(problem.model(y), data, problem.max_reversals)
    return force, overflow.astype(force.dtype)


@eqx.filter_custom_jvp
def _dense_forces(y, problem, data):
    return _forces(y, problem, data)


@_dense_forces.def_jvp
def _dense_forces_jvp(primals, tangents):
    # Why a custom JVP: compiling the simulation's JVP is by far the dominant cost of a
    # fit, and Levenberg-Marquardt uses the linearised residual several times per step
    # (materialising J for the QR solve, the trust region's predicted reduction, ...), each
    # use a fresh copy of the linearised simulation in the compiled loop. Computing J once
    # per evaluation with `jacfwd` here turns every later use into a matrix product. On a
    # 1200-sample two-state fit: compile 28 s -> 18 s, run 1.7 s -> 0.3 s; for a vmapped
    # batch of 32: compile 83 s -> 35 s. (Only `y` is differentiated; data and problem
    # are constants of the fit.)
    y, problem, data = primals
    t_y = tangents[0]

    def both(yy):
        out = _forces(yy, problem, data)
        return out[0], out

    if t_y is None:
        t_y = jnp.zeros_like(y)
    if problem.width is None:
        jac, out = jax.jacfwd(both, has_aux=True)(y)
        return out, (jac @ t_y, jnp.zeros_like(out[1]))
    # `_Problem.narrowed`: the columns of the free coordinates only, `width` slots (the
    # unused ones have a zero tangent); a held coordinate's column is 0 either way.
    free = problem.layout.coordinate_mask() > 0
    idx = jnp.nonzero(free, size=problem.width, fill_value=0)[0]
    used = (jnp.arange(problem.width) < jnp.sum(free)).astype(y.dtype)
    basis = jax.nn.one_hot(idx, y.size, dtype=y.dtype) * used[:, None]
    _, cols, out = jax.vmap(lambda b: jax.jvp(both, (y,), (b,), has_aux=True),
                            out_axes=(None, -1, None))(basis)
    return out, (cols @ (t_y[idx] * used), jnp.zeros_like(out[1]))


def _residuals(y, args):
    """Dimensionless residuals, with the simulated force and overflow count as aux."""
    problem, data, scale = args
    force, overflow = _dense_forces(y, problem, data)
    return jnp.sqrt(data.weights) * (force - data.F) / scale, (force, overflow)


def _problem(model, props, free, reparameterize):
    """The solver's view of `model` (given in the user's representation) and ``y0``."""
    fit_model = _params.to_fit_representation(model, reparameterize)
    get = _params.two_state_part(model)
    paper_shape = get is not None and isinstance(get(model).shape, jaxfric.PaperShape) and (
        isinstance(get(fit_model).shape, NormalizedPaperShape))
    return _problem_from_fit(fit_model, props, free, paper_shape)


def _problem_from_fit(fit_model, props, free, paper_shape: bool):
    """As `_problem` for a model already in the fit representation; `paper_shape` says
    whether results are reported with a `PaperShape`."""
    fit_model = _params.as_float_arrays(fit_model)
    if props is None:
        props = _params.default_props(fit_model)
    if free is not None:
        props = _params.set_free(fit_model, props, free)
    fit_model = _params.inside_domains(fit_model, props)
    layout = _params.make_layout(fit_model, props)
    problem = _Problem(template=fit_model, layout=layout, paper_shape=paper_shape)
    return problem, _params.to_vector(fit_model, layout)
