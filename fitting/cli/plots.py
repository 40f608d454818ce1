"""Figures of the commands (matplotlib, Agg backend): measured against fitted force, and the
diagnosis figures of ``jaxfric diagnose --report`` and ``jaxfric demo``."""

from pathlib import Path

import numpy as np

from ._output import save_figure


def _axes(kind: str) -> dict:
    """``{column: (scale, axis label)}`` for a file of `kind`: a linear file's positions in
    mm, a rotary file's angles in rad (its forces are torques, N m)."""
    if kind == "rotary":
        return {"x": (1.0, "angle [rad]"), "v": (1.0, "angular velocity [rad/s]"),
                "a": (1.0, "a [rad/s^2]"), "F": "torque [N m]", "r": "residual [N m]",
                "Fu": "N m"}
    return {"x": (1e3, "x [mm]"), "v": (1e3, "v [mm/s]"), "a": (1.0, "a [m/s^2]"),
            "F": "F [N]", "r": "residual [N]", "Fu": "N"}


def plot_fit(path: str, m, res, kind: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pred = np.asarray(res.prediction)
    axes = _axes(getattr(m, "kind", "linear"))
    (xs, xlabel) = axes["x"]
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    ax[0].plot(m.t, m.F, lw=0.6, color="0.4", label="measured")
    ax[0].plot(m.t, pred, lw=0.8, color="C3", label=kind)
    ax[0].set(xlabel="t [s]", ylabel=axes["F"], title="friction over time")
    ax[0].legend(fontsize=8)
    ax[1].plot(m.x * xs, m.F, lw=0.4, color="0.4", label="measured")
    ax[1].plot(m.x * xs, pred, lw=0.6, color="C3", label=kind)
    ax[1].set(xlabel=xlabel, ylabel=axes["F"], title="friction vs position")
    fig.suptitle(f"{Path(str(m.source)).name}: {kind} fit, RMSE {float(res.rmse):.3g} "
                 f"{axes['Fu']}")
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
    axes = _axes(getattr(m, "kind", "linear"))
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
    ax[0].set(ylabel=axes["F"])
    ax[0].legend(fontsize=8)
    ax[1].plot(t, F - before, lw=0.5, color="C0", label="baseline residual")
    ax[1].plot(t, F - after, lw=0.5, color="C3", label="final residual")
    ax[1].set(xlabel="t [s]", ylabel=axes["r"])
    ax[1].legend(fontsize=8)
    save(fig, "time.png")

    save(_loops_figure(plt, x, v, F, after, d, axes, float(np.ptp(t))), "loops.png")

    fig, ax = plt.subplots(2, 2, figsize=(11, 7))
    r0, r1 = F - before, F - after
    columns = [(x * axes["x"][0], axes["x"][1]), (v * axes["v"][0], axes["v"][1]),
               (a * axes["a"][0], axes["a"][1]), (t, "t [s]")]
    for axis, (xs, label) in zip(ax.flat, columns):
        axis.plot(xs, r0, ".", ms=1, color="C0", label="baseline")
        axis.plot(xs, r1, ".", ms=1, color="C3", label="final")
        axis.set(xlabel=label, ylabel=axes["r"])
    ax[0, 0].legend(fontsize=8, markerscale=8)
    save(fig, "residuals.png")
    return files


def _loops_figure(plt, x, v, F, after, d, axes, duration):
    """Force against position and against velocity, with the model's static curve."""
    (xs, xlabel), (vs_, vlabel) = axes["x"], axes["v"]
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.5))
    ax[0].plot(x * xs, F, lw=0.4, color="0.5", label="measured")
    ax[0].plot(x * xs, after, lw=0.5, color="C3", label="final model")
    ax[0].set(xlabel=xlabel, ylabel=axes["F"], title="friction vs position")
    ax[0].legend(fontsize=8)
    ax[1].plot(v * vs_, F, ".", ms=1, color="0.5", label="measured")
    # The final model's actual steady state (effects and offset included), at mid travel.
    from .._plausibility import steady_state

    vs = np.linspace(v.min(), v.max(), 121)
    vs = vs[vs != 0]
    static = steady_state(d.final.fit.model, vs, duration=duration or 1.0,
                          at=0.5 * (x.min() + x.max()))
    ax[1].plot(vs * vs_, static, color="C3", label="final model's steady state (mid travel)")
    ax[1].set(xlabel=vlabel, ylabel=axes["F"], title="friction vs velocity")
    ax[1].legend(fontsize=8)
    return fig

