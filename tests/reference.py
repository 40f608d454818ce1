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

The shape families are in `tests/reference_shapes.py` (re-exported here); the reference's
self-check against the specification's properties is ``python -m tests.reference_check``.

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

import math

import numpy as np

from .reference_shapes import (  # noqa: F401  (re-exported: the reference's public names)
    _as_output,
    _paper_F,
    _paper_scalar,
    _power_scalar,
    paper_gamma,
    paper_kappa,
    paper_pi,
    power_gamma,
    power_kappa,
    power_pi,
)


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

    The friction lag charges ``gamma(xi_n) * (S_n - S_{n-1})`` per step, except on a
    direction-change step (a reversal or the first motion), which charges nothing (spec
    section 4, step 4).

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
        Fl_start = 0.0 if reversal else Fl_prev_sample  # Rule 1: F_l(t_k+) = 0
        if moving[n]:
            a_n = math.exp(-C * float(dts[n]) / abs(S_n))
        else:
            a_n = 1.0  # no attraction during a dwell: every element sticks
        if moving[n] and D_prev != int(d[n]):
            # A direction-change step (reversal or first motion) charges nothing: S drops
            # from the new side's rest value at xi = 0, where gamma = 0, before the step's
            # travel (spec section 4, step 4).
            charge = 0.0
        else:
            charge = gamma_n * (S_n - S_prev_sample)
        Fl_n = a_n * Fl_start - charge

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
    S_prev = 0.0
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
                before = Fi[i]
                Fi[i] = Fi[i] + k[i] * dx
                if moving[n] and int(d[n]) * Fi[i] > nu[i] * abs(S_n):
                    # the limit met at fraction theta of the sample (force and limit both
                    # linear over it), slipping for the rest of it
                    lim0, lim1 = nu[i] * abs(S_prev), nu[i] * abs(S_n)
                    gap0, gap1 = lim0 - int(d[n]) * before, lim1 - int(d[n]) * Fi[i]
                    theta = min(max(gap0 / (gap0 - gap1), 0.0), 1.0) if gap0 > 0 else 0.0
                    met = int(d[n]) * (lim0 + theta * (lim1 - lim0))
                    target = nu[i] * S_n
                    Fi[i] = target + (met - target) * math.exp(
                        -C * (1.0 - theta) * float(dts[n]) / abs(S_n))
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
        S_prev = S_n
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
    """LuGre model with an exponential bristle update, spec section 6: the state follows
    the step's displacement ``x_n - x_{n-1}`` with ``1/g`` the mean of its values at
    ``|v_{n-1}|`` and ``|v_n|``, the force is taken at ``v_n``.

    Args:
        t [s], x [m], v [m/s] (optional): see ``prepare``.
        Fs, Fc [N], Vs [m/s], delta [-]: Stribeck curve.
        sigma0: bristle stiffness [N/m]. sigma1: bristle damping [N s/m].
        sigma2: viscous coefficient [N s/m].

    Returns:
        dict with ``F`` [N] and bristle deflection ``z`` [m].
    """
    prep = prepare(t, x, v)
    xs, vs = prep["x"], prep["v"]
    N = vs.size
    F = np.zeros(N)
    z_out = np.zeros(N)
    z = 0.0  # z_{-1}

    def g_of(u):
        return abs(_stribeck_scalar(u, Fs, Fc, Vs, delta)) if u != 0.0 else Fs

    for n in range(N):
        v_n = float(vs[n])
        g = g_of(v_n)
        if n > 0:
            dx = float(xs[n] - xs[n - 1])  # the step's displacement
            sgn = 1.0 if dx > 0 else (-1.0 if dx < 0 else 0.0)
            k = 0.5 * (1.0 / g + 1.0 / g_of(float(vs[n - 1])))  # 1/g, trapezoid rule
            z_ss = sgn / (sigma0 * k)
            z = z_ss + (z - z_ss) * math.exp(-sigma0 * abs(dx) * k)
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
