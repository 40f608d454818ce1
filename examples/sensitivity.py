"""Monte-Carlo sensitivity: how uncertain is a fitted model's force?

A fit gives its parameters' covariance (`FitResult.cov_fit`, from the Jacobian at the
optimum). This script turns it into a spread of the predicted force:

1. a measurement that jaxfric did not make (`jaxfric.synthetic.measurement`: a 60-element
   GMS with a power-law virgin curve, 0.05 um encoder, 10 ms sampling, noise), with the
   velocity by central difference as a user would estimate it;
2. a fit of the two-state model (`fitting.fit`);
3. `fitting.monte_carlo(result.model, t, x, v, param_sigma=result, refit=False)`: `num`
   parameter sets drawn from the fit's covariance, all simulated along the motion in one
   vectorised call (`jax.vmap` of `simulate`);
4. the band (5 % to 95 % of the draws) against the measured force, where it is widest, and
   the time of the Monte-Carlo step (first call with compilation, then warm; median of
   `--repeats`).

Run ``python examples/sensitivity.py [--num 256] [--out DIR]``: prints a summary, writes
``DIR/sensitivity.json`` and ``DIR/sensitivity.png`` (default ``docs/figures``).
"""

import argparse
import json
import sys
import time
from pathlib import Path

import jax
import matplotlib
import numpy as np


matplotlib.use("Agg")
import matplotlib.pyplot as plt

import fitting
from jaxfric.synthetic import measurement


def run(num: int = 256, noise: float = 0.05, seed: int = 3, repeats: int = 3,
        max_steps: int = 200) -> dict:
    """Fit, draw `num` models from the fit's covariance, simulate them; the numbers."""
    t, x, F = measurement("gms_power", (), noise=noise, dt=1e-2, seed=seed)
    v = fitting.estimate_velocity(t, x)
    start = fitting.initial_model("two-state", t, x, F, v)
    t0 = time.perf_counter()
    res = fitting.fit(start, t, x, F, v, max_steps=max_steps)
    fit_time = time.perf_counter() - t0

    times = []
    for k in range(repeats + 1):
        t0 = time.perf_counter()
        mc = fitting.monte_carlo(res.model, t, x, v, key=jax.random.key(k), num=num,
                                 param_sigma=res, refit=False)
        jax.block_until_ready(mc.force)
        times.append(time.perf_counter() - t0)
    width = np.asarray(mc.force_q95 - mc.force_q05)
    return {
        "samples": int(t.size),
        "draws": num,
        "fit": {"rmse_N": float(res.rmse), "status": str(res.status),
                "seconds": fit_time},
        "stderr_rel": {k: float(res.stderr[k] / abs(res.params[k]))
                       for k in res.params if float(res.params[k]) != 0.0},
        "band_90_N": {"median": float(np.median(width)), "max": float(np.max(width)),
                      "where_max_s": float(t[int(np.argmax(width))])},
        "noise_N": noise,
        "monte_carlo_seconds": {"first_call": times[0],
                                "warm_median": float(np.median(times[1:]))},
        "_arrays": (t, F, np.asarray(res.prediction), np.asarray(mc.force_q05),
                    np.asarray(mc.force_q95)),
    }


def plot(out: dict, path: Path) -> None:
    t, F, pred, lo, hi = out["_arrays"]
    width = hi - lo
    k = int(np.argmax(width))
    zoom = slice(max(k - 150, 0), k + 150)
    fig, axes = plt.subplots(2, 1, figsize=(9, 6.5))
    for ax, sl, title in ((axes[0], slice(None), "whole record"),
                          (axes[1], zoom, "where the band is widest")):
        ax.plot(t[sl], F[sl], ".", ms=2, color="0.6", label="measured")
        ax.fill_between(t[sl], lo[sl], hi[sl], color="C0", alpha=0.35,
                        label=f"5-95 % of {out['draws']} draws from the fit's covariance")
        ax.plot(t[sl], pred[sl], color="C0", lw=0.8, label="fitted two-state model")
        ax.set(xlabel="t [s]", ylabel="friction force [N]", title=title)
    axes[0].legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--num", type=int, default=256, help="parameter sets drawn (default 256)")
    p.add_argument("--repeats", type=int, default=3, help="warm timings (median)")
    p.add_argument("--max-steps", type=int, default=200, help="fit iteration limit")
    p.add_argument("--out", type=Path, default=Path(__file__).parents[1] / "docs" / "figures")
    args = p.parse_args(argv)
    if args.num < 2 or args.repeats < 1:
        p.error("--num must be >= 2 and --repeats >= 1")
    args.out.mkdir(parents=True, exist_ok=True)
    out = run(args.num, repeats=args.repeats, max_steps=args.max_steps)
    plot(out, args.out / "sensitivity.png")
    out.pop("_arrays")
    (args.out / "sensitivity.json").write_text(json.dumps(out, indent=2) + "\n")
    b, mc = out["band_90_N"], out["monte_carlo_seconds"]
    print(f"{out['samples']} samples; fit RMSE {out['fit']['rmse_N']:.4g} N "
          f"({out['fit']['status']}, {out['fit']['seconds']:.1f} s)")
    print(f"90 % band of the force: median {b['median']:.4g} N, widest {b['max']:.4g} N "
          f"at t = {b['where_max_s']:.2f} s (noise {out['noise_N']} N)")
    print(f"{out['draws']} draws simulated in {mc['first_call']:.2f} s (first call), "
          f"{mc['warm_median']:.3f} s warm (median)")
    print(f"wrote {args.out / 'sensitivity.json'} and {args.out / 'sensitivity.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
