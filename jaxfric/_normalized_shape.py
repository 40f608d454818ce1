"""The paper's presliding shape in well-conditioned coordinates (the a/b correlation).

`PaperShape` normalises the saw-tooth curve
``F(x) = a*exp(b*beta**alpha) - a*exp(b*(x+beta)**alpha) - c*x**4`` on ``[0, X]``,
``X = 2*Fs*l1``, into ``Pi(xi) = F(2*Fs*xi) / F(X)``. Fitted in the symbols ``a..beta``
this is badly posed:

* ``Pi`` is a ratio, so ``(a, c) -> (lambda*a, lambda*c)`` changes nothing: one direction of
  ``J^T J`` is exactly singular;
* with the paper's values ``b*(x+beta)**alpha`` is about -0.03, so ``exp`` is nearly linear
  and ``a`` and ``b`` enter almost only through ``a*b``: a second, nearly singular direction
  (the correlation of ``a`` and ``b`` is +-1 to many digits);
* the values are SI numbers from 1e-6 (beta, m) to 1e15 (c, N/m^4).

`NormalizedPaperShape` is the same family written on ``u = xi/l1`` in ``[0, 1]``:

    w(u)   = ((u + beta_rel)**alpha - beta_rel**alpha) / ((1 + beta_rel)**alpha - beta_rel**alpha)
    Pi     = (expm1(-curvature*w) / expm1(-curvature) - quartic*u**4) / (1 - quartic)

with five dimensionless-or-natural coordinates: ``l1`` (m/N), ``alpha``, ``beta_rel = beta/X``,
``curvature = -b*((X+beta)**alpha - beta**alpha)`` (how far the exponential is from linear;
0 is allowed) and ``quartic = c*X**4 / (a*exp(b*beta**alpha) - a*exp(b*(X+beta)**alpha))`` (the
share of the ``c*x**4`` term at ``X``). The scale of ``(a, c)`` is gone, and the near-linear
exponential becomes one small coordinate instead of a ridge between two huge ones. It is a
`AbstractShape`, so a `TwoState` holding it is an ordinary jaxfric model (the fit
simulates it directly), and `to_paper` maps it back to the paper's symbols.

Mapping back needs the scale the ratio dropped. We use ``F(X) = 2*Fs``: in the saw-tooth
experiment the force rises by twice the static level across the presliding region, and the
paper's own numbers satisfy it to 2.4e-4 (F(X) = 52.212 N for 2*Fs = 52.2 N).
"""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from ._compile import jit
from ._fields import param
from ._numerics import safe_div, safe_pow
from ._shapes import AbstractShape, PaperShape


# Below this |curvature| the exponential's ratio is replaced by its series (see _ratio).
_SMALL = 1e-6


def _ratio(w: Array, k: Array) -> Array:
    """``expm1(-k*w) / expm1(-k)``, with its limit ``w`` (and the first-order correction)
    near ``k = 0``, and finite gradients there (double `where`)."""
    small = jnp.abs(k) < _SMALL
    k_safe = jnp.where(small, 1.0, k)
    exact = jnp.expm1(-k_safe * w) / jnp.expm1(-k_safe)
    series = w * (1.0 + 0.5 * k * (1.0 - w))
    return jnp.where(small, series, exact)


class NormalizedPaperShape(AbstractShape):
    """The paper's presliding family in well-conditioned coordinates (see module docstring).

    **Arguments:**

    - `l1`: presliding extent, m/N.
    - `alpha`: exponent of the power law, dimensionless (0 < alpha <= 1 for concave).
    - `beta_rel`: ``beta / X`` with ``X = 2*Fs*l1``, dimensionless, > 0.
    - `curvature`: ``-b*((X+beta)**alpha - beta**alpha)``, dimensionless (paper: 0.0225).
    - `quartic`: share of the ``c*x**4`` term at ``X``, dimensionless, < 1 (paper: 0.102).
    """

    l1: Array = param("m/N", constraint="positive", group="shape", role="presliding")
    alpha: Array = param("-", constraint=("interval", 0.0, 1.0), group="shape", role="presliding")
    beta_rel: Array = param("-", constraint="positive", group="shape", role="presliding")
    curvature: Array = param("-", group="shape", role="presliding")
    # F(X) = 2*Fs / (1 - quartic) must stay positive; below 0 means c < 0 (allowed).
    quartic: Array = param("-", constraint=("interval", -1.0, 0.95), group="shape",
                           role="presliding")

    def _profile(self, u, s_st):
        del s_st  # the normalised coordinates make Pi independent of Fs
        lo = safe_pow(self.beta_rel, self.alpha)
        w = safe_div(safe_pow(u + self.beta_rel, self.alpha) - lo,
                     safe_pow(1.0 + self.beta_rel, self.alpha) - lo)
        return (_ratio(w, self.curvature) - self.quartic * u**4) / (1.0 - self.quartic)

    @classmethod
    def from_paper(cls, shape: PaperShape, Fs: ArrayLike) -> "NormalizedPaperShape":
        """The same ``Pi`` as `shape` for a static level `Fs` (N)."""
        return _from_paper(cls, shape, jnp.asarray(Fs))

    def to_paper(self, Fs: ArrayLike) -> PaperShape:
        """The paper's symbols ``a, b, c, alpha, beta, l1`` (SI) for static level `Fs` (N),
        with the scale convention ``F(X) = 2*Fs``. ``a -> inf`` and ``b -> 0`` as
        ``curvature -> 0`` (a straight power law): ``a*b`` stays finite. A `curvature`
        below 1e-8 in magnitude is taken as +-1e-8 (changing ``Pi`` by about 1e-9), so that
        ``a`` stays finite and `from_paper` can map the result back."""
        Fs = jnp.asarray(Fs)
        curvature = jnp.where(jnp.abs(self.curvature) < 1e-8,
                              jnp.where(self.curvature < 0, -1e-8, 1e-8), self.curvature)
        big_x = 2.0 * Fs * self.l1
        beta = self.beta_rel * big_x
        b_lo = safe_pow(beta, self.alpha)
        span = safe_pow(big_x + beta, self.alpha) - b_lo
        b = -curvature / span
        exp_part = 2.0 * Fs / (1.0 - self.quartic)  # a*e^{b beta^alpha}*(1 - e^{-curvature})
        a = -exp_part / (jnp.exp(b * b_lo) * jnp.expm1(-curvature))
        c = self.quartic * exp_part / big_x**4
        return PaperShape(a=a, b=b, c=c, alpha=self.alpha, beta=beta, l1=self.l1)


# One compiled call: op by op, the first fit of a session compiled some ten small kernels.
@jit
def _from_paper(cls, shape, Fs):
    big_x = 2.0 * Fs * shape.l1
    b_lo = safe_pow(shape.beta, shape.alpha)
    span = safe_pow(big_x + shape.beta, shape.alpha) - b_lo
    curvature = -shape.b * span
    exp_part = -shape.a * jnp.exp(shape.b * b_lo) * jnp.expm1(-curvature)
    return cls(
        l1=shape.l1,
        alpha=shape.alpha,
        beta_rel=shape.beta / big_x,
        curvature=curvature,
        quartic=shape.c * big_x**4 / exp_part,
    )
