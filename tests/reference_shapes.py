"""The presliding shape families of the NumPy reference (`tests/reference.py`, spec section
3): the paper's family and the power family, each as Pi, kappa and gamma of a scalar or an
array of xi (m/N). Imports nothing from ``jaxfric``; the choices the specification leaves
open are listed in `tests/reference.py`.
"""

import math

import numpy as np


def _as_output(values, like):
    """Return a float for scalar input ``like``, else a float64 array."""
    values = np.asarray(values, dtype=np.float64)
    if np.ndim(like) == 0:
        return float(values.reshape(()))
    return values


# ---------------------------------------------------------------------------------------
# 3. Shape functions
# ---------------------------------------------------------------------------------------


def _paper_F(x, a, b, c, alpha, beta):
    """The paper's fitted saw-tooth curve F(x) [N] for x [m] >= 0 (F(0) = 0)."""
    return a * math.exp(b * beta**alpha) - a * math.exp(b * (x + beta) ** alpha) - c * x**4


def _paper_dF(x, a, b, c, alpha, beta):
    """Analytic derivative dF/dx [N/m]."""
    return (
        -a * b * alpha * (x + beta) ** (alpha - 1.0) * math.exp(b * (x + beta) ** alpha)
        - 4.0 * c * x**3
    )


def _paper_scalar(xi, a, b, c, alpha, beta, l1, Fs):
    """(Pi, kappa, gamma) of the paper family at one xi [m/N]."""
    xi = max(xi, 0.0)  # negative arguments are clipped to 0
    if xi >= l1:
        return 1.0, 0.0, 1.0
    X = 2.0 * Fs * l1
    FX = _paper_F(X, a, b, c, alpha, beta)
    ratio = _paper_F(2.0 * Fs * xi, a, b, c, alpha, beta) / FX
    if ratio >= 1.0:
        # clipped part (F overshoots F(X) just before X): flat at 1
        return 1.0, 0.0, 1.0
    pi = ratio
    kappa = _paper_dF(2.0 * Fs * xi, a, b, c, alpha, beta) * 2.0 * Fs / FX
    gamma = pi - xi * kappa
    return pi, kappa, gamma


def _map_scalar(func, xi, *args):
    """Apply ``func(xi_scalar, *args) -> tuple`` over an array; returns a list of arrays."""
    xi_arr = np.asarray(xi, dtype=np.float64)
    outs = None
    for idx in np.ndindex(xi_arr.shape):
        values = func(float(xi_arr[idx]), *args)
        if outs is None:
            outs = [np.zeros(xi_arr.shape) for _ in values]
        for o, val in zip(outs, values):
            o[idx] = val
    if outs is None:  # empty input
        outs = [np.zeros(xi_arr.shape) for _ in range(3)]
    return outs


def paper_pi(xi, a, b, c, alpha, beta, l1, Fs):
    """Paper shape Pi(xi) [-], spec section 3.

    ``Pi(xi) = min(F(2*Fs*xi)/F(X), 1)`` for ``0 <= xi < l1`` with ``X = 2*Fs*l1``,
    ``Pi = 1`` for ``xi >= l1``, ``Pi(xi < 0) = 0`` (argument clipped to 0).

    Args:
        xi: presliding argument [m/N], scalar or array.
        a [N], b [m^-alpha], c [N/m^4], alpha [-], beta [m], l1 [m/N]: shape parameters.
        Fs: static force s_st [N] (fixes X = 2*Fs*l1).
    """
    return _as_output(_map_scalar(_paper_scalar, xi, a, b, c, alpha, beta, l1, Fs)[0], xi)


def paper_kappa(xi, a, b, c, alpha, beta, l1, Fs):
    """Paper shape kappa(xi) = dPi/dxi [N/m], from the analytic derivative of F.

    ``kappa = F'(2*Fs*xi) * 2*Fs / F(X)`` where Pi is not clipped; 0 where
    ``F(2*Fs*xi)/F(X) >= 1`` and for ``xi >= l1``. Choice: xi < 0 is clipped to 0 first,
    so ``kappa(xi < 0) = kappa(0)`` (it only ever multiplies the clipped xi = 0).
    """
    return _as_output(_map_scalar(_paper_scalar, xi, a, b, c, alpha, beta, l1, Fs)[1], xi)


def paper_gamma(xi, a, b, c, alpha, beta, l1, Fs):
    """Paper shape gamma(xi) = Pi - xi*kappa [-] (1 for xi >= l1 and on the clipped part,
    0 for xi <= 0)."""
    return _as_output(_map_scalar(_paper_scalar, xi, a, b, c, alpha, beta, l1, Fs)[2], xi)


def _power_scalar(xi, l1, n):
    """(Pi, kappa, gamma) of the power family at one xi [m/N]."""
    xi = max(xi, 0.0)
    if xi >= l1:
        return 1.0, 0.0, 1.0
    u = 1.0 - xi / l1
    pi = 1.0 - u**n
    kappa = n / l1 * u ** (n - 1.0)
    gamma = pi - xi * kappa
    return pi, kappa, gamma


def power_pi(xi, l1, n):
    """Power shape ``Pi(xi) = 1 - (1 - xi/l1)**n`` on [0, l1], 1 beyond, 0 for xi < 0.

    Args: xi [m/N] scalar or array; l1 [m/N]; n [-] >= 1.
    """
    return _as_output(_map_scalar(_power_scalar, xi, l1, n)[0], xi)


def power_kappa(xi, l1, n):
    """Power shape ``kappa = (n/l1)*(1 - xi/l1)**(n-1)`` [N/m] on [0, l1), 0 for xi >= l1,
    kappa(0) for xi < 0 (argument clipped to 0)."""
    return _as_output(_map_scalar(_power_scalar, xi, l1, n)[1], xi)


def power_gamma(xi, l1, n):
    """Power shape ``gamma = Pi - xi*kappa`` [-] (1 for xi >= l1, 0 for xi <= 0)."""
    return _as_output(_map_scalar(_power_scalar, xi, l1, n)[2], xi)
