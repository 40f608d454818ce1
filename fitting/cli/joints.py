"""``jaxfric fit``, ``diagnose``, ``compare`` and ``simulate`` on a file of several joints:
each joint is fitted (diagnosed, compared, simulated) on its own, with its own data-derived
start, and the results are printed per joint, then side by side in one table; the JSON
holds one result per joint.

The joints are fitted one after the other rather than by `fitting.fit_batch`: a batch
starts every dataset from one model, while joints of one robot differ by orders of
magnitude (a 50 N m base joint, a 2 N m wrist); joints of equal length reuse the compiled
solve, so the loop costs little more than one compilation."""

import json
import sys
import warnings
from pathlib import Path

import numpy as np

from jaxfric import data as _data

from ._io import cli_kind, diagnosis_json, param_units, parse_units, print_warnings, result_json
from ._output import atomic_file, write_json
from ._signals import (
    _deadband_option,
    _load_of,
    derivatives_as_saved,
    derivatives_json,
    identification_derivatives,
    played_measurement,
    saved_derivatives,
    velocity_words,
)


def load_joints_for_cli(args, log, **options) -> dict:
    """``{joint: Measurement}`` of `args.file` with the command line's options (and
    `options` for `jaxfric.data.load_joints`)."""
    options.setdefault("flip_force", getattr(args, "flip_force", False))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", _data.DataWarning)
        joints = _data.load_joints(args.file, units=parse_units(args.units),
                                   kind=cli_kind(args), **options)
    print_warnings(caught, args)
    log(f"{args.file}: {len(joints)} joints ({', '.join(joints)})")
    for name, m in joints.items():
        for note in m.notes:
            log(f"note: {name}: {note}")
    return joints


def _suffixed(path: str, name: str) -> Path:
    p = Path(path)
    return p.with_name(f"{p.stem}_{name.replace(' ', '')}{p.suffix}")


def summary_table(results: dict, joints: dict) -> str:
    """One row per joint: status, RMSE, R2 and the parameters common to all, with units."""
    names = [n for n in next(iter(results.values())).names
             if all(n in r.params for r in results.values())]
    units = param_units(next(iter(results.values())), next(iter(joints.values())).kind)
    head = f"{'joint':<9} {'status':<28} {'RMSE':>10} {'R2':>7}" + "".join(
        f" {n:>11}" for n in names)
    under = f"{'':<9} {'':<28} {next(iter(joints.values())).unit('F'):>10} {'':>7}" + "".join(
        f" {units.get(n, '?'):>11}" for n in names)
    rows = [head, under]
    for joint, res in results.items():
        rows.append(f"{joint:<9} {res.status[:28]:<28} {float(res.rmse):>10.4g} "
                    f"{float(res.r2):>7.4f}" + "".join(
                        f" {float(res.params[n]):>11.4g}" for n in names))
    return "\n".join(rows)


def fit_joints(args, kind: str, log, fit_measurement) -> int:
    """`fit_measurement` (`fitting.cli.commands`) on each joint, then the joints' table."""
    from .plots import plot_fit

    joints = load_joints_for_cli(args, log)
    results, deadbands = {}, {}
    for name, m in joints.items():
        log(f"\n=== {name} ===")
        played, b = played_measurement(m, _deadband_option(args.deadband, None), log)
        deadbands[name] = {} if b is None else {"deadband": b}
        results[name] = fit_measurement(args, kind, played, log)
    log(f"\n{kind} per joint:\n{summary_table(results, joints)}")
    if args.json:
        first = next(iter(joints.values()))
        write_json(args.json, {"file": str(args.file), "kind": first.kind,
                               "joints": {n: {**result_json(kind, results[n], joints[n]),
                                              "velocity": velocity_words(joints[n], args),
                                              "derivatives": derivatives_json(joints[n], args),
                                              **deadbands[n]} for n in joints}})
        log(f"JSON written to {args.json}")
    if args.plot:
        for name, m in joints.items():
            target = _suffixed(args.plot, name)
            plot_fit(target, m, results[name], kind)
            log(f"plot written to {target}")
    return 0


def diagnose_joints(args, kind: str, log, diagnose_measurement) -> int:
    """`diagnose_measurement` on each joint (reports in one folder per joint), then a
    table of the joints."""

    joints = load_joints_for_cli(args, log)
    out = {}
    for name, m in joints.items():
        log(f"\n=== {name} ===")
        report = Path(args.report) / name.replace(" ", "_") if args.report else None
        d = diagnose_measurement(args, kind, m, log, report)
        out[name] = diagnosis_json(d, m.kind)
    rows = [f"{'joint':<9} {'baseline RMSE':>14} {'final RMSE':>11}  added"]
    for name, d in out.items():
        rows.append(f"{name:<9} {d['baseline']['rmse']:>14.4g} {d['after']['rmse']:>11.4g}  "
                    f"{' + '.join(d['after']['added']) or '-'}")
    unit = next(iter(joints.values())).unit("F")
    log(f"\ndiagnosis per joint (RMSE in {unit}):\n" + "\n".join(rows))
    if args.json:
        write_json(args.json, {"file": str(args.file), "joints": out})
        log(f"JSON written to {args.json}")
    return 0


def compare_joints(args, kinds, log, compare_measurement) -> int:
    """`compare_measurement` on each joint; the JSON holds one comparison per joint."""
    joints = load_joints_for_cli(args, log)
    out = {}
    for name, m in joints.items():
        log(f"\n=== {name} ===")
        out[name] = compare_measurement(args, kinds, m, log)
    if args.json:
        write_json(args.json, {"file": str(args.file), "kind": next(iter(joints.values())).kind,
                               "joints": out})
        log(f"JSON written to {args.json}")
    return 0


def _params_spec(params) -> dict | None:
    """The ``--params`` JSON as a dict, read once; None without one, or when it is not a
    readable JSON object (`model_from_json` then names the problem)."""
    if not params:
        return None
    try:
        spec = json.loads(Path(params).read_text())
    except (OSError, ValueError):
        return None
    return spec if isinstance(spec, dict) else None


def _joint_models(args, kind: str, joints: dict, model_from_json, spec) -> dict:
    """``{joint: (model, description)}``: from a several-joint fit (``"joints"`` in `spec`,
    the ``--params`` JSON), one model for all joints (any other ``--params``), or the
    paper's values."""
    import jaxfric
    from jaxfric import paper

    if not args.params:
        model = {"two-state": paper.two_state, "gms": paper.gms5, "lugre": paper.lugre,
                 "tustin": paper.tustin}[kind]()
        return dict.fromkeys(joints, (model, f"{kind} with the paper's parameters"))
    if not (spec is not None and isinstance(spec.get("joints"), dict)):
        model = model_from_json(args.params, kind)
        return dict.fromkeys(joints, model)
    out = {}
    for name, m in joints.items():
        entry = spec["joints"].get(name)
        if not isinstance(entry, dict):
            raise _data.DataError(f"{args.params}: no model for {name} (it has "
                                  f"{', '.join(spec['joints']) or 'none'})")
        if entry.get("kind", m.kind) != m.kind:
            raise _data.DataError(f"{args.params}: {name} was fitted to {entry['kind']} data, "
                                  f"{m.source} is {m.kind}")
        try:
            out[name] = (jaxfric.load_model(entry), f"{name} as fitted in {args.params}")
        except (ValueError, TypeError, KeyError) as e:
            raise _data.DataError(f"{args.params}: {name}: {e}") from None
    return out


def _joint_deadband(args, name: str, spec):
    """The deadband for joint `name`: ``--deadband``, else the one saved for that joint in
    a several-joint ``--params`` (`spec`; or at the top of a one-model one), else 'auto'. A
    model saved without one was played through none."""
    if args.deadband is not None or spec is None:
        return _deadband_option(args.deadband, None)
    per_joint = spec.get("joints")
    entry = per_joint.get(name) if isinstance(per_joint, dict) else None
    saved = entry.get("deadband") if isinstance(entry, dict) else spec.get("deadband")
    return None if saved is None else _deadband_option(saved, None)


def _joint_derivatives(spec, joints) -> dict:
    """``{joint: "derivatives" entry}`` of the result JSON `spec` (a several-joint result:
    each joint's own; a one-axis result: its entry for every joint; none: empty)."""
    if spec is None:
        return {name: {} for name in joints}
    per_joint = spec.get("joints")
    if isinstance(per_joint, dict):
        return {name: saved_derivatives(per_joint.get(name)) for name in joints}
    return dict.fromkeys(joints, saved_derivatives(spec))


def simulate_joints(args, kind: str, log, model_from_json) -> int:
    """Each joint's model along its motion; one CSV: ``t``, then per joint i ``x{i}``,
    ``v{i}``, ``F_model{i}`` (and the measured ``F{i}``), in the file's units; the
    velocity and acceleration from `identification_derivatives` as the joint's fit or
    diagnosis took them (its saved ``"derivatives"``, unless ``--derivatives`` says)."""
    import jaxfric

    joints = load_joints_for_cli(args, log, require_force=False, check_sign=False,
                                 flip_force=False)
    spec = _params_spec(args.params)  # read once: model, deadband, derivatives
    models = _joint_models(args, kind, joints, model_from_json, spec)
    saved = _joint_derivatives(spec, joints)
    first = next(iter(joints.values()))
    cols = {f"t[{first.unit('t')}]": first.t}
    for name, m in joints.items():
        model, what = models[name]
        log(f"{name}: {what}")
        m, _ = played_measurement(m, _joint_deadband(args, name, spec), log)
        # The velocity and acceleration the joint's fit or diagnosis used (its columns, or
        # the same zero-phase estimates), so that the force is its prediction.
        v, a, _ = identification_derivatives(m, derivatives_as_saved(args, saved[name]), log)
        out = jaxfric.simulate(model, m.t, m.x, v, full_output=True,
                               load=_load_of(m, model), a=a)
        force, i = np.asarray(out.force), name.split()[-1]
        cols[f"x{i}[{m.unit('x')}]"] = m.x
        cols[f"v{i}[{m.unit('v')}]"] = v
        cols[f"F_model{i}[{m.unit('F')}]"] = force
        if m.force is not None:
            cols[f"{m.force_column}{i}[{m.unit('F')}]"] = m.force
            rmse = float(np.sqrt(np.mean((force - m.force) ** 2)))
            log(f"{name}: RMSE against {m.force_column}: {rmse:.4g} {m.unit('F')}")
        if int(out.overflow) > 0:
            print(f"warning: {name}: the memory stack overflowed {int(out.overflow)} times; "
                  f"raise the model's stack_size, or play the positions through a wider "
                  f"deadband (--deadband B, in {m.unit('x')}; the log says what was used)",
                  file=sys.stderr)
    if len({len(c) for c in cols.values()}) > 1:
        raise _data.DataError(f"{args.file}: the joints have different lengths; simulate "
                              "them one file at a time")
    header = ",".join(cols)
    with atomic_file(args.out) as f:
        np.savetxt(f, np.column_stack(list(cols.values())), delimiter=",", header=header,
                   comments="", fmt="%.17g")
    log(f"{len(first)} samples of {len(joints)} joints written to {args.out}")
    return 0
