"""Building blocks of the C export: named constants with units, and the `Part` that each
model and effect translator returns (its state fields, constants, helper functions, and
the C statements of its init and step)."""

import dataclasses
import math

import numpy as np


class ExportError(ValueError):
    """The model (or one of its effects) cannot be exported; the message says which."""


@dataclasses.dataclass
class Part:
    """One piece of the generated code.

    - `fields`: declarations inside ``jaxfric_state`` (without the trailing ``;``);
    - `consts`: ``(name, value, comment)``, emitted as ``static const double``;
    - `helpers`: C functions (static) placed before ``jaxfric_step``;
    - `init`: statements of ``jaxfric_init`` (``s``, ``t0``, ``x0`` in scope);
    - `step`: statements of ``jaxfric_step``; a model's sets ``f`` (its force, N), an
      effect's adds its term to ``total`` (locals ``t, x, v, dt, dx, a, f, stat``).
    """

    fields: list[str] = dataclasses.field(default_factory=list)
    consts: list[tuple[str, float, str]] = dataclasses.field(default_factory=list)
    helpers: str = ""
    init: str = ""
    step: str = ""


def c_double(value) -> str:
    """`value` as a C double literal that reads back to the same float64."""
    v = float(np.asarray(value, dtype=np.float64))
    if not math.isfinite(v):
        raise ExportError(f"a parameter is not finite ({v}); cannot export it")
    text = repr(v)
    return text if any(c in text for c in ".en") else text + ".0"


def unit_of(module, name: str) -> str:
    """The SI unit recorded by `param` for field `name` of `module` (``"?"`` if none)."""
    for f in dataclasses.fields(module):
        if f.name == name:
            return f.metadata.get("unit", "?") if f.metadata else "?"
    return "?"


def const(module, name: str, c_name: str, owner: str) -> tuple[str, float, str]:
    """The constant for parameter `name` of `module`, named `c_name` in C."""
    value = float(np.asarray(getattr(module, name), dtype=np.float64))
    return c_name, value, f"{owner}.{name} [{unit_of(module, name)}]"


def derived(c_name: str, value, comment: str) -> tuple[str, float, str]:
    """A constant computed from the parameters at export time (formula in `comment`)."""
    return c_name, float(np.asarray(value, dtype=np.float64)), f"derived: {comment}"
