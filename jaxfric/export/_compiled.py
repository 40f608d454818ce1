"""Compile an exported model with the system C compiler and call it from Python through
``ctypes`` (`compile_c`): for checking the export against `jaxfric.simulate`, for timing it,
and as the worked example of using the generated step from another language.

Besides the two exported files, a small driver ``jaxfric_run.c`` is compiled in: one C loop
that calls ``jaxfric_step_load`` on every sample of arrays (the load 0 when none is given),
so that a whole trajectory costs a single ``ctypes`` call (a Python loop over the step
would time Python, not C).
"""

import ctypes
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np

from .c import to_c


DRIVER_NAME = "jaxfric_run.c"

_DRIVER = """\
/* jaxfric_run.c: the exported step over whole arrays (one call from Python). */
#include "jaxfric_model.h"

/* f[i] = jaxfric_step_load on (t[i], x[i], v[i], load[i]) for i = 0..n-1, from
   jaxfric_init(t[0], x[0]) (load NULL: 0); repeated `reps` times (for timing; every
   repetition starts from the zero state). */
void jaxfric_run(const double *t, const double *x, const double *v, const double *load,
                 double *f, long n, long reps)
{
    jaxfric_state s;
    long i, r;
    for (r = 0; r < reps; ++r) {
        jaxfric_init(&s, t[0], x[0]);
        for (i = 0; i < n; ++i)
            f[i] = jaxfric_step_load(&s, t[i], x[i], v[i], load ? load[i] : 0.0);
    }
}
"""

#: Flags used by `compile_c` (besides ``-shared -fPIC``).
DEFAULT_FLAGS = ("-O2", "-std=c99")


def find_compiler(name: str = "cc") -> str | None:
    """Path of the C compiler `name` (default the system ``cc``), or None."""
    return shutil.which(name)


class CompiledModel:
    """An exported model compiled into a shared library (`compile_c`)."""

    def __init__(self, library: Path, needs_load: bool = False):
        self.library = Path(library)
        self.needs_load = bool(needs_load)
        self._lib = ctypes.CDLL(str(self.library))
        ptr = ctypes.POINTER(ctypes.c_double)
        self._lib.jaxfric_run.argtypes = [ptr, ptr, ptr, ptr, ptr, ctypes.c_long,
                                          ctypes.c_long]
        self._lib.jaxfric_run.restype = None

    def _call(self, t, x, v, load, reps: int) -> np.ndarray:
        inputs = (t, x, v) if load is None else (t, x, v, load)
        arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in inputs]
        if not (arrays[0].ndim == 1 and arrays[0].size > 0
                and all(a.shape == arrays[0].shape for a in arrays)):
            raise ValueError("t, x, v (and load) must be 1-D arrays of one nonzero length")
        if self.needs_load and load is None:
            raise ValueError("the load_friction effect needs the load signal: pass "
                             "run(t, x, v, load=L) (N or N m)")
        f = np.empty_like(arrays[0])
        ptr = ctypes.POINTER(ctypes.c_double)
        t_, x_, v_ = (a.ctypes.data_as(ptr) for a in arrays[:3])
        load_ = arrays[3].ctypes.data_as(ptr) if load is not None else None
        self._lib.jaxfric_run(t_, x_, v_, load_, f.ctypes.data_as(ptr), f.size, reps)
        return f

    def run(self, t, x, v, load=None) -> np.ndarray:
        """The force (N) of every sample: ``jaxfric_init(t[0], x[0])`` then
        ``jaxfric_step_load`` on each sample in order (SI inputs; `load` the transmitted
        load, N or N m, needed when the model reads it, else 0)."""
        return self._call(t, x, v, load, 1)

    def time_per_step(self, t, x, v, reps: int = 10, load=None) -> float:
        """Seconds per step: one C loop over the arrays, `reps` times."""
        start = time.perf_counter()
        self._call(t, x, v, load, reps)
        return (time.perf_counter() - start) / (reps * len(t))


def compile_c(model, directory, cc: str = "cc", flags=DEFAULT_FLAGS) -> CompiledModel:
    """Export `model` (`to_c`) into `directory`, compile it with the C compiler `cc` and the
    driver (``cc <flags> -shared -fPIC ... -lm``) into ``libjaxfric_model.so``, and load it.
    Raises `RuntimeError` with the compiler's message if compilation fails."""
    folder = Path(directory)
    header, source = to_c(model, folder)
    needs_load = "#define JAXFRIC_NEEDS_LOAD 1" in header.read_text()
    driver = folder / DRIVER_NAME
    driver.write_text(_DRIVER)
    library = folder / "libjaxfric_model.so"
    cmd = [cc, *flags, "-shared", "-fPIC", "-o", str(library), str(source), str(driver), "-lm"]
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{run.stderr}")
    return CompiledModel(library, needs_load)
