"""Export identified models to where they are used: `to_c` writes dependency-free C99 for a
controller's per-sample loop (`jaxfric.export.c`)."""

from ._effects_c import EXPORTABLE as EXPORTABLE
from ._parts import ExportError as ExportError
from .c import c_code as c_code, to_c as to_c
