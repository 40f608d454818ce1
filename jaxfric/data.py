"""Measurements from files (CSV, NPZ), DataFrames or arrays, checked and converted to SI.

A measurement has columns ``t`` (time), ``x`` (position) and either ``F`` (the friction force)
or ``u`` (the drive force, which also contains inertia and offsets); optionally ``v``
(velocity), ``a`` (acceleration) and ``normal`` (normal load). Any other column is kept in
`Measurement.extra`.

**Units.** SI by default (s, m, m/s, m/s^2, N). A unit in the header converts:
``t[ms]``, ``x[mm]``, ``x[um]``, ``F[mN]``, ``v[mm/s]`` ... (see `UNITS`), or pass
``units={"x": "mm"}`` (the CLI's ``--units x=mm``).

**Checks.** Every problem raises `DataError`, a `ValueError` whose one-line message names the
source, the column and the (1-based, data) row: missing or empty file, no header, missing
column, non-numeric cell, NaN/inf, time not increasing or duplicated, too few samples, no
motion at all, absurd magnitudes, and positions spanning more than 2 m with no unit
declared (millimetres read as metres; declare ``x[m]`` to confirm). Suspicious but possible
data give a `DataWarning` instead: a force whose sign is opposite to the friction convention
(friction has the sign of ``v``), corrected with ``flip_force=True`` (CLI ``--flip-force``).

Irregular sampling is kept as it is: every model takes the time column as given.
"""

import csv
import dataclasses
import re
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import equinox as eqx
import numpy as np

from .motion import velocity


class DataError(ValueError):
    """A measurement cannot be used; the message names the source, column and row."""


class DataWarning(UserWarning):
    """A measurement looks suspicious (units, sign convention) but can be used."""


#: Unit name -> factor to SI, per physical quantity.
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0},
    "length": {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "nm": 1e-9, "cm": 1e-2},
    "velocity": {"m/s": 1.0, "mm/s": 1e-3, "um/s": 1e-6, "µm/s": 1e-6, "cm/s": 1e-2},
    "acceleration": {"m/s^2": 1.0, "m/s2": 1.0, "mm/s^2": 1e-3, "mm/s2": 1e-3},
    "force": {"N": 1.0, "mN": 1e-3, "uN": 1e-6, "µN": 1e-6, "kN": 1e3},
}
QUANTITY = {"t": "time", "x": "length", "v": "velocity", "a": "acceleration",
            "F": "force", "u": "force", "normal": "force"}
SI_UNIT = {"time": "s", "length": "m", "velocity": "m/s", "acceleration": "m/s^2", "force": "N"}

MIN_SAMPLES = 10
#: Travel (m) beyond which an undeclared position unit is taken for a mistake.
MAX_UNDECLARED_SPAN_M = 2.0
# Beyond these a value is not a friction measurement in SI, whatever the machine.
ABSURD = {"t": 1e7, "x": 1e3, "v": 1e3, "a": 1e6, "F": 1e7, "u": 1e7, "normal": 1e8}

_HEADER = re.compile(r"^\s*([A-Za-z_][A-Za-z_0-9]*)\s*(?:\[\s*([^\]]*?)\s*\])?\s*$")


class Measurement(eqx.Module):
    """One experiment in SI units: 1-D float arrays of equal length, and where it came from.

    The one container for measured data: `load` returns it, and the fits take it
    (`fitting.Dataset` is this class).

    - `t` (s), `x` (m): always present.
    - `F` (N): friction force, sign of ``v``, or ``None``.
    - `v` (m/s): velocity, or ``None`` (then derived from `x`, see `velocity`).
    - `weights`: per-sample weights >= 0 for a fit (0 drops a sample), or ``None`` (ones).
    - `u` (N): drive force (friction plus inertia and offsets), or ``None``; `a` (m/s^2)
      and `normal` (N): ``None`` unless given.
    - `source`: where it came from (file name or ``"<arrays>"``); `notes`: what was
      converted or flipped while loading; `extra`: other columns by name.
    """

    t: Any
    x: Any
    F: Any = None
    v: Any = None
    weights: Any = None
    u: Any = None
    a: Any = None
    normal: Any = None
    source: str = eqx.field(static=True, default="<arrays>")
    notes: tuple[str, ...] = eqx.field(static=True, default=(), converter=tuple)
    extra: dict = eqx.field(default_factory=dict)

    @property
    def force(self) -> np.ndarray:
        """`F` if present, else `u`."""
        return self.F if self.F is not None else self.u

    @property
    def force_column(self) -> str:
        return "F" if self.F is not None else "u"

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
        cols = [c for c in ("t", "x", "F", "u", "v", "a", "normal") if getattr(self, c) is not None]
        span = self.t[-1] - self.t[0]
        return f"Measurement({self.source!r}, {len(self)} samples, {span:.3g} s, columns {cols})"


def _unit_factor(source: str, column: str, unit: str) -> float:
    quantity = QUANTITY.get(column)
    if quantity is None:
        return 1.0
    table = UNITS[quantity]
    key = unit.replace(" ", "")
    if key not in table:
        raise DataError(
            f"{source}: column {column!r}: unknown unit {unit!r} for a {quantity}; "
            f"use one of {', '.join(table)}"
        )
    return table[key]


def _parse_header(source: str, names: list[str]) -> list[tuple[str, str | None]]:
    parsed = []
    for i, raw in enumerate(names):
        m = _HEADER.match(raw)
        if m is None:
            raise DataError(
                f"{source}: header cell {i + 1} ({raw!r}) is not a column name like 'x' or 'x[mm]'"
            )
        parsed.append((m.group(1), m.group(2) or None))
    seen = set()
    for name, _ in parsed:
        if name in seen:
            raise DataError(f"{source}: column {name!r} appears twice in the header")
        seen.add(name)
    return parsed


def _read_csv(path: Path) -> tuple[list[tuple[str, str | None]], dict[str, np.ndarray]]:
    source = str(path)
    if not path.exists():
        raise DataError(f"{source}: no such file")
    if path.is_dir():
        raise DataError(f"{source}: is a folder, not a data file")
    text = path.read_text(encoding="utf-8-sig", errors="replace")
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise DataError(f"{source}: the file is empty")
    dialect = csv.excel
    try:
        dialect = csv.Sniffer().sniff(lines[0], delimiters=",;\t ")
    except csv.Error:
        pass
    rows = list(csv.reader(lines, dialect))
    header = [h.strip() for h in rows[0]]
    if all(_is_number(h) for h in header if h):
        raise DataError(
            f"{source}: no header row; the first line must name the columns, e.g. 't,x,F' "
            "(units in brackets: 't[s],x[mm],F[N]')"
        )
    parsed = _parse_header(source, header)
    body = rows[1:]
    if not body:
        raise DataError(f"{source}: a header but no data rows")
    ncol = len(header)
    values = np.empty((len(body), ncol))
    for r, row in enumerate(body):
        if len(row) != ncol:
            raise DataError(f"{source}: row {r + 1}: {len(row)} cells, the header has {ncol}")
        for c, cell in enumerate(row):
            try:
                values[r, c] = float(cell)
            except ValueError:
                raise DataError(
                    f"{source}: column {parsed[c][0]!r}, row {r + 1}: "
                    f"{cell.strip()!r} is not a number"
                ) from None
    return parsed, {name: values[:, c] for c, (name, _) in enumerate(parsed)}


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _read_npz(path: Path):
    source = str(path)
    if not path.exists():
        raise DataError(f"{source}: no such file")
    try:
        archive = np.load(path, allow_pickle=False)
    except Exception as e:
        raise DataError(f"{source}: not a readable .npz file ({e})") from None
    if not archive.files:
        raise DataError(f"{source}: the file is empty (no arrays)")
    parsed = _parse_header(source, list(archive.files))
    columns = {}
    for (name, _), key in zip(parsed, archive.files):
        arr = archive[key]
        if not np.issubdtype(arr.dtype, np.number):
            raise DataError(f"{source}: column {name!r}: not numeric (dtype {arr.dtype})")
        columns[name] = np.asarray(arr, dtype=np.float64).reshape(-1)
    return parsed, columns


def _from_mapping(data: Mapping[str, Any]):
    parsed = _parse_header("<arrays>", [str(k) for k in data])
    columns = {}
    for (name, _), value in zip(parsed, data.values()):
        arr = np.asarray(value)
        if arr.ndim != 1:
            raise DataError(f"<arrays>: column {name!r} must be 1-D, got shape {arr.shape}")
        if not np.issubdtype(arr.dtype, np.number):
            raise DataError(f"<arrays>: column {name!r}: not numeric (dtype {arr.dtype})")
        columns[name] = arr.astype(np.float64)
    return parsed, columns


def _read(data) -> tuple[str, list[tuple[str, str | None]], dict[str, np.ndarray]]:
    """``(source, [(column, header unit)], {column: values})`` from a path, a DataFrame or
    a mapping."""
    if isinstance(data, str | Path):
        path = Path(data)
        source = str(path)
        if path.suffix.lower() == ".npz":
            parsed, columns = _read_npz(path)
        else:
            parsed, columns = _read_csv(path)
    elif hasattr(data, "columns") and hasattr(data, "to_numpy"):  # a DataFrame
        source = "<DataFrame>"
        parsed, columns = _from_mapping({str(c): data[c].to_numpy() for c in data.columns})
    elif isinstance(data, Mapping):
        source = "<arrays>"
        parsed, columns = _from_mapping(data)
    else:
        raise TypeError(f"cannot load a {type(data).__name__}; give a path, a DataFrame or a dict")
    return source, parsed, columns


def _to_si(source: str, columns: dict[str, np.ndarray], header_unit: dict, units: dict
           ) -> list[str]:
    """Convert `columns` in place to SI from the header's units or the caller's `units`;
    returns the notes of what was converted."""
    for name in units:
        if name not in columns:
            raise DataError(
                f"{source}: a unit was given for column {name!r}, which is not in the data"
            )
    notes = []
    for name in list(columns):
        unit = header_unit.get(name) or units.get(name)
        if header_unit.get(name) and name in units and units[name] != header_unit[name]:
            raise DataError(
                f"{source}: column {name!r} is declared in {header_unit[name]!r} in the header "
                f"and in {units[name]!r} by the caller"
            )
        if unit is not None:
            factor = _unit_factor(source, name, unit)
            if factor != 1.0:
                columns[name] = columns[name] * factor
                notes.append(f"{name} converted from {unit} to {SI_UNIT[QUANTITY[name]]}")
    return notes


def _orient_force(m: Measurement, *, flip_force: bool, check_sign: bool) -> Measurement:
    """`m` with its force flipped when asked; otherwise `m`, with a warning when its force
    looks recorded with the opposite sign to the friction convention."""
    source = m.source
    if flip_force and m.force is not None:
        column = m.force_column
        flipped = {column: -getattr(m, column)}
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
                stacklevel=3,  # the caller of `load`
            )
    return m


def load(
    data,
    *,
    units: Mapping[str, str] | None = None,
    flip_force: bool = False,
    require_force: bool = True,
    check_sign: bool = True,
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

    **Returns:** a `Measurement`. **Raises:** `DataError` with a one-line message.
    """
    source, parsed, columns = _read(data)
    units = dict(units or {})
    header_unit = dict(parsed)
    notes = _to_si(source, columns, header_unit, units)
    _check(source, columns, require_force)
    m = Measurement(
        **{k: columns.get(k) for k in ("t", "x", "F", "u", "v", "a", "normal")},
        source=source,
        extra={k: v for k, v in columns.items() if k not in QUANTITY},
        notes=notes,
    )
    if header_unit.get("x") is None and "x" not in units:
        _check_length_unit(m)
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


def _check(source: str, columns: dict[str, np.ndarray], require_force: bool) -> None:
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
            raise DataError(f"{source}: column {name!r}, row {row}: {arr[row - 1]} (not finite)")
    if n < MIN_SAMPLES:
        raise DataError(f"{source}: only {n} samples; need at least {MIN_SAMPLES}")
    t = columns["t"]
    dt = np.diff(t)
    if (dt <= 0).any():
        i = int(np.argmax(dt <= 0))
        what = "repeats" if dt[i] == 0 else "decreases"
        raise DataError(
            f"{source}: column 't', row {i + 2}: time {what} ({t[i + 1]!r} after {t[i]!r}); "
            "it must be strictly increasing"
        )
    _check_ranges(source, columns)
    if np.ptp(columns["x"]) == 0:
        raise DataError(f"{source}: column 'x' is constant: there is no motion at all")


def _check_ranges(source: str, columns: dict[str, np.ndarray]) -> None:
    """Refuse values beyond `ABSURD` in SI (a time span from the first sample): almost
    always a unit mistake."""
    for name, limit in ABSURD.items():
        if name in columns:
            big = np.abs(columns[name]) > limit
            if name == "t":
                big = np.abs(columns[name] - columns[name][0]) > limit
            if big.any():
                row = int(np.argmax(big)) + 1
                raise DataError(
                    f"{source}: column {name!r}, row {row}: {columns[name][row - 1]:.6g} is absurd "
                    f"for a {QUANTITY[name]} in {SI_UNIT[QUANTITY[name]]} (limit {limit:g}); "
                    "is the unit right?"
                )


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
