"""Self-check of the NumPy reference (`tests/reference.py`) against properties of the
specification alone (shapes, loop closure, steady state, ...): ``python -m
tests.reference_check`` prints each check and exits 1 if one fails."""

import itertools

import numpy as np

from .reference import (
    _paper_F,
    gms,
    gms_from_shape_elements,
    lugre,
    PAPER_C,
    paper_gamma,
    paper_kappa,
    paper_pi,
    PAPER_SHAPE,
    PAPER_SIGMA2,
    PAPER_STRIBECK,
    power_gamma,
    power_kappa,
    power_pi,
    prepare,
    stribeck,
    tustin,
    two_state,
)


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
