"""How noisy is the acceleration a fitted mass reads, at each sampling interval?

Without an acceleration input a model's acceleration is the backward difference of the
velocity it is given (`jaxfric.effects`, as a controller's step computes it); fits and
diagnoses of measured data give it the zero-phase estimate of `fitting.estimate_derivatives`
(the central difference, over 10 ms, of the central-difference velocity of a quantised
position). On the diagnosis bench's mass-error file (`jaxfric.synthetic.measurement`,
two-state truth, hidden ``inertia``, seed 3 as in the bench, 0.05 um encoder), for each
sampling interval and each estimate (`KINDS`): the 90th percentile of the acceleration's
slow part (a 50 ms moving mean, where it exceeds 1 % of its maximum), the standard
deviation of the rest (the noise), the mass that gives the bench's 2 N at that
acceleration, and the noise force it makes of the noise.

    python benchmarks/acceleration_noise.py [--json OUT.json]

Prints a table and writes JSON (default benchmarks/acceleration_noise.json).
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

import fitting
from jaxfric.motion import velocity
from jaxfric.synthetic import measurement


RATES = (1e-2, 5e-3, 1e-3)  # s
SMOOTH_S = 0.05  # s: the moving mean that keeps the acceleration's slow part


#: The acceleration estimates compared: the backward difference of the velocity (what a
#: model takes without an acceleration input), the central difference of neighbouring
#: samples, and `fitting.estimate_derivatives`'s default (the central difference over
#: `fitting._derivatives.ACCELERATION_WINDOW_S`).
KINDS = ("backward", "neighbours", "default")


def row(dt: float, kind: str) -> dict:
    t, x, _ = measurement("two_state_power", ("inertia",), noise=0.03, dt=dt, seed=3)
    v, a = fitting.estimate_derivatives(t, x)
    if kind == "backward":
        a = velocity(t, v)  # without a window: the backward difference
    elif kind == "neighbours":
        a = np.gradient(v, t)
    k = max(1, round(SMOOTH_S / dt))
    slow = np.convolve(a, np.ones(k) / k, mode="same")
    typical = float(np.quantile(np.abs(slow[np.abs(slow) > 0.01 * np.abs(slow).max()]), 0.9))
    noise = float(np.std(a - slow))
    mass = 2.0 / typical
    return {"dt_s": dt, "acceleration": kind,
            "samples": int(t.size), "a_p90": typical, "a_noise": noise,
            "mass_kg": mass, "noise_force_N": mass * noise}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", default=str(Path(__file__).resolve().parent
                                          / "acceleration_noise.json"))
    args = ap.parse_args(argv)
    rows = [row(dt, kind) for dt in RATES for kind in KINDS]
    print(f"{'dt [ms]':>8} {'accel.':>10} {'samples':>8} {'a p90 [m/s^2]':>14} "
          f"{'a noise [m/s^2]':>16} {'mass [kg]':>10} {'noise force [N]':>16}")
    for r in rows:
        print(f"{r['dt_s'] * 1e3:>8g} {r['acceleration']:>10} {r['samples']:>8} "
              f"{r['a_p90']:>14.3g} "
              f"{r['a_noise']:>16.3g} {r['mass_kg']:>10.3g} {r['noise_force_N']:>16.3g}")
    Path(args.json).write_text(json.dumps({"rows": rows}, indent=2) + "\n")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
