"""Export identified models to where they are used: `to_c` writes dependency-free C99 for a
controller's per-sample loop (`jaxfric.export.c`); `compile_c` compiles it with the system
C compiler and calls it through ``ctypes`` (`jaxfric.export._compiled`); `to_mujoco`
writes a LuGre model as a MuJoCo MJCF with a passive ``dcmotor`` actuator
(`jaxfric.export._mujoco`)."""

from ._compiled import (
    compile_c as compile_c,
    CompiledModel as CompiledModel,
    find_compiler as find_compiler,
)
from ._effects_c import EXPORTABLE as EXPORTABLE
from ._mujoco import approximations as approximations, mjcf as mjcf, to_mujoco as to_mujoco
from ._parts import ExportError as ExportError
from .c import c_code as c_code, to_c as to_c
