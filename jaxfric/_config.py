"""Floating-point precision policy.

Presliding displacements are micrometres on strokes of metres and presliding forces change
by millinewtons over nanometres: float32 (about 7 significant digits) loses most of that.
jaxfric therefore turns on JAX's 64-bit mode when it is imported, unless the environment
variable ``JAXFRIC_NO_X64`` is set to a non-empty value other than ``0``. The switch is
global to JAX (it is how JAX works), so import jaxfric before creating any JAX arrays.
Everything in jaxfric also runs in float32 if x64 is left off, with less accurate
presliding.

Compiled programs can be kept on disk between processes (`enable_compilation_cache`):
the ``jaxfric`` command does it by default, the library only when asked.
"""

import os
import warnings
from pathlib import Path

import jax


def _want_x64() -> bool:
    flag = os.environ.get("JAXFRIC_NO_X64", "")
    return flag in ("", "0")


if _want_x64():
    jax.config.update("jax_enable_x64", True)


def x64_enabled() -> bool:
    """Whether JAX currently computes in 64-bit by default."""
    return bool(jax.config.jax_enable_x64)


def cache_home() -> Path:
    """jaxfric's folder for what it builds: ``$XDG_CACHE_HOME/jaxfric``, or
    ``~/.cache/jaxfric``."""
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "jaxfric"


def cache_env() -> str | None:
    """The folder ``JAXFRIC_CACHE_DIR`` names, or None: unset, or empty or ``0``, which turn
    the compilation cache off (`enable_compilation_cache`); what else is kept there (the
    compiled kernels, `jaxfric._kernel.cache_dir`) then goes under `cache_home`."""
    env = os.environ.get("JAXFRIC_CACHE_DIR")
    return None if env in (None, "", "0") else env


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/jaxfric/xla``, or ``~/.cache/jaxfric/xla``."""
    return cache_home() / "xla"


#: Programs that took at least this long to compile (s) are kept on disk (JAX: 1 s).
MIN_COMPILE_S = 0.0


def enable_compilation_cache(path: str | os.PathLike | None = None) -> Path | None:
    """Keep compiled programs on disk, so that a new process skips their compilation.

    A fit compiles its solver for seconds on a CPU (docs/speed.md); with the
    cache, a later process that runs the same fit (same model, free parameters, data
    shape and solver settings) loads it instead. This is JAX's persistent compilation
    cache (``jax_compilation_cache_dir``); JAX keys it by the program, the JAX version
    and the device. JAX stores by default only programs that took at least a second to
    compile; here every program is kept (`MIN_COMPILE_S`): a diagnosis compiles dozens of
    small ones (a simulation, a fit's last evaluation), which add up
    (`benchmarks/diagnose_speed.py` measures a diagnosis with an empty and a filled
    cache).

    `path`: the folder (created if missing). Without one: the environment variable
    ``JAXFRIC_CACHE_DIR`` if set (empty or ``0`` disables the cache), else
    `default_cache_dir`; but a folder already given to JAX (``JAX_COMPILATION_CACHE_DIR``
    or ``jax.config``) is kept. Call it before the first compilation. Returns the folder
    in use, or None if the cache is off (disabled, or the folder cannot be created: a
    warning says why).

    Only use a folder that no one else can write to: JAX runs what it loads from there.
    Deleting the folder is safe (it only costs the compilations again).
    The ``jaxfric`` command calls this at start; the library never does by itself.
    """
    if path is None:
        current = jax.config.jax_compilation_cache_dir
        if current:
            return Path(current)
        if os.environ.get("JAXFRIC_CACHE_DIR") is not None and cache_env() is None:
            return None  # set, empty or 0: off
        path = Path(cache_env() or default_cache_dir())
    path = Path(path).expanduser()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        warnings.warn(f"jaxfric: compilation cache disabled, cannot create {path}: {e}",
                      stacklevel=2)
        return None
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_S)
    return path
