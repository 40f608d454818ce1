"""Generalized Maxwell-slip model with N elements (paper Sec. 2; docs/algorithm.md sec. 5)."""

import equinox as eqx
import jax
import jax.flatten_util
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from .._fields import param
from .._kernel import gms as kernel_gms
from .._numerics import safe_div, tangent_zeros
from .._shapes import AbstractShape
from .._stribeck import Stribeck
from ..motion import consistent_velocity, Motion
from ._base import AbstractFrictionModel, SimResult


class GMSState(eqx.Module):
    """Element forces `F` (N), slip flags, last direction, previous position (m) and the
    previous sample's limit curve `S_prev` (N; 0 before the first sample)."""

    F: Float[Array, " N"]
    slipping: Bool[Array, " N"]
    last_d: Array
    x_prev: Array
    S_prev: Array


class GMS(AbstractFrictionModel):
    """N-element GMS: ``F = sum_i F_i + sigma2*v``.

    **Arguments:**

    - `stribeck`: the `Stribeck` curve.
    - `sigma2`: viscous coefficient, N s/m.
    - `C`: attraction parameter, N/s.
    - `nu`: element weights (dimensionless, ``sum(nu) = 1`` normally), shape ``(N,)``.
    - `k`: element stiffnesses, N/m, shape ``(N,)``. Element i slips after ``nu_i*|s|/k_i``.
    """

    stribeck: Stribeck
    sigma2: Array = param("N s/m", constraint="positive")
    C: Array = param("N/s", constraint="positive", role="lag")
    nu: Array = param("-", constraint="simplex", role="presliding")
    k: Array = param("N/m", constraint="positive", role="presliding")

    def __check_init__(self):
        if self.nu.ndim != 1 or self.nu.shape != self.k.shape:
            raise ValueError(
                f"nu and k must be 1-D of equal length, got {self.nu.shape} and {self.k.shape}"
            )

    @classmethod
    def from_shape(
        cls,
        shape: AbstractShape,
        stribeck: Stribeck,
        sigma2: ArrayLike,
        C: ArrayLike,
        n: int,
        breakpoints: ArrayLike | None = None,
    ) -> "GMS":
        """A GMS whose piecewise-linear virgin curve interpolates ``shape``'s ``Pi``.

        Breakpoints ``l_1 = l1 > l_2 > ... > l_n > 0`` (m/N) default to a geometric spacing
        from ``l1`` down to ``1e-3*l1`` (dense where ``Pi`` bends most, near 0). Then
        ``Pi_0(xi) = sum_i k_i*min(xi, l_i)`` equals ``Pi`` at every breakpoint, and
        ``nu_i = k_i*l_i`` (so ``sum nu_i = Pi(l1) = 1``). Differentiable in the shape.
        """
        if n < 1:
            raise ValueError(f"n must be >= 1, got {n}")
        if breakpoints is None:
            ratio = jnp.asarray(np.geomspace(1.0, 1e-3, n))
            breakpoints = shape.l1 * ratio
        lb = jnp.asarray(breakpoints)
        if lb.shape != (n,):
            raise ValueError(f"breakpoints must have shape ({n},), got {lb.shape}")
        pi = shape.pi(lb, stribeck.Fs)
        # Slope of Pi_0 on (l_{m+1}, l_m] is sum_{i<=m} k_i; on (0, l_n] it is sum of all.
        upper = jnp.concatenate([lb, jnp.zeros((1,), lb.dtype)])
        values = jnp.concatenate([pi, jnp.zeros((1,), pi.dtype)])
        slopes = (values[:-1] - values[1:]) / (upper[:-1] - upper[1:])
        k = jnp.diff(slopes, prepend=jnp.zeros((1,), slopes.dtype))
        return cls(stribeck=stribeck, sigma2=sigma2, C=C, nu=k * lb, k=k)

    def _update(self, F, slipping, dx, s, d, same_direction, rate, s_prev):
        """One sample for all elements at once (docs/algorithm.md section 5, steps 1-3);
        `rate`: ``C*dt/|s|`` while moving (`_rate`), `s_prev`: the previous sample's S."""
        slipping = slipping & same_direction
        target = self.nu * s
        f_slip = target + (F - target) * jnp.exp(-rate)
        f_stick = F + self.k * dx
        # Slip starts only at the limit in the direction of motion (Eq. 2); on the other
        # side an element may sit beyond nu*|s| after |s| dropped, and keeps sticking.
        limit = self.nu * jnp.abs(s)
        starts = (d != 0) & (d * f_stick > limit)
        # Where within the sample the limit was met: the force grows linearly over the
        # sample, the limit moves linearly from nu*|S_prev|; from there the element slips
        # for the rest of the sample. (Slipping from the sample's end instead makes the
        # force jump with the parameters when the start moves by one sample.)
        limit0 = self.nu * jnp.abs(s_prev)
        gap0 = limit0 - d * F
        theta = jnp.where(gap0 > 0, jnp.clip(safe_div(gap0, gap0 - (limit - d * f_stick)),
                                             0.0, 1.0), 0.0)
        met = d * (limit0 + theta * (limit - limit0))
        f_start = target + (met - target) * jnp.exp(-(1.0 - theta) * rate)
        cap = self.nu * jnp.maximum(self.stribeck.Fs, self.stribeck.Fc)
        f_stick = jnp.where(starts, f_start, jnp.clip(f_stick, -cap, cap))
        return jnp.where(slipping, f_slip, f_stick), slipping | starts

    def _rate(self, dt, s, moving):
        return jnp.where(moving, self.C * safe_div(dt, jnp.abs(s)), 0.0)

    def init_state(self, x0: ArrayLike = 0.0) -> GMSState:
        x0 = jnp.asarray(x0, dtype=self.C.dtype)
        return GMSState(
            F=jnp.zeros_like(self.nu),
            slipping=jnp.zeros(self.nu.shape, bool),
            last_d=jnp.zeros((), x0.dtype),
            x_prev=x0,
            S_prev=jnp.zeros((), x0.dtype),
        )

    def step(self, state: GMSState, x, v, dt):
        x, v, dt = jnp.asarray(x), jnp.asarray(v), jnp.asarray(dt)
        v = consistent_velocity(v, x - state.x_prev, dt)
        d = jnp.sign(v)
        moving = d != 0
        same = moving & (d == state.last_d)
        last_d = jnp.where(moving, d, state.last_d)
        s = self.stribeck.effective(v, last_d)
        F, slipping = self._update(
            state.F, state.slipping, x - state.x_prev, s, d, same, self._rate(dt, s, moving),
            state.S_prev,
        )
        new_state = GMSState(F=F, slipping=slipping, last_d=last_d, x_prev=x, S_prev=s)
        return new_state, jnp.sum(F) + self.sigma2 * v

    def _inputs(self, motion: Motion):
        """The smooth per-sample inputs of the element recursion of a `consistent` motion:
        the Stribeck value ``s`` (N), the rate ``C*dt/|s|`` while moving, ``s`` of the
        sample before (0 before the first), whether the sample moves in the direction of
        the one before, and the cap factor (an element's cap is ``nu_i`` times it)."""
        s = self.stribeck.effective(motion.v, motion.last_d)
        moving = motion.moving
        same = moving & (motion.d == motion.prev_last_d)
        rate = self._rate(motion.dt, s, moving)
        s_prev = jnp.concatenate([jnp.zeros_like(s[:1]), s[:-1]])
        return s, rate, s_prev, same, jnp.maximum(self.stribeck.Fs, self.stribeck.Fc)

    def _element_forces(self, motion: Motion, each: bool = True) -> Array:
        """Every element's force (N) at every sample of a `consistent` motion, shape
        ``(n, N)``; not `each`: their sum, ``(n,)`` (the scan keeps no per-element force).
        The scan in JAX (the kernel's reference, `jaxfric._kernel.gms`)."""
        s, rate, s_prev, same, _ = self._inputs(motion)

        def body(carry, inp):
            F, slipping = self._update(*carry, *inp)
            return (F, slipping), F if each else jnp.sum(F)

        carry0 = (jnp.zeros_like(self.nu), jnp.zeros(self.nu.shape, bool))
        _, forces = jax.lax.scan(body, carry0, (motion.dx, s, motion.d, same, rate, s_prev))
        return forces

    def _simulate(self, motion: Motion) -> SimResult:
        motion = motion.consistent()
        elements = _elements(self, motion)
        viscous = self.sigma2 * motion.v
        return SimResult(
            force=elements + viscous,
            parts={"elements": elements, "viscous": viscous},
            overflow=jnp.zeros((), jnp.int32),
        )


def _without_own(tree):
    """`tree` (a GMS or its tangent) with `nu` and `k` set to None."""
    return eqx.tree_at(lambda m: (m.nu, m.k), tree, replace=(None, None),
                       is_leaf=lambda x: x is None)


def _on_kernel(model: GMS, motion: Motion) -> bool:
    return kernel_gms.supported(motion.x, motion.dx, model.nu, model.k, model.C,
                                *jax.tree.leaves(eqx.filter(model.stribeck, eqx.is_array)))


@eqx.filter_custom_jvp
def _elements(model: GMS, motion: Motion):
    """The summed element force (N) per sample, `GMS._element_forces` (in the compiled
    kernel where it runs, `jaxfric._kernel.gms`), with a JVP that uses the elements'
    independence (`_elements_jvp`)."""
    if _on_kernel(model, motion):
        s, rate, s_prev, same, capf = model._inputs(motion)
        return kernel_gms.elements(motion.dx, s, motion.d, same, rate, s_prev, model.nu,
                                   model.k, capf)
    return model._element_forces(motion, each=False)


@_elements.def_jvp
def _elements_jvp(primals, tangents):
    # Element i's force depends on its own nu_i and k_i and on the parameters all elements
    # share (the Stribeck curve, C): a tangent of ones on every nu (or every k) gives each
    # element's derivative with respect to its own, in one direction. So one forward pass
    # in 2 + (shared scalars) directions gives every column of the Jacobian, whatever the
    # caller asks for (a fit asks for 2 N + shared columns at once, each of which would
    # carry all N elements through the scan: a fit of 20 elements on 1e4 samples takes a
    # third to a half of the time), and the caller's tangents are contracted with it. The
    # arithmetic of each derivative is the plain JVP's (tests/core/test_gms_jvp.py); in the
    # kernel, the shared directions enter as the tangents of the smooth per-sample inputs,
    # computed here (tests/core/test_gms_kernel.py).
    model, motion = primals
    t_model, t_motion = tangents
    if any(leaf is not None for leaf in jax.tree.leaves(t_motion, is_leaf=lambda x: x is None)):
        # the motion is differentiated too (with respect to the positions): the plain JVP
        return jax.jvp(lambda m, mo: m._element_forces(mo, each=False), (model, motion),
                       (tangent_zeros(model, t_model), tangent_zeros(motion, t_motion)))
    params, static = eqx.partition(model, eqx.is_inexact_array)
    shared, unravel = jax.flatten_util.ravel_pytree(_without_own(params))

    def with_shared(vec, nu, k):
        own = eqx.tree_at(lambda p: (p.nu, p.k), unravel(vec), (nu, k),
                          is_leaf=lambda x: x is None)
        return eqx.combine(own, static)

    t_p = tangent_zeros(model, t_model)
    t_shared = jax.flatten_util.ravel_pytree(_without_own(t_p))[0]
    if _on_kernel(model, motion):
        def smooth(vec):  # the inputs, differentiated, and as they are (aux)
            inputs = with_shared(vec, model.nu, model.k)._inputs(motion)
            return inputs[:3] + inputs[4:], inputs

        (ds, drate, ds_prev, dcapf), (s, rate, s_prev, same, capf) = jax.jacfwd(
            smooth, has_aux=True)(shared)
        out, jac_nu, jac_k, jac_shared = kernel_gms.jacobian(
            motion.dx, s, motion.d, same, rate, s_prev, model.nu, model.k, capf, ds, drate,
            ds_prev, dcapf)
        return out, jac_nu @ t_p.nu + jac_k @ t_p.k + jac_shared @ t_shared

    def forces(vec, nu, k):
        return with_shared(vec, nu, k)._element_forces(motion)

    n_dir = 2 + shared.size
    directions = (jnp.eye(n_dir, dtype=shared.dtype)[:, 2:],  # shared, one by one
                  jnp.zeros((n_dir,) + model.nu.shape, model.nu.dtype).at[0].set(1.0),
                  jnp.zeros((n_dir,) + model.k.shape, model.k.dtype).at[1].set(1.0))
    out, jac = jax.vmap(lambda *d: jax.jvp(forces, (shared, model.nu, model.k), d),
                        out_axes=(None, 0))(*directions)  # jac: (directions, n, N)
    tangent = jac[0] @ t_p.nu + jac[1] @ t_p.k + jnp.sum(jac[2:], axis=-1).T @ t_shared
    return jnp.sum(out, axis=-1), tangent
