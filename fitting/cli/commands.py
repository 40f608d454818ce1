"""The work behind ``jaxfric fit``, ``diagnose``, ``simulate`` and ``compare``: each takes the
parsed arguments, prints what it does, writes its outputs and returns the exit code."""

import json
import sys
import time
import warnings
from pathlib import Path

import jax
import numpy as np

from jaxfric import data as _data, units as _units

from .._diagnose import SEARCH_SAMPLES
from .._fit import fit as _fit
from .._start import initial_model, steady_sliding_weights
from ._io import (
    about,
    chosen_kind,
    cli_kind,
    describe,
    diagnosis_json,
    load_for_cli,
    MODEL_NAMES,
    param_table,
    parse_units,
    print_warnings,
    result_json,
)
from ._output import atomic_file, write_json
from ._signals import (
    _deadband_option,
    _load_json,
    _load_of,
    _saved_derivatives,
    derivatives_as_saved,
    derivatives_json,
    identification_derivatives,
    played_measurement,
    velocity_words,
)
from .plots import plot_fit
from .runs import run_compare_runs, run_diagnose_runs, run_fit_runs, several


def _progress(log, scale: float, unit: str):
    """A `fitting.fit` progress callback printing the steps and the RMSE of the samples
    (`scale`: the force scale of the residuals, from the data) after each compiled chunk
    of steps (about a second each)."""

    def show(p):
        log(f"  step {p.steps:4d}   RMSE {scale * (2.0 * p.cost) ** 0.5:.4g} {unit}   "
            f"({p.seconds:.0f} s)")

    return show


def _kind_of_command(args) -> str:
    """The model a command fits or simulates: the one of ``--params`` (an explicit
    ``--model`` must agree), else ``--model`` (`chosen_kind`)."""
    if not getattr(args, "params", None):
        return chosen_kind(args)
    asked = MODEL_NAMES[args.model] if args.model else "two-state"
    return chosen_kind(args, model_from_json(args.params, asked)[0])


def run_fit(args) -> int:
    log = (lambda *a: None) if args.quiet else (lambda *a: print(*a, flush=True))
    kind = _kind_of_command(args)
    if several(args):
        if args.plot:
            raise _data.DataError("--plot takes one file (no --validate); plot a run with "
                                  "'jaxfric simulate FILE --params FIT.json'")
        start = model_from_json(args.params, kind)[0] if args.params else None
        return run_fit_runs(args, kind, start, log)
    if _data.joint_layout(args.file):
        from .joints import fit_joints

        return fit_joints(args, kind, log, fit_measurement)
    m = load_for_cli(args, log)
    m, deadband = played_measurement(m, _deadband_option(args.deadband, None), log)
    res = fit_measurement(args, kind, m, log)
    if args.json:
        extra = {} if deadband is None else {"deadband": deadband}
        extra.update(_load_json(m))
        if getattr(args, "known_force", None):
            extra["known_force"] = {"column": args.known_force, "unit": m.unit("F")}
        write_json(args.json, {**result_json(kind, res, m), "velocity": velocity_words(m, args),
                               "derivatives": derivatives_json(m, args), **extra})
        log(f"JSON written to {args.json}")
    if args.plot:
        plot_fit(args.plot, m, res, kind)
        log(f"plot written to {args.plot}")
    return 0


def fit_measurement(args, kind: str, m, log):
    """Fit model `kind` to `m` with the command line's options, printing its table."""
    if m.F is None and not args.params:
        raise _data.DataError(
            f"{m.source}: 'fit' needs the friction force F; this file has only the drive force "
            "u (inertia and offsets included): use 'jaxfric diagnose' or subtract them first"
        )
    log(describe(m))
    v, a, _ = identification_derivatives(m, args, log)
    if args.params:
        start, what = model_from_json(args.params, kind)
        log(f"starting from {what}")
    else:
        with about(m.source):
            start = initial_model(kind, m.t, m.x, m.F if m.known is None else m.F - m.known,
                                  v, n_elements=args.elements)
    log(f"fitting {kind}" + (f" ({args.elements} elements)" if kind == "gms" else "")
        + " with Levenberg-Marquardt (the first step includes compilation) ...")
    t0 = time.perf_counter()
    watched = not args.quiet and sys.stdout.isatty()
    # The residuals are in units of the force's standard deviation (`fitting._problem`).
    # (`_force_scale`: the standard deviation, or 1 for a constant force.)
    scale = (float(np.std(m.force)) or 1.0) / np.sqrt(m.force.size)
    with about(m.source):
        res = _fit(start, m.t, m.x, m.force, v, max_steps=args.max_steps,
                   progress=_progress(log, scale, m.unit("F")) if watched else None,
                   load=_load_of(m, start), a=a, known=m.known)
    elapsed = time.perf_counter() - t0
    # The verdict first: a status name alone ("nonlinear_max_steps_reached") does not say
    # to everyone that the values are not a converged fit.
    verdict = "converged" if bool(res.converged) else "NOT converged"
    log(f"\n{kind}: {verdict} ({res.status}) after {int(res.num_steps)} steps ({elapsed:.1f} s); "
        f"RMSE {float(res.rmse):.4g} {m.unit('F')}, NRMSE {float(res.nrmse):.4g}, "
        f"R2 {float(res.r2):.4f}\nstopped: {res.stopped}")
    log(param_table(res, m.kind))
    if not bool(res.converged):
        print(f"warning: {m.source}: the fit did not converge ({res.status}); the values are "
              "the last iterate", file=sys.stderr)
    return res


def run_diagnose(args) -> int:
    log = (lambda *a: None) if args.quiet else (lambda *a: print(*a, flush=True))
    kind = MODEL_NAMES[args.model]
    if several(args):
        return run_diagnose_runs(args, kind, log)
    if _data.joint_layout(args.file):
        from .joints import diagnose_joints

        return diagnose_joints(args, kind, log, diagnose_measurement)
    m = load_for_cli(args, log)
    d = diagnose_measurement(args, kind, m, log, args.report)
    if args.json:
        write_json(args.json, {**diagnosis_json(d, m.kind), **_load_json(m)})
        log(f"JSON written to {args.json}")
    return 0


def diagnose_measurement(args, kind: str, m, log, report):
    """Diagnose `m` from model `kind` with the command line's options; the report (if
    `report` names a folder) and the summary speak `m`'s units. Returns the diagnosis."""
    from .._diagnose import diagnose

    if m.kind == _units.ROTARY:  # the diagnosis speaks SI linear words: say them rotary
        plain = log
        log = lambda *a: plain(*(_units.speak(str(s), m.kind) for s in a))
    m, deadband = played_measurement(m, _deadband_option(args.deadband, None), log)
    force, column = m.force, m.force_column
    if m.known is not None:  # --known-force: subtracted, not fitted
        force = force - m.known
    if column == "u":
        log("note: the file has the drive force u (not F): the model starts as friction only; "
            "inertia and offset are among the effects the diagnosis looks for")
    log(describe(m))
    window = args.velocity_window
    if window is None and column == "u" and m.v is None and args.derivatives == "central":
        args.velocity_window = window = 0.01
        log("note: velocity from a central difference over 10 ms (--velocity-window), "
            "because inertia makes the force depend on its derivative")
    v, a, how = identification_derivatives(m, args, log)
    with about(m.source):
        start = initial_model(kind, m.t, m.x, force, v, n_elements=args.elements)
    t0 = time.perf_counter()
    if m.load is not None:
        log(f"load: the 'load' column ({m.unit('load')}); load-dependent friction is screened")
    with about(m.source):
        d = diagnose(start, m.t, m.x, force, v, max_steps=args.max_steps, model_name=kind,
                     log=log, rotary=m.kind == _units.ROTARY, load=m.load,
                     search_samples=getattr(args, "search_samples", SEARCH_SAMPLES), a=a)
    d.velocity, d.derivatives, d.deadband = how, derivatives_json(m, args), deadband
    log(f"\n{d.summary()}\n({time.perf_counter() - t0:.1f} s)")
    if report:
        from types import SimpleNamespace

        from ._output import output_folder
        from .report import write_report

        with output_folder(report):  # a folder made here goes again if interrupted
            page = write_report(
                report,
                SimpleNamespace(t=m.t, x=m.x, F=force, velocity=lambda: v, kind=m.kind),
                d, title=f"jaxfric diagnose {Path(str(m.source)).name}",
            )
        log(f"report written to {page} (figures and diagnosis.json beside it)")
    return d


def model_from_params(kind: str, params: dict):
    """A model of `kind` with the parameter values of a ``jaxfric fit --json`` result
    (``{"model": ..., "params": {name: SI value}}`` or just the params dict)."""
    from jaxfric import paper

    from .. import _params

    if not isinstance(params, dict) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in params.values()):
        raise _data.DataError("'params' must be an object of parameter names and numbers, "
                              "as 'jaxfric fit --json' writes it")
    n = sum(1 for k in params if k.startswith("nu_"))
    template = {"two-state": paper.two_state, "lugre": paper.lugre, "tustin": paper.tustin,
                "gms": lambda: paper.gms(max(n, 1))}[kind]()
    names = _params.natural_names(template)
    missing = [k for k in names if k not in params]
    if missing:
        raise _data.DataError(f"parameters for a {kind} model are missing: {', '.join(missing)}")
    vector = np.asarray([float(params[k]) for k in names])
    return _params.from_natural_vector(jax.numpy.asarray(vector), template)


def model_from_json(path, kind: str):
    """``(model, description)`` from a JSON file: a saved model (`jaxfric.save_model`),
    a fit or diagnosis result with a ``"fitted_model"`` entry (the model exactly as
    fitted, effects included), or an older fit result with only ``"params"`` (paper names,
    rebuilt on a model of its ``"model"`` kind, or of `kind`)."""
    import jaxfric

    path = Path(path)
    if not path.is_file():
        raise _data.DataError(f"{path}: no such file")
    try:
        spec = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise _data.DataError(f"{path}: not valid JSON ({e.msg}, line {e.lineno})") from None
    except UnicodeDecodeError:
        raise _data.DataError(f"{path}: not a JSON file (binary data, not UTF-8 text)"
                              ) from None
    except OSError as e:
        raise _data.DataError(f"{path}: cannot be read ({e.strerror or e})") from None
    if not isinstance(spec, dict):
        raise _data.DataError(f"{path}: expected a JSON object (a fit, a diagnosis or a saved "
                              f"model), got a {type(spec).__name__}")
    if isinstance(spec.get("fitted_model"), dict) or "class" in spec or isinstance(
            spec.get("model"), dict):
        try:
            model = jaxfric.load_model(spec)
        except (ValueError, TypeError) as e:
            raise _data.DataError(f"{path}: {e}") from None
        return model, f"{type(model).__name__} as saved in {path}"
    if "params" not in spec:
        raise _data.DataError(f"{path}: holds no model: expected 'fitted_model' (from "
                              "'jaxfric fit --json' or 'jaxfric diagnose --json') or 'params'")
    kind = MODEL_NAMES.get(spec.get("model", kind), kind)
    try:
        model = model_from_params(kind, spec["params"])
    except _data.DataError as e:
        raise _data.DataError(f"{path}: {e}") from None
    return model, f"{kind} with the parameters of {path}"


def _json_kind(path) -> str | None:
    """The kind (linear, rotary) of the data a saved result was fitted to, if it says."""
    try:
        spec = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    return spec.get("kind") if isinstance(spec, dict) else None


def run_simulate(args) -> int:
    log = (lambda *a: None) if args.quiet else (lambda *a: print(*a, flush=True))
    files = getattr(args, "files", None) or [args.file]
    if len(files) == 1 and _data.joint_layout(args.file):
        if args.run is not None:
            raise _data.DataError("--run picks a run of a fit to several files; a joint file "
                                  "is simulated with each joint's own fit")
        from .joints import simulate_joints

        return simulate_joints(args, MODEL_NAMES[args.model or "two-state"], log,
                               model_from_json)
    for path in files if len(files) > 1 else ():
        if _data.joint_layout(path):
            raise _data.DataError(f"{path}: holds several joints; simulate a joint file alone")
    measurements = []
    for path in files:  # every file read (and checked) before any work
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", _data.DataWarning)
            m = _data.load(path, units=parse_units(args.units), require_force=False,
                           check_sign=False, kind=cli_kind(args))
        print_warnings(caught, args)
        for note in m.notes:
            log(f"note: {note}")
        measurements.append(m)
    model = _simulated_model(args, measurements, log)
    # The velocity the fit used, so that the model's force is the fit's prediction.
    args = derivatives_as_saved(args, _saved_derivatives(args.params) if args.params else {})
    if len(files) == 1:
        return _simulate_file(args, measurements[0], model, Path(args.out), log)
    folder = Path(args.out_dir)
    folder.mkdir(parents=True, exist_ok=True)
    code = 0
    for m, name in zip(measurements, args.out_dir_names):
        log(f"\n{m.source}:")
        code = max(code, _simulate_file(args, m, model, folder / name, log))
    return code


def _simulated_model(args, measurements, log):
    """The model ``simulate`` runs: the one of ``--params`` (``--run K``: the fitted model
    of run K of a fit to several runs), else `--model` with the paper's values."""
    from jaxfric import paper

    kind = _kind_of_command(args)
    if not args.params:
        if args.run is not None:
            raise _data.DataError("--run picks a run of the fit in --params; give --params")
        log(f"model: {kind} with the paper's parameters (give --params FIT.json for yours)")
        model = {"two-state": paper.two_state, "gms": paper.gms5, "lugre": paper.lugre,
                 "tustin": paper.tustin}[kind]()
        return _with_stack_size(model, args.stack_size)
    fitted_on = _json_kind(args.params)
    for m in measurements:
        if fitted_on in _units.KINDS and fitted_on != m.kind:
            raise _data.DataError(f"{args.params}: the model was fitted to {fitted_on} data, "
                                  f"{m.source} is {m.kind} (declare its units or --kind)")
    model, what = model_from_json(args.params, kind)
    runs = _json_runs(args.params)
    if args.run is not None:
        if not runs:
            raise _data.DataError(f"--run {args.run}: {args.params} is a fit to one run")
        if not 1 <= args.run <= len(runs):
            raise _data.DataError(f"--run {args.run}: {args.params} is a fit to {len(runs)} "
                                  f"runs (1 to {len(runs)})")
        saved = runs[args.run - 1].get("fitted_model")
        if isinstance(saved, dict):  # per-run parameters: that run's own values
            model = _loaded(saved, args.params)
            what = (f"{type(model).__name__} of run {args.run} "
                    f"({runs[args.run - 1].get('file', '?')}) as fitted in {args.params}")
    elif any(isinstance(r.get("fitted_model"), dict) for r in runs):
        what += ("; per-run parameters at their mean over the fitted runs (--run K for "
                 "run K's own)")
    log(f"model: {what}")
    return _with_stack_size(model, args.stack_size)


def _json_runs(path) -> list[dict]:
    """The ``"runs"`` of a fit to several runs saved in `path` (``[]`` for one run)."""
    runs = json.loads(Path(path).read_text()).get("runs")
    return [r for r in runs if isinstance(r, dict)] if isinstance(runs, list) else []


def _loaded(saved: dict, path):
    """A model saved by `jaxfric.save_model`, read from `path`."""
    import jaxfric

    try:
        return jaxfric.load_model(saved)
    except (ValueError, TypeError) as e:
        raise _data.DataError(f"{path}: {e}") from None


def _simulate_file(args, m, model, target: Path, log) -> int:
    """Simulate `model` along measurement `m` and write the force to `target` (CSV)."""
    import jaxfric

    m, _ = played_measurement(m, _deadband_option(args.deadband, args.params), log)
    v, a, _ = identification_derivatives(m, args, log)
    out = jaxfric.simulate(model, m.t, m.x, v, full_output=True, load=_load_of(m, model),
                           a=a)
    force = np.asarray(out.force)
    cols = {"t": m.t, "x": m.x, "v": v, "F_model": force}
    if m.force is not None:
        cols[m.force_column] = m.force
        err = force - m.force
        log(f"RMSE against {m.force_column}: {float(np.sqrt(np.mean(err**2))):.4g} "
            f"{m.unit('F')}")
    units = [m.unit(c) for c in ("t", "x", "v", "F", "F")]
    header = ",".join(f"{k}[{u}]" for k, u in zip(cols, units))
    with atomic_file(target) as f:
        np.savetxt(f, np.column_stack(list(cols.values())), delimiter=",", header=header,
                   comments="", fmt="%.17g")
    log(f"{len(m)} samples written to {target} (columns {header})")
    if int(out.overflow) > 0:
        print(f"warning: the memory stack overflowed {int(out.overflow)} times; raise "
              "--stack-size, or play the positions through a wider deadband against noisy "
              f"standstill (--deadband B, in {m.unit('x')}; the log says what was used)",
              file=sys.stderr)
    return 0


def _with_stack_size(model, stack_size):
    """`model` with `stack_size` memory slots (a two-state model; `None`: unchanged)."""
    if stack_size is None:
        return model
    if stack_size < 1:
        raise _data.DataError(f"--stack-size must be >= 1, got {stack_size}")
    if not hasattr(model, "stack_size"):
        raise _data.DataError("--stack-size applies to the two-state model only")
    import dataclasses

    return dataclasses.replace(model, stack_size=stack_size)


def run_compare(args) -> int:
    log = (lambda *a: None) if args.quiet else (lambda *a: print(*a, flush=True))
    kinds = [MODEL_NAMES.get(k.strip()) for k in args.models.split(",")]
    if None in kinds:
        raise _data.DataError(f"--models {args.models!r}: choose from two-state, gms, lugre, "
                              "tustin")
    if several(args):
        return run_compare_runs(args, kinds, log)
    if _data.joint_layout(args.file):
        from .joints import compare_joints

        return compare_joints(args, kinds, log, compare_measurement)
    m = load_for_cli(args, log)
    results = compare_measurement(args, kinds, m, log)
    if args.json:
        known = ({"known_force": {"column": args.known_force, "unit": m.unit("F")}}
                 if getattr(args, "known_force", None) else {})
        write_json(args.json, {"file": str(m.source), "kind": m.kind, "models": results,
                               **known})
        log(f"JSON written to {args.json}")
    return 0


def compare_measurement(args, kinds, m, log) -> dict:
    """Fit each model of `kinds` to `m` and print their RMSE per regime; returns
    ``{model: result JSON with its "regimes"}``."""
    from .._regimes import regime_errors, regimes

    if m.F is None:
        raise _data.DataError(f"{m.source}: 'compare' needs the friction force F")
    m, deadband = played_measurement(m, _deadband_option(args.deadband, None), log)
    extra = {} if deadband is None else {"deadband": deadband}
    v, a, _ = identification_derivatives(m, args, log)
    masks = regimes(m.t, m.x, v)
    target = m.F if m.known is None else m.F - m.known  # the force the models explain
    rows, results = {}, {}
    for kind in kinds:
        log(f"fitting {kind} ...")
        with about(m.source):
            start = initial_model(kind, m.t, m.x, target, v, n_elements=args.elements)
            # A static model cannot represent presliding: fitted on the steady sliding only.
            w = steady_sliding_weights(m.t, m.x, target, v) if kind == "tustin" else None
            res = _fit(start, m.t, m.x, m.F, v, max_steps=args.max_steps, a=a, weights=w,
                       known=m.known)
        # Every sample's error (a sample of weight 0 has no residual in the result).
        errs = regime_errors(np.asarray(res.prediction) - target, masks)
        rows[kind] = errs = _units.speak_json(errs, m.kind)  # regime names in its units
        on = "all samples" if w is None or w.all() else f"{int(w.sum())} steady sliding samples"
        results[kind] = {**result_json(kind, res, m), "regimes": errs, "fitted_on": on, **extra}
        if on != "all samples":  # "rmse" over the whole file, as for the other models
            results[kind].update(rmse=errs["all"]["rmse"], rmse_fitted_samples=float(res.rmse))
    names = list(next(iter(rows.values())))
    steady = [f"{k} to its {r['fitted_on']}" for k, r in results.items()
              if r["fitted_on"] != "all samples"]
    log(f"\nRMSE per regime, {m.unit('F')} (fitted to the whole file"
        + "".join(f"; {s}" for s in steady) + "):")
    log(f"{'model':<10}" + "".join(f"{n[:22]:>24}" for n in names))
    for kind, errs in rows.items():
        log(f"{kind:<10}" + "".join(f"{errs[n]['rmse'] if n in errs else float('nan'):>24.4g}"
                                    for n in names))
    return results
