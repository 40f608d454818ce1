"""Worked example: a robot joint from its log (rad, N m) to a diagnosed, saved, reused model.

    python examples/rotary_joint.py [--out DIR] [--json OUT.json] [--quick]

**The joint** (`truth`, `joint_torque`): a geared joint whose friction is a 40-element GMS
with a power-law presliding curve (not a model jaxfric fits: `jaxfric.synthetic`'s
``gms_power`` family, in joint units: Fs 6 N m, Fc 4.5 N m, Vs 0.08 rad/s, viscous 2 N m
s/rad, about 1 mrad of presliding), plus what a joint's torque carries besides friction and
the friction model does not: the link's gravity ``3 cos(q + 0.5)`` N m (what is left of it
after an imperfect compensation) and a gear ripple of 80 per turn with two harmonics (0.6
and 0.2 N m). These are computed here in NumPy, not with `jaxfric.effects`.

**The log** (`record`): point-to-point moves between angles in +-1.4 rad with
minimum-jerk profiles (peak speeds 0.1 to 1.2 rad/s), dwells, and small back-and-forth
moves of +-2 mrad where the joint stays in presliding. The truth runs on a grid ten times
finer than the log's 200 Hz; the log holds the angle quantised to a 17-bit encoder on the
joint (2 pi / 2^17 = 48 urad per count) and the torque with 0.04 N m of white noise, and
no velocity (whoever uses it differentiates the angle, as on a real robot). Written as
``joint.csv`` with header ``t[s],q[rad],tau[N m]``.

**The commands** (run in-process through `fitting.cli.main.main`, as ``jaxfric ...``):

1. ``jaxfric diagnose joint.csv --json diagnosis.json``: the file is rotary (its header
   says rad and N m), so the diagnosis also screens the effects of an angle (`ripple`,
   `angle_load`) and speaks rad and N m;
2. the diagnosis JSON holds the model as fitted, effects included (``fitted_model``);
3. ``jaxfric simulate check.csv --params diagnosis.json``: the saved model reused on a
   second log of the same joint (other moves, other noise), never seen by the fit; the
   RMSE of its prediction is compared with the noise and with the baseline model's.

The script prints a table and writes `--json` (default ``rotary_joint.json`` in `--out`).
docs/rotary.md quotes the numbers of ``python examples/rotary_joint.py``. ``--quick`` (the
test's) records half the duration.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import sys
from pathlib import Path

import numpy as np


FINE = 10  # the truth runs this many times finer than the log
RATE = 200.0  # Hz, the log
COUNTS = 2**17  # encoder counts per turn, on the joint
NOISE = 0.04  # N m, torque sensor
GRAVITY = (3.0, 0.5)  # N m amplitude, phase (rad): 3 cos(q + 0.5)
GEAR = 80  # ripples per turn
RIPPLE = (0.6, 0.2)  # N m, first and second harmonic


def truth():
    """The joint's friction: a 40-element GMS with a power-law virgin curve (N m, rad)."""
    from jaxfric import GMS, PowerShape, Stribeck

    stribeck = Stribeck(Fs=6.0, Fc=4.5, Vs=0.08, delta=1.5)
    return GMS.from_shape(PowerShape(l1=1.5e-4, n=2.5), stribeck, sigma2=2.0, C=20.0, n=40)


def _min_jerk(q0, q1, duration, dt):
    s = np.arange(1, int(np.rint(duration / dt)) + 1) * dt / duration
    return q0 + (q1 - q0) * (10 * s**3 - 15 * s**4 + 6 * s**5)


def moves(seconds: float, seed: int, dt: float) -> np.ndarray:
    """Angles (rad) every `dt` s: point-to-point moves, dwells, presliding wiggles."""
    rng = np.random.default_rng(seed)
    q, out = 0.0, [np.zeros(int(0.5 / dt))]
    while len(out) < 2 or sum(a.size for a in out) * dt < seconds:
        target = rng.uniform(-1.4, 1.4)
        peak = rng.choice([0.1, 0.2, 0.4, 0.7, 1.2])
        duration = max(1.875 * abs(target - q) / peak, 0.2)  # min-jerk: peak 1.875 mean
        out.append(_min_jerk(q, target, duration, dt))
        q = target
        out.append(np.full(int(rng.uniform(0.2, 0.8) / dt), q))  # dwell
        if rng.uniform() < 0.4:  # small back-and-forth moves in presliding
            for amp in (2e-3, -2e-3, 1e-3, 0.0):
                out.append(_min_jerk(q, q + amp, 0.4, dt))
                q += amp
    return np.concatenate(out)[: int(seconds / dt)]


def joint_torque(t, q, v, ripple=RIPPLE):
    """The torque the joint's sensor sees (N m): friction plus gravity plus the ripple of
    first and second harmonic amplitudes `ripple`."""
    import jaxfric

    friction = np.asarray(jaxfric.simulate(truth(), t, q, v))
    amp, phase = GRAVITY
    gravity = amp * np.cos(q + phase)
    wave = ripple[0] * np.sin(GEAR * q + 0.4) + ripple[1] * np.cos(2 * GEAR * q - 1.0)
    return friction + gravity + wave


def record(seconds: float, seed: int, ripple=RIPPLE):
    """``(t, q, tau)``: a log as the robot records it (see the module docstring)."""
    dt = 1.0 / (RATE * FINE)
    q_fine = moves(seconds, seed, dt)
    t_fine = np.arange(q_fine.size) * dt
    tau_fine = joint_torque(t_fine, q_fine, np.gradient(q_fine, t_fine), ripple)
    keep = slice(0, None, FINE)
    count = 2 * math.pi / COUNTS
    rng = np.random.default_rng(100 + seed)
    t = t_fine[keep]
    q = np.round(q_fine[keep] / count) * count
    return t, q, tau_fine[keep] + NOISE * rng.standard_normal(t.size)


def write_csv(path: Path, t, q, tau) -> Path:
    np.savetxt(path, np.column_stack([t, q, tau]), delimiter=",",
               header="t[s],q[rad],tau[N m]", comments="", fmt="%.10g")
    return path


def jaxfric_cli(*argv: str) -> str:
    """Run ``jaxfric argv...`` in this process; its standard output (exit code 0 checked)."""
    from fitting.cli.main import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = main(list(argv))
    if rc != 0:
        raise RuntimeError(f"jaxfric {' '.join(argv)} exited with {rc}:\n{out.getvalue()}")
    return out.getvalue()


def _rmse(a, b) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


def found(diagnosis: dict) -> dict:
    """The joint effects of the diagnosed model, in the terms of the truth."""
    from jaxfric import load_model

    model = load_model(diagnosis["fitted_model"])
    out = {"added": diagnosis["after"]["added"]}
    for e in getattr(model, "effects", ()):
        if e.name == "angle_load":  # g_sin sin q + g_cos cos q = A cos(q + phi)
            g_s, g_c = float(e.g_sin), float(e.g_cos)
            out["gravity_amplitude"] = math.hypot(g_s, g_c)
            out["gravity_phase"] = math.atan2(-g_s, g_c)
        if e.name == "ripple":
            out["ripple_per_turn"] = 2 * math.pi / float(e.period)
            out["ripple_amplitudes"] = [float(a) for a in np.hypot(e.rip_sin, e.rip_cos)]
    return out


def run(out_dir: Path, quick: bool = False, ripple=RIPPLE) -> dict:
    """The worked example in `out_dir`: returns what it prints (see `main`)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    seconds = 30.0 if quick else 60.0
    joint = write_csv(out_dir / "joint.csv", *record(seconds, seed=1, ripple=ripple))
    check_t, check_q, check_tau = record(seconds / 2, seed=2, ripple=ripple)
    check = write_csv(out_dir / "check.csv", check_t, check_q, check_tau)
    diag_json = out_dir / "diagnosis.json"
    diag_text = jaxfric_cli("diagnose", str(joint), "--json", str(diag_json))
    diagnosis = json.loads(diag_json.read_text())
    sim_csv = out_dir / "simulated.csv"
    sim_text = jaxfric_cli("simulate", str(check), "--params", str(diag_json), "--out",
                           str(sim_csv))
    header = sim_csv.read_text().splitlines()[0].split(",")
    column = next(i for i, h in enumerate(header) if h.startswith("F_model"))
    predicted = np.loadtxt(sim_csv, delimiter=",", skiprows=1)[:, column]
    noise_free = joint_torque(check_t, check_q, np.gradient(check_q, check_t), ripple)
    return {
        "samples": int(np.loadtxt(joint, delimiter=",", skiprows=1).shape[0]),
        "seconds": seconds,
        "truth": {"gravity_amplitude": GRAVITY[0], "gravity_phase": GRAVITY[1],
                  "ripple_per_turn": GEAR, "ripple_amplitudes": list(ripple),
                  "noise": NOISE, "encoder_counts": COUNTS},
        "found": found(diagnosis),
        "holdout_rmse": {"baseline": diagnosis["baseline"]["rmse_holdout"],
                         "final": diagnosis["after"]["rmse_holdout"]},
        "check_rmse": _rmse(predicted, check_tau),
        "check_rmse_noise_free": _rmse(predicted, noise_free),
        "diagnose_output": diag_text,
        "simulate_output": sim_text,
    }


def table(r: dict) -> str:
    f, t = r["found"], r["truth"]
    amps = ", ".join(f"{a:.3f}" for a in f.get("ripple_amplitudes", []))
    rows = [
        ("effects added (in order)", "angle_load, ripple", ", ".join(f["added"]) or "none"),
        ("gravity amplitude [N m]", f"{t['gravity_amplitude']:.3f}",
         f"{f.get('gravity_amplitude', float('nan')):.3f}"),
        ("gravity phase [rad]", f"{t['gravity_phase']:.3f}",
         f"{f.get('gravity_phase', float('nan')):.3f}"),
        ("ripples per turn", f"{t['ripple_per_turn']}",
         f"{f.get('ripple_per_turn', float('nan')):.2f}"),
        ("ripple amplitudes [N m]", ", ".join(f"{a:.3f}" for a in t["ripple_amplitudes"]),
         amps or "-"),
    ]
    width = max(len(a) for a, _, _ in rows)
    lines = [f"{'':{width}}  {'truth':>18}  {'diagnosed':>24}"]
    lines += [f"{a:{width}}  {b:>18}  {c:>24}" for a, b, c in rows]
    h = r["holdout_rmse"]
    lines += [
        "",
        f"held-out RMSE of the diagnosis fit: baseline {h['baseline']:.4f} N m -> "
        f"final {h['final']:.4f} N m (sensor noise {t['noise']} N m)",
        f"saved model on the second log (simulate --params): RMSE {r['check_rmse']:.4f} N m "
        f"against the measured torque, {r['check_rmse_noise_free']:.4f} N m against the "
        "noise-free one",
    ]
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="rotary_joint_out", help="folder for the files")
    p.add_argument("--json", help="results JSON (default: OUT/rotary_joint.json)")
    p.add_argument("--quick", action="store_true", help="half the log (for tests)")
    p.add_argument("--ripple", default=",".join(map(str, RIPPLE)), metavar="A1,A2",
                   help="the gear ripple's harmonic amplitudes, N m (default: %(default)s)")
    args = p.parse_args(argv)
    out = Path(args.out)
    r = run(out, quick=args.quick, ripple=tuple(float(a) for a in args.ripple.split(",")))
    print(r["diagnose_output"])
    print(table(r))
    target = Path(args.json) if args.json else out / "rotary_joint.json"
    target.write_text(json.dumps({k: v for k, v in r.items() if not k.endswith("_output")},
                                 indent=2) + "\n")
    print(f"results written to {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
