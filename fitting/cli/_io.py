"""What the commands share: model names, parameter units, checking the options, reading a
file with the command line's unit, kind and sign options, result tables and JSON.

Tables and JSON speak the file's kind (`jaxfric.units`): a rotary file's parameters are in
N m, rad, rad/s, N m s/rad ..., its travel in rad and deg."""

import contextlib
import math
import sys
import warnings

import numpy as np

from jaxfric import data as _data, units as _units

from .._params import natural_units
from .._result import saved_model, weak_lines


MODEL_NAMES = {"two-state": "two-state", "two_state": "two-state", "gms": "gms",
               "lugre": "lugre", "tustin": "tustin"}
DEFAULT_MODEL = "two-state"


def model_kind(model) -> str:
    """The command line's name (``"two-state"``, ``"gms"``, ``"lugre"``, ``"tustin"``) of
    `model`'s class, its effects aside."""
    import jaxfric
    from jaxfric.effects import WithEffects

    base = model.base if isinstance(model, WithEffects) else model
    for cls, name in ((jaxfric.TwoState, "two-state"), (jaxfric.GMS, "gms"),
                      (jaxfric.LuGre, "lugre"), (jaxfric.Tustin, "tustin")):
        if isinstance(base, cls):
            return name
    return type(base).__name__


def chosen_kind(args, model=None) -> str:
    """The model kind of a command: `model`'s (from ``--params``) when given, which an
    explicit ``--model`` must agree with; else ``--model``, else `DEFAULT_MODEL`.
    `DataError` when they disagree."""
    asked = MODEL_NAMES[args.model] if getattr(args, "model", None) else None
    if model is None:
        return asked or DEFAULT_MODEL
    held = model_kind(model)
    if asked is not None and asked != held:
        raise _data.DataError(
            f"--model {args.model}: {args.params} holds a {type(model).__name__} model "
            f"({held}); leave out --model to use it, or --params to start a {asked} model "
            "from the data")
    return held

def param_units(res, kind: str = _units.LINEAR) -> dict[str, str]:
    """``{name: SI unit}`` of a fit result's parameters, as declared on the model's fields,
    in the words of a file of `kind` (``"N m"`` for a rotary file's ``"N"``)."""
    return {k: _units.unit_for(u, kind) for k, u in natural_units(res.model).items()}


def check_options(args) -> None:
    """The numeric options of a command are usable: `DataError` (one line) otherwise."""
    elements = getattr(args, "elements", None)
    if elements is not None and elements < 1:
        raise _data.DataError(f"--elements {elements}: a GMS model needs at least 1 element")
    steps = getattr(args, "max_steps", None)
    if steps is not None and steps < 0:
        raise _data.DataError(f"--max-steps {steps}: must be 0 or more")
    search = getattr(args, "search_samples", None)
    if search is not None and search < 0:
        raise _data.DataError(f"--search-samples {search}: must be 0 (every sample) or more")
    if getattr(args, "rotary", False) and getattr(args, "kind", None) == _units.LINEAR:
        raise _data.DataError("--rotary and --kind linear contradict each other")
    window = getattr(args, "velocity_window", None)
    if window is not None and not (math.isfinite(window) and window > 0):
        raise _data.DataError(f"--velocity-window {window}: must be a finite time > 0 "
                              "(seconds)")


@contextlib.contextmanager
def about(source):
    """Within it, a `DataError` the library raises on the arrays of a file (a start value it
    cannot estimate, a derived velocity it refuses) names the file `source` first."""
    try:
        yield
    except _data.DataError as e:
        if str(e).startswith(str(source)):
            raise
        raise _data.DataError(f"{source}: {e}") from None


def cli_kind(args) -> str | None:
    """The kind asked on the command line (``--rotary`` or ``--kind``), or ``None``."""
    if getattr(args, "rotary", False):
        return _units.ROTARY
    return getattr(args, "kind", None)


def print_warnings(caught, args) -> None:
    for w in caught:
        if not args.quiet:
            print(f"warning: {w.message}", file=sys.stderr)


def describe(m) -> str:
    """One line on a measurement: samples, duration, travel and force range, in its kind."""
    f, col = m.force, m.force_column
    line = (f"{m.source}: {m.kind}, {len(m)} samples over {m.t[-1] - m.t[0]:.4g} s, travel "
            f"{_units.travel_text(float(np.ptp(m.x)), m.kind)}")
    if f is not None:
        line += f", {col} {f.min():.4g} .. {f.max():.4g} {m.unit(col)}"
    return line


def parse_units(specs) -> dict[str, str]:
    """``["x=mm", "F=mN,t=ms"]`` -> ``{"x": "mm", "F": "mN", "t": "ms"}``."""
    units = {}
    for spec in specs or []:
        for part in spec.split(","):
            if not part.strip():
                continue
            if "=" not in part:
                raise _data.DataError(f"--units {part!r}: expected COLUMN=UNIT, e.g. x=mm")
            col, unit = (s.strip() for s in part.split("=", 1))
            units[col] = unit
    return units


def load_for_cli(args, log):
    """Load `args.file` with the CLI's unit and sign options (and its ``--known-force``
    column); warnings become one line on stderr (unless --quiet)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", _data.DataWarning)
        m = _data.load(args.file, units=parse_units(args.units), flip_force=args.flip_force,
                       kind=cli_kind(args), known=getattr(args, "known_force", None))
    print_warnings(caught, args)
    for note in m.notes:
        log(f"note: {note}")
    return m


def data_units(kind: str) -> dict[str, str]:
    """``{column: SI unit}`` of the standard columns of a file of `kind`."""
    return {c: _units.si_unit(c, kind) for c in ("t", "x", "v", "a", "F", "u")}


def result_json(kind: str, res, m) -> dict:
    """The JSON of a fit: ``"model"`` is the kind of the model fitted (`model_kind` of
    ``res.model``), whatever the caller's `kind` says."""
    units = param_units(res, m.kind)
    return {
        "model": model_kind(res.model),
        "kind": m.kind,
        "data_units": data_units(m.kind),
        "file": str(m.source),
        "samples": len(m),
        "params": {k: float(v) for k, v in res.params.items()},
        "stderr": {k: float(v) for k, v in res.stderr.items()},
        "units": {k: units.get(k, "?") for k in res.params},
        "rmse": float(res.rmse),
        "nrmse": float(res.nrmse),
        "r2": float(res.r2),
        "converged": bool(res.converged),
        "status": res.status,
        "stopped": getattr(res, "stopped", ""),  # which stopping rule ended the fit, in words
        "stop": getattr(res, "stop", ""),  # its kind (fitting._result.STOPS)
        # Parameters the data do not determine (held at their start, stderr null) and those
        # pinned at a bound of their transform.
        "undetermined": list(getattr(res, "undetermined", ())),
        "at_bound": [n for n, b in zip(getattr(res, "leaf_names", ()),
                                       np.asarray(res.at_bound).ravel()) if b]
        if getattr(res, "at_bound", None) is not None and np.ndim(res.rmse) == 0 else [],
        "iterations": int(res.num_steps),
        "overflow": int(res.overflow),  # memory entries dropped in the final simulation
        "fitted_model": saved_model(res.fit_model),
    }


def param_table(res, kind: str = _units.LINEAR) -> str:
    lines = [f"{'parameter':>10}  {'value':>14}  {'std. error':>10}  {'rel.':>8}  unit"]
    units = param_units(res, kind)
    for name in res.names:
        v, s = float(res.params[name]), float(res.stderr[name])
        rel = f"{100 * s / abs(v):7.2g}%" if v != 0 and np.isfinite(s) else "       -"
        lines.append(f"{name:>10}  {v:>14.6g}  {s:>10.3g}  {rel:>8}  {units.get(name, '?')}")
    single = hasattr(res, "weakly_determined") and np.ndim(res.rmse) == 0
    return "\n".join(lines + (weak_lines(res) if single else []))


def diagnosis_json(d, kind: str) -> dict:
    """`fitting.Diagnosis.to_json` in the words of a file of `kind`, with the kind and the
    units of its numbers (the saved model is left as saved)."""
    out = d.to_json()
    model = out.pop("fitted_model", None)
    out = _units.speak_json(out, kind)
    out.update(kind=kind, data_units={c: _units.si_unit(c, kind) for c in ("t", "x", "v", "F")})
    if model is not None:
        out["fitted_model"] = model
    return out
