"""Figures of the commands (matplotlib, Agg backend): measured against fitted force, and the
diagnosis figures of ``jaxfric diagnose --report`` and ``jaxfric demo``."""

from pathlib import Path

import numpy as np

from ._output import save_figure


def plot_fit(path: str, m, res, kind: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pred = np.asarray(res.prediction)
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    ax[0].plot(m.t, m.F, lw=0.6, color="0.4", label="measured")
    ax[0].plot(m.t, pred, lw=0.8, color="C3", label=kind)
    ax[0].set(xlabel="t [s]", ylabel="F [N]", title="force over time")
    ax[0].legend(fontsize=8)
    ax[1].plot(m.x * 1e3, m.F, lw=0.4, color="0.4", label="measured")
    ax[1].plot(m.x * 1e3, pred, lw=0.6, color="C3", label=kind)
    ax[1].set(xlabel="x [mm]", ylabel="F [N]", title="force vs position")
    fig.suptitle(f"{Path(str(m.source)).name}: {kind} fit, RMSE {float(res.rmse):.3g} N")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def plot_diagnosis(out_dir: Path, m, d) -> list[str]:
    """Figures a person reads at a glance: measured vs model over time (before/after),
    force vs position, force vs velocity with the model's static curve, and the residual
    against position, velocity, acceleration and time. Returns the file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    t, x, F = m.t, m.x, m.F
    v = m.velocity()
    a = np.r_[0.0, np.diff(v) / np.diff(t)]
    before = np.asarray(d.baseline.fit.prediction)
    after = np.asarray(d.final.fit.prediction)
    files = []

    def save(fig, name):
        fig.tight_layout()
        save_figure(fig, out_dir / name, dpi=100)
        plt.close(fig)
        files.append(name)

    fig, ax = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    ax[0].plot(t, F, lw=0.5, color="0.5", label="measured")
    ax[0].plot(t, before, lw=0.7, color="C0", label="baseline")
    ax[0].plot(t, after, lw=0.7, color="C3", label="after: " + (" + ".join(d.final.added) or "-"))
    ax[0].set(ylabel="F [N]")
    ax[0].legend(fontsize=8)
    ax[1].plot(t, F - before, lw=0.5, color="C0", label="baseline residual")
    ax[1].plot(t, F - after, lw=0.5, color="C3", label="final residual")
    ax[1].set(xlabel="t [s]", ylabel="residual [N]")
    ax[1].legend(fontsize=8)
    save(fig, "time.png")

    save(_loops_figure(plt, x, v, F, after, d), "loops.png")

    fig, ax = plt.subplots(2, 2, figsize=(11, 7))
    r0, r1 = F - before, F - after
    for axis, (xs, label) in zip(ax.flat, [(x * 1e3, "x [mm]"), (v * 1e3, "v [mm/s]"),
                                           (a, "a [m/s^2]"), (t, "t [s]")]):
        axis.plot(xs, r0, ".", ms=1, color="C0", label="baseline")
        axis.plot(xs, r1, ".", ms=1, color="C3", label="final")
        axis.set(xlabel=label, ylabel="residual [N]")
    ax[0, 0].legend(fontsize=8, markerscale=8)
    save(fig, "residuals.png")
    return files


def _loops_figure(plt, x, v, F, after, d):
    """Force against position and against velocity, with the model's static curve."""
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.5))
    ax[0].plot(x * 1e3, F, lw=0.4, color="0.5", label="measured")
    ax[0].plot(x * 1e3, after, lw=0.5, color="C3", label="final model")
    ax[0].set(xlabel="x [mm]", ylabel="F [N]", title="force vs position")
    ax[0].legend(fontsize=8)
    ax[1].plot(v * 1e3, F, ".", ms=1, color="0.5", label="measured")
    vs = np.linspace(v.min(), v.max(), 400)
    base_model = d.final.fit.model
    base_model = getattr(base_model, "base", base_model)
    if hasattr(base_model, "stribeck"):
        static = np.asarray(base_model.stribeck(vs)) + float(base_model.sigma2) * vs
        ax[1].plot(vs * 1e3, static, color="C3", label="model s(v) + sigma2 v")
    ax[1].set(xlabel="v [mm/s]", ylabel="F [N]", title="force vs velocity")
    ax[1].legend(fontsize=8)
    return fig

