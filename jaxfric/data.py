"""Measurements from files (CSV, NPZ), DataFrames or arrays, checked and converted to SI.

A measurement has columns ``t`` (time), ``x`` (position or angle) and either ``F`` (the
friction force or torque) or ``u`` (the drive force or torque, which also contains inertia
and offsets); optionally ``v`` (velocity), ``a`` (acceleration), ``normal`` (normal load)
and ``load`` (the transmitted load: N, or N m on a rotary file; for
`jaxfric.effects.LoadFriction`).
Any other numeric column is kept in `Measurement.extra`; a text column is ignored with a note.

**Units.** SI by default: s, m, m/s, m/s^2, N for a linear file; s, rad, rad/s, rad/s^2,
N m for a rotary one (a joint or motor axis). A unit in the header converts: ``t[ms]``,
``x[mm]``, ``F[mN]``, ``x[deg]``, ``v[rpm]``, ``F[N m]`` ... (see `jaxfric.units`), or pass
``units={"x": "mm"}`` (the CLI's ``--units x=mm``). The units decide whether a file is
linear or rotary (`Measurement.kind`); ``kind=`` (``--rotary``) decides for a file without
units.

**Checks.** Every problem raises `DataError`, a `ValueError` whose one-line message names the
source, the column and the (1-based, data) row, and for a text file the line as
``FILE:LINE:``: a missing, unreadable or non-regular file
(devices and FIFOs are refused unread), a file or column beyond the size limits
(`MAX_FILE_BYTES`, `MAX_SAMPLES`), a wrong NPZ, no header, missing column, non-numeric
cell, NaN/inf, time not increasing or duplicated, a time step shorter than
`MIN_STEP_FRACTION` of the median step (a logger glitch), position steps implying an absurd
velocity, a force column with one value throughout (when a force is required), too few
samples, no motion at all, absurd
magnitudes (beyond `ABSURD`, or a glitch 1000 times beyond the rest of its column,
`jaxfric._outliers`), and linear positions spanning more than 2 m with no unit declared (millimetres
read as metres; declare ``x[m]`` to confirm). Suspicious but possible data give a
`DataWarning` instead: undeclared units that look like another unit (`jaxfric._plausible`:
ms, mm, mN, deg, mm/s, deg/s, rpm), and a force whose sign is opposite to the friction
convention (friction has the sign of ``v``), corrected with ``flip_force=True`` (CLI
``--flip-force``).

Irregular sampling is kept as it is: every model takes the time column as given. A step
shorter than `MIN_STEP_FRACTION` (1/1000) of the median step is refused, naming its row:
jitter and dropped samples make steps of a fraction to a few times the median, while a
step a thousand times shorter is a logger glitch (a record written twice with a clock
tick between), and a velocity taken over it is a thousand times what the same position
change gives over an ordinary step (one encoder count becomes an absurd velocity). The
fraction is the same factor of 1000 the relative outlier rule uses (`jaxfric._outliers`).
"""

import dataclasses
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import equinox as eqx
import numpy as np

from . import _files, _joints, _outliers, _plausible, units as _units
from ._files import DataError
from .motion import velocity
from .units import LINEAR


class DataWarning(UserWarning):
    """A measurement looks suspicious (units, sign convention) but can be used."""


# The unit tables live in `jaxfric.units` (linear and rotary); these names stay here.
UNITS = _units.UNITS
QUANTITY = _units.QUANTITY[LINEAR]
SI_UNIT = _units.SI_UNIT
MAX_FILE_BYTES = _files.MAX_FILE_BYTES
MAX_SAMPLES = _files.MAX_SAMPLES
MAX_COLUMNS = _files.MAX_COLUMNS

MIN_SAMPLES = 10
#: A time step shorter than this fraction of the median step is a logger glitch: refused.
MIN_STEP_FRACTION = 1e-3
#: Travel (m) beyond which an undeclared position unit is taken for a mistake.
MAX_UNDECLARED_SPAN_M = 2.0
# Beyond these a value is not a friction measurement in SI, whatever the machine.
ABSURD = {"t": 1e7, "x": 1e3, "v": 1e3, "a": 1e6, "F": 1e7, "u": 1e7, "normal": 1e8,
          "load": 1e8}
#: The same for a rotary file (rad, rad/s, rad/s^2, N m): a motor axis turns many times.
ABSURD_ROTARY = {**ABSURD, "x": 1e6, "v": 1e4, "a": 1e7}
_STANDARD = frozenset(QUANTITY)


class Measurement(eqx.Module):
    """One experiment in SI units: 1-D float arrays of equal length, and where it came from.

    The one container for measured data: `load` returns it, and the fits take it
    (`fitting.Dataset` is this class).

    - `t` (s), `x` (m, or rad for a rotary file): always present.
    - `F` (N, or N m): friction force (torque), sign of ``v``, or ``None``.
    - `v` (m/s, or rad/s): velocity, or ``None`` (then derived from `x`, see `velocity`).
    - `weights`: per-sample weights >= 0 for a fit (0 drops a sample), or ``None`` (ones).
    - `u` (N, or N m): drive force (friction plus inertia and offsets), or ``None``; `a`
      (m/s^2, or rad/s^2), `normal` (N) and `load` (the transmitted load: N, or N m on a
      rotary file; what `jaxfric.effects.LoadFriction` reads): ``None`` unless given.
    - `known` (N, or N m): a known force component in the measured force (an external
      force applied on purpose, a model part already identified), subtracted from `F`
      (or `u`) by the fits and not fitted; ``None`` unless given (``load(..., known=)``).
    - `source`: where it came from (file name or ``"<arrays>"``); `notes`: what was
      converted or flipped while loading; `extra`: other columns by name.
    - `kind`: ``"linear"`` (a slide) or ``"rotary"`` (a joint or motor axis), from the
      units of the file (see `jaxfric.units`).
    """

    t: Any
    x: Any
    F: Any = None
    v: Any = None
    weights: Any = None
    u: Any = None
    a: Any = None
    normal: Any = None
    load: Any = None
    known: Any = None
    source: str = eqx.field(static=True, default="<arrays>")
    notes: tuple[str, ...] = eqx.field(static=True, default=(), converter=tuple)
    extra: dict = eqx.field(default_factory=dict)
    kind: str = eqx.field(static=True, default=LINEAR)

    @property
    def force(self) -> np.ndarray:
        """`F` if present, else `u`."""
        return self.F if self.F is not None else self.u

    @property
    def force_column(self) -> str:
        return "F" if self.F is not None else "u"

    def unit(self, column: str) -> str:
        """The SI unit of a standard `column` for this measurement's kind (``"N m"``)."""
        return _units.si_unit(column, self.kind)

    def __len__(self) -> int:
        return int(self.t.size)

    def velocity(self, window_s: float | None = None) -> np.ndarray:
        """Velocity, m/s: `v` if given; else, with `window_s` (s), the central difference of
        `x` over ``+-h`` samples, ``h`` = half the window in median sample steps (smooths
        quantised positions, as needed before differentiating again for inertia); else the
        backward difference of `x` (``v[0] = 0``), as `jaxfric.simulate` derives it."""
        if self.v is not None:
            return self.v
        return velocity(self.t, self.x, window_s)

    def __repr__(self) -> str:
        cols = [c for c in ("t", "x", "F", "u", "v", "a", "normal", "load", "known")
                if getattr(self, c) is not None]
        span = self.t[-1] - self.t[0]
        return (f"Measurement({self.source!r}, {self.kind}, {len(self)} samples, {span:.3g} s, "
                f"columns {cols})")


def _from_mapping(data: Mapping[str, Any]):
    parsed = _files.parse_header("<arrays>", [str(k) for k in data])
    columns = {}
    for (name, _), value in zip(parsed, data.values()):
        arr = np.asarray(value)
        if arr.ndim != 1:
            raise DataError(f"<arrays>: column {name!r} must be 1-D, got shape {arr.shape}")
        if not np.issubdtype(arr.dtype, np.number):
            raise DataError(f"<arrays>: column {name!r}: not numeric (dtype {arr.dtype})")
        columns[name] = arr.astype(np.float64)
    return parsed, columns, [], None


def _read(data) -> tuple[str, list[tuple[str, str | None]], dict[str, np.ndarray], list[str],
                         Any]:
    """``(source, [(column, header unit)], {column: values}, notes, where)`` from a path, a
    DataFrame or a mapping; ``where(row)`` is how a message names a data row's place
    (``FILE:LINE`` for a text file, else the source)."""
    lines = None
    if isinstance(data, str | Path):
        path = Path(data)
        source = str(path)
        if path.suffix.lower() == ".npz":
            parsed, columns, notes, lines = _files.read_npz(path, _STANDARD)
        else:
            parsed, columns, notes, lines = _files.read_csv(path, _STANDARD)
    elif hasattr(data, "columns") and hasattr(data, "to_numpy"):  # a DataFrame
        source = "<DataFrame>"
        parsed, columns, notes, _ = _from_mapping(
            {str(c): data[c].to_numpy() for c in data.columns})
    elif isinstance(data, Mapping):
        source = "<arrays>"
        parsed, columns, notes, _ = _from_mapping(data)
    else:
        raise TypeError(f"cannot load a {type(data).__name__}; give a path, a DataFrame or a dict")
    return source, parsed, columns, notes, _where(source, lines)


def _where(source: str, lines=None):
    """``row -> place`` for messages: ``FILE:LINE`` when the file's lines are known."""
    if lines is None:
        return lambda row: source
    return lambda row: f"{source}:{lines.line(row)}"


def _declared(source: str, columns: dict, header_unit: dict, units: dict) -> dict[str, str]:
    """``{column: unit}`` from the header and the caller, which must agree."""
    for name in units:
        if name not in columns:
            raise DataError(
                f"{source}: a unit was given for column {name!r}, which is not in the data"
            )
    declared = {}
    for name in columns:
        if header_unit.get(name) and name in units and units[name] != header_unit[name]:
            raise DataError(
                f"{source}: column {name!r} is declared in {header_unit[name]!r} in the header "
                f"and in {units[name]!r} by the caller"
            )
        unit = header_unit.get(name) or units.get(name)
        if unit is not None:
            declared[name] = unit
    return declared


def _decide_kind(source: str, declared: dict[str, str], kind: str | None,
                 default: str = LINEAR) -> str:
    """Linear or rotary from the declared units, or `kind` (else `default`) when they do
    not tell."""
    if kind is not None and kind not in _units.KINDS:
        raise DataError(f"kind {kind!r}: expected 'linear' or 'rotary'")
    votes = {c: _units.kind_of_unit(c, u) for c, u in declared.items()}
    votes = {c: k for c, k in votes.items() if k is not None}
    found = set(votes.values())
    if len(found) > 1:
        said = ", ".join(f"{c} in {declared[c]}" for c in votes)
        raise DataError(f"{source}: mixes linear and rotary units ({said}); a rotary file has "
                        "x in rad or deg, v in rad/s and F in N m")
    if found and kind is not None and kind not in found:
        said = ", ".join(f"{c} in {declared[c]}" for c in votes)
        raise DataError(f"{source}: asked for a {kind} file, but its units are "
                        f"{found.pop()} ({said})")
    return found.pop() if found else (kind or default)


def _to_si(source: str, columns: dict[str, np.ndarray], declared: dict[str, str], kind: str
           ) -> list[str]:
    """Convert `columns` in place to SI from the `declared` units; returns the notes of
    what was converted."""
    notes = []
    for name, unit in declared.items():
        factor = _units.unit_factor(name, unit, kind)
        if factor is None:
            quantity = _units.QUANTITY[kind][name]
            article = "an" if quantity[0] in "aeiou" else "a"
            raise DataError(
                f"{source}: column {name!r}: unknown unit {unit!r} for {article} {quantity}; "
                f"use one of {', '.join(UNITS[quantity])}"
            )
        if factor != 1.0:
            columns[name] = columns[name] * factor
            notes.append(f"{name} converted from {unit} to {_units.si_unit(name, kind)}")
    return notes


def _known_to_si(source: str, columns: dict, declared: dict, kind: str, known: str
                 ) -> list[str]:
    """Convert the known-force column `known` in place to SI as a force (N, or N m)."""
    if known not in columns:
        raise DataError(f"{source}: no column {known!r} for the known force (columns: "
                        f"{', '.join(columns)})")
    if known in QUANTITY:
        raise DataError(f"{source}: column {known!r} is a standard column ({QUANTITY[known]}), "
                        "not a known force")
    unit = declared.get(known)
    if unit is None:
        return [f"known force: column {known!r} in {_units.si_unit('F', kind)} (no unit "
                "declared)"]
    factor = _units.unit_factor("F", unit, kind)
    if factor is None:
        raise DataError(f"{source}: column {known!r}: unknown force unit {unit!r}")
    columns[known] = columns[known] * factor
    return [f"known force: column {known!r} converted from {unit} to "
            f"{_units.si_unit('F', kind)}"]


def _orient_force(m: Measurement, *, flip_force: bool, check_sign: bool) -> Measurement:
    """`m` with its force flipped when asked; otherwise `m`, with a warning when its force
    looks recorded with the opposite sign to the friction convention."""
    source = m.source
    if flip_force and m.force is not None:
        column = m.force_column
        flipped = {column: -getattr(m, column)}
        if m.known is not None:
            flipped["known"] = -m.known
        notes = (*m.notes, f"{column} multiplied by -1 (--flip-force)")
        return dataclasses.replace(m, **flipped, notes=notes)
    elif check_sign and m.force is not None:
        corr = sign_correlation(m)
        if corr < -0.2:
            warnings.warn(
                f"{source}: column {m.force_column!r} is anti-correlated with the direction of "
                f"motion (corr(sign v, {m.force_column}) = {corr:.2f}): it looks recorded with the "
                "opposite sign to the friction convention (friction has the sign of v). "
                "Use --flip-force (flip_force=True) if so.",
                DataWarning,
                stacklevel=4,  # the caller of `load`
            )
    return m


def load(
    data,
    *,
    units: Mapping[str, str] | None = None,
    flip_force: bool = False,
    require_force: bool = True,
    check_sign: bool = True,
    kind: str | None = None,
    known: str | None = None,
) -> Measurement:
    """Read, check and convert a measurement to SI.

    **Arguments:**

    - `data`: a path (``.csv``/``.txt``/``.tsv`` or ``.npz``), a pandas ``DataFrame``, or a
      mapping of column name -> 1-D array (names may carry units: ``{"x[mm]": ...}``).
    - `units`: units for columns whose header has none, e.g. ``{"x": "mm", "F": "mN"}``.
    - `flip_force`: multiply `F` (or `u`) by -1 (for data recorded with the opposite sign).
    - `require_force`: a column ``F`` or ``u`` must exist.
    - `check_sign`: warn (`DataWarning`) when the force is anti-correlated with the direction
      of motion, i.e. recorded with the opposite sign convention.
    - `kind`: ``"linear"`` or ``"rotary"`` for a file whose units do not tell (``None``:
      from the units, linear when there are none); a contradiction is an error.
    - `known`: the name of a column holding a known force component (EMPS's ``pulse``):
      read as a force (its unit converted as ``F``'s, N or N m; flipped with the force),
      kept as `Measurement.known` and subtracted from the force by the fits.

    Undeclared units that look wrong (`jaxfric._plausible`: ms read as s, mm as m, mN as N,
    deg as rad, v in mm/s or rpm) give a `DataWarning` naming the likely unit.

    **Returns:** a `Measurement`. **Raises:** `DataError` with a one-line message.
    """
    return _load(_read(data), units=units, flip_force=flip_force, require_force=require_force,
                 check_sign=check_sign, kind=kind, known=known)


def load_joints(
    data,
    *,
    units: Mapping[str, str] | None = None,
    flip_force: bool = False,
    require_force: bool = True,
    check_sign: bool = True,
    kind: str | None = None,
) -> dict[str, Measurement]:
    """Read a file of several joints: ``{"joint 1": Measurement, ...}``, each checked and
    converted as `load` does.

    The layouts (`jaxfric._joints`): numbered columns beside one ``t`` (``q1..qN``,
    ``dq1..dqN``, ``tau1..tauN``, or ``x1``, ``v1``, ``F1`` ...; units per column such as
    ``q1[deg]``), or a numeric ``joint`` column with the standard columns. Robot names
    (q, dq, tau) make the joints rotary unless their units say otherwise. `units` may name
    a numbered column (``{"q2": "deg"}``), a prefix for all joints (``{"q": "deg"}``) or a
    standard column (``{"x": "deg"}``); the other arguments are as for `load`.
    """
    source, parsed, columns, notes, _ = _read(data)
    if _joints.joint_layout(columns) is None:
        raise DataError(f"{source}: one joint only (no q1.., x1.. or 'joint' column); "
                        "use jaxfric.data.load")
    per_joint, robot = _joints.split(source, parsed, columns, dict(units or {}), DataError)
    out = {}
    for name, mapping in per_joint.items():
        read = (f"{source} {name}", _files.parse_header(source, list(mapping)),
                {k.split("[")[0]: v for k, v in mapping.items()}, notes, None)
        out[name] = _load(read, units={}, flip_force=flip_force, require_force=require_force,
                          check_sign=check_sign, kind=kind,
                          default_kind=_units.ROTARY if robot else LINEAR)
    return out


def joint_layout(data) -> str | None:
    """``"wide"`` (q1, dq1, tau1 ...), ``"long"`` (a ``joint`` column) or ``None`` (one
    joint) for a path (only its header is read), a DataFrame or a mapping."""
    if isinstance(data, str | Path):
        names = _files.header_names(Path(data))
    else:
        names = [str(c).split("[")[0].strip() for c in data]
    return _joints.joint_layout(names)


def _load(read, *, units, flip_force, require_force, check_sign, kind,
          default_kind: str = LINEAR, known: str | None = None) -> Measurement:
    source, parsed, columns, read_notes, where = read
    layout = _joints.joint_layout(columns)
    if layout is not None:
        raise DataError(f"{source}: holds several joints ({layout} layout: "
                        f"{', '.join(list(columns)[:4])}, ...); read it with "
                        "jaxfric.data.load_joints (the command line fits each joint)")
    parsed, columns, units, renamed, robot = _joints.rename_aliases(parsed, columns,
                                                                    dict(units or {}))
    header_unit = dict(parsed)
    declared = _declared(source, columns, header_unit, units)
    kind = _decide_kind(source, declared, kind, _units.ROTARY if robot else default_kind)
    notes = [*read_notes, *renamed, *_to_si(source, columns, declared, kind)]
    if known is not None:
        notes += _known_to_si(source, columns, declared, kind, known)
    _check(source, columns, require_force, kind, where)
    for message in _spike_warnings(source, columns, kind, where or _where(source)):
        warnings.warn(message, DataWarning, stacklevel=3)
    m = Measurement(
        **{k: columns.get(k) for k in ("t", "x", "F", "u", "v", "a", "normal", "load")},
        known=None if known is None else columns[known],
        source=source,
        extra={k: v for k, v in columns.items() if k not in QUANTITY and k != known},
        notes=notes,
        kind=kind,
    )
    if "x" not in declared and kind == LINEAR:
        _check_length_unit(m)
    _check_motion(source, columns, kind, where or _where(source), require_force)
    for message in _plausible.unit_warnings(m, set(declared)):
        warnings.warn(f"{source}: {message}", DataWarning, stacklevel=3)
    return _orient_force(m, flip_force=flip_force, check_sign=check_sign)


def sign_correlation(m: Measurement) -> float:
    """Correlation of ``sign(v)`` with the force over moving samples (about +0.5..+1 for
    friction in the models' convention, negative for the opposite one)."""
    d = np.sign(m.velocity())
    f = m.force
    moving = d != 0
    if moving.sum() < 3 or np.std(f[moving]) == 0 or np.std(d[moving]) == 0:
        return 0.0
    return float(np.corrcoef(d[moving], f[moving])[0, 1])


def _check(source: str, columns: dict[str, np.ndarray], require_force: bool,
           kind: str = LINEAR, where=None) -> None:
    where = where or _where(source)
    for name in ("t", "x"):
        if name not in columns:
            raise DataError(f"{source}: missing column {name!r} (columns: {', '.join(columns)})")
    if require_force and "F" not in columns and "u" not in columns:
        raise DataError(
            f"{source}: missing column 'F' (friction force) or 'u' (drive force); "
            f"columns: {', '.join(columns)}"
        )
    n = columns["t"].size
    for name, arr in columns.items():
        if arr.size != n:
            raise DataError(f"{source}: column {name!r} has {arr.size} values, 't' has {n}")
        bad = ~np.isfinite(arr)
        if bad.any():
            row = int(np.argmax(bad)) + 1
            raise DataError(
                f"{where(row)}: column {name!r}, row {row}: {float(arr[row - 1])} (not finite)")
    if n < MIN_SAMPLES:
        raise DataError(f"{source}: only {n} samples; need at least {MIN_SAMPLES}")
    t = columns["t"]
    dt = np.diff(t)
    if (dt <= 0).any():
        i = int(np.argmax(dt <= 0))
        what = "repeats" if dt[i] == 0 else "decreases"
        raise DataError(
            f"{where(i + 2)}: column 't', row {i + 2}: time {what} ({float(t[i + 1])!r} after "
            f"{float(t[i])!r}); "
            "it must be strictly increasing"
        )
    _check_ranges(columns, kind, where)
    _check_steps(columns["t"], where)
    if np.ptp(columns["x"]) == 0:
        raise DataError(f"{source}: column 'x' is constant: there is no motion at all")


def _check_steps(t: np.ndarray, where) -> None:
    """Refuse a time step shorter than `MIN_STEP_FRACTION` of the median step (see the
    module docstring)."""
    dt = np.diff(t)
    median = float(np.median(dt))
    short = dt < MIN_STEP_FRACTION * median
    if short.any():
        i = int(np.argmax(short))
        raise DataError(
            f"{where(i + 2)}: column 't', row {i + 2}: {float(dt[i]):.3g} s after row "
            f"{i + 1}, {median / float(dt[i]):.3g} times shorter than the median time step "
            f"({median:.3g} s; the limit is 1/{1 / MIN_STEP_FRACTION:.0f} of it): a logger "
            f"glitch, not a sample; delete row {i + 2} (or merge it with row {i + 1})")


def _check_motion(source: str, columns: dict[str, np.ndarray], kind: str, where,
                  require_force: bool) -> None:
    """After the unit checks: refuse position steps whose velocity is beyond `ABSURD` (a
    time unit mistake: a time column scaled wrongly), and a force column with one value
    throughout when a force is required (nothing to fit)."""
    t, x = columns["t"], columns["x"]
    dt = np.diff(t)
    limit = (ABSURD_ROTARY if kind == _units.ROTARY else ABSURD)["v"]
    speed = np.abs(np.diff(x)) / dt
    fast = speed > limit
    if fast.any():
        i = int(np.argmax(fast))
        unit = _units.si_unit("v", kind)
        raise DataError(
            f"{where(i + 2)}: column 'x', row {i + 2}: the step from row {i + 1} "
            f"({float(x[i + 1] - x[i]):.3g} {_units.si_unit('x', kind)} in "
            f"{float(dt[i]):.3g} s) is a velocity of {float(speed[i]):.3g} {unit}, absurd "
            f"(limit {limit:g} {unit}): is the unit of t right (declare it, e.g. t[ms])?")
    for name in ("F", "u") if require_force else ():
        if name in columns and np.ptp(columns[name]) == 0:
            raise DataError(
                f"{source}: column {name!r} is {float(columns[name][0]):g} "
                f"{_units.si_unit(name, kind)} in every row: no force was measured, there "
                "is nothing to fit")


def _check_ranges(columns: dict[str, np.ndarray], kind: str, where) -> None:
    """Refuse values beyond `ABSURD` in SI (a time span from the first sample): a unit
    mistake when many are, a glitch when a few are; then glitches relative to the rest of
    their column (`jaxfric._outliers`)."""
    for name, limit in (ABSURD_ROTARY if kind == _units.ROTARY else ABSURD).items():
        if name in columns:
            big = np.abs(columns[name]) > limit
            if name == "t":
                big = np.abs(columns[name] - columns[name][0]) > limit
            if big.any():
                row = int(np.argmax(big)) + 1
                count = int(big.sum())
                hint = ("is the unit right?" if count > max(1, big.size // 100) else
                        f"{count} such sample(s): a glitch? repair or delete that row (or "
                        "declare the unit if it is wrong)")
                raise DataError(
                    f"{where(row)}: column {name!r}, row {row}: {columns[name][row - 1]:.6g} is "
                    f"absurd for a {_units.QUANTITY[kind][name]} in "
                    f"{_units.si_unit(name, kind)} (limit {limit:g}); {hint}"
                )
    for name in ("x", "v", "F", "u", "normal"):
        found = _outliers.relative_outlier(columns[name]) if name in columns else None
        if found is not None:
            i, ratio, spread = found
            raise DataError(
                f"{where(i + 1)}: column {name!r}, row {i + 1}: "
                f"{_outliers.message(name, columns[name][i], ratio, spread)}; repair or "
                "delete that row"
            )


def _spike_warnings(source: str, columns: dict[str, np.ndarray], kind: str, where
                    ) -> list[str]:
    """A warning per force column with isolated spikes where the motion is steady
    (`jaxfric._outliers.spikes`): too small to refuse, large enough to pull a fit."""
    out = []
    for name in ("F", "u"):
        if name not in columns:
            continue
        idx, sizes, noise = _outliers.spikes(columns[name], columns["t"], columns["x"])
        if idx.size == 0:
            continue
        rows = [int(i) + 1 for i in idx]
        shown = ", ".join(map(str, rows[:10])) + (", ..." if len(rows) > 10 else "")
        places = [where(r) for r in rows[:10]]  # FILE:LINE for a text file, else source
        lines = ("" if places[0] == source else
                 " (lines " + ", ".join(p[len(source) + 1:] for p in places) + ")")
        size = (f"{sizes.min():.0f}" if sizes.min() == sizes.max() or len(rows) == 1 else
                f"{sizes.min():.0f} to {sizes.max():.0f}")
        out.append(
            f"{places[0]}: column {name!r}, row(s) {shown}{lines}: {len(rows)} isolated "
            f"spike(s) of {size} times the noise ({noise:.3g} {_units.si_unit(name, kind)}) "
            "in steady motion: glitches? They are fitted as given; if they are not "
            "friction, delete those rows (or give them weight 0 in a fit)")
    return out


def _check_length_unit(m: Measurement) -> None:
    """Positions spanning more than `MAX_UNDECLARED_SPAN_M` in a file that does not declare
    the unit of ``x`` are almost certainly millimetres (or micrometres): refuse them. Declaring
    the unit (``x[m]`` in the header, ``units={"x": "m"}``, ``--units x=m``) accepts them."""
    span = float(np.ptp(m.x))
    if span > MAX_UNDECLARED_SPAN_M:
        raise DataError(
            f"{m.source}: column 'x' spans {span:.4g} but its unit is not declared, and "
            f"{span:.4g} m of travel is implausible for a friction measurement: if it is in mm, "
            "write the header as 'x[mm]' or pass --units x=mm (x=m to confirm metres)"
        )
