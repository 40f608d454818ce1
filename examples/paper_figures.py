"""Reproduce the simulation results of the paper (Sec. 6.1, Figs. 5-8) with jaxfric.

Each figure has a computing function that returns its curves and the numbers checked in
``tests/core/test_paper_results.py`` (SI units; plots in um and N):

* `presliding_hysteresis` (Fig. 5): a slow constant-speed triangle in presliding; the
  two-state model's branches bend smoothly, the 5-element GMS (Table 2) is piecewise linear.
  Checked: the number of slope discontinuities on a branch and the largest jump of the local
  slope dF/dx between neighbouring samples, at grid steps h and 5h (a continuous slope gives
  a jump that shrinks with h; a kink gives one that does not).
* `nonlocal_memory` (Fig. 6): inner loops opened on the rising and on the falling branch of a
  presliding loop close, and the force goes back onto the main loop. Checked: the largest
  force difference after closure against the same main loop traversed without inner loops.
* `friction_lag` (Fig. 7): v(t) = v0 + v1 sin(2 pi t / T) > 0 gives a force-velocity loop
  around the Stribeck curve. Checked: loop area (closed integral of F dv over one period,
  positive when the force is higher while accelerating), and how much of the Stribeck curve
  lies between the two branches.
* `non_drift` (Fig. 8): a 1 kg mass with friction under the applied force of the paper's
  test (a ramp above breakaway, a drop below Coulomb, then an oscillation that never reaches
  breakaway); two-state model beside LuGre. Checked: the drift of the position per period
  of the oscillation.

Closed loops (Fig. 8) call ``model.step`` inside ``jax.lax.scan``: ``m*dv/dt = F_app - F``
integrated with semi-implicit (symplectic) Euler, ``v += dt*(F_app - F)/m; x += dt*v``, then
``F = model.step(state, x, v, dt)``. The step size is set by the stiffest part, presliding:
kappa(0) ~ 4.3e6 N/m with m = 1 kg gives omega ~ 2.1e3 rad/s, and dt = 20 us gives
omega*dt ~ 0.04 (symplectic Euler is stable below 2; halving dt changes the positions by
less than 0.3 um on a 2 mm slide).

Run ``python examples/paper_figures.py [--out docs/figures] [--json OUT.json]``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxfric
from jaxfric import paper


UM = 1e-6


def constant_speed_path(turns, h: float, speed: float):
    """A motion through the turning points `turns` (m) at constant `speed` (m/s), sampled
    every `h` metres (each leg must be a whole number of steps). Returns ``t, x, v``: the
    velocity is given explicitly (its sign is the direction of the step into each sample)."""
    xs = [float(turns[0])]
    vs = [0.0]
    for a, b in itertools.pairwise(turns):
        n = round(abs(b - a) / h)
        xs.extend(np.linspace(a, b, n + 1)[1:])
        vs.extend([np.sign(b - a) * speed] * n)
    x = np.asarray(xs)
    t = np.arange(x.size) * (h / speed)
    return t, x, np.asarray(vs)


def _sim(model, t, x, v):
    return np.asarray(jaxfric.simulate(model, t, x, v))


# ---- Fig. 5: presliding hysteresis, smooth vs piecewise linear ------------------------


def slope_discontinuities(x, F, window: float = 2 * UM, factor: float = 20.0):
    """Kinks of a curve F(x) sampled on a uniform grid.

    The local slope is ``dF/dx`` per interval; a kink is a jump of it between neighbouring
    intervals that stands out: more than `factor` times the median jump within +-`window`
    (and above 1e-6 of the initial slope, to ignore round-off). A smooth curve has jumps that
    vary slowly along x, so none stands out; a piecewise-linear one has exact zeros between
    its kinks. Returns (number of kinks, their x positions, slope, |jump| per sample).
    """
    slope = np.diff(F) / np.diff(x)
    jump = np.abs(np.diff(slope))
    w = max(round(window / abs(x[1] - x[0])), 1)
    padded = np.pad(jump, w, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * w + 1)
    local = np.median(windows, axis=1)
    kink = jump > np.maximum(factor * local, 1e-6 * abs(slope[0]))
    # A kink falling inside one sample interval shows as two neighbouring jumps: count runs.
    starts = kink & ~np.concatenate([[False], kink[:-1]])
    return int(starts.sum()), x[1:-1][starts], slope, jump


def presliding_hysteresis(amplitude: float = 80 * UM, h: float = 0.02 * UM, speed: float = 20 * UM):
    """Fig. 5: 0 -> A -> -A -> A at constant speed (A < X/2 ~ 112 um: presliding only)."""
    t, x, v = constant_speed_path(np.array([0.0, 1.0, -1.0, 1.0]) * amplitude, h, speed)
    models = {"two_state": paper.two_state(), "gms5": paper.gms5()}
    out = {"x": x, "force": {}, "branch": {}, "metrics": {}}
    # The rising branch starts at the reversal at -A; its first sample after the reversal
    # is the branch start (the reversal sample itself carries the model's Rule-1 step).
    start = int(np.argmin(x)) + 1
    for name, model in models.items():
        F = _sim(model, t, x, v)
        xb, Fb = x[start:], F[start:]
        n_kinks, at, slope, jump = slope_discontinuities(xb, Fb)
        coarse = np.abs(np.diff(np.diff(Fb[::5]) / np.diff(xb[::5])))
        out["force"][name] = F
        out["branch"][name] = {"x": xb, "slope": slope}
        out["metrics"][name] = {
            "slope_discontinuities": n_kinks,
            "kink_offsets_um": [float(a) for a in (at - xb[0]) / UM],
            "initial_slope_N_per_m": float(slope[0]),
            "max_slope_jump_N_per_m": {"h": float(jump.max()), "5h": float(coarse.max())},
        }
    out["settings"] = {"amplitude_m": amplitude, "h_m": h, "speed_m_per_s": speed}
    return out


# ---- Fig. 6: nonlocal memory ---------------------------------------------------------


def nonlocal_memory(amplitude: float = 80 * UM, h: float = 0.05 * UM, speed: float = 20 * UM):
    """Fig. 6: a main presliding loop +-A with an inner loop on each branch.

    Path (um, A = 80): 0, 80, -80, 20, -30, 80 (inner loop 20 -> -30 -> 20 on the rising
    branch), -10, 40, -80 (inner loop -10 -> 40 -> -10 on the falling branch). The reference
    is the same main loop without inner loops: 0, 80, -80, 80, -80. After each inner loop
    closes, the force must be back on the reference branch.
    """
    a = amplitude / (80 * UM)
    turns = np.array([0, 80, -80, 20, -30, 80, -10, 40, -80]) * UM * a
    ref_turns = np.array([0, 80, -80, 80, -80]) * UM * a
    model = paper.two_state()
    t, x, v = constant_speed_path(turns, h, speed)
    tr, xr, vr = constant_speed_path(ref_turns, h, speed)
    F = _sim(model, t, x, v)
    Fr = _sim(model, tr, xr, vr)

    def leg(xs, vs, i):
        """Index range of leg i (between turning points i and i+1)."""
        turns_at = np.nonzero(np.diff(np.sign(vs[1:])) != 0)[0] + 1
        bounds = np.concatenate([[0], turns_at, [len(xs) - 1]])
        return bounds[i] + 1, bounds[i + 1] + 1

    errors = []
    checks = [
        # (leg of the path, part after closure, leg of the reference, direction)
        (4, (turns[3], turns[5]), 2),  # rising from -30 up to 80: closes at 20
        (7, (turns[8], turns[6]), 3),  # falling from 40 down to -80: closes at -10
    ]
    for i_leg, (lo, hi), i_ref in checks:
        i0, i1 = leg(x, v, i_leg)
        j0, j1 = leg(xr, vr, i_ref)
        xs, Fs_ = x[i0:i1], F[i0:i1]
        keep = (xs > min(lo, hi) + h / 2) & (xs < max(lo, hi) - h / 2)
        xb, Fb = xr[j0:j1], Fr[j0:j1]
        order = np.argsort(xb)
        ref_at = np.interp(xs[keep], xb[order], Fb[order])
        errors.append(float(np.max(np.abs(Fs_[keep] - ref_at))))
    return {
        "x": x,
        "force": F,
        "x_ref": xr,
        "force_ref": Fr,
        "metrics": {
            "closure_error_N": max(errors),
            "closure_error_per_loop_N": errors,
            "loop_force_range_N": float(Fr.max() - Fr.min()),
        },
        "settings": {"turns_m": [float(u) for u in turns], "h_m": h, "speed_m_per_s": speed},
    }


# ---- Fig. 7: friction lag -------------------------------------------------------------


def friction_lag(v0: float = 3e-3, v1: float = 2.5e-3, period: float = 30.0, dt: float = 2e-3,
                 n_periods: int = 3, model=None):
    """Fig. 7: ``v = v0 + v1 sin(2 pi t/T)`` (always > 0), integrated exactly to x.

    The lag time constant is ``|s|/C`` ~ 2.2 s, so T = 30 s (omega*tau ~ 0.45) gives a wide
    loop that still follows the Stribeck curve; a faster oscillation (T = 10 s) gives a
    flatter loop that the Stribeck curve crosses (the force cannot follow it any more).
    Returns the force-velocity loop of the last period, the steady Stribeck curve
    ``s(v) + sigma2 v`` on the same velocities, the loop area and the fraction of the
    velocity range where the Stribeck curve lies between the falling and rising branches.
    """
    model = paper.two_state() if model is None else model
    t = np.arange(round(n_periods * period / dt)) * dt
    w = 2 * np.pi / period
    v = v0 + v1 * np.sin(w * t)
    x = v0 * t + v1 * (1 - np.cos(w * t)) / w
    F = _sim(model, t, x, v)
    last = t >= (n_periods - 1) * period
    vl, Fl = v[last], F[last]
    # Closed integral of F dv over one period (trapezoid, closing the loop).
    vc, Fc_ = np.append(vl, vl[0]), np.append(Fl, Fl[0])
    area = float(np.sum(0.5 * (Fc_[1:] + Fc_[:-1]) * np.diff(vc)))
    st = model.stribeck
    steady = np.asarray(st(jnp.asarray(vl))) + float(model.sigma2) * vl
    accelerating = np.gradient(vl) > 0
    grid = np.linspace(vl.min(), vl.max(), 202)[1:-1]

    def branch(mask):
        order = np.argsort(vl[mask])
        return np.interp(grid, vl[mask][order], Fl[mask][order])

    up, down = branch(accelerating), branch(~accelerating)
    s_grid = np.asarray(st(jnp.asarray(grid))) + float(model.sigma2) * grid
    inside = float(np.mean((down < s_grid) & (s_grid < up)))
    return {
        "v": vl,
        "force": Fl,
        "stribeck": steady,
        "metrics": {
            "loop_area_N_m_per_s": area,
            "mean_branch_gap_N": float(area / (vl.max() - vl.min())),
            "stribeck_between_branches_fraction": inside,
        },
        "settings": {"v0": v0, "v1": v1, "period_s": period, "dt_s": dt},
    }


# ---- Fig. 8: non-drifting -------------------------------------------------------------


def applied_force(t, F_peak=28.0, t_ramp=1.0, F0=18.0, dF=6.0, freq=1.0):
    """The test force (N): a ramp 0 -> `F_peak` (> Fs = 26.1 N) over `t_ramp`, then at once
    ``F0 + dF sin(2 pi freq (t - t_ramp))`` with ``F0 < Fc = 21.6 N`` and ``F0 + dF < Fs``."""
    t = np.asarray(t)
    return np.where(
        t < t_ramp, F_peak * t / t_ramp, F0 + dF * np.sin(2 * np.pi * freq * (t - t_ramp))
    )


def mass_with_friction(model, force, dt: float, mass: float = 1.0):
    """Closed loop ``mass * dv/dt = force - F_friction`` from rest at x = 0.

    Semi-implicit Euler with the friction model advanced by ``model.step`` after every
    position update (so the friction sees a step whose sign is that of its velocity input).
    Returns (x, v, friction, final model state), one entry per sample of `force`.
    """

    def body(carry, f_app):
        state, x, v, f = carry
        v = v + dt * (f_app - f) / mass
        x = x + dt * v
        state, f = model.step(state, x, v, dt)
        return (state, x, v, f), (x, v, f)

    zero = jnp.zeros(())
    carry0 = (model.init_state(0.0), zero, zero, zero)
    run = jax.jit(lambda c, f: jax.lax.scan(body, c, f))
    (state, *_), (x, v, f) = run(carry0, jnp.asarray(force))
    return np.asarray(x), np.asarray(v), np.asarray(f), state


def non_drift(n_periods: int = 10, dt: float = 2e-5, mass: float = 1.0, stack_size: int = 64,
              force_kwargs=None):
    """Fig. 8: two-state model beside LuGre under `applied_force`.

    The drift is measured on the position sampled once per force period (same phase):
    ``(x[last] - x[after the first period]) / (n_periods - 1)`` in m per period. The first
    period is excluded: it contains the stop after the slide.
    """
    kw = {"F_peak": 28.0, "t_ramp": 1.0, "F0": 18.0, "dF": 6.0, "freq": 1.0}
    kw.update(force_kwargs or {})
    t_end = kw["t_ramp"] + n_periods / kw["freq"]
    t = np.arange(round(t_end / dt) + 1) * dt
    f_app = applied_force(t, **kw)
    models = {"two_state": paper.two_state(stack_size), "lugre": paper.lugre()}
    out = {"t": t, "applied": f_app, "x": {}, "friction": {}, "metrics": {}}
    period_idx = np.round((kw["t_ramp"] + np.arange(n_periods + 1) / kw["freq"]) / dt).astype(int)
    for name, model in models.items():
        x, v, f, state = mass_with_friction(model, f_app, dt, mass)
        xp = x[period_idx]
        osc = t >= kw["t_ramp"] + (n_periods - 1) / kw["freq"]
        d = np.sign(v)
        reversals = int(np.sum((d[1:] * d[:-1] < 0) & (t[1:] > kw["t_ramp"])))
        out["x"][name] = x
        out["friction"][name] = f
        m = {
            "drift_m_per_period": float((xp[-1] - xp[1]) / (n_periods - 1)),
            "slide_m": float(xp[0]),
            "last_period_peak_to_peak_m": float(np.ptp(x[osc])),
            "velocity_reversals_after_drop": reversals,
        }
        if name == "two_state":
            m["stack_overflow"] = int(state.stack.overflow)
        out["metrics"][name] = m
    out["settings"] = {"mass_kg": mass, "dt_s": dt, "integrator": "semi-implicit Euler",
                       "n_periods": n_periods, "stack_size": stack_size, **kw}
    return out


# ---- plots and CLI --------------------------------------------------------------------


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_fig5(r, path):
    plt = _plt()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    styles = {
        "two_state": {"color": "C3", "label": "two-state"},
        "gms5": {"color": "C0", "label": "GMS, 5 elements (Table 2)"},
    }
    for name, F in r["force"].items():
        ax1.plot(r["x"] / UM, F, lw=1.2, **styles[name])
        b = r["branch"][name]
        ax2.plot((b["x"][1:] - b["x"][0]) / UM, b["slope"] / 1e6, lw=1.2, **styles[name])
    ax1.set_xlabel("x [um]")
    ax1.set_ylabel("F [N]")
    ax1.set_title("presliding hysteresis (0 -> 80 -> -80 -> 80 um)", fontsize=9)
    ax1.legend(fontsize=8)
    ax2.set_xlabel("x - x_reversal on the rising branch [um]")
    ax2.set_ylabel("dF/dx [N/um]")
    ax2.set_title("local slope: continuous vs piecewise constant", fontsize=9)
    fig.suptitle("Fig. 5 analogue")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_fig6(r, path):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot(r["x_ref"] / UM, r["force_ref"], "k--", lw=1, label="main loop alone")
    ax.plot(r["x"] / UM, r["force"], color="C3", lw=1.2, label="with inner loops")
    ax.set_xlabel("x [um]")
    ax.set_ylabel("F [N]")
    ax.set_title(f"Fig. 6 analogue: nonlocal memory (closure error "
                 f"{r['metrics']['closure_error_N'] * 1e3:.2g} mN)", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_fig7(r, path):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    order = np.argsort(r["v"])
    ax.plot(r["v"][order] * 1e3, r["stribeck"][order], "k--", lw=1, label="s(v) + sigma2 v")
    ax.plot(r["v"] * 1e3, r["force"], color="C3", lw=1.2, label="two-state")
    ax.set_xlabel("v [mm/s]")
    ax.set_ylabel("F [N]")
    st = r["settings"]
    ax.set_title(f"Fig. 7 analogue: friction lag, v = {st['v0'] * 1e3:g} + {st['v1'] * 1e3:g} "
                 f"sin(2 pi t / {st['period_s']:g} s) mm/s", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_fig8(r, path):
    plt = _plt()
    fig, (ax1, ax2, ax3) = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    t = r["t"]
    st = r["settings"]
    ax1.plot(t, r["applied"], "k", lw=1)
    ax1.axhline(26.1, color="gray", ls=":", lw=0.8)
    ax1.axhline(21.6, color="gray", ls="--", lw=0.8)
    ax1.text(0.02, 26.6, "Fs", fontsize=8)
    ax1.text(0.02, 20.2, "Fc", fontsize=8)
    ax1.set_ylabel("F applied [N]")
    # Drift is read from the end of the first oscillation period on (the stop after the
    # slide is over by then).
    i1 = round((st["t_ramp"] + 1.0 / st["freq"]) / st["dt_s"])
    labels = {"two_state": ("C3", "two-state"), "lugre": ("C0", "LuGre")}
    for name, x in r["x"].items():
        c, lab = labels[name]
        drift = r["metrics"][name]["drift_m_per_period"] / UM
        ax2.plot(t, x * 1e3, color=c, lw=1, label=lab)
        ax3.plot(t[i1:], (x[i1:] - x[i1]) / UM, color=c, lw=1,
                 label=f"{lab}: drift {drift:.3g} um/period")
    ax2.set_ylabel("x [mm]")
    ax2.legend(fontsize=8)
    ax3.set_xlabel("t [s]")
    ax3.set_ylabel("x - x(t_ramp + 1 period) [um]")
    ax3.legend(fontsize=8)
    fig.suptitle(f"Fig. 8 analogue: non-drifting ({st['mass_kg']:g} kg mass, dt = "
                 f"{st['dt_s'] * 1e6:g} us, semi-implicit Euler)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/figures", help="directory for the PNGs")
    ap.add_argument("--json", help="write the checked numbers to this JSON file")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    results = {}
    jobs = [
        ("fig5_presliding", presliding_hysteresis, plot_fig5),
        ("fig6_nonlocal_memory", nonlocal_memory, plot_fig6),
        ("fig7_friction_lag", friction_lag, plot_fig7),
        ("fig8_non_drift", non_drift, plot_fig8),
    ]
    for name, compute, plot in jobs:
        t0 = time.perf_counter()
        r = compute()
        plot(r, os.path.join(args.out, f"{name}.png"))
        results[name] = {"metrics": r["metrics"], "settings": r["settings"]}
        print(f"{name} ({time.perf_counter() - t0:.1f} s)")
        print(json.dumps(r["metrics"], indent=2))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
