"""`Diagnosis`, what `fitting.diagnose` returns, and `Step`, one model of it (the baseline,
or the model after an addition) with its errors."""

import dataclasses

import numpy as np

from ._candidates import Candidate
from ._result import FitResult, saved_model


@dataclasses.dataclass
class Step:
    """After adding `added` and refitting: the fit, its RMSE on every sample and the RMSE of
    the blocked cross-validation's held-out predictions (N), the RMSE per regime
    (`fitting.regimes`)."""

    added: list[str]
    fit: FitResult
    rmse: float
    rmse_holdout: float
    regimes: dict
    rel_error: float = float("nan")  # rmse / RMS of the measured force
    #: The baseline: the start its fit was kept from where starts raced
    #: (`fitting._start.lag_starts`: ``"given start"`` or ``"fast-lag start"``), else "";
    #: the summary names a start other than the given one.
    start: str = ""


@dataclasses.dataclass
class Diagnosis:
    """Outcome of `fitting.diagnose`: `baseline` and `steps` (one `Step` per addition),
    `rankings` (every option of each round, `rankings[0]` on the baseline; an option
    cross-validated has its held-out gain as ``score`` and its ``z``), `holdout` (all
    False: no sample is set aside, the cross-validation holds every sample out once), and
    the final model."""

    baseline: Step
    steps: list[Step]
    rankings: list[list[Candidate]]
    holdout: np.ndarray
    model: object
    model_name: str
    velocity: str = ""  # how the velocity was obtained (`fitting._derivatives.describe`)
    #: The velocity estimate as options (``{"method": ..., "window_s": ...}``; None for a
    #: given velocity), so that `jaxfric simulate --params` can use the same.
    derivatives: dict | None = None
    #: Implausible features of the baseline and of the final model (`fitting._plausibility`).
    warnings: dict = dataclasses.field(default_factory=dict)
    #: The deadband (m or rad) the positions were played through before the diagnosis
    #: (`jaxfric.motion.play`; the command line's ``--deadband``), or None.
    deadband: float | None = None
    #: Every option fitted, round by round: ``{"round", "effects", "sse_train",
    #: "held_out_share_removed", "z", "physical", "added"}`` (None where not
    #: cross-validated).
    trials: list[dict] = dataclasses.field(default_factory=list)
    #: For a long record, how the effects were searched on fewer samples; empty when every
    #: sample was used throughout.
    search: str = ""
    #: What the diagnosis found beyond the effects, in words: "the base model is the limit
    #: here: ..." when a richer base model won; empty otherwise.
    finding: str = ""
    #: What the cross-validation held out: ``"time blocks"`` (one run), ``"runs"`` (leave
    #: one run out, several runs) or ``"given"`` (``diagnose(..., folds=)``).
    folds: str = "time blocks"
    #: Per run: ``{"run": name, "samples", "rmse_holdout": [baseline, after each addition]
    #: (N, its held-out predictions), "rmse": [baseline, final] (N, in-sample)}``, and
    #: ``"params"``, its per-run parameters, when the model has some.
    runs: list[dict] = dataclasses.field(default_factory=list)

    @property
    def candidates(self) -> list[Candidate]:
        return self.rankings[0]

    @property
    def final(self) -> Step:
        return self.steps[-1] if self.steps else self.baseline

    def to_json(self) -> dict:
        return {
            "baseline": {"model": self.model_name, "rmse": self.baseline.rmse,
                         "rmse_holdout": self.baseline.rmse_holdout,
                         "rel_error": self.baseline.rel_error,
                         "regimes": self.baseline.regimes, "start": self.baseline.start},
            "candidates": [c.to_json() for c in self.candidates],
            "after": {"added": self.final.added, "rmse": self.final.rmse,
                      "rmse_holdout": self.final.rmse_holdout,
                      "rel_error": self.final.rel_error,
                      "regimes": self.final.regimes,
                      "steps": [{"added": s.added, "rmse": s.rmse,
                                 "rmse_holdout": s.rmse_holdout} for s in self.steps]},
            "velocity": self.velocity,
            "derivatives": self.derivatives,
            "warnings": self.warnings,
            "trials": self.trials,
            "folds": self.folds,
            "runs": self.runs,
            **({"search": self.search} if self.search else {}),
            **({"finding": self.finding} if self.finding else {}),
            **({} if self.deadband is None else {"deadband": self.deadband}),
            "fitted_model": saved_model(self.model),
        }

    def run_table(self) -> list[str]:
        """Each run's held-out RMSE before and after each addition (N), in lines."""
        heads = ["baseline"] + ["+ " + " + ".join(s.added[len(b.added):])
                                for b, s in zip([self.baseline, *self.steps], self.steps)]
        width = max([len(str(r["run"])) for r in self.runs] + [3]) + 2
        cols = [max(len(h), 8) + 2 for h in heads]
        lines = [f"held-out RMSE per run, N (folds: {self.folds}):",
                 f"{'run':<{width}}" + "".join(f"{h:>{w}}" for h, w in zip(heads, cols))]
        for r in self.runs:
            lines.append(f"{r['run']!s:<{width}}" + "".join(
                f"{v:>{w}.4g}" for v, w in zip(r["rmse_holdout"], cols)))
        return lines

    def summary(self) -> str:
        lines = ([f"cross-validation: leave one run out ({len(self.runs)} runs)"]
                 if self.folds == "runs" else [])
        start = (f" (from the {self.baseline.start})"
                 if self.baseline.start not in ("", "given start") else "")
        lines += [f"baseline {self.model_name}{start}: RMSE {self.baseline.rmse:.4g} N "
                 f"(held out {self.baseline.rmse_holdout:.4g} N, "
                 f"{100 * self.baseline.rel_error:.3g} % of the RMS force)"]
        if self.velocity:
            lines.append(f"velocity: {self.velocity}")
        if self.search:
            lines.append(f"search: {self.search}")
        lines.append("candidates (refitted; held-out gain and z where cross-validated):")
        for c in self.candidates:
            mark = "*" if c.significant else " "
            judged = np.isfinite(c.score)
            lines.append(f" {mark} {c.name:<20} " + (
                f"gain {c.score:7.3f}  z {c.t_stat:6.2f}  " if judged else " " * 25)
                + c.evidence)
        for before, s in zip([self.baseline, *self.steps], self.steps):
            new = " + ".join(s.added[len(before.added):])
            lines.append(f"+ {new:<20} RMSE {s.rmse:.4g} N (held out "
                         f"{s.rmse_holdout:.4g} N, {100 * s.rel_error:.3g} %)")
        if not self.steps:
            lines.append("nothing significant to add")
        if len(self.runs) > 1 or self.folds == "runs":
            lines += self.run_table()
        if self.finding:
            lines.append(self.finding)
        for which, flags in self.warnings.items():
            lines += [f"warning ({which} model): {flag}" for flag in flags]
        return "\n".join(lines)
