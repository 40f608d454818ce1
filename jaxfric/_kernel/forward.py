"""The two-state model's whole forward pass in the compiled CPU kernel (forward.cc).

`jaxfric.simulate` (through `jaxfric._simulate._run`) and `TwoState._simulate` call
`simulate` here when `supported`: on the CPU backend, float64 inputs and parameters, the
kernels built (``JAXFRIC_EVENT_KERNEL`` as for the event pass, `jaxfric._kernel`), a plain
`TwoState` with the `Stribeck` curve and one of the shapes the kernel implements
(`PaperShape`, `PowerShape`, `NormalizedPaperShape`; any other runs the JAX path). One
kernel call then gives the force of every sample, the parts and the overflow count; it
derives the velocity itself (the backward difference, or the given one made consistent
with the steps), so XLA runs nothing else. Forces agree with the JAX path
(`TwoState._simulate_jax`) to rounding (tests/core/test_forward_kernel.py). The force and
the parts come from two calls (`simulate`), so that a program that needs the force only
(a fit, ``jaxfric.simulate`` without ``full_output``) has the kernel write nothing else.

Derivatives: the call is a `jax.custom_jvp`. For tangents of the parameters (``grad``,
``jacfwd``, a fit's Jacobian) its rule calls the same loop on dual numbers
(`jacobian_pass`), which returns the Jacobians of the force and of the hysteresis force
with respect to the packed parameters (`pack`), and contracts them with the tangent; the
derivatives agree with the JAX path's to rounding. For tangents of the motion (positions,
times, velocities) the rule is ``jax.jvp`` of the JAX path. Under ``vmap`` a call receives
the batch (``vmap_method="expand_dims"``: an unbatched input keeps a dimension of 1, which
the kernel broadcasts) and loops over it, on several threads when the batch is large.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_derivatives import SymbolicZero

from .. import _kernel
from .._normalized_shape import NormalizedPaperShape
from .._shapes import PaperShape, PowerShape
from .._stribeck import Stribeck
from ..motion import make_motion


#: Shape families the kernel implements: its code (forward.cc) and the coordinates it takes
#: after ``l1``.
SHAPES = {
    PaperShape: (0, ("a", "b", "c", "alpha", "beta")),
    PowerShape: (1, ("n",)),
    NormalizedPaperShape: (2, ("alpha", "beta_rel", "curvature", "quartic")),
}
#: Length of the packed parameter vector: Fs, Fc, Vs, delta, sigma2, C, l1, 5 shape slots.
N_PARAMS = 12


def _leaves(model):
    st, sh = model.stribeck, model.shape
    names = SHAPES[type(sh)][1]
    return [st.Fs, st.Fc, st.Vs, st.delta, model.sigma2, model.C, sh.l1,
            *(getattr(sh, k) for k in names)]


def supported(model, *arrays, scalar_params: bool = True) -> bool:
    """Whether `model` (a plain `TwoState`: the caller checks) on a motion of `arrays` (its
    t, x, v) runs in the forward kernel (module docstring); decided when a program is
    traced. ``scalar_params=False`` allows parameters with batch axes (a batched model
    before its ``vmap``)."""
    if type(model.stribeck) is not Stribeck or type(model.shape) not in SHAPES:
        return False
    leaves = _leaves(model)
    if not all(_kernel.is_float64(a) for a in leaves):
        return False
    if scalar_params and any(jnp.ndim(a) != 0 for a in leaves):
        return False
    # every array of the model is one of the packed parameters
    if len(jax.tree.leaves(eqx.filter(model, eqx.is_array))) != len(leaves):
        return False
    return _kernel.use_kernel(*arrays)


def pack(model) -> jax.Array:
    """The parameters of `model` as the kernel's float64 vector (`N_PARAMS`)."""
    leaves = [jnp.asarray(a, jnp.float64) for a in _leaves(model)]
    leaves += [jnp.zeros((), jnp.float64)] * (N_PARAMS - len(leaves))
    return jnp.stack(leaves)


def _call(target, t, x, v, params, shape, stack_size, limit, has_v, parts, jacobian):
    n = x.shape[-1]
    k = n if parts else 0  # the parts (and the hysteresis Jacobian): 0 elements when not wanted
    f64, i32 = jnp.float64, jnp.int32
    out = [jax.ShapeDtypeStruct((n,), f64)] + [jax.ShapeDtypeStruct((k,), f64)] * 3 + [
        jax.ShapeDtypeStruct((k,), i32), jax.ShapeDtypeStruct((), i32)]
    if jacobian:
        out += [jax.ShapeDtypeStruct((n, N_PARAMS), f64), jax.ShapeDtypeStruct((k, N_PARAMS), f64)]
    call = jax.ffi.ffi_call(target, tuple(out), vmap_method="expand_dims")
    return call(t, x, v, params, shape=np.int64(shape), stack_size=np.int64(stack_size),
                limit=np.int64(limit), has_v=np.int64(has_v),
                threads=np.int64(_kernel.threads()))


def forward_pass(t, x, v, params, shape: int, stack_size: int, limit: int, parts: bool = True):
    """One call of the kernel: ``(force, hysteresis, lag, viscous, depth, overflow)``
    (forward.cc). `v` None: the backward difference of `x`. `limit` is the static reversal
    bound (-1: none). Without `parts`, hysteresis, lag, viscous and depth have 0 elements
    (the kernel writes the force only)."""
    return _call(_kernel.FORWARD_TARGET, t, x, x if v is None else v, params, shape,
                 stack_size, limit, v is not None, parts, False)


def jacobian_pass(t, x, v, params, shape: int, stack_size: int, limit: int,
                  parts: bool = True):
    """`forward_pass` plus the Jacobians of the force and of the hysteresis force with
    respect to the packed parameters, each ``(n, N_PARAMS)`` (forward.cc, dual numbers);
    without `parts`, the hysteresis force's has 0 rows too."""
    return _call(_kernel.FORWARD_JACOBIAN_TARGET, t, x, x if v is None else v, params, shape,
                 stack_size, limit, v is not None, parts, True)


def _zero_tangent(a):
    return np.zeros(jnp.shape(a), dtype=jax.dtypes.float0)


def simulate(model, t, x, v=None, max_reversals: int | None = None):
    """`TwoState._simulate` of the motion ``(t, x[, v])`` (1-D; `v` None: the backward
    difference; a given one is made consistent with the steps) through the kernel (module
    docstring). Returns the force, the parts (a dict as `SimResult.parts`) and the overflow
    count.

    Two calls, each a `jax.custom_jvp`: one for the force and the overflow count, one for the
    parts; a program that does not use the parts (a fit, `jaxfric.simulate` without
    ``full_output``) has the second removed by the compiler, and the kernel then writes
    only the force (and, for a derivative, only the force's Jacobian)."""
    params, static = eqx.partition(model, eqx.is_array)
    flat, treedef = jax.tree.flatten(params)
    order = _leaves(model)
    where = [next(i for i, a in enumerate(order) if a is leaf) for leaf in flat]
    bound = -1 if max_reversals is None else max_reversals
    shape, size, has_v = SHAPES[type(model.shape)][0], model.stack_size, v is not None

    def velocity(t, x, v):
        return make_motion(t, x, v if has_v else None).consistent().v

    def jax_path(packed, t, x, v):
        m = eqx.combine(jax.tree.unflatten(treedef, [packed[i] for i in where]), static)
        r = m._simulate_jax(make_motion(t, x, v if has_v else None, max_reversals).consistent())
        return (r.force, r.parts["hysteresis"], r.parts["lag"], r.parts["viscous"],
                r.parts["depth"], r.overflow)

    def motion_jvp(primals, tangents, pick):
        # Derivatives with respect to the motion: the JAX path's.
        tangents = [jnp.zeros_like(p) if type(d) is SymbolicZero else d
                    for p, d in zip(primals, tangents)]
        out, d_out = jax.jvp(jax_path, tuple(primals), tuple(tangents))
        return tuple(out[i] for i in pick), tuple(d_out[i] for i in pick)

    def kernel(packed, t, x, v, parts, jacobian):
        run = jacobian_pass if jacobian else forward_pass
        return run(t, x, v if has_v else None, packed, shape, size, bound, parts)

    run_force, run_parts = _custom_calls(kernel, motion_jvp, velocity)
    args = (pack(model), t, x, x if v is None else v)
    force, overflow = run_force(*args)
    hyst, lag, viscous, depth = run_parts(*args)
    parts = {"hysteresis": hyst, "lag": lag, "viscous": viscous, "depth": depth}
    return force, parts, overflow


def _custom_calls(kernel, motion_jvp, velocity):
    """The two `jax.custom_jvp` calls of `simulate`, ``(packed, t, x, v)`` ->
    ``(force, overflow)`` and -> ``(hysteresis, lag, viscous, depth)``: `kernel` ``(packed,
    t, x, v, parts, jacobian)`` calls forward.cc, `motion_jvp` ``(primals, tangents,
    pick)`` is the JAX path's JVP for tangents of the motion (outputs `pick`), `velocity`
    ``(t, x, v)`` the motion's velocity."""

    @jax.custom_jvp
    def run_force(packed, t, x, v):
        out = kernel(packed, t, x, v, False, False)
        return out[0], out[5]

    def run_force_jvp(primals, tangents):
        dp, *motion_tangents = tangents
        if any(type(d) is not SymbolicZero for d in motion_tangents):
            return motion_jvp(primals, tangents, (0, 5))
        force, *_, overflow, jac_f, _ = kernel(*primals, False, True)
        if type(dp) is SymbolicZero:
            dp = jnp.zeros_like(primals[0])
        return (force, overflow), (jac_f @ dp, _zero_tangent(overflow))

    @jax.custom_jvp
    def run_parts(packed, t, x, v):
        return kernel(packed, t, x, v, True, False)[1:5]

    def run_parts_jvp(primals, tangents):
        packed, t, x, v = primals
        dp, *motion_tangents = tangents
        if any(type(d) is not SymbolicZero for d in motion_tangents):
            return motion_jvp(primals, tangents, (1, 2, 3, 4))
        _, hyst, lag, visc, depth, _, jac_f, jac_h = kernel(*primals, True, True)
        if type(dp) is SymbolicZero:
            dp = jnp.zeros_like(packed)
        d_f, d_h, d_visc = jac_f @ dp, jac_h @ dp, velocity(t, x, v) * dp[4]
        return (hyst, lag, visc, depth), (d_h, d_f - d_h - d_visc, d_visc,
                                          _zero_tangent(depth))

    run_force.defjvp(run_force_jvp, symbolic_zeros=True)
    run_parts.defjvp(run_parts_jvp, symbolic_zeros=True)
    return run_force, run_parts
