"""The figures of `examples/tribometer.py` (`plot`): loops, time series and residuals of
each fitted model against the measured record."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from tribometer_data import strokes

from jaxfric.motion import velocity


if TYPE_CHECKING:
    from tribometer import Report


# ---- figures ----------------------------------------------------------------------------

#: Line colours per model in the figures (measured data in black).
COLORS = {"two_state": "tab:red", "gms5": "tab:blue", "gms10": "tab:cyan",
          "lugre": "tab:green", "tustin": "tab:gray"}


def _window(report: Report, cycles: int) -> slice:
    """Samples of `cycles` full cycles (2 strokes each, with their dwells) starting at the
    first stroke of the validation part (of the fitted part if there is no validation)."""
    r = report.record
    runs = strokes(r.x)
    first = r.split if r.split < r.t.size else 0
    k = next((i for i, (a, _) in enumerate(runs) if a >= first), 0)
    last = min(k + 2 * cycles, len(runs) - 1)
    stop = runs[last][0] if last > k else r.t.size
    return slice(runs[k][0], stop)


def plot(report: Report, out_dir: str | Path, *, cycles: int = 2) -> list[Path]:
    """Write the figures (PNG, matplotlib's Agg backend) into `out_dir` and return their
    paths:

    - ``tribometer_loops.png``: force against position over `cycles` cycles of the
      validation part, measured and every model, with the two turning points zoomed (the
      start of the presliding branches);
    - ``tribometer_time.png``: force against time over the same window, and each model's
      error (Tustin, off the scale, left out of the error panel);
    - ``tribometer_residuals.png``: the two-state model's error against position over the
      whole record, per direction of motion and coloured by time, and the measured
      sliding level of every stroke against time (run-in drift).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    r = report.record
    w = _window(report, cycles)
    t, F = r.t[w], r.F[w]
    fits = report.fits
    paths = []

    figures = {
        "tribometer_loops.png": _loops_figure(plt, r, w, fits),
        "tribometer_time.png": _time_figure(plt, w, fits, t, F),
        "tribometer_residuals.png": _residuals_figure(plt, r, fits),
    }
    for name, fig in figures.items():
        paths.append(out / name)
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    return paths


def _loops_figure(plt, r, w, fits):
    """Force against position over the window `w`, with both turning points zoomed."""
    t, x_mm, F = r.t[w], 1e3 * r.x[w], r.F[w]
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2), gridspec_kw={"width_ratios": [2, 1, 1]})
    span = np.ptp(x_mm)
    zooms = [(None, "two cycles"), ((x_mm.max() - 0.4 * span, x_mm.max() + 0.02 * span),
                                    "upper turning point"),
             ((x_mm.min() - 0.02 * span, x_mm.min() + 0.4 * span), "lower turning point")]
    for ax, (xlim, title) in zip(axes, zooms):
        ax.plot(x_mm, F, ".", color="k", ms=2, label="measured")
        for name, f in fits.items():
            ax.plot(x_mm, f.force[w], "-", lw=1.0, color=COLORS.get(name), label=name)
        if xlim is not None:
            ax.set_xlim(*xlim)
        ax.ticklabel_format(axis="x", useOffset=False)
        ax.set_xlabel("position x [mm]")
        ax.set_title(title)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("friction force F [N] (sign of v)")
    axes[0].legend(loc="center right", fontsize=8)
    fig.suptitle(f"Tribometer, validation part: t = {t[0]:.1f}..{t[-1]:.1f} s "
                 f"(normal load {r.normal_plateau:.3g} N)")
    fig.tight_layout()
    return fig


def _time_figure(plt, w, fits, t, F):
    """Force and each model's error against time over the window `w`."""
    fig, (ax0, ax1) = plt.subplots(2, 1, figsize=(12, 7), sharex=True,
                                   gridspec_kw={"height_ratios": [3, 2]})
    ax0.plot(t, F, ".", color="k", ms=2, label="measured")
    for name, f in fits.items():
        ax0.plot(t, f.force[w], "-", lw=1.0, color=COLORS.get(name), label=name)
        if name != "tustin":
            ax1.plot(t, f.force[w] - F, "-", lw=0.8, color=COLORS.get(name), label=name)
    ax0.set_ylabel("F [N]")
    ax0.legend(loc="upper right", fontsize=8, ncol=3)
    ax0.grid(alpha=0.3)
    ax1.axhline(0.0, color="k", lw=0.5)
    ax1.set_ylabel("model - measured [N]")
    ax1.set_xlabel("t [s]")
    ax1.grid(alpha=0.3)
    ax1.legend(loc="upper right", fontsize=8, ncol=4)
    fig.suptitle("Force against time, validation part (Tustin's error is off this scale)")
    fig.tight_layout()
    return fig


def _residuals_figure(plt, r, fits):
    """Two-state error against position, and the measured sliding level over time."""
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    if "two_state" in fits:
        v = velocity(r.t, r.x)
        err = fits["two_state"].force - r.F
        for ax, d, label in ((axes[0], 1.0, "motion toward +x"), (axes[1], -1.0,
                                                                 "motion toward -x")):
            sel = np.sign(v) == d
            sc = ax.scatter(1e3 * r.x[sel], err[sel], c=r.t[sel], s=1, cmap="viridis",
                            rasterized=True)
            ax.axhline(0.0, color="k", lw=0.5)
            ax.ticklabel_format(axis="x", useOffset=False)
            ax.set_xlabel("position x [mm]")
            ax.set_title(f"two-state error, {label}")
            ax.grid(alpha=0.3)
        axes[0].set_ylabel("model - measured [N]")
        fig.colorbar(sc, ax=axes[1], label="t [s]")
    runs = strokes(r.x)
    for d, marker in ((1.0, "^"), (-1.0, "v")):
        level, when = [], []
        for a, b in runs:
            if np.sign(r.x[b] - r.x[a]) != d:
                continue
            tail = slice(a + int(0.7 * (b - a)), b)  # the last 30 % of the stroke
            level.append(abs(np.mean(r.F[tail])))
            when.append(r.t[a])
        toward = "+x" if d > 0 else "-x"
        axes[2].plot(when, level, marker, ms=4, label=f"|F| sliding, toward {toward}")
    if r.split < r.t.size:
        axes[2].axvline(r.t[r.split], color="k", ls="--", lw=0.8, label="fit | validation")
    axes[2].set_xlabel("t [s]")
    axes[2].set_ylabel("mean |F| over the last 30 % of each stroke [N]")
    axes[2].set_title("measured sliding level (run-in)")
    axes[2].legend(fontsize=8)
    axes[2].grid(alpha=0.3)
    fig.tight_layout()
    return fig
