"""Independent, slow NumPy reference for the jaxfric friction models.

This file re-implements ``docs/algorithm.md`` (the specification) with plain Python loops,
so that the JAX implementation can be compared against it to < 1e-6 N. It imports nothing
from ``jaxfric`` on purpose: it was written from the specification alone.

Units are SI throughout: t [s], x [m], v [m/s], forces [N], xi [m/N].

Public functions
----------------
* ``stribeck(v, Fs, Fc, Vs, delta)``                    Stribeck curve s(v), s(0) = 0.
* ``paper_pi / paper_kappa / paper_gamma``               paper shape family (spec section 3).
* ``power_pi / power_kappa / power_gamma``               power shape family (spec section 3).
* ``prepare(t, x, v=None)``                              dt, v, d, moving, D (spec section 1).
* ``two_state(t, x, v=None, **params)``                  two-state model (spec section 4).
* ``gms(t, x, v=None, **params)``                        N-element GMS (spec section 5).
* ``gms_from_shape_elements(pi_func, l1, n, breakpoints=None)``  (nu, k) from a shape.
* ``lugre(t, x, v=None, **params)``                      LuGre (spec section 6).
* ``tustin(t, x, v=None, **params)``                     static Tustin model (spec section 7).

Choices made where the specification leaves room (they are repeated in the docstrings):

1. Shapes: a negative xi is clipped to 0 *before* anything else, so Pi(xi<0) = 0,
   kappa(xi<0) = kappa(0) and gamma(xi<0) = gamma(0) = 0.
2. Paper shape: "clipped" means F(2*Fs*xi)/F(X) >= 1; there Pi = 1, kappa = 0, gamma = 1.
   For xi >= l1: Pi = 1, kappa = 0, gamma = 1 (both families).
3. GMS: the position increment of sample 0 is 0 (x_{-1} := x_0).
4. Two-state loop closure compares the *unclipped* xi_e = (x_n - x_e)/(S_n - s_e) with
   theta_e (as written in the spec), and is checked on every sample, moving or not.
5. "e is the zero state" means: e is the bottom entry (index 0) and zero_bottom is True.
6. The two-state ``depth`` output is the stack size (zero state included) after the events
   (reversal, overflow, loop closure) of the sample; K bounds that same count.
7. Two-state: theta's denominator |s_r - s_e| cannot be 0 (s alternates in sign along the
   stack, the zero state has s = 0); an assert guards it instead of a silent fallback.
8. GMS at rest with a user-given v = 0 but x changing: the step is still applied and clipped
   to nu_i*|S_n| (S_n = D_n*Fs, so 0 before any motion), as the spec reads literally.
9. ``gms_from_shape_elements`` does not clip k_i: a non-concave Pi gives negative k_i, and
   rounding gives |k_i| ~ 1e-11 N/m values where Pi is linear. With the paper shape and the
   default breakpoints, l_2 = 0.966*l1 lies in the clipped (flat) part, so k_1 = nu_1 = 0.
"""

import itertools
import math

import numpy as np


# Paper values (Table 1 and Sec. 6.2), converted to SI. Handy for tests.
PAPER_STRIBECK = {"Fs": 26.1, "Fc": 21.6, "Vs": 3.1e-3, "delta": 0.6}
PAPER_SIGMA2 = 54.0  # N s/m  (0.054 N s/mm)
PAPER_C = 10.8  # N/s
PAPER_SHAPE = {
    "a": 2631.0,  # N
    "b": -0.0438 * 1000.0**0.3,  # m^-alpha  (-0.0438 mm^-0.3)
    "c": 2367.9e12,  # N/m^4     (2367.9 N/mm^4)
    "alpha": 0.3,  # -
    "beta": 1e-6,  # m         (1e-3 mm)
    "l1": 4.291e-6,  # m/N       (0.004291 mm/N)
}


def _as_output(values, like):
    """Return a float for scalar input ``like``, else a float64 array."""
    values = np.asarray(values, dtype=np.float64)
    if np.ndim(like) == 0:
        return float(values.reshape(()))
    return values


# ---------------------------------------------------------------------------------------
# 2. Stribeck curve
# ---------------------------------------------------------------------------------------


def _stribeck_scalar(v, Fs, Fc, Vs, delta):
    if v == 0.0:
        return 0.0
    sign = 1.0 if v > 0.0 else -1.0
    return sign * (Fc + (Fs - Fc) * math.exp(-((abs(v) / Vs) ** delta)))


def stribeck(v, Fs, Fc, Vs, delta):
    """Stribeck curve without viscous term, spec section 2.

    ``s(v) = sgn(v) * (Fc + (Fs - Fc) * exp(-(|v|/Vs)**delta))`` with ``s(0) = 0``.

    Args:
        v: velocity [m/s], scalar or array.
        Fs: static force [N]. Fc: Coulomb force [N]. Vs: Stribeck velocity [m/s].
        delta: Stribeck shape exponent [-].

    Returns:
        s(v) [N], a float for scalar ``v``, else a float64 array of the same shape.
    """
    v_arr = np.asarray(v, dtype=np.float64)
    out = np.zeros(v_arr.shape)
    for idx in np.ndindex(v_arr.shape):
        out[idx] = _stribeck_scalar(float(v_arr[idx]), Fs, Fc, Vs, delta)
    return _as_output(out, v)


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


def _shape_scalar_func(shape, shape_params, Fs):
    """Return (l1, f) with f(xi) -> (Pi, kappa, gamma) for one scalar xi."""
    if shape == "paper":
        p = dict(PAPER_SHAPE) if shape_params is None else dict(shape_params)
        a, b, c = p["a"], p["b"], p["c"]
        alpha, beta, l1 = p["alpha"], p["beta"], p["l1"]

        def f(xi):
            return _paper_scalar(xi, a, b, c, alpha, beta, l1, Fs)

        return l1, f
    if shape == "power":
        if shape_params is None:
            raise ValueError("shape='power' needs shape_params=dict(l1=..., n=...)")
        l1, n = shape_params["l1"], shape_params["n"]

        def f(xi):
            return _power_scalar(xi, l1, n)

        return l1, f
    raise ValueError(f"unknown shape {shape!r}; use 'paper' or 'power'")


# ---------------------------------------------------------------------------------------
# 1. Inputs and the direction signal
# ---------------------------------------------------------------------------------------


def prepare(t, x, v=None, consistent=False):
    """Time steps, velocity and direction signals, spec section 1.

    Args:
        t: sample times [s], 1-D, strictly increasing.
        x: positions [m], same length.
        v: optional velocities [m/s]. If None: ``v_0 = 0``, ``v_n = (x_n - x_{n-1})/dt_n``.
        consistent: for the models with a memory in position (two-state, GMS): where the
            sign of a given ``v_n`` disagrees with the step ``x_n - x_{n-1}``, use the step's
            backward difference instead, so direction and displacement agree.

    Returns:
        dict with float64 arrays ``t``, ``x``, ``dt`` (dt_0 = 0), ``v``; int arrays
        ``d`` = sign(v) in {-1, 0, 1} and ``D`` (direction of the last moving sample at or
        before n, 0 if none yet); bool array ``moving`` = (d != 0).
    """
    t = np.asarray(t, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    if t.ndim != 1 or x.shape != t.shape or t.size == 0:
        raise ValueError("t and x must be 1-D arrays of the same non-zero length")
    N = t.size
    dt = np.zeros(N)
    for n in range(1, N):
        dt[n] = t[n] - t[n - 1]
        if not dt[n] > 0.0:
            raise ValueError("t must be strictly increasing")

    if v is None:
        v = np.zeros(N)
        for n in range(1, N):
            v[n] = (x[n] - x[n - 1]) / dt[n]  # backward difference: sign(v) == sign(dx)
    else:
        v = np.array(v, dtype=np.float64)
        if v.shape != t.shape:
            raise ValueError("v must have the same shape as t")
        if consistent:
            for n in range(1, N):
                step = x[n] - x[n - 1]
                if (v[n] > 0.0 and step < 0.0) or (v[n] < 0.0 and step > 0.0):
                    v[n] = step / dt[n]

    d = np.zeros(N, dtype=np.int64)
    moving = np.zeros(N, dtype=bool)
    D = np.zeros(N, dtype=np.int64)
    last = 0  # D_{-1} = 0
    for n in range(N):
        if v[n] > 0.0:
            d[n] = 1
        elif v[n] < 0.0:
            d[n] = -1
        else:
            d[n] = 0
        moving[n] = d[n] != 0
        if moving[n]:
            last = d[n]
        D[n] = last
    return {"t": t, "x": x, "dt": dt, "v": v, "d": d, "moving": moving, "D": D}


def _effective_S(prep, n, Fs, Fc, Vs, delta):
    """Effective Stribeck value S_n [N]: s(v_n) if moving, else r(D_n) = D_n*Fs."""
    if prep["moving"][n]:
        return _stribeck_scalar(float(prep["v"][n]), Fs, Fc, Vs, delta)
    return float(prep["D"][n]) * Fs


# ---------------------------------------------------------------------------------------
# 4. Two-state model
# ---------------------------------------------------------------------------------------


def _branch_arg(x, S, entry):
    """xi = (x - x_e)/(S - s_e) [m/N] (not clipped); 0 if S == s_e."""
    if S == entry["s"]:
        return 0.0
    return (x - entry["x"]) / (S - entry["s"])


def _branch_force(x, S, entry, shape_f):
    """H(x, S; e) = h_e + Pi(xi)*(S - s_e) [N] (Eq. 32). Pi clips xi < 0 to 0."""
    xi = _branch_arg(x, S, entry)
    pi, _, _ = shape_f(xi)
    return entry["h"] + pi * (S - entry["s"])


def two_state(
    t,
    x,
    v=None,
    *,
    Fs,
    Fc,
    Vs,
    delta,
    sigma2,
    C,
    shape="paper",
    shape_params=None,
    K=16,
):
    """Two-state GMS-based friction model, spec section 4.

    Args:
        t [s], x [m], v [m/s] (optional): see ``prepare``.
        Fs, Fc [N], Vs [m/s], delta [-]: Stribeck curve.
        sigma2: viscous coefficient [N s/m]. C: attraction parameter [N/s].
        shape: "paper" (shape_params keys a, b, c, alpha, beta, l1; default: the paper's
            values in SI, with s_st = Fs) or "power" (keys l1, n).
        K: stack capacity (>= 3).

    Note: an earlier version of the spec started the step after a reversal from the OLD
    side's rest value; with gamma taken at the end of the step that leaked the +-Fs jump
    of s into F_l (-5.5 N at v = 1 mm/s, dt = 10 ms). The spec now starts from the new side.

    Returns:
        dict with float64 arrays ``F`` (total force), ``Fh``, ``Fl`` [N], ``S`` (effective
        Stribeck value) [N], ``xi`` (clipped branch argument) [m/N], int array ``depth``
        (stack entries after the sample's events) and int ``overflow`` (entries dropped).
    """
    if K < 3:
        raise ValueError("K must be >= 3")
    prep = prepare(t, x, v, consistent=True)
    xs, vs, dts = prep["x"], prep["v"], prep["dt"]
    d, D, moving = prep["d"], prep["D"], prep["moving"]
    N = xs.size
    l1, shape_f = _shape_scalar_func(shape, shape_params, Fs)

    # The stack: a Python list, bottom first. The zero state has no theta.
    stack = [{"x": float(xs[0]), "h": 0.0, "s": 0.0, "theta": None, "closable": False}]
    zero_bottom = True
    overflow = 0

    F = np.zeros(N)
    Fh = np.zeros(N)
    Fl = np.zeros(N)
    S_out = np.zeros(N)
    xi_out = np.zeros(N)
    depth = np.zeros(N, dtype=np.int64)

    S_prev_sample = 0.0  # S_{-1}
    Fl_prev_sample = 0.0  # F_l,-1
    for n in range(N):
        x_n = float(xs[n])
        S_n = _effective_S(prep, n, Fs, Fc, Vs, delta)
        D_prev = int(D[n - 1]) if n > 0 else 0

        # --- 1. motion reversal (Rule 1) ---
        reversal = bool(moving[n]) and D_prev != 0 and int(d[n]) != D_prev
        s_r = None
        if reversal:
            x_r = float(xs[n - 1])
            s_r = D_prev * Fs  # v -> 0 limit on the side we came from
            e = stack[-1]
            h_r = _branch_force(x_r, s_r, e, shape_f)
            # s alternates in sign along the stack, so s_r - s_e is never 0 here
            assert s_r != e["s"], "reversal with s_r == s_e: should be impossible"
            theta = abs(x_r - e["x"]) / abs(s_r - e["s"])
            if theta > l1:
                # wiping-out: keep e (the branch start), drop everything below it
                e_is_zero_state = len(stack) == 1 and zero_bottom
                stack = [e]
                zero_bottom = e_is_zero_state
            stack.append({"x": x_r, "h": h_r, "s": s_r, "theta": theta, "closable": (theta <= l1)})
            if len(stack) > K:
                stack.pop(0)  # drop the oldest entry
                zero_bottom = False
                overflow += 1

        # --- 2. loop closure cascade (Rules 2 and 3) ---
        while True:
            k = len(stack) - 1
            if k < 1:
                break
            e = stack[-1]
            if not e["closable"]:
                break
            xi_e = _branch_arg(x_n, S_n, e)
            if xi_e < e["theta"]:
                break
            if k == 1 and zero_bottom:
                stack.pop()  # Rule 3: back on the virgin curve
            elif k >= 2:
                stack.pop()  # Rule 2: the branch of entry k-2 continues
                stack.pop()
            else:
                break  # the entry below was lost to overflow: nothing to close onto

        # --- 3. hysteresis force (algebraic, Eq. 32) ---
        top = stack[-1]
        xi_n = max(_branch_arg(x_n, S_n, top), 0.0)
        pi_n, _, gamma_n = shape_f(xi_n)
        Fh_n = top["h"] + pi_n * (S_n - top["s"])

        # --- 4. friction lag, exact decay over a step with constant S ---
        # S at the start of the step. After a reversal or at the first motion, s jumps
        # across v = 0 at xi = 0 where gamma = 0: the step starts from the rest limit on
        # the NEW side (spec section 4, step 4).
        if moving[n] and D_prev != int(d[n]):
            S_prev = int(d[n]) * Fs
        else:
            S_prev = S_prev_sample
        Fl_start = 0.0 if reversal else Fl_prev_sample  # Rule 1: F_l(t_k+) = 0
        if moving[n]:
            a_n = math.exp(-C * float(dts[n]) / abs(S_n))
        else:
            a_n = 1.0  # no attraction during a dwell: every element sticks
        Fl_n = a_n * Fl_start - gamma_n * (S_n - S_prev)

        # --- 5. total force ---
        F[n] = Fh_n + Fl_n + sigma2 * float(vs[n])
        Fh[n] = Fh_n
        Fl[n] = Fl_n
        S_out[n] = S_n
        xi_out[n] = xi_n
        depth[n] = len(stack)

        S_prev_sample = S_n
        Fl_prev_sample = Fl_n

    return {"F": F, "Fh": Fh, "Fl": Fl, "S": S_out, "xi": xi_out, "depth": depth, "overflow": int(overflow)}


# ---------------------------------------------------------------------------------------
# 5. GMS with N elements
# ---------------------------------------------------------------------------------------


def gms(t, x, v=None, *, Fs, Fc, Vs, delta, sigma2, C, nu, k):
    """Generalized Maxwell-slip model with explicit per-element stick/slip, spec section 5.

    Args:
        t [s], x [m], v [m/s] (optional): see ``prepare``.
        Fs, Fc [N], Vs [m/s], delta [-]: Stribeck curve.
        sigma2: viscous coefficient [N s/m]. C: attraction parameter [N/s].
        nu: element weights [-] (sum 1). k: element stiffnesses [N/m].

    Returns:
        dict with ``F`` [N] (N,) and ``Fi`` [N] (N, n_elements), the element forces.

    Choice: the position increment of sample 0 is 0 (x_{-1} := x_0).
    """
    prep = prepare(t, x, v, consistent=True)
    xs, vs, dts = prep["x"], prep["v"], prep["dt"]
    d, D, moving = prep["d"], prep["D"], prep["moving"]
    nu = [float(val) for val in np.atleast_1d(np.asarray(nu, dtype=np.float64))]
    k = [float(val) for val in np.atleast_1d(np.asarray(k, dtype=np.float64))]
    if len(nu) != len(k):
        raise ValueError("nu and k must have the same length")
    m = len(nu)
    N = xs.size

    Fi = [0.0] * m
    slipping = [False] * m
    F_out = np.zeros(N)
    Fi_out = np.zeros((N, m))
    for n in range(N):
        S_n = _effective_S(prep, n, Fs, Fc, Vs, delta)
        D_prev = int(D[n - 1]) if n > 0 else 0
        dx = float(xs[n] - xs[n - 1]) if n > 0 else 0.0

        # 1. every element sticks at rest and at a change of direction
        if (not moving[n]) or int(d[n]) != D_prev:
            slipping = [False] * m

        for i in range(m):
            if slipping[i]:
                # 2. slipping: exact solution of dF/dt = (C/|s|)(nu*s - F) at constant s
                target = nu[i] * S_n
                Fi[i] = target + (Fi[i] - target) * math.exp(-C * float(dts[n]) / abs(S_n))
            else:
                # 3. sticking: spring; slip starts at the limit in the direction of motion
                Fi[i] = Fi[i] + k[i] * dx
                if moving[n] and int(d[n]) * Fi[i] > nu[i] * abs(S_n):
                    Fi[i] = nu[i] * S_n
                    slipping[i] = True
                else:
                    # beyond the limit on the other side (|s| dropped): keeps sticking, but
                    # never past what any element can hold
                    cap = nu[i] * max(Fs, Fc)
                    Fi[i] = min(max(Fi[i], -cap), cap)

        total = 0.0
        for i in range(m):
            total += Fi[i]
            Fi_out[n, i] = Fi[i]
        F_out[n] = total + sigma2 * float(vs[n])
    return {"F": F_out, "Fi": Fi_out}


def gms_from_shape_elements(pi_func, l1, n, breakpoints=None):
    """GMS elements (nu, k) whose piecewise-linear Pi_0 interpolates a shape Pi.

    ``Pi_0(xi) = sum_i k_i*min(xi, l_i)`` has slope ``sum_{i<=j} k_i`` on (l_{j+1}, l_j) and
    slope ``sum_i k_i`` on (0, l_N). Matching those slopes to the chords of Pi between the
    breakpoints (and from 0, Pi(0) = 0) gives ``k_1 = m_1``, ``k_j = m_j - m_{j-1}``, and
    ``nu_i = k_i*l_i``, so ``sum nu_i = Pi_0(l1) = Pi(l1) = 1``. A concave Pi gives k_i >= 0.

    Args:
        pi_func: callable, Pi(xi) for an array xi [m/N].
        l1: presliding limit [m/N] (= the first breakpoint).
        n: number of elements.
        breakpoints: l_i [m/N], strictly descending, positive, first = l1, length n.
            Default: geometric spacing from l1 down to l1*1e-3 (``np.geomspace``),
            i.e. ``l_i = l1 * 1e-3**((i-1)/(n-1))``.

    Returns:
        (nu, k): float64 arrays, nu [-] and k [N/m], ordered like the breakpoints.
    """
    if breakpoints is None:
        if n == 1:
            bp = np.array([float(l1)])
        else:
            bp = np.geomspace(l1, l1 * 1e-3, n)
            bp[0] = l1
    else:
        bp = np.array(breakpoints, dtype=np.float64)
    if bp.ndim != 1 or bp.size != n:
        raise ValueError("breakpoints must be 1-D with n entries")
    if bp[0] != l1:
        raise ValueError("the first breakpoint must be l1")
    for j in range(n - 1):
        if not bp[j] > bp[j + 1]:
            raise ValueError("breakpoints must be strictly descending")
    if not bp[-1] > 0.0:
        raise ValueError("breakpoints must be positive")

    pi_vals = np.asarray(pi_func(bp), dtype=np.float64)
    slopes = np.zeros(n)  # slopes[j] = chord slope of Pi on (l_{j+1}, l_j), last one from 0
    for j in range(n - 1):
        slopes[j] = (pi_vals[j] - pi_vals[j + 1]) / (bp[j] - bp[j + 1])
    slopes[n - 1] = pi_vals[n - 1] / bp[n - 1]
    k = np.zeros(n)
    k[0] = slopes[0]
    for j in range(1, n):
        k[j] = slopes[j] - slopes[j - 1]
    nu = k * bp
    return nu, k


# ---------------------------------------------------------------------------------------
# 6. LuGre and 7. Tustin
# ---------------------------------------------------------------------------------------


def lugre(t, x, v=None, *, Fs, Fc, Vs, delta, sigma0, sigma1, sigma2):
    """LuGre model with an exact-exponential bristle update, spec section 6.

    Args:
        t [s], x [m], v [m/s] (optional): see ``prepare``.
        Fs, Fc [N], Vs [m/s], delta [-]: Stribeck curve.
        sigma0: bristle stiffness [N/m]. sigma1: bristle damping [N s/m].
        sigma2: viscous coefficient [N s/m].

    Returns:
        dict with ``F`` [N] and bristle deflection ``z`` [m].
    """
    prep = prepare(t, x, v)
    vs, dts, moving = prep["v"], prep["dt"], prep["moving"]
    N = vs.size
    F = np.zeros(N)
    z_out = np.zeros(N)
    z = 0.0  # z_{-1}
    for n in range(N):
        v_n = float(vs[n])
        if moving[n]:
            g = abs(_stribeck_scalar(v_n, Fs, Fc, Vs, delta))
        else:
            g = Fs
        lam = sigma0 * abs(v_n) / g
        sgn = 1.0 if v_n > 0 else (-1.0 if v_n < 0 else 0.0)
        z_ss = sgn * g / sigma0
        z = z_ss + (z - z_ss) * math.exp(-lam * float(dts[n]))
        zdot = v_n - sigma0 * abs(v_n) * z / g
        F[n] = sigma0 * z + sigma1 * zdot + sigma2 * v_n
        z_out[n] = z
    return {"F": F, "z": z_out}


def tustin(t, x, v=None, *, Fs, Fc, Vs, delta, sigma2):
    """Static Tustin model ``F = s(v) + sigma2*v`` [N] (0 at v = 0), spec section 7.

    Returns:
        dict with ``F`` [N].
    """
    prep = prepare(t, x, v)
    vs = prep["v"]
    F = np.zeros(vs.size)
    for n in range(vs.size):
        F[n] = _stribeck_scalar(float(vs[n]), Fs, Fc, Vs, delta) + sigma2 * float(vs[n])
    return {"F": F}


# ---------------------------------------------------------------------------------------
# Self-checks: /work/venv/bin/python tests/reference.py
# ---------------------------------------------------------------------------------------


def _path(points, speed, dt):
    """Piecewise-linear path through ``points`` [m] at constant |v| = speed [m/s].

    Every segment length must be a multiple of speed*dt, so the samples sit on one grid.
    Returns (t, x).
    """
    step = speed * dt
    xs = [points[0]]
    for a, b in itertools.pairwise(points):
        m = round(abs(b - a) / step)
        assert abs(m * step - abs(b - a)) < 1e-12 * max(1.0, abs(b - a)) + 1e-15
        sgn = 1.0 if b > a else -1.0
        for j in range(1, m + 1):
            xs.append(a + sgn * j * step)
        xs[-1] = b
    x = np.array(xs)
    t = dt * np.arange(x.size)
    return t, x


def _self_check():
    stri = dict(PAPER_STRIBECK)
    Fs = stri["Fs"]
    common = dict(stri, sigma2=PAPER_SIGMA2, C=PAPER_C)
    sh = dict(PAPER_SHAPE)
    l1 = sh["l1"]
    ok = True

    def report(name, value, tol):
        nonlocal ok
        good = value <= tol
        ok = ok and good
        print(f"  [{'ok' if good else 'FAIL'}] {name}: {value:.3e} (tol {tol:.0e})")

    print("Shapes")
    p0 = paper_pi(0.0, **sh, Fs=Fs)
    p1 = paper_pi(l1, **sh, Fs=Fs)
    report("paper Pi(0)", abs(p0), 0.0)
    report("paper |Pi(l1) - 1|", abs(p1 - 1.0), 0.0)
    xi = np.linspace(-0.1 * l1, 1.2 * l1, 2001)
    P = paper_pi(xi, **sh, Fs=Fs)
    Kp = paper_kappa(xi, **sh, Fs=Fs)
    G = paper_gamma(xi, **sh, Fs=Fs)
    err = np.max(np.abs(G - (P - np.maximum(xi, 0) * Kp)))
    report("paper max|gamma - (Pi - max(xi,0)*kappa)|", err, 1e-15)
    report("paper Pi monotone (max decrease)", max(0.0, -np.min(np.diff(P))), 0.0)
    report("paper max Pi - 1", max(0.0, np.max(P) - 1.0), 0.0)
    # analytic kappa against a central difference, away from the clip kink
    X = 2 * Fs * l1
    FX = _paper_F(X, sh["a"], sh["b"], sh["c"], sh["alpha"], sh["beta"])
    xi_in = np.linspace(0.05 * l1, 0.9 * l1, 50)
    h = 1e-6 * l1
    fd = (paper_pi(xi_in + h, **sh, Fs=Fs) - paper_pi(xi_in - h, **sh, Fs=Fs)) / (2 * h)
    kap = paper_kappa(xi_in, **sh, Fs=Fs)
    rel = np.max(np.abs(fd - kap) / np.abs(kap))
    report("paper kappa vs finite difference (rel)", rel, 1e-6)
    xi_pos = xi[xi > 0]
    ratio = np.array([_paper_F(2 * Fs * q, sh["a"], sh["b"], sh["c"], sh["alpha"], sh["beta"]) / FX
                      for q in xi_pos])
    cross = xi_pos[np.argmax(ratio >= 1.0)] / l1
    print(f"  info: F(X) = {FX:.4f} N; max F/F(X) = {ratio.max():.6f}; clipped from xi = {cross:.4f}*l1;"
          f" kappa(0) = {paper_kappa(0.0, **sh, Fs=Fs):.4e} N/m")
    P = power_pi(xi, l1, 3.0)
    G = power_gamma(xi, l1, 3.0)
    Kw = power_kappa(xi, l1, 3.0)
    report("power Pi(0), |Pi(l1)-1|", max(abs(power_pi(0.0, l1, 3.0)), abs(power_pi(l1, l1, 3.0) - 1)), 0.0)
    report("power max|gamma - (Pi - xi*kappa)|", np.max(np.abs(G - (P - np.maximum(xi, 0) * Kw))), 1e-15)

    print("prepare / Stribeck")
    pr = prepare([0.0, 1.0, 2.0, 3.0, 4.0, 5.0], [0.0, 0.0, 1.0, 1.0, 0.5, 0.5])
    print(f"  v={pr['v'].tolist()} d={pr['d'].tolist()} D={pr['D'].tolist()}")
    report("s(0)", abs(stribeck(0.0, **stri)), 0.0)
    report("s(-v) + s(v)", abs(stribeck(-1e-3, **stri) + stribeck(1e-3, **stri)), 0.0)

    print("Constant-velocity stroke -> s(v) + sigma2*v")
    nu200, k200 = gms_from_shape_elements(lambda q: paper_pi(q, **sh, Fs=Fs), l1, 200)
    report("GMS-from-shape |sum nu - 1|", abs(np.sum(nu200) - 1.0), 1e-12)
    print(f"  info: min k_i = {np.min(k200):.3e} N/m (negative only from rounding),"
          f" elements with nu_i == 0: {int(np.sum(nu200 == 0))}")
    nu50, k50 = gms_from_shape_elements(lambda q: paper_pi(q, **sh, Fs=Fs), l1, 50)
    for vel in (1e-3, -2e-4):
        t = np.linspace(0.0, 60.0, 6001)
        x = vel * t
        target = stribeck(vel, **stri) + PAPER_SIGMA2 * vel
        r2 = two_state(t, x, **common)
        rg = gms(t, x, **common, nu=nu50, k=k50)
        rl = lugre(t, x, **stri, sigma0=1e6, sigma1=300.0, sigma2=PAPER_SIGMA2)
        rt = tustin(t, x, **stri, sigma2=PAPER_SIGMA2)
        print(f"  v = {vel:+.1e} m/s: target {target:+.6f} N")
        report("    two_state end error", abs(r2["F"][-1] - target), 1e-6)
        report("    gms(50 from shape) end error", abs(rg["F"][-1] - target), 1e-6)
        report("    lugre end error", abs(rl["F"][-1] - target), 1e-6)
        report("    tustin end error", abs(rt["F"][-1] - target), 1e-12)

    print("Observation: F_l at the first moving sample, -gamma(xi_1)*(s(v) - 0), depends on dt")
    for step in (1e-2, 1e-3, 1e-4):
        t = np.arange(0.0, 0.05, step)
        r2 = two_state(t, 1e-3 * t, **common)
        print(f"  info: v = 1 mm/s, dt = {step:.0e} s: F_l[1] = {r2['Fl'][1]:+.4f} N,"
              f" xi_1 = {r2['xi'][1] / l1:.2e}*l1")

    print("Stop after a sliding stroke: F - sigma2*v continuous, F_l frozen during the dwell")
    t = np.linspace(0.0, 20.0, 2001)
    x = np.minimum(5e-4 * t, 5e-4 * 10.0)  # slide 10 s, then rest
    r2 = two_state(t, x, **common)
    i_stop = 1001  # first sample at rest
    jump = (r2["F"][i_stop] - 0.0) - (r2["F"][i_stop - 1] - PAPER_SIGMA2 * 5e-4)
    report("two_state |jump of F_h + F_l| at stop", abs(jump), 1e-9)
    report("two_state F_l change during dwell", np.max(np.abs(np.diff(r2["Fl"][i_stop:]))), 0.0)

    print("Nested inner loop returns to the outer branch (slow presliding triangle)")
    A = 80e-6  # m, A/Fs = 3.1e-6 m/N < l1
    speed, dt = 1e-6, 0.05  # 1 um/s: s(v) = 26.06 N ~ Fs
    t_dir, x_dir = _path([0.0, A, -A], speed, dt)
    t_nest, x_nest = _path([0.0, A, 0.0, A / 2, -A], speed, dt)
    r_dir = two_state(t_dir, x_dir, **common)
    r_nest = two_state(t_nest, x_nest, **common)
    print(f"  depth along nested path (changes): {np.unique(r_nest['depth']).tolist()},"
          f" final depth {r_nest['depth'][-1]}, direct final depth {r_dir['depth'][-1]}")
    # both paths end with the same grid from just below x = 0 down to -A
    n_tail = round(A / (speed * dt))  # samples strictly below 0 on the last segment
    dF = np.abs(r_nest["F"][-n_tail:] - r_dir["F"][-n_tail:])
    assert np.allclose(x_nest[-n_tail:], x_dir[-n_tail:], atol=1e-15)
    report("two_state max |F_nested - F_direct| for x < 0 after closure", np.max(dF), 1e-6)
    # before the closure (between the inner reversal at A/2 and 0) the forces differ
    n_last = round(1.5 * A / (speed * dt))
    print(f"  info: max |F_nested - F_direct| on the whole last segment (incl. before closure):"
          f" {np.max(np.abs(r_nest['F'][-n_last:] - r_dir['F'][-n_last:])):.3f} N")
    i_A = round(A / (speed * dt))  # sample at x = +A
    # virgin curve: F_h = Pi(x/S)*S
    S1 = r_dir["S"][1:i_A + 1]
    virgin = paper_pi(x_dir[1:i_A + 1] / S1, **sh, Fs=Fs) * S1
    report("two_state virgin curve (Fh vs Pi(x/S)*S)", np.max(np.abs(r_dir["Fh"][1:i_A + 1] - virgin)), 1e-12)
    # branch from +A (until Rule 3 near -A): h_A + Pi((x-A)/(S-Fs))*(S-Fs), with the branch
    # start stored in the v -> 0 limit, h_A = Pi(A/Fs)*Fs (not the F_h of the last moving sample)
    seg = slice(i_A + 1, i_A + 1 + round(1.9 * A / (speed * dt)))
    S_seg = r_dir["S"][seg]
    h_A = paper_pi(A / Fs, **sh, Fs=Fs) * Fs
    branch = h_A + paper_pi((x_dir[seg] - A) / (S_seg - Fs), **sh, Fs=Fs) * (S_seg - Fs)
    report("two_state descending branch formula", np.max(np.abs(r_dir["Fh"][seg] - branch)), 1e-12)
    # Masing: that branch is the virgin curve doubled, exactly so only if |S| = Fs
    masing = h_A - 2.0 * Fs * paper_pi((A - x_dir[seg]) / (2.0 * Fs), **sh, Fs=Fs)
    print(f"  info: max |F_h - Masing (virgin doubled, |S| = Fs)| on that branch:"
          f" {np.max(np.abs(r_dir['Fh'][seg] - masing)):.4f} N (|s(v)| = {abs(S_seg[0]):.4f} N)")

    print("200-element GMS (from the paper shape) vs two_state, slow presliding paths")
    r_g = gms(t_nest, x_nest, **common, nu=nu200, k=k200)
    diff = np.abs(r_g["F"] - r_nest["F"])
    report("nested path: max |F_gms - F_two_state| / Fs", np.max(diff) / Fs, 0.05)
    print(f"  info: max diff {np.max(diff):.4f} N, RMS {np.sqrt(np.mean(diff**2)):.4f} N")
    t_big, x_big = _path([0.0, 3 * A, -2 * A, 0.5 * A, -0.5 * A, 2 * A], speed, dt)
    r2b = two_state(t_big, x_big, **common)
    rgb = gms(t_big, x_big, **common, nu=nu200, k=k200)
    diff = np.abs(rgb["F"] - r2b["F"])
    report("larger path (leaves presliding): max |F_gms - F_two_state| / Fs", np.max(diff) / Fs, 0.05)
    print(f"  info: max diff {np.max(diff):.4f} N, RMS {np.sqrt(np.mean(diff**2)):.4f} N")

    print("Power shape, n = 1 (linear Pi): GMS with one element = elastic-perfectly-plastic")
    lp = 3e-6
    nu1, k1 = gms_from_shape_elements(lambda q: power_pi(q, lp, 1.0), lp, 5)
    print(f"  info: nu = {np.array2string(nu1, precision=3)}")
    r2p = two_state(t_nest, x_nest, **common, shape="power", shape_params={"l1": lp, "n": 1.0})
    rgp = gms(t_nest, x_nest, **common, nu=nu1, k=k1)
    print(f"  info: max |F_gms - F_two_state| = {np.max(np.abs(rgp['F'] - r2p['F'])):.4f} N")

    print("Overflow: many small nested reversals with K = 3")
    # shrinking nested loops, then a long stroke that would close all of them
    pts = [0.0, 40e-6, 10e-6, 30e-6, 15e-6, 25e-6, 18e-6, 22e-6, 60e-6]
    t_o, x_o = _path(pts, speed, dt)
    ro = two_state(t_o, x_o, **common, K=3)
    ro16 = two_state(t_o, x_o, **common, K=16)
    print(f"  info: K=3 overflow = {ro['overflow']}, max depth = {ro['depth'].max()};"
          f" K=16 overflow = {ro16['overflow']}, max depth = {ro16['depth'].max()};"
          f" max |F_K3 - F_K16| = {np.max(np.abs(ro['F'] - ro16['F'])):.3e} N")
    report("K=3 depth never exceeds 3", max(0, ro["depth"].max() - 3), 0)

    print("ALL OK" if ok else "SOME CHECKS FAILED")
    return ok


if __name__ == "__main__":
    import sys

    sys.exit(0 if _self_check() else 1)
