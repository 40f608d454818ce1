"""``jaxfric fit``, ``compare`` and ``diagnose`` with several runs (files) and ``--validate``.

Every file is read with its own unit, column and sign detection (runs may differ in
sampling rate, units and columns) and converted to SI; one model is fitted to all the
fitted runs at once (`fitting.fit_datasets`: shared physical parameters, per-run nuisance
parameters where an effect declares them), and the runs given to ``--validate`` are only
predicted: the model for them is the fitted one with each per-run parameter at its mean
over the fitted runs (`fitting.run_model`), since a run not fitted has no value of its own.

``diagnose`` with several files diagnoses them together (`fitting.diagnose`: leave one
run out), and predicts the runs given to ``--validate`` with the baseline and with the
diagnosed model.

Errors are RMSE of ``prediction + known - force`` per run and per regime
(`fitting._regimes`); the sliding speed bands are the terciles of the sliding speeds of
all fitted runs together, so that every run's regimes have the same names.
"""

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import equinox as eqx
import numpy as np

import jaxfric
from jaxfric import data as _data, units as _units

from .._data import Dataset
from .._fit import fit_datasets
from .._per_run import per_run_values, run_model
from .._regimes import regime_errors, regimes
from .._result import saved_model
from .._start import initial_model, steady_sliding_weights
from ._io import about, describe, load_for_cli, param_table, result_json
from ._output import write_json
from ._signals import (
    _deadband_option,
    _load_of,
    derivatives_json,
    identification_derivatives,
    played_measurement,
    velocity_words,
)


@dataclasses.dataclass
class Run:
    """One file ready to fit or predict: the measurement (SI, played through its deadband),
    the force column fitted (F, or u for a model with inertia), its velocity and
    acceleration, and what was done to it."""

    m: _data.Measurement
    force: np.ndarray
    v: np.ndarray
    a: np.ndarray | None
    deadband: float | None
    velocity: str

    @property
    def name(self) -> str:
        return str(self.m.source)

    def target(self) -> np.ndarray:
        """The force the model should predict: the measured one less any known force."""
        return self.force if self.m.known is None else self.force - self.m.known


def several(args) -> bool:
    """Whether a ``fit``/``compare``/``diagnose`` command line names several runs or runs
    to validate."""
    return len(getattr(args, "files", ())) > 1 or bool(getattr(args, "validate", None))


def _load(args, path, log, drive_ok: bool) -> _data.Measurement:
    one = argparse.Namespace(**{**vars(args), "file": path})
    if _data.joint_layout(path):
        raise _data.DataError(f"{path}: holds several joints; several runs are fitted from "
                              "files of one axis each (fit the joint file alone)")
    try:
        m = load_for_cli(one, log)
    except _data.DataError as e:
        if not args.known_force or "for the known force" not in str(e):
            raise
        m = load_for_cli(argparse.Namespace(**{**vars(one), "known_force": None}), log)
        log(f"note: {path}: no column {args.known_force!r}: no known force in this run")
    if m.F is None and not drive_ok:
        raise _data.DataError(
            f"{m.source}: '{args.command}' needs the friction force F; this file has only the "
            "drive force u (inertia and offsets included): start from a model with inertia "
            "(--params from 'jaxfric diagnose --json') or subtract them first")
    return m


def load_runs(args, paths, log, drive_ok: bool = False) -> list[Run]:
    """Each file of `paths` read with the command line's options, through its deadband,
    with its derivatives; `drive_ok`: a file with only the drive force u is accepted."""
    runs = []
    for path in paths:
        m = _load(args, path, log, drive_ok)
        m, deadband = played_measurement(m, _deadband_option(args.deadband, None), log)
        log(describe(m))
        one = args
        if m.F is None and m.v is None and args.velocity_window is None:
            one = argparse.Namespace(**{**vars(args), "velocity_window": 0.01})
            log("note: velocity from a central difference over 10 ms, as 'diagnose' "
                "takes it for drive-force data u")
        v, a, _ = identification_derivatives(m, one, log)
        runs.append(Run(m, m.force, v, a, deadband, velocity_words(m, one)))
    kinds = {r.m.kind for r in runs}
    if len(kinds) > 1:
        said = ", ".join(f"{r.name} {r.m.kind}" for r in runs)
        raise _data.DataError(f"the runs mix linear and rotary files ({said}): declare the "
                              "units (or --kind)")
    return runs


def _speed_bands(runs: list[Run]) -> list[float]:
    """The terciles of the sliding speeds of `runs` together (m/s, or rad/s)."""
    speeds = []
    for r in runs:
        masks = regimes(r.m.t, r.m.x, r.v)
        slide = np.zeros(r.m.t.size, bool)
        for name, mask in masks.items():
            if name.startswith("sliding"):
                slide |= mask
        speeds.append(np.abs(r.v[slide]))
    allv = np.concatenate(speeds)
    return list(np.quantile(allv, [1 / 3, 2 / 3])) if allv.size else [1e-3, 1e-2]


def run_errors(r: Run, prediction, bands, kind: str) -> dict:
    """``{"file", "samples", "rmse", "regimes"}`` of `prediction` on run `r`."""
    resid = np.asarray(prediction) - r.target()
    errs = regime_errors(resid, regimes(r.m.t, r.m.x, r.v, speed_bands=bands))
    return {"file": r.name, "samples": len(r.m), "rmse": errs["all"]["rmse"],
            "regimes": _units.speak_json(errs, kind)}


def _dataset(r: Run, model, weights=None) -> Dataset:
    return Dataset(t=r.m.t, x=r.m.x, F=r.force, v=r.v, a=r.a, load=_load_of(r.m, model),
                   known=r.m.known, weights=weights)


def predict(model, r: Run) -> np.ndarray:
    """`model`'s force along run `r` (N, or N m), without the known force."""
    return np.asarray(jaxfric.simulate(model, r.m.t, r.m.x, r.v, load=_load_of(r.m, model),
                                       a=r.a))


def fit_runs(args, kind: str, fitted: list[Run], log, start=None, weights=None):
    """One model of `kind` (or from `start`) fitted to all `fitted` runs."""
    first = fitted[0]
    if start is None:
        with about(first.name):
            start = initial_model(kind, first.m.t, first.m.x, first.target(), first.v,
                                  n_elements=args.elements)
    data = [_dataset(r, start, None if weights is None else weights[i])
            for i, r in enumerate(fitted)]
    t0 = time.perf_counter()
    with about(", ".join(r.name for r in fitted)):
        res = fit_datasets(start, data, max_steps=args.max_steps,
                           progress=_progress(log, data, first.m.unit("F"))
                           if not args.quiet and sys.stdout.isatty() else None)
    return res, time.perf_counter() - t0


def _progress(log, data: list[Dataset], unit: str):
    """A progress callback printing the steps and the RMSE over all runs after each
    compiled chunk of steps (the residuals are in units of the force's standard deviation
    over all runs, `fitting._problem`)."""
    force = np.concatenate([np.asarray(d.F) - (0 if d.known is None else d.known)
                            for d in data])
    scale = (float(np.std(force)) or 1.0) / np.sqrt(force.size)

    def show(p):
        log(f"  step {p.steps:4d}   RMSE {scale * (2.0 * p.cost) ** 0.5:.4g} {unit}   "
            f"({p.seconds:.0f} s)")

    return show


def _table(rows: list[dict], names: list[str], unit: str) -> list[str]:
    width = max([len(Path(r["file"]).name) for r in rows] + [4]) + 2
    cols = [max(len(n), 9) + 2 for n in names]
    lines = [f"RMSE per run and regime, {unit}:",
             f"{'run':<{width}}{'role':<12}" + "".join(f"{n:>{w}}" for n, w in zip(names, cols))]
    for r in rows:
        errs = r["regimes"]
        lines.append(f"{Path(r['file']).name:<{width}}{r['role']:<12}" + "".join(
            f"{errs[n]['rmse'] if n in errs else float('nan'):>{w}.4g}"
            for n, w in zip(names, cols)))
    return lines


def evaluate(res, fitted: list[Run], held: list[Run], kind: str) -> tuple[list, list]:
    """Errors of a fit on its runs (its own prediction) and on the runs held out (the
    model with per-run parameters at their mean)."""
    bands = _speed_bands(fitted)
    rows = [{**run_errors(r, p, bands, kind), "role": "fitted"}
            for r, p in zip(fitted, res.prediction)]
    mean = run_model(res.fit_model, None)
    held_rows = [{**run_errors(r, predict(mean, r), bands, kind), "role": "validation"}
                 for r in held]
    return rows, held_rows


def _as_mean(res):
    """`res` with `model`/`fit_model` the plain model for a run not fitted (per-run
    parameters at their mean), for the saved JSON; per-run values stay in `params`."""
    return eqx.tree_at(lambda r: (r.model, r.fit_model), res,
                       (run_model(res.model, None), run_model(res.fit_model, None)))


def run_fit_runs(args, kind: str, start, log) -> int:
    """``jaxfric fit`` with several files and/or ``--validate``."""
    fitted = load_runs(args, args.files, log, drive_ok=start is not None)
    held = load_runs(args, args.validate or [], log, drive_ok=start is not None)
    if len({r.m.kind for r in fitted + held}) > 1:
        raise _data.DataError("the fitted and validation runs mix linear and rotary files: "
                              "declare the units (or --kind)")
    m0 = fitted[0].m
    unit = m0.unit("F")
    log(f"fitting {kind} to {len(fitted)} run(s) at once with Levenberg-Marquardt (the first "
        "step includes compilation) ...")
    res, elapsed = fit_runs(args, kind, fitted, log, start)
    verdict = "converged" if bool(res.converged) else "NOT converged"
    log(f"\n{kind}: {verdict} ({res.status}) after {int(res.num_steps)} steps ({elapsed:.1f} s);"
        f" RMSE {float(res.rmse):.4g} {unit} over all fitted runs, NRMSE {float(res.nrmse):.4g},"
        f" R2 {float(res.r2):.4f}\nstopped: {res.stopped}")
    log(param_table(res, m0.kind))
    values = per_run_values(res.fit_model)
    if values:
        log("per-run parameters (_1, _2, ... in the order of the files); a validation run "
            "uses their mean")
    rows, held_rows = evaluate(res, fitted, held, m0.kind)
    names = list(rows[0]["regimes"])
    log("\n" + "\n".join(_table(rows + held_rows, names, unit)))
    if not bool(res.converged):
        print(f"warning: the fit did not converge ({res.status}); the values are the last "
              "iterate", file=sys.stderr)
    if args.json:
        out = result_json(kind, _as_mean(res), m0)
        out.pop("file")
        out.update(files=[r.name for r in fitted], samples=sum(len(r.m) for r in fitted),
                   derivatives=derivatives_json(m0, args),
                   runs=[{**row, "velocity": r.velocity, "deadband": r.deadband,
                          **({"params": values[i],
                              "fitted_model": saved_model(run_model(res.fit_model, i))}
                             if values else {})}
                         for i, (r, row) in enumerate(zip(fitted, rows))],
                   validation=[{**row, "velocity": r.velocity, "deadband": r.deadband}
                               for r, row in zip(held, held_rows)],
                   regime_speed_bands=_speed_bands(fitted))
        if args.known_force:
            out["known_force"] = {"column": args.known_force, "unit": unit}
        write_json(args.json, out)
        log(f"JSON written to {args.json}")
    return 0


def run_compare_runs(args, kinds: list[str], log) -> int:
    """``jaxfric compare`` with several files and/or ``--validate``."""
    fitted = load_runs(args, args.files, log)
    held = load_runs(args, args.validate or [], log)
    if len({r.m.kind for r in fitted + held}) > 1:
        raise _data.DataError("the fitted and validation runs mix linear and rotary files: "
                              "declare the units (or --kind)")
    m0 = fitted[0].m
    results, table = {}, []
    for kind in kinds:
        log(f"fitting {kind} to {len(fitted)} run(s) ...")
        w = None
        if kind == "tustin":  # a static model: fitted on the steady sliding only
            w = [steady_sliding_weights(r.m.t, r.m.x, r.target(), r.v) for r in fitted]
        res, _ = fit_runs(args, kind, fitted, log, weights=w)
        rows, held_rows = evaluate(res, fitted, held, m0.kind)
        on = "all samples" if w is None else "steady sliding samples"
        out = result_json(kind, _as_mean(res), m0)
        out.pop("file")
        out.update(files=[r.name for r in fitted], fitted_on=on, runs=rows,
                   validation=held_rows, samples=sum(len(r.m) for r in fitted))
        results[kind] = out
        table += [{**row, "file": f"{kind}: {Path(row['file']).name}"}
                  for row in rows + held_rows]
    names = list(table[0]["regimes"])
    log("\n" + "\n".join(_table(table, names, m0.unit("F"))))
    if any(r["fitted_on"] != "all samples" for r in results.values()):
        log("(tustin fitted to the steady sliding samples of each run; errors over all)")
    if args.json:
        known = ({"known_force": {"column": args.known_force, "unit": m0.unit("F")}}
                 if args.known_force else {})
        write_json(args.json, {"files": [r.name for r in fitted],
                               "validate": [r.name for r in held], "kind": m0.kind,
                               "regime_speed_bands": _speed_bands(fitted),
                               "models": results, **known})
        log(f"JSON written to {args.json}")
    return 0


def _timeline(runs: list[Run]) -> np.ndarray:
    """The runs' times laid end to end (each run from where the previous one ended, plus
    one of its sampling steps), for figures of several runs on one axis."""
    out, end = [], 0.0
    for r in runs:
        t = r.m.t - r.m.t[0]
        out.append(t + end)
        end = out[-1][-1] + (float(np.median(np.diff(t))) if t.size > 1 else 1.0)
    return np.concatenate(out)


def _write_runs_report(args, d, fitted: list[Run], validation: list[dict], log) -> None:
    """``--report`` of a diagnosis of several runs: the figures over the runs laid end to
    end (`_timeline`), the per-run tables on the page."""
    from types import SimpleNamespace

    from .._diagnose import _prediction
    from ._output import output_folder
    from .report import write_report

    def view(step):
        fit = SimpleNamespace(prediction=_prediction(step.fit),
                              model=run_model(step.fit.model, None))
        return SimpleNamespace(**{**vars(step), "fit": fit})

    shown = SimpleNamespace(**{**vars(d), "baseline": view(d.baseline),
                               "final": view(d.final)})
    v = np.concatenate([r.v for r in fitted])
    m = SimpleNamespace(t=_timeline(fitted), x=np.concatenate([r.m.x for r in fitted]),
                        F=np.concatenate([r.force for r in fitted]), velocity=lambda: v,
                        kind=fitted[0].m.kind)
    with output_folder(args.report):
        page = write_report(args.report, m, d, shown=shown, validation=validation,
                            title="jaxfric diagnose " + " ".join(
                                Path(r.name).name for r in fitted))
    log(f"report written to {page} (figures and diagnosis.json beside it)")


def run_diagnose_runs(args, kind: str, log) -> int:
    """``jaxfric diagnose`` with several files and/or ``--validate``: one diagnosis of all
    the files (leave one run out, `fitting.diagnose`), the runs to validate predicted by
    the baseline and by the diagnosed model (per-run parameters at their mean)."""
    from .._diagnose import diagnose
    from ._io import diagnosis_json

    fitted = load_runs(args, args.files, log, drive_ok=True)
    held = load_runs(args, args.validate or [], log, drive_ok=True)
    if len({r.m.kind for r in fitted + held}) > 1:
        raise _data.DataError("the fitted and validation runs mix linear and rotary files: "
                              "declare the units (or --kind)")
    m0 = fitted[0].m
    if m0.kind == _units.ROTARY:  # the diagnosis speaks SI linear words: say them rotary
        plain = log
        log = lambda *a: plain(*(_units.speak(str(s), m0.kind) for s in a))
    first = fitted[0]
    with about(first.name):
        start = initial_model(kind, first.m.t, first.m.x, first.target(), first.v,
                              n_elements=args.elements)
    sets = [Dataset(t=r.m.t, x=r.m.x, F=r.force, v=r.v, a=r.a, load=r.m.load,
                    known=r.m.known) for r in fitted]
    t0 = time.perf_counter()
    with about(", ".join(r.name for r in fitted)):
        d = diagnose(start, sets, max_steps=args.max_steps, model_name=kind, log=log,
                     rotary=m0.kind == _units.ROTARY,
                     search_samples=getattr(args, "search_samples", None),
                     run_names=[r.name for r in fitted])
    d.velocity, d.derivatives = first.velocity, derivatives_json(m0, args)
    d.deadband = first.deadband
    log(f"\n{d.summary()}\n({time.perf_counter() - t0:.1f} s)")
    bands = _speed_bands(fitted)
    base = run_model(d.baseline.fit.fit_model, None)
    validation = [{"file": r.name, "samples": len(r.m),
                   "baseline": run_errors(r, predict(base, r), bands, m0.kind),
                   "diagnosed": run_errors(r, predict(d.model, r), bands, m0.kind)}
                  for r in held]
    if validation:
        rows = [{**v[which], "role": which} for v in validation
                for which in ("baseline", "diagnosed")]
        log("\nruns not used (validation):\n" + "\n".join(
            _table(rows, list(rows[0]["regimes"]), m0.unit("F"))))
    if args.report:
        _write_runs_report(args, d, fitted, validation, log)
    if args.json:
        out = {**diagnosis_json(d, m0.kind), "files": [r.name for r in fitted],
               "validation": validation, "regime_speed_bands": bands}
        if args.known_force:
            out["known_force"] = {"column": args.known_force, "unit": m0.unit("F")}
        write_json(args.json, out)
        log(f"JSON written to {args.json}")
    return 0
