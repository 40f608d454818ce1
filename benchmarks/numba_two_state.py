"""A Numba baseline of the two-state GMS-based friction model (docs/algorithm.md section 4).

The same discrete-time algorithm as `jaxfric.TwoState` with the paper's shape family
(`jaxfric.PaperShape`), written the way a performance-minded user would write it by hand:
one tight ``@numba.njit`` loop over the samples in float64, the memory stack in fixed-size
arrays, no Python objects inside the loop, ``error_model="numpy"`` (no zero-division checks;
every division is guarded explicitly, as in jaxfric) and no ``fastmath`` (which would
reorder the float arithmetic and break the < 1e-9 N agreement). It exists to measure jaxfric against
(``benchmarks/throughput.py``). ``python benchmarks/numba_two_state.py --check`` checks
that both give the same forces to < 1e-9 N (and the same overflow counts, and the same
shape as `jaxfric.PaperShape`), exiting non-zero otherwise; ``tests/core/test_numba_baseline.py``
runs it.

Units are SI: t [s], x [m], v [m/s], forces [N], xi [m/N].

Parameters are a dict with the 12 names of `PARAM_NAMES`:
``Fs, Fc`` [N], ``Vs`` [m/s], ``delta`` [-] (Stribeck curve), ``sigma2`` [N s/m],
``C`` [N/s], and the paper shape ``a`` [N], ``b`` [m^-alpha], ``c`` [N/m^4], ``alpha`` [-],
``beta`` [m], ``l1`` [m/N]. `params_from_model` reads them from a jaxfric `TwoState`.

Per sample (tests/reference.py spells out the same rules with Python lists):

1. ``v`` given, or the backward difference ``(x_n - x_{n-1})/dt_n`` (``v_0 = 0``); the
   direction is ``d = sign(v)`` and ``S = s(v)`` while moving, ``D*Fs`` at rest (``D`` the
   last direction of motion).
2. Reversal (moving, ``D != 0``, ``d != D``): push the reversal point ``x_{n-1}`` with its
   rest value ``s_r = D*Fs``, its branch-start force ``h_r = H(x_r, s_r)`` and its extent
   ``theta``; wiping-out (``theta > l1``) keeps only the current branch start below it;
   a full stack drops its bottom entry (counted as overflow).
3. Loop closure cascade (Rules 2-3): while the top entry is closable and
   ``(x - x_e)/(S - s_e) >= theta_e``, pop two entries (one onto the zero state).
4. ``F_h = h_e + Pi(xi)*(S - s_e)``; ``F_l = a*F_l - gamma(xi)*(S - S_{n-1})`` with the
   exact decay ``a = exp(-C*dt/|S|)`` while moving, ``F_l`` reset to 0 at a reversal (Rule 1)
   and no charge on a direction-change step (a reversal or the first motion).
5. ``F = F_h + F_l + sigma2*v``.

The paper shape uses the analytic derivative: with ``F(z) = a*exp(b*beta^alpha) -
a*exp(b*(z+beta)^alpha) - c*z^4`` (written with ``expm1`` as jaxfric does, the two
exponentials are ~50x larger than their difference), ``X = 2*Fs*l1``,
``Pi(xi) = min(F(2*Fs*xi)/F(X), 1)`` and ``kappa = 2*Fs*F'(2*Fs*xi)/F(X)`` (0 where clipped
and for ``xi >= l1``), ``gamma = Pi - xi*kappa``.

Public functions: `simulate_numba`, `simulate_numba_batch` (``prange`` over trajectories),
`simulate_numba_params` (``prange`` over parameter sets on one trajectory),
`params_from_model`, `paper_params`, `warm_up` (compiles the kernels, returns seconds), and
`shape_constants` (to call the shape kernel `_pi_gamma` from Python, for the tests).
"""

from __future__ import annotations

import math

import numba
import numpy as np


#: Order of the parameters in the packed float64 vector the kernels take.
PARAM_NAMES = ("Fs", "Fc", "Vs", "delta", "sigma2", "C", "a", "b", "c", "alpha", "beta", "l1")


def paper_params() -> dict[str, float]:
    """The paper's two-state values (Table 1, Sec. 6.2) in SI, as `jaxfric.paper.two_state()`."""
    alpha = 0.3
    return {
        "Fs": 26.1,
        "Fc": 21.6,
        "Vs": 3.1e-3,
        "delta": 0.6,
        "sigma2": 0.054 * 1e3,
        "C": 10.8,
        "a": 2631.0,
        "b": -0.0438 * 1e3**alpha,
        "c": 2367.9e12,
        "alpha": alpha,
        "beta": 1e-6,
        "l1": 0.004291e-3,
    }


def params_from_model(model) -> dict[str, float]:
    """The 12 parameters (SI floats) of a jaxfric `TwoState` with a `PaperShape`."""
    st, sh = model.stribeck, model.shape
    missing = [k for k in ("a", "b", "c", "alpha", "beta", "l1") if not hasattr(sh, k)]
    if missing:
        raise TypeError(f"the Numba baseline implements the paper shape only; {type(sh)}")
    out = {k: float(getattr(st, k)) for k in ("Fs", "Fc", "Vs", "delta")}
    out.update(sigma2=float(model.sigma2), C=float(model.C))
    out.update({k: float(getattr(sh, k)) for k in ("a", "b", "c", "alpha", "beta", "l1")})
    return out


def _pack(params: dict) -> np.ndarray:
    missing = [k for k in PARAM_NAMES if k not in params]
    if missing:
        raise KeyError(f"missing parameters: {missing}")
    return np.array([float(params[k]) for k in PARAM_NAMES], dtype=np.float64)


@numba.njit(cache=False, nogil=True, inline="always", error_model="numpy")
def _pi_gamma(xi, l1, two_fs, big_x, beta, beta_a, alpha, b, c, ea, f_big_x):
    """(Pi, gamma) of the paper shape at ``xi >= 0`` [m/N] (section 3, clipped at 1)."""
    if xi >= l1:
        return 1.0, 1.0
    z = big_x * (xi / l1)  # = 2*Fs*xi, written as jaxfric does (same rounding)
    zb = z + beta
    pw = zb**alpha
    em1 = math.expm1(b * (pw - beta_a))
    p = (-ea * em1 - c * z * z * z * z) / f_big_x
    if p >= 1.0:  # clipped part: flat, kappa = 0
        return 1.0, 1.0
    dfdz = -ea * (em1 + 1.0) * b * alpha * pw / zb - 4.0 * c * z * z * z
    kappa = two_fs * dfdz / f_big_x
    return p, p - xi * kappa


@numba.njit(cache=False, nogil=True)
def _shape_constants(p):
    """The arguments of `_pi_gamma` after ``xi``, from the packed parameters: ``l1``,
    ``2*Fs``, ``X = 2*Fs*l1``, ``beta``, ``beta**alpha``, ``alpha``, ``b``, ``c``,
    ``a*exp(b*beta**alpha)`` and ``F(X)`` (N)."""
    Fs, a, b, c, alpha, beta, l1 = p[0], p[6], p[7], p[8], p[9], p[10], p[11]
    two_fs = 2.0 * Fs
    big_x = two_fs * l1
    beta_a = beta**alpha
    ea = a * math.exp(b * beta_a)
    f_big_x = -ea * math.expm1(b * ((big_x + beta) ** alpha - beta_a)) - c * big_x**4
    return l1, two_fs, big_x, beta, beta_a, alpha, b, c, ea, f_big_x


def shape_constants(params: dict) -> tuple:
    """`_shape_constants` for a parameter dict (to call `_pi_gamma` from Python in tests)."""
    return _shape_constants(_pack(params))


@numba.njit(cache=False, nogil=True, error_model="numpy")
def _simulate_one(t, x, v, use_v, p, size, out):
    """Fill ``out`` with the force [N] along one trajectory; return the overflow count.

    ``t``, ``x`` (and ``v`` if ``use_v``) are 1-D float64 arrays; ``p`` the packed
    parameters (`PARAM_NAMES`); ``size`` the stack capacity K (>= 3).
    """
    Fs, Fc, Vs, delta = p[0], p[1], p[2], p[3]
    sigma2, C = p[4], p[5]

    # Shape constants (per trajectory, not per sample).
    l1, two_fs, big_x, beta, beta_a, alpha, b, c, ea, f_big_x = _shape_constants(p)
    dfs = Fs - Fc

    # The memory stack, bottom at index 0, top at depth - 1. Entry 0 starts as the zero state.
    sx = np.empty(size)
    sh = np.empty(size)
    ss = np.empty(size)
    sth = np.empty(size)
    scl = np.empty(size, dtype=np.bool_)
    sx[0] = x[0]
    sh[0] = 0.0
    ss[0] = 0.0
    sth[0] = 0.0
    scl[0] = False
    depth = 1
    zero_bottom = True
    overflow = 0

    last_d = 0.0  # D_{n-1}: direction of the last moving sample (0 before any motion)
    s_prev = 0.0  # S_{n-1}
    lag = 0.0  # F_l,n-1
    n = t.shape[0]
    for i in range(n):
        xn = x[i]
        dt = t[i] - t[i - 1] if i > 0 else 0.0
        if use_v:
            vn = v[i]
            dxn = xn - x[i - 1] if i > 0 else 0.0
            if vn * dxn < 0.0:  # a velocity that disagrees with the step: the step's
                vn = dxn / dt if dt > 0.0 else 0.0  # (jaxfric.motion.consistent_velocity)
        elif i > 0 and dt > 0.0:
            vn = (xn - x[i - 1]) / dt  # backward difference: sign(v) == sign(dx)
        else:
            vn = 0.0
        if vn > 0.0:
            d = 1.0
        elif vn < 0.0:
            d = -1.0
        else:
            d = 0.0
        moving = d != 0.0
        if moving:
            u = abs(vn) / Vs
            s = d * (Fc + dfs * math.exp(-(u**delta)))
        else:
            s = last_d * Fs  # at rest: the v -> 0 limit of the last motion
        reversal = moving and last_d != 0.0 and d != last_d

        # ---- Rule 1: push the reversal point (wiping-out, overflow) ----
        if reversal:
            x_r = x[i - 1]
            s_r = last_d * Fs
            top = depth - 1
            den = s_r - ss[top]
            dxr = x_r - sx[top]
            if den != 0.0:
                xi_r = dxr / den
                theta = abs(dxr) / abs(den)
            else:
                xi_r = 0.0
                theta = 0.0
            if xi_r < 0.0:
                xi_r = 0.0
            pi_r, _ = _pi_gamma(xi_r, l1, two_fs, big_x, beta, beta_a, alpha, b, c, ea, f_big_x)
            h_r = sh[top] + pi_r * den
            if theta > l1 and depth > 1:
                # wiping-out: the current branch start becomes the bottom entry
                sx[0] = sx[top]
                sh[0] = sh[top]
                ss[0] = ss[top]
                sth[0] = sth[top]
                scl[0] = scl[top]
                depth = 1
                zero_bottom = False
            if depth == size:
                # overflow: drop the oldest entry
                for j in range(size - 1):
                    sx[j] = sx[j + 1]
                    sh[j] = sh[j + 1]
                    ss[j] = ss[j + 1]
                    sth[j] = sth[j + 1]
                    scl[j] = scl[j + 1]
                depth = size - 1
                zero_bottom = False
                overflow += 1
            sx[depth] = x_r
            sh[depth] = h_r
            ss[depth] = s_r
            sth[depth] = theta
            scl[depth] = theta <= l1
            depth += 1

        # ---- Rules 2-3: loop closure cascade ----
        while depth >= 2:
            top = depth - 1
            if not scl[top]:
                break
            den = s - ss[top]
            xi_e = (xn - sx[top]) / den if den != 0.0 else 0.0
            if xi_e < sth[top]:
                break
            if top >= 2:
                depth -= 2  # Rule 2: the branch of entry top-2 continues
            elif zero_bottom:
                depth = 1  # Rule 3: back on the virgin curve
            else:
                break  # the entry below was lost to overflow or wiping

        # ---- hysteresis force (Eq. 32) ----
        top = depth - 1
        den = s - ss[top]
        xi = (xn - sx[top]) / den if den != 0.0 else 0.0
        if xi < 0.0:
            xi = 0.0
        pi_n, gamma_n = _pi_gamma(xi, l1, two_fs, big_x, beta, beta_a, alpha, b, c, ea, f_big_x)
        f_h = sh[top] + pi_n * den

        # ---- friction lag: exact decay over a step with constant S ----
        if reversal:
            lag = 0.0
        elif moving and s != 0.0:
            lag *= math.exp(-C * dt / abs(s))
        if not (moving and d != last_d):  # a direction-change step charges nothing
            lag = lag - gamma_n * (s - s_prev)

        out[i] = f_h + lag + sigma2 * vn
        s_prev = s
        if moving:
            last_d = d
    return overflow


@numba.njit(cache=False, parallel=True, error_model="numpy")
def _simulate_batch(T, X, V, use_v, p, size, out, overflow):
    for j in numba.prange(T.shape[0]):
        overflow[j] = _simulate_one(T[j], X[j], V[j], use_v, p, size, out[j])


@numba.njit(cache=False, parallel=True, error_model="numpy")
def _simulate_params(t, x, v, use_v, P, size, out, overflow):
    for j in numba.prange(P.shape[0]):
        overflow[j] = _simulate_one(t, x, v, use_v, P[j], size, out[j])


def _check_size(stack_size: int) -> int:
    size = int(stack_size)
    if size < 3:
        raise ValueError(f"stack_size must be >= 3, got {stack_size}")
    return size


def _trajectory(t, x, v):
    """One trajectory as contiguous float64 ``(t, x, v, use_v)`` (``v`` is ``x`` when not
    given, unused), with its shapes checked."""
    t = np.ascontiguousarray(t, dtype=np.float64)
    x = np.ascontiguousarray(x, dtype=np.float64)
    if t.ndim != 1 or x.shape != t.shape or t.size == 0:
        raise ValueError("t and x must be 1-D arrays of the same non-zero length")
    use_v = v is not None
    v = np.ascontiguousarray(v, dtype=np.float64) if use_v else x
    if v.shape != t.shape:
        raise ValueError("v must have the same shape as t")
    return t, x, v, use_v


def simulate_numba(params: dict, t, x, v=None, stack_size: int = 16, *, full_output=False):
    """Two-state friction force along one trajectory, N (float64, one per sample).

    **Arguments:** `params` (dict, `PARAM_NAMES`, SI); `t` times [s], strictly increasing;
    `x` positions [m]; `v` velocities [m/s] or ``None`` for the backward difference;
    `stack_size` the memory capacity K. With `full_output`, returns ``(F, overflow)``.
    No input checks beyond shapes: this is the hot path of a benchmark.
    """
    t, x, v, use_v = _trajectory(t, x, v)
    out = np.empty_like(t)
    overflow = _simulate_one(t, x, v, use_v, _pack(params), _check_size(stack_size), out)
    return (out, int(overflow)) if full_output else out


def simulate_numba_batch(params: dict, T, X, V=None, stack_size: int = 16, *,
                         full_output=False):
    """`simulate_numba` for B trajectories at once, in parallel (``numba.prange``).

    `T`, `X` (and `V`) have shape ``(B, n)``; every trajectory uses the same `params` and
    starts from the zero state at its own ``X[j, 0]``. Returns forces ``(B, n)`` in N (and
    the per-trajectory overflow counts with `full_output`). Threads: ``numba.get_num_threads()``.
    """
    T = np.ascontiguousarray(T, dtype=np.float64)
    X = np.ascontiguousarray(X, dtype=np.float64)
    if T.ndim != 2 or X.shape != T.shape:
        raise ValueError("T and X must be 2-D arrays (B, n) of the same shape")
    use_v = V is not None
    V = np.ascontiguousarray(V, dtype=np.float64) if use_v else X
    if V.shape != T.shape:
        raise ValueError("V must have the same shape as T")
    out = np.empty_like(T)
    overflow = np.zeros(T.shape[0], dtype=np.int64)
    _simulate_batch(T, X, V, use_v, _pack(params), _check_size(stack_size), out, overflow)
    return (out, overflow) if full_output else out


def simulate_numba_params(params: list[dict], t, x, v=None, stack_size: int = 16, *,
                          full_output=False):
    """`simulate_numba` for B parameter sets on one trajectory, in parallel
    (``numba.prange`` over the sets): a Monte-Carlo over parameters. Returns forces
    ``(B, n)`` in N (and the per-set overflow counts with `full_output`)."""
    t, x, v, use_v = _trajectory(t, x, v)
    P = np.stack([_pack(p) for p in params])
    out = np.empty((P.shape[0], t.size))
    overflow = np.zeros(P.shape[0], dtype=np.int64)
    _simulate_params(t, x, v, use_v, P, _check_size(stack_size), out, overflow)
    return (out, overflow) if full_output else out


def warm_up() -> float:
    """Compile both kernels (with and without a given v) on a tiny input; returns seconds."""
    import time

    t0 = time.perf_counter()
    t = np.linspace(0.0, 0.01, 11)
    x = 1e-6 * np.sin(300.0 * t)
    p = paper_params()
    simulate_numba(p, t, x)
    simulate_numba(p, t, x, np.gradient(x, t))
    simulate_numba_batch(p, np.stack([t, t]), np.stack([x, x]))
    simulate_numba_batch(p, np.stack([t, t]), np.stack([x, x]), np.stack([x, x]))
    simulate_numba_params([p, p], t, x)
    return time.perf_counter() - t0


# ---- the check against jaxfric ------------------------------------------------------------


TOL = 1e-9  # N


def _check_motions():
    """``{name: (t, x, v)}``: the built-in identification motion (nested presliding loops,
    strokes with small loops at the ends, a varying velocity), and an irregularly sampled
    mixed motion with its velocity given."""
    from jaxfric.examples import excitation

    try:  # run as a module of the repository, or as a script from its folder
        from benchmarks.motions import mixed_path
    except ImportError:
        from motions import mixed_path

    t, x = excitation(dt=2e-3)
    rng = np.random.default_rng(0)
    t2 = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, 4000))
    _, x2 = mixed_path(4000)
    x2 = np.interp(t2, 1e-3 * np.arange(4000), x2)
    return {"excitation": (t, x, None), "irregular, v given": (t2, x2, np.gradient(x2, t2))}


def check() -> list[str]:
    """The baseline against `jaxfric.simulate(paper.two_state(K), ...)`; returns the
    failures (empty: all agree)."""
    import warnings

    import jaxfric
    from jaxfric import paper

    failures = []
    model = paper.two_state()
    if params_from_model(model) != paper_params():
        failures.append("paper_params() differs from params_from_model(paper.two_state())")
    p = paper_params()
    xi = np.linspace(0.0, 1.1 * p["l1"], 1201)
    got = np.array([_pi_gamma(q, *shape_constants(p)) for q in xi])
    pi, _, gamma = model.shape.pi_kappa_gamma(xi, p["Fs"])
    for name, a, b in (("Pi", got[:, 0], pi), ("gamma", got[:, 1], gamma)):
        err = float(np.max(np.abs(a - np.asarray(b))))
        if not err < 1e-12:
            failures.append(f"shape {name} differs from jaxfric.PaperShape by {err:.3g}")
    for name, (t, x, v) in _check_motions().items():
        for size in (16, 3):  # 3 overflows on purpose: both must drop alike
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", jaxfric.StackOverflowWarning)
                ref = jaxfric.simulate(paper.two_state(size), t, x, v, full_output=True)
            force, overflow = simulate_numba(p, t, x, v, size, full_output=True)
            err = float(np.max(np.abs(force - np.asarray(ref.force))))
            print(f"{name}, stack {size}: max |F_numba - F_jaxfric| = {err:.3g} N, "
                  f"overflow {overflow} / {int(ref.overflow)}")
            if not err < TOL or overflow != int(ref.overflow) or (overflow > 0) != (size == 3):
                failures.append(f"{name}, stack {size}: error {err:.3g} N, overflow "
                                f"{overflow} vs {int(ref.overflow)}")
    t, x, _ = _check_motions()["excitation"]
    T, X = np.stack([t, t + 1.0, t]), np.stack([x, 0.5 * x, -x + 3e-6])
    F = simulate_numba_batch(p, T, X)
    if not all(np.array_equal(F[j], simulate_numba(p, T[j], X[j])) for j in range(3)):
        failures.append("the prange batch differs from one trajectory at a time")
    sets = [p, {**p, "Fs": 1.05 * p["Fs"], "l1": 0.95 * p["l1"]}, {**p, "C": 2.0 * p["C"]}]
    F = simulate_numba_params(sets, t, x)
    if not all(np.array_equal(F[j], simulate_numba(q, t, x)) for j, q in enumerate(sets)):
        failures.append("the prange over parameter sets differs from one set at a time")
    return failures


if __name__ == "__main__":
    import sys

    if sys.argv[1:] != ["--check"]:
        sys.exit("usage: python benchmarks/numba_two_state.py --check")
    problems = check()
    print("\n".join(problems) if problems else "all agree")
    sys.exit(1 if problems else 0)
