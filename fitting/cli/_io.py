"""What the commands share: model names, parameter units, reading a file with the command
line's unit and sign options, result tables and JSON."""

import sys
import warnings

import numpy as np

from jaxfric import data as _data

from .._params import natural_units
from .._result import saved_model


MODEL_NAMES = {"two-state": "two-state", "two_state": "two-state", "gms": "gms",
               "lugre": "lugre", "tustin": "tustin"}

def param_units(res) -> dict[str, str]:
    """``{name: SI unit}`` of a fit result's parameters, as declared on the model's fields."""
    return natural_units(res.model)


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
    """Load `args.file` with the CLI's unit and sign options; warnings become one line on
    stderr (unless --quiet)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", _data.DataWarning)
        m = _data.load(args.file, units=parse_units(args.units), flip_force=args.flip_force)
    for w in caught:
        if not args.quiet:
            print(f"warning: {w.message}", file=sys.stderr)
    for note in m.notes:
        log(f"note: {note}")
    return m


def result_json(kind: str, res, m) -> dict:
    units = param_units(res)
    return {
        "model": kind,
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
        "iterations": int(res.num_steps),
        "fitted_model": saved_model(res.fit_model),
    }


def param_table(res) -> str:
    lines = [f"{'parameter':>10}  {'value':>14}  {'std. error':>10}  {'rel.':>8}  unit"]
    units = param_units(res)
    for name in res.names:
        v, s = float(res.params[name]), float(res.stderr[name])
        rel = f"{100 * s / abs(v):7.2g}%" if v != 0 and np.isfinite(s) else "       -"
        lines.append(f"{name:>10}  {v:>14.6g}  {s:>10.3g}  {rel:>8}  {units.get(name, '?')}")
    return "\n".join(lines)


