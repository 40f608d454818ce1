"""Several joints in one file: which layout a header has, and splitting it per joint.

Two layouts are recognised (`joint_layout`):

- **wide**: numbered columns per joint beside one time column, in the robotics names
  ``q1..qN`` (angle), ``dq1..dqN`` (velocity), ``ddq1..ddqN`` (acceleration), ``tau1..tauN``
  (friction torque), ``tau_u1..tau_uN`` (drive torque), ``load1..loadN`` (each joint's
  transmitted load, for load-dependent friction), or the standard names numbered (``x1``,
  ``v1``, ``F1``, ``u1``, ``a1``); a unit may follow each (``q1[deg]``);
- **long**: a numeric ``joint`` column beside the standard columns, one row per sample of
  one joint (the joints' rows may interleave; each joint's time must increase).

`split` turns the columns of either layout into one mapping per joint with the standard
column names (units kept in the names, ``x[deg]``), ready for `jaxfric.data.load`.
"""

import re

import numpy as np


#: Numbered column prefix -> standard column.
PREFIX = {"q": "x", "dq": "v", "ddq": "a", "tau": "F", "tau_u": "u",
          "x": "x", "v": "v", "a": "a", "F": "F", "u": "u", "load": "load"}
#: Prefixes that say "a robot joint": rotary unless the units say otherwise.
ROTARY_PREFIXES = frozenset({"q", "dq", "ddq", "tau", "tau_u"})
_NUMBERED = re.compile(r"^(q|dq|ddq|tau_u|tau|x|v|a|F|u|load)(\d+)$")
JOINT_COLUMN = "joint"


#: Robot names of one joint's columns -> standard column (used when the standard name is
#: absent); all but ``time`` make the file rotary unless its units say otherwise.
ALIASES = {"q": "x", "dq": "v", "qd": "v", "ddq": "a", "qdd": "a", "tau": "F", "tau_f": "F",
           "tau_u": "u", "time": "t"}


def rename_aliases(parsed, columns: dict, units: dict):
    """``(parsed, columns, units, notes, robot)`` with robot names (`ALIASES`) renamed to
    the standard ones where the standard column is absent; `robot` tells whether a joint's
    name (not ``time``) was among them."""
    rename = {a: c for a, c in ALIASES.items() if a in columns and c not in columns}
    if not rename:
        return parsed, columns, units, [], False
    parsed = [(rename.get(n, n), u) for n, u in parsed]
    columns = {rename.get(n, n): v for n, v in columns.items()}
    units = {rename.get(n, n): u for n, u in units.items()}
    notes = [f"column {a!r} read as {c!r}" for a, c in rename.items()]
    return parsed, columns, units, notes, any(a != "time" for a in rename)


def numbered(name: str) -> tuple[str, int] | None:
    """``("q", 3)`` for ``"q3"``; ``None`` for a name that is not a numbered column."""
    m = _NUMBERED.match(name)
    return (m.group(1), int(m.group(2))) if m else None


def joint_layout(names) -> str | None:
    """``"wide"``, ``"long"`` or ``None`` (one joint) for the column names of a header."""
    names = list(names)
    if JOINT_COLUMN in names:
        return "long"
    if "x" not in names and any(numbered(n) and PREFIX[numbered(n)[0]] == "x" for n in names):
        return "wide"
    return None


def _with_unit(name: str, unit: str | None) -> str:
    return f"{name}[{unit}]" if unit else name


def split(source: str, parsed, columns, units: dict, error) -> tuple[dict, bool]:
    """``({joint name: {column[unit]: array}}, robot_names)`` from the parsed header
    ``[(name, unit)]`` and `columns` of a multi-joint file; `units` (``{"q": "deg"}``,
    ``{"q2": "deg"}`` or ``{"x": "deg"}``) become header units per joint; `error` makes the
    exception to raise. `robot_names` tells whether q/dq/tau names were used."""
    header_unit = dict(parsed)
    known = set(columns) | {PREFIX.get(n, n) for n in columns} | {
        h[0] for n in columns if (h := numbered(n))} | {PREFIX[h[0]] for n in columns
                                                       if (h := numbered(n))}
    for name in units:
        if name not in known:
            raise error(f"{source}: a unit was given for column {name!r}, which is not in "
                        "the data")
    if joint_layout(columns) == "long":
        return _split_long(source, columns, header_unit, units, error), False
    joints: dict[int, dict] = {}
    shared, robot = {}, False
    for name, values in columns.items():
        hit = numbered(name)
        if hit is None:
            shared[_with_unit(name, header_unit.get(name) or units.get(name))] = values
            continue
        prefix, index = hit
        robot |= prefix in ROTARY_PREFIXES
        column = PREFIX[prefix]
        unit = (header_unit.get(name) or units.get(name) or units.get(prefix)
                or units.get(column))
        joint = joints.setdefault(index, {})
        key = _with_unit(column, unit)
        if any(k.split("[")[0] == column for k in joint):
            raise error(f"{source}: joint {index} has two {column} columns ({name})")
        joint[key] = values
    if "t" not in {k.split("[")[0] for k in shared}:
        raise error(f"{source}: missing column 't' (columns: {', '.join(columns)})")
    return {f"joint {i}": {**shared, **joints[i]} for i in sorted(joints)}, robot


def _split_long(source, columns, header_unit, units, error) -> dict:
    ids = columns[JOINT_COLUMN]
    if not np.all(ids == np.round(ids)):
        raise error(f"{source}: column 'joint' must hold whole numbers (joint ids)")
    out = {}
    for j in np.unique(ids):
        rows = ids == j
        out[f"joint {int(j)}"] = {
            _with_unit(name, header_unit.get(name) or units.get(name)): values[rows]
            for name, values in columns.items() if name != JOINT_COLUMN}
    return out
