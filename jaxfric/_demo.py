"""The computation behind ``jaxfric demo``."""

import json
from pathlib import Path

import numpy as np

from . import paper
from ._simulate import simulate
from .examples import excitation


NOISE_N = 0.05


def _regimes(t, x, v):
    """Masks: 'presliding' = within 0.3 mm of travel after a reversal and |v| < 1 mm/s;
    'sliding slow' / 'sliding fast' = |v| below / above 3 mm/s elsewhere."""
    d = np.sign(v)
    last = np.maximum.accumulate(np.where(d != 0, np.arange(d.size), 0))
    dir_ = d[last]
    rev = np.r_[False, (dir_[1:] != dir_[:-1]) & (dir_[:-1] != 0)]
    x_rev = x[np.maximum.accumulate(np.where(rev, np.arange(x.size), 0))]
    near = (np.abs(x - x_rev) < 0.3e-3) & (np.abs(v) < 1e-3)
    return {
        "presliding": near,
        "sliding <3 mm/s": ~near & (np.abs(v) < 3e-3),
        "sliding >=3 mm/s": ~near & (np.abs(v) >= 3e-3),
    }


def run(out: Path, log=print) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    t, x = excitation()
    v = np.r_[0.0, np.diff(x) / np.diff(t)]
    log(f"example motion: {t.size} samples, {t[-1]:.1f} s, travel {np.ptp(x) * 1e3:.2f} mm")
    truth = np.asarray(simulate(paper.gms(200), t, x))
    rng = np.random.default_rng(0)
    measured = truth + rng.normal(0.0, NOISE_N, truth.size)
    models = {
        "two_state": paper.two_state(),
        "gms5": paper.gms5(),
        "gms10": paper.gms10(),
        "lugre": paper.lugre(),
        "tustin": paper.tustin(),
    }
    regimes = _regimes(t, x, v)
    table = {}
    forces = {}
    for name, model in models.items():
        f = np.asarray(simulate(model, t, x))
        forces[name] = f
        err = f - measured
        row = {"all": float(np.sqrt(np.mean(err**2)))}
        for reg, m in regimes.items():
            row[reg] = float(np.sqrt(np.mean(err[m] ** 2)))
        table[name] = row
    cols = ["all", *regimes]
    log(f"\nRMS error against the measurement, N (noise level {NOISE_N:.2f} N):")
    log(f"{'model':<10}" + "".join(f"{c:>21}" for c in cols))
    for name, row in table.items():
        log(f"{name:<10}" + "".join(f"{row[c]:>21.3f}" for c in cols))

    # figures
    pres = slice(0, int(np.argmax(np.abs(x) > 0.5e-3)))
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    ax[0].plot(x[pres] * 1e6, measured[pres], ".", ms=1, color="0.6", label="measured")
    for name in ("two_state", "gms5", "lugre"):
        ax[0].plot(x[pres] * 1e6, forces[name][pres], lw=1, label=name)
    ax[0].set(xlabel="position [um]", ylabel="friction force [N]", title="presliding loops")
    ax[0].legend(fontsize=8)
    vv = np.linspace(-25e-3, 25e-3, 2001)
    ax[1].plot(v * 1e3, measured, ".", ms=1, color="0.6", label="measured")
    st = paper.stribeck()
    ax[1].plot(vv * 1e3, np.asarray(st(vv)) + paper.SIGMA2 * vv, "k", lw=1,
               label="s(v) + sigma2 v")
    ax[1].set(xlabel="velocity [mm/s]", ylabel="friction force [N]", title="force vs velocity")
    ax[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "loops_and_stribeck.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(11, 3.5))
    ax.plot(t, measured, color="0.6", lw=0.5, label="measured")
    ax.plot(t, forces["two_state"], lw=0.8, label="two_state")
    ax.plot(t, forces["tustin"], lw=0.8, label="tustin")
    ax.set(xlabel="time [s]", ylabel="friction force [N]")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "force_vs_time.png", dpi=120)
    plt.close(fig)

    summary = {
        "samples": int(t.size),
        "noise_N": NOISE_N,
        "truth": "GMS, 200 elements from the paper's presliding shape",
        "rmse_N": table,
        "figures": ["loops_and_stribeck.png", "force_vs_time.png"],
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary
