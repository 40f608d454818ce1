"""Per-parameter transforms between SI values and the solver's unconstrained coordinates.

Every fitted parameter leaf ``p`` (SI units) is represented to the solver by an unconstrained
coordinate ``y`` of order one:

    p = forward(y, ref),      y = inverse(p, ref)

where ``ref`` is a reference magnitude in the parameter's own unit (by default taken from the
starting value). Dividing by ``ref`` is what makes a problem whose SI values span 1e-9 m/N
(``l1``) to 1e15 N/m^4 (the paper's ``c``) well scaled: Levenberg-Marquardt damps every
coordinate by the same ``lambda * I``, and its convergence test compares steps of all
coordinates with one tolerance, so all coordinates must live on comparable scales.
"""

import abc
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike


class AbstractTransform(eqx.Module):
    """Maps an unconstrained, scaled coordinate ``y`` to a parameter value (SI) and back."""

    @abc.abstractmethod
    def forward(self, y: Array, ref: Array) -> Array:
        """The parameter value for the unconstrained coordinate `y`."""

    @abc.abstractmethod
    def inverse(self, value: Array, ref: Array) -> Array:
        """The unconstrained coordinate of `value` (the exact inverse of `forward`)."""

    def default_ref(self, value: Array) -> Array:
        """Reference magnitude used when the properties do not give a `scale`."""
        return jnp.ones_like(value)

    def size(self, shape: tuple[int, ...]) -> int:
        """Number of unconstrained coordinates for a leaf of this shape."""
        return math.prod(shape)

    def in_domain(self, value: np.ndarray) -> np.ndarray:
        """Elementwise: can `value` be represented (NumPy, for boundary checks)?"""
        return np.isfinite(value)

    def domain(self) -> str:
        """Human-readable domain, for error messages."""
        return "finite"

    def inside(self, value: Array) -> Array:
        """`value` with any entry exactly on a bound of the domain moved just inside it
        (none here; `Sigmoid`)."""
        return value

    def at_bound(self, y: Array) -> Array:
        """Elementwise: does the coordinate `y` sit at a bound of the transform, where the
        parameter no longer moves with `y` (see `PINNED`)? Never for an unbounded one."""
        return jnp.zeros(jnp.shape(y), bool)


#: A coordinate is pinned at a bound when the parameter's distance to that bound has fallen
#: below this fraction of its reference magnitude (`Exp`, `Softplus`: ``(p - lower)/ref``;
#: `Sigmoid`: the distance to either end over the interval's width): six decades, far
#: beyond any change a fit makes to a parameter the data determine, and where the
#: parameter's derivative with respect to ``y`` has all but vanished (a collapse, e.g.
#: ``Fs`` = 1e-9 N from a start of 26 N, or the exponential underflowing).
PINNED = 1e-6
_PINNED_Y = float(np.log(PINNED))


class Identity(AbstractTransform):
    """``p = ref * y``: any real value, scaled by ``ref`` (default ``|p0|``, or 1 if 0)."""

    def forward(self, y, ref):
        return ref * y

    def inverse(self, value, ref):
        return value / ref

    def default_ref(self, value):
        mag = jnp.abs(value)
        return jnp.where(mag > 0, mag, 1.0)


class _LowerBounded(AbstractTransform):
    """Values above `lower`; ``ref`` defaults to ``p0 - lower``."""

    lower: eqx.AbstractVar[float]

    def default_ref(self, value):
        excess = value - self.lower
        return jnp.where(excess > 0, excess, 1.0)

    def in_domain(self, value):
        return np.isfinite(value) & (value > self.lower)

    def domain(self):
        return f"> {self.lower:g}"


class Exp(_LowerBounded):
    """``p = lower + ref * exp(y)``: a log scale, for positive quantities spanning decades.

    A step in ``y`` is a relative change of ``p - lower``, whatever its unit and size, and
    ``p`` can never reach ``lower``. ``ref`` defaults to ``p0 - lower`` (so ``y0 = 0``).
    """

    lower: float = 0.0

    def forward(self, y, ref):
        return self.lower + ref * jnp.exp(y)

    def at_bound(self, y):
        return y < _PINNED_Y

    def inverse(self, value, ref):
        return jnp.log((value - self.lower) / ref)


class Softplus(_LowerBounded):
    """``p = lower + ref * softplus(y)``: positive, but linear (not logarithmic) far from
    ``lower``; ``ref`` defaults to ``p0 - lower``."""

    lower: float = 0.0

    def forward(self, y, ref):
        return self.lower + ref * jax.nn.softplus(y)

    def inverse(self, value, ref):
        u = (value - self.lower) / ref
        # log(expm1(u)) written so that it neither overflows nor cancels.
        return u + jnp.log(-jnp.expm1(-u))

    def at_bound(self, y):
        return y < _PINNED_Y  # softplus(y) ~ exp(y) there


class Sigmoid(AbstractTransform):
    """``p = low + (high - low) * sigmoid(y)``: strictly between two bounds (``ref`` unused:
    the bounds already fix the scale)."""

    low: float
    high: float

    def __check_init__(self):
        if not self.high > self.low:
            raise ValueError(f"Sigmoid needs low < high, got ({self.low}, {self.high})")

    def forward(self, y, ref):
        return self.low + (self.high - self.low) * jax.nn.sigmoid(y)

    def inverse(self, value, ref):
        u = (value - self.low) / (self.high - self.low)
        return jnp.log(u) - jnp.log1p(-u)

    def at_bound(self, y):
        return jnp.abs(y) > -_PINNED_Y  # sigmoid(y) or 1 - sigmoid(y) below PINNED

    def in_domain(self, value):
        return np.isfinite(value) & (value > self.low) & (value < self.high)

    def domain(self):
        return f"in ({self.low:g}, {self.high:g})"

    def inside(self, value):
        """An entry equal to `low` or `high` (a fit's value pinned there: the sigmoid
        saturates in floating point) moved `10 * PINNED` of the width inside, where it is
        not pinned (`at_bound`) and a fit can move it."""
        v = np.asarray(value)  # concrete, as `fitting._params.make_layout` checks it
        if not np.any((v == self.low) | (v == self.high)):
            return value
        gap = 10 * PINNED * (self.high - self.low)
        v = np.where(v == self.high, self.high - gap, np.where(v == self.low, self.low + gap, v))
        return jnp.asarray(v, dtype=jnp.asarray(value).dtype)


class Simplex(AbstractTransform):
    """A 1-D leaf of ``N`` positive weights summing to one (the GMS ``nu_i``), through the
    ``N - 1`` log-ratios ``y_i = log(p_{i+1} / p_1)`` (``ref`` unused).

    ``N - 1`` rather than ``N`` coordinates: a softmax of ``N`` logits has a direction that
    changes nothing, which would make ``J^T J`` exactly singular.
    """

    def forward(self, y, ref):
        logits = jnp.concatenate([jnp.zeros((1,), y.dtype), y])
        return jax.nn.softmax(logits)

    def inverse(self, value, ref):
        logv = jnp.log(value)
        return logv[1:] - logv[0]

    def size(self, shape):
        if len(shape) != 1 or shape[0] < 1:
            raise ValueError(f"Simplex needs a non-empty 1-D leaf, got shape {shape}")
        return shape[0] - 1

    def in_domain(self, value):
        return np.isfinite(value) & (value > 0)

    def domain(self):
        return "> 0 (weights are renormalised to sum to 1)"


class ParamProps(eqx.Module):
    """Fitting properties of one parameter leaf, held beside the model (dynamax style).

    **Arguments:**

    - `transform`: an `AbstractTransform` (`Identity`, `Exp`, `Softplus`, `Sigmoid`,
      `Simplex`): how the leaf is kept in its domain.
    - `free`: whether the leaf is fitted (``True``) or held at its starting value.
    - `scale`: reference magnitude in the leaf's SI unit (scalar or the leaf's shape);
      ``None`` takes it from the starting value (`AbstractTransform.default_ref`).
    """

    transform: AbstractTransform
    free: bool = True
    scale: ArrayLike | None = None
