"""The paper's parameter values (Tables 1-3 and Sec. 6.2), converted to SI units.

The paper gives mm, N and s: ``b`` in mm^-alpha becomes ``b * 1000**alpha`` m^-alpha,
``c`` in N/mm^4 becomes ``c * 1e12`` N/m^4, stiffnesses in N/mm become N/m (x 1000),
``Vs`` in mm/s and ``beta`` in mm become m, ``l1`` in mm/N becomes m/N, and ``sigma2`` in
N s/mm becomes N s/m (x 1000).
"""

import jax.numpy as jnp

from ._models.gms import GMS
from ._models.lugre import LuGre
from ._models.tustin import Tustin
from ._models.two_state import TwoState
from ._shapes import PaperShape
from ._stribeck import Stribeck


#: Attraction parameter C of the paper (Sec. 6.2), N/s.
C = 10.8
#: Viscous coefficient sigma2 of Table 1: 0.054 N s/mm, in N s/m.
SIGMA2 = 0.054 * 1e3


def stribeck() -> Stribeck:
    """Table 1: Fs = 26.1 N, Fc = 21.6 N, Vs = 3.1 mm/s, delta = 0.6."""
    return Stribeck(Fs=26.1, Fc=21.6, Vs=3.1e-3, delta=0.6)


def shape() -> PaperShape:
    """Sec. 6.2: a = 2631 N, b = -0.0438 mm^-0.3, c = 2367.9 N/mm^4, alpha = 0.3,
    beta = 1e-3 mm, l1 = 0.004291 mm/N."""
    alpha = 0.3
    return PaperShape(
        a=2631.0,
        b=-0.0438 * 1e3**alpha,
        c=2367.9e12,
        alpha=alpha,
        beta=1e-6,
        l1=0.004291e-3,
    )


def two_state(stack_size: int = 16) -> TwoState:
    """The two-state model of Sec. 6.2 with Table 1's Stribeck curve and C = 10.8 N/s."""
    return TwoState(stribeck=stribeck(), shape=shape(), sigma2=SIGMA2, C=C, stack_size=stack_size)


def tustin() -> Tustin:
    """Tustin's model with Table 1's Stribeck curve and viscous coefficient."""
    return Tustin(stribeck=stribeck(), sigma2=SIGMA2)


def _gms(nu, k_per_mm) -> GMS:
    return GMS(
        stribeck=stribeck(),
        sigma2=SIGMA2,
        C=C,
        nu=jnp.asarray(nu),
        k=jnp.asarray(k_per_mm) * 1e3,
    )


def gms5() -> GMS:
    """Table 2 (5 elements). As printed, the weights sum to 0.997, not 1: kept as printed."""
    return _gms([0.17, 0.13, 0.30, 0.017, 0.38], [1152.07, 377.23, 215.33, 9.39, 87.66])


def gms10() -> GMS:
    """Table 3 (10 elements). As printed, the weights sum to 0.9999: kept as printed."""
    return _gms(
        [0.1198, 0.0077, 0.0809, 0.0841, 0.0053, 0.0505, 0.139, 0.0895, 0.0355, 0.3876],
        [2051.68, 47.15, 288.57, 248.35, 10.37, 60.05, 104.15, 58.05, 19.99, 92.16],
    )


def lugre() -> LuGre:
    """Not in the paper (it gives no LuGre values): Table 1's Stribeck curve and sigma2,
    ``sigma0`` = the two-state model's initial presliding stiffness ``kappa(0)`` (about
    4.33e6 N/m), and ``sigma1 = 2*sqrt(sigma0 * 1 kg)`` (critical bristle damping for a
    1 kg reference mass)."""
    sigma0 = float(shape().kappa(0.0, stribeck().Fs))
    return LuGre(stribeck=stribeck(), sigma0=sigma0, sigma1=2.0 * sigma0**0.5, sigma2=SIGMA2)


def gms(n: int = 200) -> GMS:
    """A many-element GMS discretising the paper's presliding shape (`GMS.from_shape`)."""
    return GMS.from_shape(shape(), stribeck(), SIGMA2, C, n)
