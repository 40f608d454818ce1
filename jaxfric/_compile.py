"""How jaxfric compiles: every program of jaxfric and `fitting` (a simulation, a fit's
solver chunk, its last evaluation, a diagnosis's screens) is `jit`, which is
``equinox.filter_jit`` with `COMPILER_OPTIONS`.

**Why.** On a CPU, XLA generates the code of its fusions with its MLIR fusion emitters by
default. jaxfric's programs are long sequences of small elementwise fusions inside
``lax.scan`` loops (the friction models' event logic), for which the older emitters
(``xla_cpu_use_fusion_emitters=False``) compile 1.3-1.9x faster and run about as fast:
measured side by side by ``benchmarks/compiler_options.py`` (its JSON; docs/speed.md
gives the table). A first fit or diagnosis spends most of its time compiling, so this is
what a user waits for on a new machine (`benchmarks/diagnose_speed.py`).

**What it changes.** Only the generated code: the same operations in the same order,
evaluated by other kernels, so that results can differ from XLA's defaults in the last
bits (a fit's prediction after 50 steps by 3e-10 N in that benchmark), as they differ
between CPUs. Where a fit's
parameters are weakly determined, a refit can end elsewhere along a flat direction.

**Where it applies.** The options are set per program, never globally: other JAX code of
the same process keeps XLA's defaults. A jaxfric function called inside a user's own
``jax.jit`` is compiled with the user's program and its options. If the installed XLA does
not know an option (a newer or older jaxlib), it is left out, after a trial compilation of
a tiny program the first time a jaxfric program runs; set the environment variable
``JAXFRIC_XLA_DEFAULTS`` to a non-empty value other than ``0`` to use XLA's defaults
everywhere.
"""

import functools
import os
import threading

import equinox as eqx
import jax.numpy as jnp


#: The XLA compiler options of every jaxfric program (module docstring).
COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False}

_lock = threading.Lock()
_accepted: dict | None = None


def _defaults_wanted() -> bool:
    return os.environ.get("JAXFRIC_XLA_DEFAULTS", "") not in ("", "0")


def compiler_options() -> dict:
    """The options jaxfric's programs are compiled with: `COMPILER_OPTIONS`, or ``{}`` when
    ``JAXFRIC_XLA_DEFAULTS`` asks for XLA's defaults or the installed XLA rejects them
    (decided once per process, by compiling a tiny program)."""
    global _accepted
    with _lock:
        if _accepted is None:
            _accepted = {} if _defaults_wanted() else _probe(COMPILER_OPTIONS)
        return dict(_accepted)


def _probe(options: dict) -> dict:
    """`options` if XLA compiles a tiny program with them, else ``{}``."""
    try:
        probe = eqx.filter_jit(lambda u: u + 1.0, compiler_options=options)
        probe(jnp.zeros(()))
    except Exception:  # XLA's error for an unknown option (JaxRuntimeError: INVALID_ARGUMENT)
        return {}
    return dict(options)


class _Jit:
    """``equinox.filter_jit(fun, compiler_options=compiler_options(), **kwargs)``, made at
    the first call (not at import: choosing the options compiles, which needs JAX's
    backend). Called while another program is being traced (inside a ``jax.jit``, a
    ``lax.scan``, ...), where JAX refuses compiler options (they belong to the top-level
    program), it is the plain ``equinox.filter_jit(fun, **kwargs)``."""

    def __init__(self, fun, kwargs):
        self._fun, self._kwargs = fun, kwargs
        self._jitted = self._nested = None
        functools.update_wrapper(self, fun)

    def _get(self):
        if self._jitted is None:
            self._jitted = eqx.filter_jit(self._fun, compiler_options=compiler_options(),
                                          **self._kwargs)
        return self._jitted

    def __call__(self, *args, **kwargs):
        try:
            return self._get()(*args, **kwargs)
        except ValueError as err:  # JAX: "`compiler_options` can only be passed to top-level"
            if "compiler_options" not in str(err):
                raise
        if self._nested is None:
            self._nested = eqx.filter_jit(self._fun, **self._kwargs)
        return self._nested(*args, **kwargs)

    def lower(self, *args, **kwargs):
        return self._get().lower(*args, **kwargs)


def jit(fun=None, **kwargs):
    """`equinox.filter_jit` with jaxfric's compiler options (module docstring): a
    decorator, with or without keyword arguments for ``filter_jit``."""
    if fun is None:
        return functools.partial(jit, **kwargs)
    return _Jit(fun, kwargs)
