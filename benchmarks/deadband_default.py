"""Should ``--deadband auto`` be the command line's default? (issue 18, item 2)

For each file: the estimated deadband (`jaxfric.motion.estimate_deadband`), as a share of
the travel; the direction reversals of the backward-difference direction signal without
and with the play; and how much the play changes the force of a data-derived two-state
model (`fitting.initial_model`, simulated with the file's positions raw and played), as
an RMS against the RMS force. Files: clean ones (the demo's, a foreign-truth synthetic
file with a 0.05 um encoder, the EMPS estimation file and the tribometer file of
../shared/data if present) and a noisy standstill (moves of 2 mm with 1 s rests, 1 um
position noise: 3 true reversals), where the memory stack of an 8-slot two-state model
is counted for overflow.

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
from jaxfric.motion import estimate_deadband, play, reversals


SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


def _reversals(x) -> int:
    return int(np.count_nonzero(reversals(np.sign(np.r_[0.0, np.diff(x)]))[0]))


def _files():
    from fitting.cli.demo import example_measurement
    from jaxfric.synthetic import measurement

    t, x, F, _ = example_measurement()
    yield "demo", t, x, F, False
    t, x, F = measurement("gms_power", (), noise=0.03, dt=1e-2, seed=0)
    yield "synthetic gms_power (0.05 um encoder)", t, x, F, False
    for name, force in (("emps_estimation.csv", "u"), ("tribometer.csv", "F")):
        path = SHARED / name
        if path.is_file():
            d = np.genfromtxt(path, delimiter=",", names=True)
            yield f"shared/{name}", d["t"], d["x"], d[force], False
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 7.0, 1e-3)
    x_true = np.interp(t, [0, 1, 2, 3, 4, 5, 6, 7], [0, 2e-3, 2e-3, 0, 0, 2e-3, 2e-3, 0])
    x = x_true + 1e-6 * rng.standard_normal(t.size)
    F = np.asarray(jaxfric.simulate(paper.tustin(), t, x_true))
    yield "noisy standstill (3 true reversals)", t, x, F, True


def _row(name, t, x, F, standstill):
    b = estimate_deadband(x)
    p = np.asarray(play(x, b)) if b > 0 else x
    if standstill:
        model = paper.two_state(stack_size=8)
    else:
        v = fitting.estimate_velocity(t, x)
        model = fitting.initial_model("two-state", t, x, F, v)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raw = jaxfric.simulate(model, t, x, full_output=True)
        played = jaxfric.simulate(model, t, p, full_output=True)
    f_raw, f_played = np.asarray(raw.force), np.asarray(played.force)
    return {
        "file": name, "samples": int(t.size), "deadband": b,
        "deadband_share_of_travel": b / float(np.ptp(x)),
        "max_position_change": float(np.max(np.abs(p - x))),
        "reversals_none": _reversals(x), "reversals_auto": _reversals(p),
        "force_change_rms_share": float(np.sqrt(np.mean((f_played - f_raw) ** 2))
                                        / np.sqrt(np.mean(f_raw**2))),
        "overflow_none": int(raw.overflow), "overflow_auto": int(played.overflow),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", default=str(Path(__file__).with_suffix(".json")))
    args = ap.parse_args(argv)
    rows = [_row(*f) for f in _files()]
    print(f"{'file':<40} {'b_auto':>10} {'b/travel':>9} {'rev none':>9} {'rev auto':>9} "
          f"{'dF rms':>9} {'ovf none':>9} {'ovf auto':>9}")
    for r in rows:
        print(f"{r['file']:<40} {r['deadband']:>10.3g} {r['deadband_share_of_travel']:>9.2g} "
              f"{r['reversals_none']:>9d} {r['reversals_auto']:>9d} "
              f"{r['force_change_rms_share']:>9.2g} {r['overflow_none']:>9d} "
              f"{r['overflow_auto']:>9d}")
    Path(args.json).write_text(json.dumps({"rows": rows}, indent=1) + "\n")
    print(f"JSON written to {args.json}")


if __name__ == "__main__":
    main()
