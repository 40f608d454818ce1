"""Units of measured data, linear and rotary, in one place.

A measurement is **linear** (a slide: position m, velocity m/s, force N) or **rotary** (a
joint or motor axis: angle rad, angular velocity rad/s, torque N m). The models are the
same equations either way; only the words change. Internally everything is SI: m or rad,
N or N m. This module holds

- `UNITS`: unit name -> factor to SI, per quantity (the spellings a header may use; spaces,
  ``*``, ``·`` and ``.`` between unit symbols are ignored, so ``N m``, ``N*m``, ``Nm`` and
  ``N·m`` are one unit);
- `QUANTITY`: the quantity of each standard column for each kind, and `SI_UNIT`;
- `unit_factor` and `kind_of_unit`: a column's unit to its SI factor and to the kind it
  implies;
- `rotary_unit` and `speak`: the linear SI unit of a model parameter (declared on its field,
  `jaxfric._fields.param`) and free text with linear units (a report line) in the words of a
  rotary file: m -> rad, N -> N m, m/s -> rad/s, N/m -> N m/rad, N s/m -> N m s/rad,
  m/N -> rad/(N m), kg -> kg m^2; prefixes carry over (mm -> mrad, mN -> mN m), so the
  numbers printed beside them stay right.
"""

import math
import re


LINEAR, ROTARY = "linear", "rotary"
KINDS = (LINEAR, ROTARY)

#: Unit name (as normalised by `_key`) -> factor to SI, per physical quantity.
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0},
    "length": {"m": 1.0, "mm": 1e-3, "um": 1e-6, "nm": 1e-9, "cm": 1e-2},
    "velocity": {"m/s": 1.0, "mm/s": 1e-3, "um/s": 1e-6, "cm/s": 1e-2, "mm/min": 1e-3 / 60},
    "acceleration": {"m/s^2": 1.0, "m/s2": 1.0, "mm/s^2": 1e-3, "mm/s2": 1e-3},
    "force": {"N": 1.0, "mN": 1e-3, "uN": 1e-6, "kN": 1e3},
    "angle": {"rad": 1.0, "mrad": 1e-3, "urad": 1e-6, "deg": math.pi / 180,
              "°": math.pi / 180, "arcmin": math.pi / 10800, "arcsec": math.pi / 648000,
              "rev": 2 * math.pi},
    "angular velocity": {"rad/s": 1.0, "mrad/s": 1e-3, "deg/s": math.pi / 180,
                         "°/s": math.pi / 180, "rpm": 2 * math.pi / 60,
                         "rev/min": 2 * math.pi / 60, "rev/s": 2 * math.pi},
    "angular acceleration": {"rad/s^2": 1.0, "rad/s2": 1.0, "deg/s^2": math.pi / 180,
                             "deg/s2": math.pi / 180},
    "torque": {"Nm": 1.0, "mNm": 1e-3, "kNm": 1e3, "Nmm": 1e-3},
}

#: Column -> quantity, per kind. ``normal`` (a normal load) is a force in both; ``load``
#: (the transmitted load that `jaxfric.effects.LoadFriction` reads) is in the unit of the
#: friction: a force on a linear file, a torque on a rotary one.
QUANTITY: dict[str, dict[str, str]] = {
    LINEAR: {"t": "time", "x": "length", "v": "velocity", "a": "acceleration",
             "F": "force", "u": "force", "normal": "force", "load": "force"},
    ROTARY: {"t": "time", "x": "angle", "v": "angular velocity", "a": "angular acceleration",
             "F": "torque", "u": "torque", "normal": "force", "load": "torque"},
}
SI_UNIT = {"time": "s", "length": "m", "velocity": "m/s", "acceleration": "m/s^2",
           "force": "N", "angle": "rad", "angular velocity": "rad/s",
           "angular acceleration": "rad/s^2", "torque": "N m"}
#: Columns whose unit tells the kind of the file (time and normal load do not).
KIND_COLUMNS = ("x", "v", "a", "F", "u")


def _key(unit: str) -> str:
    """A unit's spelling reduced to its table key: ``"N·m"``, ``"N * m"``, ``"N.m"`` ->
    ``"Nm"``; ``"µm"``/``"μm"`` -> ``"um"``; ``"s²"`` -> ``"s^2"``."""
    key = unit.strip().replace("µ", "u").replace("μ", "u").replace("²", "^2")
    return re.sub(r"[\s*·⋅.]", "", key)


def kind_of_unit(column: str, unit: str) -> str | None:
    """``"linear"`` or ``"rotary"`` if `unit` is a unit of `column` of that kind (``x[deg]``
    is rotary), ``None`` if the column does not tell the kind or the unit is unknown."""
    if column not in KIND_COLUMNS:
        return None
    key = _key(unit)
    for kind in KINDS:
        if key in UNITS[QUANTITY[kind][column]]:
            return kind
    return None


def unit_factor(column: str, unit: str, kind: str) -> float | None:
    """Factor from `unit` to SI for `column` of a file of `kind`, 1 for a column that has
    no quantity, ``None`` if the unit is not one of that quantity."""
    quantity = QUANTITY[kind].get(column)
    if quantity is None:
        return 1.0
    return UNITS[quantity].get(_key(unit))


def si_unit(column: str, kind: str) -> str:
    """The SI unit of a standard `column` in a file of `kind` (``"N m"`` for ``F`` rotary)."""
    return SI_UNIT[QUANTITY[kind][column]]


# --- speaking rotary -----------------------------------------------------------------

_BASE = {"m": "rad", "N": "N m", "kg": "kg m^2"}
_PREFIXED = {"mm": "mrad", "um": "µrad", "µm": "µrad", "nm": "nrad", "mN": "mN m",
             "uN": "µN m", "µN": "µN m", "kN": "kN m"}


def _rotary_token(token: str) -> str:
    base, _, power = token.partition("^")
    new = _BASE.get(base) or _PREFIXED.get(base) or base
    return new + (f"^{power}" if power else "")


def rotary_unit(unit: str) -> str:
    """The rotary counterpart of a linear SI unit as declared on a model field:
    ``"N/m"`` -> ``"N m/rad"``, ``"m/N"`` -> ``"rad/(N m)"``, ``"m^-alpha"`` ->
    ``"rad^-alpha"``; ``"-"``, ``"s"``, ``"1/s"`` unchanged."""
    if unit in ("-", "?", ""):
        return unit
    num, _, den = unit.partition("/")
    top = " ".join(_rotary_token(t) for t in num.split())
    if not den:
        return top
    bottom = " ".join(_rotary_token(t) for t in den.split())
    return f"{top}/({bottom})" if " " in bottom else f"{top}/{bottom}"


def unit_for(unit: str, kind: str) -> str:
    """`unit` (linear SI, as declared on a model field) in the words of a file of `kind`."""
    return rotary_unit(unit) if kind == ROTARY else unit


#: Linear unit expressions that `speak` rewrites, longest first.
_TEXT_UNITS = sorted(
    ["N s^2/m^2", "N s/m", "N/m^4", "N/m", "N/s", "m/N", "m^-alpha", "m/s^2", "m/s", "mm/s",
     "um/s", "µm/s", "mm", "um", "µm", "nm", "m", "mN", "uN", "µN", "kN", "N", "kg"],
    key=len, reverse=True)
_TEXT = re.compile(
    r"(?P<pre>(?:[\d\]\)%]\s)|\[|\bin\s)(?P<unit>"
    + "|".join(re.escape(u) for u in _TEXT_UNITS)
    + r")(?=$|[\s,;.:)\]])(?!\s+m\b)")  # not followed by " m": already rotary (N m)


def speak(text: str, kind: str) -> str:
    """`text` with the linear units that follow a number (``"0.4 N"``, ``"1 mm/s"``), sit in
    brackets (``"[N]"``) or follow "in " rewritten for a file of `kind` (unchanged for a
    linear one). The numbers stay right: a rotary file's values are rad and N m where a
    linear one's are m and N, and prefixes map one to one (mm -> mrad)."""
    if kind != ROTARY:
        return text
    return _TEXT.sub(lambda m: m.group("pre") + rotary_unit(m.group("unit")), text)


def speak_json(obj, kind: str):
    """`speak` applied to every string (keys included) of a JSON-like object."""
    if kind != ROTARY:
        return obj
    if isinstance(obj, str):
        return speak(obj, kind)
    if isinstance(obj, dict):
        return {speak(k, kind) if isinstance(k, str) else k: speak_json(v, kind)
                for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [speak_json(v, kind) for v in obj]
    return obj


def travel_text(span: float, kind: str) -> str:
    """A travel (m or rad) as a person reads it: ``"12.3 mm"``; ``"0.52 rad (29.8 deg)"``."""
    if kind == ROTARY:
        return f"{span:.4g} rad ({math.degrees(span):.4g} deg)"
    return f"{span * 1e3:.4g} mm"
