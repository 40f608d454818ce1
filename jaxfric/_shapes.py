"""Presliding shape functions ``Pi``, ``kappa``, ``gamma`` (paper Sec. 4-5, App. A.1).

A shape is the normalised virgin curve of presliding: ``Pi(xi)`` for ``xi`` in m/N, with
``Pi(0) = 0``, ``Pi(xi) = 1`` for ``xi >= l1``, non-decreasing. From it
``kappa = dPi/dxi`` (the nonlinear spring stiffness, 0 beyond ``l1``) and
``gamma = Pi - xi*kappa`` (the slipping fraction, 1 beyond ``l1``), which satisfy the
appendix properties A-2a/A-2b/A-3 by construction. Negative ``xi`` is clipped to 0.

A new family subclasses `AbstractShape` and implements ``_profile(u, s_st)`` on
``u = xi/l1`` in ``[0, 1)``, with ``_profile(0) = 0`` and ``_profile(1) = 1``.
"""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from ._fields import param
from ._numerics import safe_div, safe_pow


class AbstractShape(eqx.Module):
    """A presliding shape family; see the module docstring. ``l1`` in m/N."""

    l1: eqx.AbstractVar[Array]

    @abc.abstractmethod
    def _profile(self, u: Array, s_st: Array) -> Array:
        """``Pi`` as a function of ``u = xi/l1`` in ``[0, 1)``."""

    def pi(self, xi: ArrayLike, s_st: ArrayLike) -> Array:
        """``Pi(xi)``, dimensionless. ``xi`` in m/N; ``s_st`` (N) is the static level Fs."""
        xi = jnp.asarray(xi)
        xi_pos = jnp.where(xi >= 0, xi, 0.0)
        inside = xi_pos < self.l1
        u = jnp.where(inside, safe_div(xi_pos, self.l1), 0.0)
        p = self._profile(u, jnp.asarray(s_st))
        # Clip from above only (see docs/algorithm.md section 3); `where`, not `clip`, so
        # that kappa at the lower end is the true one-sided derivative.
        return jnp.where(inside, jnp.where(p < 1.0, p, 1.0), 1.0)

    def pi_kappa_gamma(self, xi: ArrayLike, s_st: ArrayLike) -> tuple[Array, Array, Array]:
        """``(Pi, kappa, gamma)`` at ``xi``; kappa in N/m, the others dimensionless."""
        xi = jnp.asarray(xi)
        s_st = jnp.asarray(s_st)
        # Negative arguments are clipped to 0 first (all three are evaluated there).
        xi = jnp.where(xi >= 0, xi, 0.0)
        # Pi is elementwise, so a JVP with a tangent of ones is its elementwise derivative.
        p, k = jax.jvp(lambda z: self.pi(z, s_st), (xi,), (jnp.ones_like(xi),))
        return p, k, p - xi * k

    def kappa(self, xi: ArrayLike, s_st: ArrayLike) -> Array:
        """``kappa(xi) = dPi/dxi`` in N/m."""
        return self.pi_kappa_gamma(xi, s_st)[1]

    def gamma(self, xi: ArrayLike, s_st: ArrayLike) -> Array:
        """``gamma(xi) = Pi(xi) - xi*kappa(xi)``, dimensionless."""
        return self.pi_kappa_gamma(xi, s_st)[2]


class PaperShape(AbstractShape):
    """The paper's parameterisation (Sec. 6.2) of the low-speed saw-tooth curve.

    ``F(x) = K - a*exp(b*(x+beta)**alpha) - c*x**4`` with ``K = a*exp(b*beta**alpha)``
    (so ``F(0) = 0``), fitted on ``0 <= x <= X = 2*Fs*l1``, and
    ``Pi(xi) = min(F(2*Fs*xi)/F(X), 1)`` (docs/algorithm.md section 3 explains the clip).

    **Arguments:** `a` (N), `b` (m^-alpha), `c` (N/m^4), `alpha` (-), `beta` (m), `l1` (m/N).
    """

    a: Array = param("N", group="shape", role="presliding")
    b: Array = param("m^-alpha", group="shape", role="presliding")
    c: Array = param("N/m^4", group="shape", role="presliding")
    # Concave power law: kappa decreasing needs 0 < alpha <= 1 (paper: 0.3).
    alpha: Array = param("-", constraint=("interval", 0.0, 1.0), group="shape", role="presliding")
    beta: Array = param("m", constraint="positive", group="shape", role="presliding")
    l1: Array = param("m/N", constraint="positive", group="shape", role="presliding")

    def saw_tooth(self, x: ArrayLike) -> Array:
        """``F(x)`` in N for a displacement ``x`` (m) from a reversal, ``x >= 0``."""
        x = jnp.asarray(x)
        b_beta = safe_pow(self.beta, self.alpha)
        # K - a*exp(b*(x+beta)**alpha) written with expm1: the two terms are ~50x larger
        # than their difference with the paper's values.
        rise = -self.a * jnp.exp(self.b * b_beta) * jnp.expm1(
            self.b * (safe_pow(x + self.beta, self.alpha) - b_beta)
        )
        return rise - self.c * x**4

    def _profile(self, u, s_st):
        big_x = 2.0 * s_st * self.l1
        return safe_div(self.saw_tooth(big_x * u), self.saw_tooth(big_x))


class PowerShape(AbstractShape):
    """``Pi(xi) = 1 - (1 - xi/l1)**n``: a simple concave family, ``n >= 1``.

    **Arguments:** `l1` (m/N), `n` (dimensionless; ``n = 1`` is linear, larger is more curved).
    """

    l1: Array = param("m/N", constraint="positive", group="shape", role="presliding")
    n: Array = param("-", constraint=("above", 1.0), group="shape", role="presliding")

    def _profile(self, u, s_st):
        return 1.0 - safe_pow(1.0 - u, self.n)
