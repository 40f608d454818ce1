"""One BLAS thread while a fit runs (`single_threaded_blas`).

On the CPU, JAX's linear algebra (the QR of each Levenberg-Marquardt step, the final
covariance) calls the LAPACK of SciPy's OpenBLAS, and NumPy's own OpenBLAS does the host-side
products of a fit's stopping rules. On matrices of n x p with p ~ 10, OpenBLAS's threads
gain little, but after every call its worker threads keep spinning (busy-waiting for more
work) for a while, on the cores XLA's own threads and the compiled kernels need: on the
2-core benchmark machine a profile of ``fitting.fit(max_steps=1)`` at 1e5 samples spent
about half of its samples in those spinning threads
(``benchmarks/profiling/profile_fit_fixed.py`` measures a fit with and without this).

`single_threaded_blas` sets every OpenBLAS loaded in the process to one thread for the
duration of a block (through its ``*_set_num_threads`` entry point, found by name; the
same thing ``threadpoolctl`` does) and restores the previous counts afterwards. Results
do not change: a one-thread BLAS does the same arithmetic in the same blocks. With another
BLAS (MKL, Accelerate), or off Linux, it does nothing.
"""

import contextlib
import ctypes
import threading


#: (get, set) entry points of OpenBLAS builds: plain, SciPy's (prefixed), and their 64-bit
#: integer variants.
_NAMES = (
    ("openblas_get_num_threads", "openblas_set_num_threads"),
    ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
    ("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
    ("openblas_get_num_threads64_", "openblas_set_num_threads64_"),
)

#: False: `single_threaded_blas` does nothing (for benchmarks/profiling/profile_fit_fixed.py,
#: which times fits both ways).
ENABLED = True

_lock = threading.Lock()
_depth = 0
_saved: list = []


def _openblas_libraries() -> list:
    """``(get, set)`` function pairs of the OpenBLAS libraries mapped into this process."""
    try:
        with open("/proc/self/maps") as f:
            paths = {line.split()[-1] for line in f if "openblas" in line.lower()}
    except OSError:  # not Linux
        return []
    found = []
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for get_name, set_name in _NAMES:
            get, put = getattr(lib, get_name, None), getattr(lib, set_name, None)
            if get is not None and put is not None:
                get.restype, put.argtypes = ctypes.c_int, [ctypes.c_int]
                found.append((get, put))
                break
    return found


@contextlib.contextmanager
def single_threaded_blas():
    """Every OpenBLAS of the process on one thread inside the block (module docstring);
    nested and concurrent blocks keep it so until the outermost one ends."""
    global _depth
    if not ENABLED:
        yield
        return
    with _lock:
        if _depth == 0:
            _saved[:] = []
            for get, put in _openblas_libraries():
                _saved.append((put, get()))
                put(1)
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                for put, count in _saved:
                    put(count)
