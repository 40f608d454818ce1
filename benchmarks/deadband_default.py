"""The command line's default ``--deadband auto`` on clean and noisy files (issue 18, item 2).

For each file: the estimated band (`jaxfric.motion.estimate_deadband`), as a share of the
travel; the direction reversals (of the direction the models use) without a play, with
the estimate always played (what 'auto' did before it decided), and with the default
(`jaxfric.motion.deadband_choice`: played only when `CHATTER_RUN` or more reversals in a
row are within the band), with the decision and its reason; how much the play changes the
force of a data-derived two-state model (`fitting.initial_model`, simulated with the
file's positions raw and played), as an RMS against the RMS force; and the memory stack's
overflow. Files: clean ones (the demo's, a foreign-truth synthetic file with a 0.05 um
encoder, the rotary example's joint log with a 17-bit encoder, the EMPS estimation file
and the tribometer file of ../shared/data if present) and noisy standstills (moves of 2
mm with 1 s rests, 1 um position noise: 3 true reversals; once more quantised to 4 um with
a velocity column of 1 mm/s noise, as a robot logs it), where an 8-slot two-state model
is used.

    python benchmarks/deadband_default.py [--json out.json]

Prints a table and writes JSON (default benchmarks/deadband_default.json).
"""

import argparse
import json
import warnings
from pathlib import Path

import numpy as np

import fitting
import jaxfric
from jaxfric import paper
from jaxfric.motion import (
    consistent_velocity,
    deadband_choice,
    estimate_deadband,
    play,
    played_velocity,
    reversals,
)


SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _reversals(t, x, v=None) -> int:
    """Reversals of the direction the models use (`consistent_velocity` with a `v`)."""
    dx, dt = np.r_[0.0, np.diff(x)], np.r_[0.0, np.diff(t)]
    d = np.sign(dx if v is None else np.asarray(consistent_velocity(v, dx, dt)))
    return int(np.count_nonzero(reversals(d)[0]))


def _files():
    """``(name, t, x, v or None, F, standstill)`` of each file."""
    import sys

    from fitting.cli.demo import example_measurement
    from jaxfric.synthetic import measurement

    t, x, F, _ = example_measurement()
    yield "demo", t, x, None, F, False
    t, x, F = measurement("gms_power", (), noise=0.03, dt=1e-2, seed=0)
    yield "synthetic gms_power (0.05 um encoder)", t, x, None, F, False
    sys.path.insert(0, str(EXAMPLES))
    from rotary_joint import record

    t, q, tau = record(60.0, 1)  # the log docs/rotary.md diagnoses
    yield "rotary example joint log (17 bit)", t, q, None, tau, False
    for name, force in (("emps_estimation.csv", "u"), ("tribometer.csv", "F")):
        path = SHARED / name
        if path.is_file():
            d = np.genfromtxt(path, delimiter=",", names=True)
            yield f"shared/{name}", d["t"], d["x"], None, d[force], False
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 7.0, 1e-3)
    x_true = np.interp(t, [0, 1, 2, 3, 4, 5, 6, 7], [0, 2e-3, 2e-3, 0, 0, 2e-3, 2e-3, 0])
    x = x_true + 1e-6 * rng.standard_normal(t.size)
    F = np.asarray(jaxfric.simulate(paper.tustin(), t, x_true))
    yield "noisy standstill (3 true reversals)", t, x, None, F, True
    x = 4e-6 * np.round(x / 4e-6)
    v = np.gradient(x_true, t) + 1e-3 * rng.standard_normal(t.size)
    yield "same, 4 um encoder + noisy v column", t, x, v, F, True


def _simulate(model, t, x, v, b):
    """The model's result along the motion played through `b` (None: unplayed), the way
    the command line plays it (`fitting.cli._signals.played_measurement`)."""
    if b is not None:
        x = np.asarray(play(x, b))
        v = None if v is None else np.asarray(played_velocity(x, v))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return jaxfric.simulate(model, t, x, v, full_output=True), x, v


def _row(name, t, x, v, F, standstill):
    b = estimate_deadband(x)
    choice = deadband_choice(x, v, t)
    if standstill:
        model = paper.two_state(stack_size=8)
    else:
        model = fitting.initial_model("two-state", t, x, F, fitting.estimate_velocity(t, x))
    raw, _, _ = _simulate(model, t, x, v, None)
    played, p, pv = _simulate(model, t, x, v, b)
    default, d, dv = _simulate(model, t, x, v, choice.deadband)
    f_raw = np.asarray(raw.force)
    rms = float(np.sqrt(np.mean(f_raw**2)))

    def change(r):
        return float(np.sqrt(np.mean((np.asarray(r.force) - f_raw) ** 2))) / rms

    return {
        "file": name, "samples": int(t.size), "deadband": b,
        "deadband_share_of_travel": b / float(np.ptp(x)),
        "max_position_change": float(np.max(np.abs(p - x))),
        "reversals_none": _reversals(t, x, v), "reversals_auto": _reversals(t, p, pv),
        "force_change_rms_share": change(played),
        "overflow_none": int(raw.overflow), "overflow_auto": int(played.overflow),
        "default": {
            "applied": choice.deadband is not None, "deadband": choice.deadband,
            "reason": choice.reason, "within_band": choice.within_band,
            "longest_run": choice.longest_run, "reversals": _reversals(t, d, dv),
            "force_change_rms_share": change(default), "overflow": int(default.overflow),
        },
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", default=str(Path(__file__).with_suffix(".json")))
    args = ap.parse_args(argv)
    rows = [_row(*f) for f in _files()]
    print("'always': the estimate always played (the old 'auto'); 'default': the command "
          "line's default 'auto' (played only when it decides so)")
    print(f"{'file':<38} {'band':>9} {'b/travel':>9} {'rev none':>8} {'always':>7} "
          f"{'dF':>8} {'default':>8} {'rev':>5} {'dF':>8} {'ovf none':>8} {'always':>7} "
          f"{'default':>8}")
    for r in rows:
        d = r["default"]
        print(f"{r['file']:<38} {r['deadband']:>9.3g} {r['deadband_share_of_travel']:>9.2g} "
              f"{r['reversals_none']:>8d} {r['reversals_auto']:>7d} "
              f"{r['force_change_rms_share']:>8.2g} {'played' if d['applied'] else 'none':>8} "
              f"{d['reversals']:>5d} {d['force_change_rms_share']:>8.2g} "
              f"{r['overflow_none']:>8d} {r['overflow_auto']:>7d} {d['overflow']:>8d}")
    for r in rows:
        print(f"  {r['file']}: {r['default']['reason']}")
    Path(args.json).write_text(json.dumps({"rows": rows}, indent=1) + "\n")
    print(f"JSON written to {args.json}")


if __name__ == "__main__":
    main()
