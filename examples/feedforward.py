"""Table 4 of the paper, in simulation: friction feedforward on a linear motor stage.

The paper (Sec. 6.2) compares model-based friction feedforward from Tustin's model, a
5-element GMS (Table 2), a 10-element GMS (Table 3) and the two-state model on a real
linear-motor stage, and reports the maximum position error for sinusoidal references of
5 mm, 250 um, 100 um and 50 um amplitude (6 s period). We have no stage, so this script
simulates one:

* **Plant.** A rigid mass ``m`` (default 10 kg) driven by the motor force ``u`` (ZOH over
  each controller sample) against friction: ``m*a = u - F_fric``. The "real" friction is a
  many-element GMS (`jaxfric.paper.gms(n)`, default n = 200 elements) built with
  `GMS.from_shape` from the paper's smooth presliding curve F(x) of Sec. 6.2, with the same
  Stribeck curve, sigma2 and C as the compared models. It is none of the compared models.
  Between controller samples the plant is integrated with semi-implicit (symplectic) Euler on
  ``substeps`` sub-steps (default 20, i.e. h = 50 us): the presliding stiffness is
  kappa(0) ~ 4.3e6 N/m, so the mass-on-presliding-spring frequency is
  sqrt(4.3e6/m) ~ 660 rad/s for 10 kg and omega*h ~ 0.03 (stable and accurate; the
  symplectic Euler limit is omega*h < 2).
* **Measurement.** ``y_k = x(t_k) + noise``, Gaussian white noise (default 10 nm std),
  seeded, identical for every model (common random numbers).
* **Controller** (sample time ``Ts``, default 1 ms): discrete pole-placement state feedback
  with integral action on the ZOH double integrator, closed-loop poles
  z = 0.9624, 0.9617 +- 0.0376j (paper Sec. 6.2), and a deadbeat full-state prediction
  observer (both observer poles at z = 0, as in the paper):

      xi_{k+1}  = xi_k + (y_k - r_k)
      u_k       = m*a_r(t_k) + F_ff,k - K1*(xhat_k - r_k) - K2*(vhat_k - rdot_k) - Ki*xi_k
      xhat_{k+1} = A xhat_k + B (u_k - F_ff,k) + L (y_k - xhat_k)

  The observer's model input is the command minus the friction feedforward, i.e. it models
  the stage as a friction-compensated double integrator. The paper's ZPETC and its cogging/
  ripple feedforward have no counterpart here (the simulated motor has no cogging, and the
  reference feedforward m*a_r is the exact inverse of the continuous mass).
* **Friction feedforward** from each compared model, computed offline on the *reference*
  trajectory (r, rdot) with `jaxfric.simulate`, as in the paper.
* **Reference** ``r(t) = A*sin(2*pi*t/6 s)``; two periods are simulated from rest and the
  maximum of ``|r - x|`` (true position, not the noisy measurement) is taken over the second
  period, after the start-up transient.

Run ``python examples/feedforward.py --json OUT.json [--out DIR]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxfric
from jaxfric import paper


#: Names of the compared feedforward models, in table order, and how to build them.
MODELS = {
    "tustin": paper.tustin,
    "gms5": paper.gms5,
    "gms10": paper.gms10,
    "two_state": paper.two_state,
}
#: Paper Table 4 (maximum position error, m), for comparison; Tustin only at 5 mm (Sec. 6.2).
PAPER_TABLE4 = {
    "amplitudes_m": [5e-3, 250e-6, 100e-6, 50e-6],
    "max_error_m": {
        "tustin": [75.2e-6, None, None, None],
        "gms5": [13e-6, 4.3e-6, 3.7e-6, 3e-6],
        "gms10": [11.5e-6, 3.2e-6, 2.5e-6, 2.5e-6],
        "two_state": [9.8e-6, 3e-6, 2.2e-6, 1.5e-6],
    },
}
AMPLITUDES = (5e-3, 250e-6, 100e-6, 50e-6)
POLES = (0.9624, 0.9617 + 0.0376j, 0.9617 - 0.0376j)


@dataclasses.dataclass(frozen=True)
class StageConfig:
    """The simulated stage and controller (SI units)."""

    mass: float = 10.0  # kg, moving mass of the stage
    Ts: float = 1e-3  # s, controller sample time
    substeps: int = 20  # plant integration sub-steps per controller sample
    period: float = 6.0  # s, reference period (paper: 6 s)
    n_periods: int = 2  # simulated periods; the error is measured on the last one
    noise_std: float = 10e-9  # m, position measurement noise (std)
    seed: int = 0
    plant_elements: int = 200  # elements of the "real" GMS friction
    poles: tuple = POLES

    @property
    def n_samples(self) -> int:
        return round(self.n_periods * self.period / self.Ts)


# ---- controller design --------------------------------------------------------------


def discrete_double_integrator(mass: float, Ts: float):
    """ZOH discretisation of ``m*a = u``: state (x [m], v [m/s]), input u [N]."""
    A = np.array([[1.0, Ts], [0.0, 1.0]])
    B = np.array([Ts**2 / (2 * mass), Ts / mass])
    return A, B


def _acker(A: np.ndarray, B: np.ndarray, poles) -> np.ndarray:
    """Ackermann's formula: K with eig(A - B K) = poles (single input)."""
    n = A.shape[0]
    ctrb = np.column_stack([np.linalg.matrix_power(A, i) @ B for i in range(n)])
    coeffs = np.real(np.poly(poles))  # [1, c1, ..., cn]
    phi = sum(c * np.linalg.matrix_power(A, n - i) for i, c in enumerate(coeffs))
    e_last = np.zeros(n)
    e_last[-1] = 1.0
    return e_last @ np.linalg.solve(ctrb, phi)


def controller_gains(cfg: StageConfig):
    """State-feedback gains ``(K1 [N/m], K2 [N s/m], Ki [N/(m sample)])`` and the deadbeat
    observer gain ``L`` for the prediction observer.

    Integral action: the plant is augmented with ``xi_{k+1} = xi_k + x_k`` and the three
    closed-loop poles are placed at `cfg.poles`. The observer gain puts both eigenvalues of
    ``A - L C`` at 0 (deadbeat: the estimate is exact after two samples without noise).
    """
    A, B = discrete_double_integrator(cfg.mass, cfg.Ts)
    Aa = np.block([[A, np.zeros((2, 1))], [np.array([[1.0, 0.0, 1.0]])]])
    Ba = np.concatenate([B, [0.0]])
    K = _acker(Aa, Ba, cfg.poles)
    # Observer: duality, eig(A^T - C^T L^T) = {0, 0}.
    C = np.array([1.0, 0.0])
    L = _acker(A.T, C, (0.0, 0.0))
    return K, L


def closed_loop_poles(cfg: StageConfig) -> np.ndarray:
    """Eigenvalues of the augmented loop (controller and observer): a design check."""
    A, B = discrete_double_integrator(cfg.mass, cfg.Ts)
    K, L = controller_gains(cfg)
    C = np.array([[1.0, 0.0]])
    # Full state (x, v, xi, xhat, vhat) with u = -K1 xhat - K2 vhat - Ki xi.
    Kx = K[:2][None, :]
    M = np.zeros((5, 5))
    M[:2, :2] = A
    M[:2, 3:] = -np.outer(B, Kx)
    M[:2, 2] = -B * K[2]
    M[2, 0] = 1.0
    M[2, 2] = 1.0
    M[3:, 0] = L
    M[3:, 3:] = A - np.outer(B, Kx) - np.outer(L, C)
    M[3:, 2] = -B * K[2]
    return np.linalg.eigvals(M)


# ---- reference and feedforward --------------------------------------------------------


def reference(cfg: StageConfig, amplitude):
    """``r = A sin(w t)`` and its first two derivatives at the controller samples."""
    t = jnp.asarray(np.arange(cfg.n_samples) * cfg.Ts)
    w = 2 * np.pi / cfg.period
    amplitude = jnp.asarray(amplitude)[..., None]
    return t, amplitude * jnp.sin(w * t), amplitude * w * jnp.cos(w * t), (
        -amplitude * w**2 * jnp.sin(w * t)
    )


def friction_feedforward(model, t, r, rdot):
    """Model force (N) along the reference, one row per reference: ``jaxfric.simulate`` with
    the reference velocity given (so the direction is the reference's)."""
    return jax.vmap(lambda x, v: jaxfric.simulate(model, t, x, v))(r, rdot)


# ---- closed loop ----------------------------------------------------------------------


def _stage_loop(plant, K, L, mass, Ts, substeps, r, rdot, acc, f_ff, noise):
    """One closed-loop run; returns the true position and the command at every sample."""
    A, B = discrete_double_integrator(mass, Ts)
    A, B, K, L = (jnp.asarray(a) for a in (A, B, K, L))
    h = Ts / substeps

    def substep(_, c):
        fstate, x, v, f, u = c
        # Semi-implicit Euler: velocity first, then position with the new velocity, so the
        # friction model sees a step dx whose sign is that of the v it is given.
        v = v + h * (u - f) / mass
        x = x + h * v
        fstate, f = plant.step(fstate, x, v, h)
        return fstate, x, v, f, u

    def sample(carry, inp):
        fstate, x, v, f, xhat, xi = carry
        r_k, rd_k, a_k, ff_k, n_k = inp
        y = x + n_k
        u = mass * a_k + ff_k - K[0] * (xhat[0] - r_k) - K[1] * (xhat[1] - rd_k) - K[2] * xi
        xhat = A @ xhat + B * (u - ff_k) + L * (y - xhat[0])
        xi = xi + (y - r_k)
        fstate, x, v, f, _ = jax.lax.fori_loop(0, substeps, substep, (fstate, x, v, f, u))
        return (fstate, x, v, f, xhat, xi), (x, u)

    zero = jnp.zeros(())
    carry0 = (plant.init_state(0.0), zero, zero, zero, jnp.zeros(2), zero)
    # Output x is the position at the END of each sample interval: shift to get x(t_k).
    _, (x_end, u) = jax.lax.scan(sample, carry0, (r, rdot, acc, f_ff, noise))
    x = jnp.concatenate([jnp.zeros(1), x_end[:-1]])
    return x, u


def _build(name: str, cfg: StageConfig):
    # "oracle": the plant's own friction model on the reference, i.e. the best any
    # friction feedforward computed on the reference could do (the floor set by the loop,
    # the noise and the difference between the reference and the actual motion).
    return paper.gms(cfg.plant_elements) if name == "oracle" else MODELS[name]()


def run(cfg: StageConfig = StageConfig(), amplitudes=AMPLITUDES, models=None):
    """Simulate every (model, amplitude) pair; returns a dict of results (SI units).

    `models`: names from `MODELS`, plus ``"oracle"`` (the plant's own friction as
    feedforward). Returns ``amplitudes_m``, ``max_error_m`` (model -> list over amplitudes
    of max |r - x| over the last period), and for plots and diagnostics ``t``, ``error``,
    ``command`` and ``feedforward`` (model -> array (n_amplitudes, n_samples)), and
    ``plant_on_reference`` (the plant friction along the reference, N).
    """
    names = list(MODELS if models is None else models)
    amplitudes = [float(a) for a in amplitudes]
    K, L = controller_gains(cfg)
    t, r, rdot, acc = reference(cfg, amplitudes)
    f_ff = jnp.concatenate(
        [friction_feedforward(_build(n, cfg), t, r, rdot) for n in names], axis=0
    )
    tile = lambda a: jnp.tile(a, (len(names), 1))
    noise = cfg.noise_std * jax.random.normal(jax.random.PRNGKey(cfg.seed), (cfg.n_samples,))
    plant = paper.gms(cfg.plant_elements)
    # One compiled loop, vmapped over every (model, amplitude) pair; mass, Ts and the
    # number of sub-steps are Python constants closed over (not traced).
    runner = jax.jit(
        jax.vmap(
            lambda r, rd, a, ff: _stage_loop(
                plant, K, L, cfg.mass, cfg.Ts, cfg.substeps, r, rd, a, ff, noise
            )
        )
    )
    x, u = runner(tile(r), tile(rdot), tile(acc), f_ff)
    shape = (len(names), len(amplitudes), -1)
    err = np.asarray(tile(r) - x).reshape(shape)
    last = np.asarray(t) >= (cfg.n_periods - 1) * cfg.period
    max_err = np.max(np.abs(err[:, :, last]), axis=-1)
    split = lambda a: {n: np.asarray(a).reshape(shape)[i] for i, n in enumerate(names)}
    return {
        "amplitudes_m": amplitudes,
        "max_error_m": {n: [float(e) for e in max_err[i]] for i, n in enumerate(names)},
        "t": np.asarray(t),
        "last_period": last,
        "error": split(err),
        "command": split(u),
        "feedforward": split(f_ff),
        "plant_on_reference": np.asarray(friction_feedforward(plant, t, r, rdot)),
    }


def force_diagnostics(result):
    """How far each feedforward is from the plant's friction along the same reference.

    Per model and amplitude, over the last period: the largest |F_model - F_plant| (N) and
    the largest change of the feedforward between two samples (N; the plant's own largest
    change is under ``"plant"``, or ``"oracle"`` when that was run). A model force that
    jumps at a reversal shows up in both.
    """
    last = result["last_period"]
    plant = result["plant_on_reference"]
    out = {"max_force_error_N": {}, "max_step_N": {}}
    for n, ff in result["feedforward"].items():
        err = np.max(np.abs(ff - plant)[:, last], axis=1)
        step = np.max(np.abs(np.diff(ff[:, last], axis=1)), axis=1)
        out["max_force_error_N"][n] = [float(v) for v in err]
        out["max_step_N"][n] = [float(v) for v in step]
    if "oracle" not in out["max_step_N"]:
        out["max_step_N"]["plant"] = [
            float(v) for v in np.max(np.abs(np.diff(plant[:, last], axis=1)), axis=1)
        ]
    return out


#: Stage variants for the sensitivity sweep (``--sweep``): (mass kg, Ts s).
SWEEP = ((5.0, 1e-3), (10.0, 1e-3), (20.0, 1e-3), (5.0, 5e-4), (10.0, 5e-4), (20.0, 5e-4))


# ---- reporting ------------------------------------------------------------------------


def _fmt_amp(a: float) -> str:
    return f"{a * 1e3:g} mm" if a >= 1e-3 else f"{a * 1e6:g} um"


def format_table(result, paper_values: bool = True, key: str = "max_error_m",
                 scale: float = 1e6, unit: str = "um") -> str:
    """Markdown table of ``result[key]`` (default: maximum errors in um), with the paper's
    Table 4 in parentheses when `paper_values`."""
    amps = result["amplitudes_m"]
    lines = [
        f"| model [{unit}] | " + " | ".join(_fmt_amp(a) for a in amps) + " |",
        "|---|" + "---:|" * len(amps),
    ]
    for name, errs in result[key].items():
        cells = []
        for a, e in zip(amps, errs):
            cell = f"{e * scale:.2f}"
            if paper_values and name in PAPER_TABLE4["max_error_m"]:
                p = PAPER_TABLE4["max_error_m"][name][PAPER_TABLE4["amplitudes_m"].index(a)]
                cell += f" ({p * 1e6:g})" if p is not None else " (-)"
            cells.append(cell)
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(result, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    amps = result["amplitudes_m"]
    fig, axes = plt.subplots(len(amps), 1, figsize=(8, 2.4 * len(amps)), sharex=True)
    t = result["t"]
    for j, (ax, a) in enumerate(zip(np.atleast_1d(axes), amps)):
        for name, err in result["error"].items():
            ax.plot(t, err[j] * 1e6, lw=0.8, label=name)
        ax.set_ylabel("r - x [um]")
        ax.set_title(f"amplitude {_fmt_amp(a)}", fontsize=9)
        # Tustin's error dwarfs the others: zoom on the dynamic models.
        others = [e[j] for n, e in result["error"].items() if n != "tustin"]
        if others:
            lim = 1.3e6 * max(np.max(np.abs(e[t >= t[-1] / 2])) for e in others)
            ax.set_ylim(-lim, lim)
    np.atleast_1d(axes)[0].legend(ncol=4, fontsize=8)
    np.atleast_1d(axes)[-1].set_xlabel("t [s]")
    fig.suptitle("Simulated stage: position error with friction feedforward (Tustin clipped)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _describe(cfg: StageConfig) -> str:
    K, L = controller_gains(cfg)
    return (
        f"stage: m = {cfg.mass:g} kg, Ts = {cfg.Ts * 1e3:g} ms, {cfg.substeps} plant sub-steps "
        f"(semi-implicit Euler, h = {cfg.Ts / cfg.substeps * 1e6:g} us), plant friction GMS with "
        f"{cfg.plant_elements} elements, noise {cfg.noise_std * 1e9:g} nm (seed {cfg.seed}), "
        f"{cfg.n_periods} periods of {cfg.period:g} s\n"
        f"gains K1 = {K[0]:.4g} N/m, K2 = {K[1]:.4g} N s/m, Ki = {K[2]:.4g} N/m per sample; "
        f"deadbeat observer L = ({L[0]:.4g}, {L[1]:.4g} 1/s)"
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", help="write amplitudes_m and max_error_m to this file")
    ap.add_argument("--out", help="directory for the error-trace PNG")
    ap.add_argument("--mass", type=float, default=StageConfig.mass, help="kg")
    ap.add_argument("--ts", type=float, default=StageConfig.Ts, help="controller sample time, s")
    ap.add_argument("--noise", type=float, default=StageConfig.noise_std, help="m (std)")
    ap.add_argument("--seed", type=int, default=StageConfig.seed)
    ap.add_argument("--elements", type=int, default=StageConfig.plant_elements)
    ap.add_argument("--sweep", action="store_true",
                    help="also print max errors for the stage variants in SWEEP (mass, Ts)")
    args = ap.parse_args(argv)
    cfg = StageConfig(
        mass=args.mass, Ts=args.ts, noise_std=args.noise, seed=args.seed,
        plant_elements=args.elements,
    )
    t0 = time.perf_counter()
    result = run(cfg, models=[*MODELS, "oracle"])
    elapsed = time.perf_counter() - t0
    print(_describe(cfg))
    print("\nmax |r - x| in um over the last period (paper Table 4 in parentheses; 'oracle' =")
    print("the plant's own friction model as feedforward, the floor of this loop):")
    print(format_table(result))
    diag = force_diagnostics(result)
    print("\nfeedforward force vs the plant friction along the reference, last period:")
    print("max |F_model - F_plant| [N]")
    print(format_table({"amplitudes_m": result["amplitudes_m"], **diag}, False,
                       "max_force_error_N", 1.0, "N"))
    print("largest change of the force between two samples [N]")
    print(format_table({"amplitudes_m": result["amplitudes_m"], **diag}, False,
                       "max_step_N", 1.0, "N"))
    print(f"({elapsed:.1f} s)")
    if args.json:
        payload = {
            "amplitudes_m": result["amplitudes_m"],
            "max_error_m": {n: result["max_error_m"][n] for n in MODELS},
        }
        with open(args.json, "w") as fh:
            json.dump(payload, fh, indent=2)
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        plot(result, os.path.join(args.out, "feedforward_errors.png"))
    if args.sweep:
        print("\nsensitivity: max |r - x| [um] for other stages (same noise, seed, plant):")
        for mass, ts in SWEEP:
            variant = dataclasses.replace(cfg, mass=mass, Ts=ts)
            res = run(variant)
            amps = " / ".join(_fmt_amp(a) for a in res["amplitudes_m"])
            print(f"m = {mass:g} kg, Ts = {ts * 1e3:g} ms ({amps}):")
            for n, errs in res["max_error_m"].items():
                print(f"  {n:10s} " + " ".join(f"{e * 1e6:8.2f}" for e in errs))
    return 0


if __name__ == "__main__":
    sys.exit(main())
