"""``jaxfric export RESULT.json --c DIR | --mujoco OUT.xml``: the fitted model of a fit or
diagnosis result (or a saved model) as dependency-free C99 for a controller
(`jaxfric.export.to_c`), or as a MuJoCo model with a passive ``dcmotor`` actuator
(`jaxfric.export.to_mujoco`, LuGre models only).

What should not drive a controller is refused, each reason named, unless ``--force``
(`objections`): a fit recorded as not converged; a parameter with an undefined standard
error, or one that must be positive whose standard error is more than `MAX_REL_STDERR` of
its value; a value outside the limits its model
field declares (`jaxfric._fields.parameter_info`: a negative ``Fs``, a weight outside
(0, 1)). The generated files carry the fit's status and standard errors in their opening
comment, and what the MuJoCo model approximates is printed as well as written there."""

import json
import math
import sys
from pathlib import Path

from jaxfric.data import DataError


#: A parameter that must be positive whose standard error is more than this fraction of its
#: value (100 %) is not determined by the data: its one-standard-error interval reaches
#: zero, so the data do not fix even its order of magnitude, and a controller would run
#: on a guess.
MAX_REL_STDERR = 1.0


EXPORT_HELP = """\
Write the model of a fit or diagnosis result (jaxfric fit/diagnose --json, or a model saved
with jaxfric.save_model) as C99 for a real-time loop: DIR/jaxfric_model.h and
DIR/jaxfric_model.c, only <math.h>, no allocation, double precision, the fitted values as
named constants with their units. Interface (SI: s, m, m/s; force N, or N m for a rotary
axis):

  jaxfric_state s;
  jaxfric_init(&s, t0, x0);
  F = jaxfric_step(&s, t, x, v);   /* every sample, in time order */

It reproduces jaxfric's simulate sample by sample. A model with load-dependent friction
(load_friction) has jaxfric_step_load(&s, t, x, v, load) instead, load in N (N m).
Effects with no causal per-sample form are refused by name.

A result that should not drive a controller is refused, each reason named, unless --force:
a fit that did not converge, a parameter with no defined standard error, or one that must
be positive (Fs, l1, ...) whose standard error is more than 100 % of its value, a value
outside its physical limits (a negative Fs). The files say
the fit's status and standard errors in their opening comment.

--mujoco writes an MJCF with one joint (--joint slide or hinge) and a passive dcmotor
actuator (MuJoCo 4) carrying LuGre friction, viscous damping and cogging; other models
and effects are refused with the reason (fit a LuGre model instead: --model lugre).

examples:
  jaxfric fit run1.csv --json fit.json && jaxfric export fit.json --c controller/
  jaxfric diagnose run1.csv --json diag.json && jaxfric export diag.json --c out/
  cc -O2 -std=c99 -c out/jaxfric_model.c -o jaxfric_model.o
  jaxfric fit run1.csv --model lugre --json l.json && jaxfric export l.json --mujoco axis.xml
"""


def add_parser(sub) -> None:
    """Register the ``export`` command on the subparsers `sub` of `build_parser`."""
    import argparse

    p = sub.add_parser("export", help="write a fitted model as C code for a controller",
                       description=EXPORT_HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("result", metavar="RESULT.json",
                   help="a fit or diagnosis result (--json), or a saved model")
    p.add_argument("--c", metavar="DIR", dest="c_dir",
                   help="folder for jaxfric_model.h and jaxfric_model.c (made if missing)")
    p.add_argument("--mujoco", metavar="OUT.xml", help="write a MuJoCo MJCF (LuGre models)")
    p.add_argument("--joint", choices=["slide", "hinge"], default="slide",
                   help="the MJCF's joint: slide (m, N) or hinge (rad, N m); default: slide")
    p.add_argument("--timestep", type=float, default=1e-3,
                   help="the MJCF's simulation time step, s (default: %(default)s)")
    p.add_argument("--force", action="store_true",
                   help="export even a fit that did not converge, or has undetermined or "
                        "non-physical parameters (the files record why it was refused)")
    p.add_argument("--quiet", action="store_true", help="print only errors and warnings")
    p.set_defaults(func=run)


def _load(path: str):
    """``(model, the JSON object)`` of a result or saved model file."""
    import jaxfric

    source = Path(path)
    if not source.is_file():
        raise DataError(f"{path}: no such file")
    try:
        data = json.loads(source.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise DataError(f"{path}: not a readable JSON file ({e})") from None
    try:
        return jaxfric.load_model(data), data
    except (ValueError, TypeError, KeyError) as e:
        raise DataError(f"{path}: {e}") from None


def _number(v) -> float | None:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None


def _outside(constraint, value: float) -> str | None:
    """The limit a `value` breaks, as text, or ``None`` (`jaxfric._fields` constraints)."""
    if constraint == "positive" and not value > 0:
        return "must be > 0"
    if isinstance(constraint, tuple) and constraint[0] == "interval":
        lo, hi = constraint[1], constraint[2]
        if not lo < value < hi:
            return f"must be between {lo:g} and {hi:g}"
    if isinstance(constraint, tuple) and constraint[0] == "above" and not value > constraint[1]:
        return f"must be > {constraint[1]:g}"
    if constraint == "simplex" and not value > 0:
        return "must be > 0 (a weight)"
    return None


def nonphysical(model) -> list[str]:
    """``"name = value (must be > 0)"`` for each parameter value of `model` outside the
    limits its field declares (`jaxfric._fields.parameter_info`), or that is not finite."""
    import equinox as eqx
    import jax
    import numpy as np

    from jaxfric._fields import parameter_info

    leaves = jax.tree.leaves(eqx.filter(model, eqx.is_inexact_array))
    out = []
    for info, leaf in zip(parameter_info(model), leaves):
        values = np.atleast_1d(np.asarray(leaf, dtype=float))
        for i, value in enumerate(values):
            name = info.name if values.size == 1 else f"{info.name}[{i}]"
            broken = ("is not finite" if not math.isfinite(value)
                      else _outside(info.constraint, float(value)))
            if broken:
                unit = "" if info.unit in ("-", "?") else f" {info.unit}"
                out.append(f"{name} = {value:.4g}{unit} ({broken})")
        if info.constraint == "simplex" and abs(float(values.sum()) - 1.0) > 1e-6:
            out.append(f"{info.name} sums to {values.sum():.6g} (weights must sum to 1)")
    return out


def _rel_error(value, error) -> float | None:
    """Standard error over |value|; ``None`` when undefined (null, or a value of 0 with
    a nonzero error)."""
    if error is None:
        return None
    if error == 0:
        return 0.0
    return abs(error) / abs(value) if value != 0 else None


def _positive(constraint) -> bool:
    """A field constraint that keeps the value > 0 (`jaxfric._fields`)."""
    if constraint in ("positive", "simplex"):
        return True
    return (isinstance(constraint, tuple) and constraint[0] in ("interval", "above")
            and constraint[1] >= 0)


def undetermined(data: dict, model) -> list[str]:
    """``"name = value +- error (rel. %)"`` for each parameter of a fit result with an
    undefined (null) standard error, and each one that must be positive (its field's
    constraint, `jaxfric._fields.parameter_info` of `model`) whose standard error is more
    than `MAX_REL_STDERR` of its value. A parameter of either sign (a shape coefficient, a
    cogging amplitude) is judged by its definedness only: near zero its relative error
    says nothing about how well the data fix it."""
    import re

    from jaxfric._fields import parameter_info

    params, stderr = data.get("params"), data.get("stderr")
    if not (isinstance(params, dict) and isinstance(stderr, dict)):
        return []
    positive = {i.name for i in parameter_info(model) if _positive(i.constraint)}
    units = data.get("units") if isinstance(data.get("units"), dict) else {}
    out = []
    for name, value in params.items():
        value = _number(value)
        if value is None or name not in stderr:
            continue
        error = _number(stderr[name])
        rel = _rel_error(value, error)
        unit = f" {units[name]}" if units.get(name) not in (None, "-", "?") else ""
        if rel is None:
            out.append(f"{name} = {value:.4g}{unit} has no defined standard error")
        elif rel > MAX_REL_STDERR and re.sub(r"_\d+$", "", name) in positive:
            out.append(f"{name} = {value:.4g} +- {error:.3g}{unit} ({100 * rel:.3g} % > "
                       f"{100 * MAX_REL_STDERR:.0f} %)")
    return out


def objections(data: dict, model) -> list[str]:
    """Why the result `data` (with its `model`) should not be exported: not converged,
    undetermined parameters (`undetermined`), non-physical values (`nonphysical`)."""
    out = []
    if "converged" in data and data["converged"] is not True:
        out.append(f"the fit did not converge (status {data.get('status', 'unknown')})")
    out += [f"undetermined: {u}" for u in undetermined(data, model)]
    out += [f"non-physical: {u}" for u in nonphysical(model)]
    return out


def record(data: dict, forced_over: list[str]) -> str | None:
    """The lines on the fit that the exported files carry in their opening comment: its
    status and the standard errors (``None`` for a saved model, which has neither), and the
    objections overridden with ``--force``."""
    lines = []
    if "converged" in data:
        verdict = "converged" if data["converged"] is True else "NOT converged"
        r2, rmse = _number(data.get("r2")), _number(data.get("rmse"))
        force = (data.get("data_units") or {}).get("F", "") if isinstance(
            data.get("data_units"), dict) else ""
        lines.append(
            f"fit: {data.get('model', '?')} to {data.get('file', '?')}: {verdict} "
            f"({data.get('status', '?')}) after {data.get('iterations', '?')} steps"
            + (f"; RMSE {rmse:.4g} {force}".rstrip() if rmse is not None else "")
            + (f", R2 {r2:.6f}" if r2 is not None else ""))
    params, stderr = data.get("params"), data.get("stderr")
    if isinstance(params, dict) and isinstance(stderr, dict):
        units = data.get("units") if isinstance(data.get("units"), dict) else {}
        cells = []
        for name, value in params.items():
            error = _number(stderr.get(name))
            unit = f" {units[name]}" if units.get(name) not in (None, "-", "?") else ""
            cells.append(f"{name} = {value!r} +- "
                         f"{'undefined' if error is None else f'{error:.3g}'}{unit}")
        lines.append("standard errors: " + cells[0] if cells else "standard errors: none")
        lines += [f"  {c}" for c in cells[1:]]
    if forced_over:
        lines.append("forced export (export option force) despite: " + "; ".join(forced_over))
    return "\n".join(lines) or None


def run(args) -> int:
    from jaxfric.export import approximations, c_code, ExportError, mjcf

    from ._output import atomic_file

    if not (args.c_dir or args.mujoco):
        raise DataError("nothing to write: give --c DIR and/or --mujoco OUT.xml")
    if not (math.isfinite(args.timestep) and args.timestep > 0):
        raise DataError(f"--timestep {args.timestep}: must be a finite time > 0 (seconds)")
    model, data = _load(args.result)
    data = data if isinstance(data, dict) else {}
    problems = objections(data, model)
    if problems and not args.force:
        raise DataError(f"{args.result}: not exported: " + "; ".join(problems)
                        + " (--force exports it anyway, and the files record why)")
    for problem in problems:
        print(f"warning: {args.result}: exported with --force although {problem}",
              file=sys.stderr)
    comment = record(data, problems)
    if comment is None and not args.quiet:
        print(f"note: {args.result} records no fit status or standard errors (a saved model "
              "or a diagnosis): only the values' physical limits were checked")
    try:
        texts = c_code(model, comment) if args.c_dir else None
        xml = mjcf(model, args.joint, args.timestep, comment) if args.mujoco else None
        approximated = approximations(model) if args.mujoco else []
    except ExportError as e:
        raise DataError(f"{args.result}: {e}") from None
    for note in approximated:
        print(f"warning: MuJoCo approximates the model: {note}", file=sys.stderr)
    if xml is not None:
        with atomic_file(args.mujoco) as f:
            f.write(xml)
        if not args.quiet:
            print(f"wrote {args.mujoco}")
    if texts is not None:
        _write_c(args, texts, atomic_file)
    return 0


def _write_c(args, texts, atomic_file) -> None:
    from ._output import output_folder

    folder = Path(args.c_dir)
    paths = [folder / "jaxfric_model.h", folder / "jaxfric_model.c"]
    with output_folder(folder):  # a folder made here goes again if interrupted
        for path, text in zip(paths, texts):
            with atomic_file(path) as f:
                f.write(text)
    if not args.quiet:
        for path in paths:
            print(f"wrote {path}")
        print(f"model: {texts[0].splitlines()[0].split('(', 1)[1].rsplit(')', 1)[0]}")
        if "#define JAXFRIC_NEEDS_LOAD 1" in texts[0]:
            print("step: jaxfric_step_load(&s, t, x, v, load), load in N (N m on a rotary "
                  "axis): the model reads the transmitted load")
