"""Compile an exported model with the system C compiler and call it from Python through
``ctypes`` (`compile_c`): for checking the export against `jaxfric.simulate`, for timing it,
and as the worked example of using the generated step from another language.

Besides the two exported files, a small driver ``jaxfric_run.c`` is compiled in: one C loop
that calls ``jaxfric_step`` on every sample of arrays, so that a whole trajectory costs a
single ``ctypes`` call (a Python loop over ``jaxfric_step`` would time Python, not C).
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

/* f[i] = jaxfric_step on (t[i], x[i], v[i]) for i = 0..n-1, from jaxfric_init(t[0], x[0]);
   repeated `reps` times (for timing; every repetition starts from the zero state). */
void jaxfric_run(const double *t, const double *x, const double *v, double *f, long n,
                 long reps)
{
    jaxfric_state s;
    long i, r;
    for (r = 0; r < reps; ++r) {
        jaxfric_init(&s, t[0], x[0]);
        for (i = 0; i < n; ++i) f[i] = jaxfric_step(&s, t[i], x[i], v[i]);
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

    def __init__(self, library: Path):
        self.library = Path(library)
        self._lib = ctypes.CDLL(str(self.library))
        ptr = ctypes.POINTER(ctypes.c_double)
        self._lib.jaxfric_run.argtypes = [ptr, ptr, ptr, ptr, ctypes.c_long, ctypes.c_long]
        self._lib.jaxfric_run.restype = None

    def _call(self, t, x, v, reps: int) -> np.ndarray:
        arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (t, x, v)]
        if not (arrays[0].ndim == 1 and arrays[0].shape == arrays[1].shape == arrays[2].shape
                and arrays[0].size > 0):
            raise ValueError("t, x and v must be 1-D arrays of one nonzero length")
        f = np.empty_like(arrays[0])
        ptr = ctypes.POINTER(ctypes.c_double)
        self._lib.jaxfric_run(*(a.ctypes.data_as(ptr) for a in (*arrays, f)), f.size, reps)
        return f

    def run(self, t, x, v) -> np.ndarray:
        """The force (N) of every sample: ``jaxfric_init(t[0], x[0])`` then
        ``jaxfric_step`` on each sample in order (SI inputs)."""
        return self._call(t, x, v, 1)

    def time_per_step(self, t, x, v, reps: int = 10) -> float:
        """Seconds per ``jaxfric_step`` call: one C loop over the arrays, `reps` times."""
        start = time.perf_counter()
        self._call(t, x, v, reps)
        return (time.perf_counter() - start) / (reps * len(t))


def compile_c(model, directory, cc: str = "cc", flags=DEFAULT_FLAGS) -> CompiledModel:
    """Export `model` (`to_c`) into `directory`, compile it with the C compiler `cc` and the
    driver (``cc <flags> -shared -fPIC ... -lm``) into ``libjaxfric_model.so``, and load it.
    Raises `RuntimeError` with the compiler's message if compilation fails."""
    folder = Path(directory)
    _, source = to_c(model, folder)
    driver = folder / DRIVER_NAME
    driver.write_text(_DRIVER)
    library = folder / "libjaxfric_model.so"
    cmd = [cc, *flags, "-shared", "-fPIC", "-o", str(library), str(source), str(driver), "-lm"]
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{run.stderr}")
    return CompiledModel(library)
