"""Python's cyclic garbage collector paused while a fit runs (`paused_gc`).

Between its compiled calls a fit builds and drops many small Python objects (pytrees of
models, problems, solver states), and each time enough have been allocated the cyclic
collector runs; its older generations walk every tracked object of the process, which
with JAX loaded is hundreds of thousands (JAX's caches, traced programs). In a perf profile
of ``fitting.fit(max_steps=1)`` at 1e5 samples about a fifth of the samples were in that
collector. `paused_gc` disables it for the duration of a block and re-enables it after
(if it was enabled): reference counting still frees everything without cycles at once,
and cycles made during the fit are collected by the next collection after it.
``benchmarks/profiling/profile_fit_fixed.py`` times fits with and without it.
"""

import contextlib
import gc
import threading


#: False: `paused_gc` does nothing (for benchmarks/profiling/profile_fit_fixed.py).
ENABLED = True

_lock = threading.Lock()
_depth = 0
_was_enabled = False


@contextlib.contextmanager
def paused_gc():
    """The cyclic garbage collector disabled inside the block (module docstring); nested
    and concurrent blocks keep it so until the outermost one ends."""
    global _depth, _was_enabled
    if not ENABLED:
        yield
        return
    with _lock:
        if _depth == 0:
            _was_enabled = gc.isenabled()
            gc.disable()
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0 and _was_enabled:
                gc.enable()
