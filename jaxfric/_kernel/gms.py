"""The N-element GMS's element recursion in the compiled CPU kernel (gms.cc).

`jaxfric._models.gms._elements` calls `elements` (the summed element force) and, for a
derivative with respect to the parameters, `jacobian` when `supported`: on the CPU
backend, float64 inputs, the kernels built (``JAXFRIC_EVENT_KERNEL`` as for the two-state
model's, `jaxfric._kernel`). The smooth per-sample inputs (the Stribeck value, the rate,
their tangents) are computed by JAX, vectorised; the kernel runs the loop over samples
and elements. Under ``jax.vmap`` each batch member is one call (``vmap_method=
"sequential"``). Forces and derivatives agree with the JAX scan to rounding
(tests/core/test_gms_kernel.py).
"""

import jax
import jax.numpy as jnp

from .. import _kernel


def supported(*arrays) -> bool:
    """Whether the element recursion of these arrays runs in the kernel (decided when a
    program is traced)."""
    return _kernel.use_kernel(*arrays)


def _f64(a):
    return jnp.asarray(a, jnp.float64)


def elements(dx, s, d, same, rate, s_prev, nu, k, capf):
    """The summed element force (N) of every sample, ``(n,)``: `dx`, `s`, `d`, `same`,
    `rate`, `s_prev` per sample (gms.cc), `nu`, `k` per element, `capf` the cap factor
    (an element's cap is ``nu_i * capf``)."""
    n = dx.shape[-1]
    call = jax.ffi.ffi_call(_kernel.GMS_TARGET, jax.ShapeDtypeStruct((n,), jnp.float64),
                            vmap_method="sequential")
    return call(*map(_f64, (dx, s, d, same, rate, s_prev, nu, k, capf)))


def jacobian(dx, s, d, same, rate, s_prev, nu, k, capf, ds, drate, ds_prev, dcapf):
    """`elements` and its derivatives: ``(force (n,), jac_nu (n, N), jac_k (n, N),
    jac_shared (n, P))``, each element's force with respect to its own `nu` and `k`, and
    the summed force along the P shared directions whose tangents of `s`, `rate`, `s_prev`
    (each ``(n, P)``) and `capf` (``(P,)``) are given."""
    n, N, P = dx.shape[-1], nu.shape[-1], dcapf.shape[-1]
    f64 = jnp.float64
    out = (jax.ShapeDtypeStruct((n,), f64), jax.ShapeDtypeStruct((n, N), f64),
           jax.ShapeDtypeStruct((n, N), f64), jax.ShapeDtypeStruct((n, P), f64))
    call = jax.ffi.ffi_call(_kernel.GMS_JACOBIAN_TARGET, out, vmap_method="sequential")
    return call(*map(_f64, (dx, s, d, same, rate, s_prev, nu, k, capf, ds, drate, ds_prev,
                            dcapf)))
