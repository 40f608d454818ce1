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

import gc

from ._outermost import outermost


#: False: `paused_gc` does nothing (for benchmarks/profiling/profile_fit_fixed.py).
ENABLED = True


def _pause() -> bool:
    was = gc.isenabled()
    gc.disable()
    return was


paused_gc = outermost(
    _pause, lambda was: gc.enable() if was else None, lambda: ENABLED,
    """The cyclic garbage collector disabled inside the block (module docstring); nested
    and concurrent blocks keep it so until the outermost one ends, and a collector that
    was off stays off.""")
