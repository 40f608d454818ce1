"""Guarded elementary functions: finite values *and* finite gradients at singular points.

Each uses the double-``where`` pattern (optax ``safe_norm``): the unsafe branch is fed a
harmless value where it would be singular, so that its (discarded) gradient is finite too.
`tangent_zeros` fills a custom JVP rule's symbolic zeros.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.custom_derivatives import SymbolicZero
from jaxtyping import Array, ArrayLike


def safe_div(num: ArrayLike, den: ArrayLike) -> Array:
    """``num / den``, and 0 where ``den == 0`` (value and gradient)."""
    num = jnp.asarray(num)
    den = jnp.asarray(den)
    zero = den == 0
    return jnp.where(zero, 0.0, num / jnp.where(zero, 1.0, den))


def safe_pow(base: ArrayLike, exponent: ArrayLike) -> Array:
    """``base ** exponent`` for ``base > 0``, and 0 for ``base <= 0``.

    ``u ** p`` has an infinite derivative in ``u`` at 0 for ``p < 1`` and a ``0 * log(0)``
    derivative in ``p``; both come out NaN under ``jax.grad`` without the guard.
    """
    base = jnp.asarray(base)
    pos = base > 0
    return jnp.where(pos, _pos_pow(jnp.where(pos, base, 1.0), jnp.asarray(exponent)), 0.0)


@jax.custom_jvp
def _pos_pow(x, p):
    """``x ** p`` for ``x > 0``, differentiated from its own value: ``d/dx = p * y / x``
    and ``d/dp = y * log(x)``. JAX's rule for ``pow`` computes ``x ** (p - 1)``, a second
    power (on the CPU a float64 power costs about ten times an exponential,
    benchmarks/profiling/xla_costs.py), and a third for a second derivative; the shapes' ``kappa``
    is a derivative, fits take another. The price: a second derivative is formed as
    ``p * (p * y / x) / x - p * y / x**2``, which is exact only up to rounding (not
    exactly 0 for ``p = 1``) and can overflow or give 0/0 for bases near float32's
    underflow (``x**2`` below 1e-38); with float64 and the shapes' arguments (``u`` in
    ``[0, 1)``, displacements of micrometres and more) neither matters.

    The value is ``exp(p * log(x))`` rather than ``x ** p``: XLA's CPU power is not
    vectorised and costs 8 ns per float64 element against 1 ns for the exponential of a
    logarithm (benchmarks/montecarlo_speed.py, op table), at a relative rounding error of
    2e-15 instead of 2e-16 (forces of tens of N change by < 1e-13 N)."""
    return jnp.exp(p * jnp.log(x))


def _pos_pow_jvp(primals, tangents):
    x, p = primals
    dx, dp = tangents
    y = _pos_pow(x, p)
    out = jnp.zeros_like(y)
    if type(dx) is not SymbolicZero:
        out = out + p * y / x * dx
    if type(dp) is not SymbolicZero:
        out = out + y * jnp.log(x) * dp
    return y, out


_pos_pow.defjvp(_pos_pow_jvp, symbolic_zeros=True)


def safe_exp_decay(rate_times_dt: ArrayLike) -> Array:
    """``exp(-r)`` for ``r >= 0``; kept for symmetry and to clip tiny negative rounding."""
    return jnp.exp(-jnp.maximum(jnp.asarray(rate_times_dt), 0.0))


def as_param(x: ArrayLike) -> Array:
    """Converter for parameter leaves: a floating, non-weakly-typed array.

    Python floats would otherwise become weakly-typed arrays, whose dtype flag is part of
    JIT cache keys (a model rebuilt from arrays would recompile).
    """
    arr = jnp.asarray(x)
    dtype = arr.dtype if jnp.issubdtype(arr.dtype, jnp.floating) else jnp.asarray(0.0).dtype
    return jnp.asarray(arr, dtype=dtype)


def linear_recurrence(a: ArrayLike, b: ArrayLike) -> Array:
    """``y_n = a_n * y_{n-1} + b_n`` with ``y_{-1} = 0``, along the first axis.

    A `lax.scan` with a two-flop body. `lax.associative_scan` (parallel prefix) was tried
    first: on CPU it runs no faster and doubles to quintuples compile time, most of all for
    gradients and Jacobians (two-state ``jacfwd`` 5.7 s -> 2.1 s, LuGre 2.7 s -> 0.5 s;
    measured with jax 0.10 on the 2-core CI machine).
    """
    a = jnp.asarray(a)
    b = jnp.asarray(b)

    def body(y, ab):
        y = ab[0] * y + ab[1]
        return y, y

    _, y = jax.lax.scan(body, jnp.zeros(a.shape[1:], jnp.result_type(a, b)), (a, b))
    return y


def running_max(a: ArrayLike) -> Array:
    """``max(a_0, ..., a_n)`` along the first axis, as a `lax.scan`.

    `lax.cummax` lowers on CPU to a blocked ``reduce_window`` that is about 5x slower
    (7 ms against 1.5 ms for 1e6 int32 on the 2-core CI machine, jax 0.10) and that XLA
    tries to constant-fold for a while when the input is a constant.
    """
    a = jnp.asarray(a)

    def body(m, v):
        m = jnp.maximum(m, v)
        return m, m

    return jax.lax.scan(body, a[0], a)[1]


def running_sum(a: ArrayLike) -> Array:
    """``a_0 + ... + a_n`` along the first axis, as a `lax.scan` (sequential summation;
    `jnp.cumsum` is about 1.5x slower on CPU, 5.4 ms against 3.5 ms for 1e6 float64)."""
    a = jnp.asarray(a)

    def body(c, v):
        c = c + v
        return c, c

    return jax.lax.scan(body, jnp.zeros(a.shape[1:], a.dtype), a)[1]


def tangent_zeros(primal, tangent):
    """`tangent` (a custom JVP rule's, None for an unperturbed leaf) with every None of an
    inexact array of `primal` replaced by zeros shaped like it."""
    params = eqx.filter(primal, eqx.is_inexact_array)
    return jax.tree.map(lambda p, t: t if p is None or t is not None else jnp.zeros_like(p),
                        params, tangent, is_leaf=lambda x: x is None)
