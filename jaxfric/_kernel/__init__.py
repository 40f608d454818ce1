"""jaxfric's compiled CPU kernels, called through the XLA FFI.

Five handlers, compiled together into one shared library from the C++ sources shipped
with the package (`SOURCES`):

* `events.cc`, the event pass: the event loop of ``jaxfric._models.two_state`` as one C++
  loop per trajectory, with the same float64 arithmetic, so that its records are
  bit-identical to the pure-JAX loop's (tests/core/test_event_kernel.py). The JAX path's
  smooth pass runs on them; it is what ``grad`` and ``jacfwd`` differentiate.
* `forward.cc`, the whole forward pass (velocity, events, branch forces, shape, lag: the
  force of every sample), and the same loop on dual numbers (`dual.h`) for the Jacobian
  with respect to the parameters; `jaxfric._kernel.forward` wraps them in a custom JVP
  (tests/core/test_forward_kernel.py). Its exponentials and logarithms are vectorised a
  block of samples at a time (`vmath.h`).
* `gms.cc`, the N-element GMS's element recursion (`jaxfric._models.gms`), and the same
  loop with every element's derivatives with respect to its own parameters and to the
  shared ones (`jaxfric._kernel.gms`; tests/core/test_gms_kernel.py).

The library is compiled on first use with the system C++ compiler (``$CXX``, else ``c++``,
``g++`` or ``clang++``) into a cache folder (``$JAXFRIC_CACHE_DIR``, else
``$XDG_CACHE_HOME/jaxfric``, else ``~/.cache/jaxfric``), under a name keyed by a hash of the
sources, the jaxlib version and the compiler, loaded with ``ctypes`` and registered once
per process with `jax.ffi.register_ffi_target`.

**When they are used** (`use_kernel`, when a program is traced): on the CPU backend, for
float64 inputs (the forward pass also needs a shape it implements, see
`jaxfric._kernel.forward`). The environment variable ``JAXFRIC_EVENT_KERNEL`` chooses:
``jax`` always uses the pure-JAX path (the path on GPU/TPU); ``kernel`` requires the
kernels (a failed build raises); unset or ``auto`` uses them when they build, else logs
one line (logger ``jaxfric``) and uses the pure-JAX path. `jaxfric.simulate` and
`jaxfric.simulate_many` take the variable's value as part of their compilation cache key,
so a change takes effect at their next call; other compiled programs (a fit's) keep the
choice they were traced with.

Under ``jax.vmap`` a call receives the batch (``vmap_method="expand_dims"``: an input not
batched keeps a dimension of 1, which the kernel broadcasts rather than copies) and loops
over it, on several threads when the batch is large (rows.h). The event pass's outputs are
integers and its inputs are on stopped gradients, so ``grad`` and ``jacfwd`` never
differentiate it.
"""

import contextlib
import ctypes
import hashlib
import logging
import os
import shutil
import subprocess
import tempfile
import threading
from importlib import resources
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxfric._config import cache_env, cache_home


TARGET = "jaxfric_event_pass"
SYMBOL = "JaxfricEventPass"
FORWARD_TARGET = "jaxfric_forward_pass"
FORWARD_SYMBOL = "JaxfricForwardPass"
FORWARD_JACOBIAN_TARGET = "jaxfric_forward_jacobian"
FORWARD_JACOBIAN_SYMBOL = "JaxfricForwardJacobian"
GMS_TARGET = "jaxfric_gms_elements"
GMS_SYMBOL = "JaxfricGmsElements"
GMS_JACOBIAN_TARGET = "jaxfric_gms_jacobian"
GMS_JACOBIAN_SYMBOL = "JaxfricGmsJacobian"
#: The sources compiled into one shared library (the .cc files) and the header they share.
SOURCES = ("events.cc", "forward.cc", "gms.cc", "rows.h", "stack.h", "dual.h", "vmath.h", "shape.h")
#: -fno-trapping-math (floating-point exceptions are never enabled) lets the compiler turn the
#: selects of the vectorised loops into SIMD code (vmath.h); values are unchanged.
FLAGS = ("-O3", "-std=c++17", "-fno-trapping-math", "-shared", "-fPIC", "-pthread", "-w")
ENV = "JAXFRIC_EVENT_KERNEL"

_logger = logging.getLogger("jaxfric")
_lock = threading.Lock()
_state: dict = {}  # "ok": bool once decided; "error": why not


def mode() -> str:
    """``JAXFRIC_EVENT_KERNEL``: ``auto`` (unset), ``jax`` or ``kernel``."""
    value = os.environ.get(ENV, "auto").strip().lower() or "auto"
    if value not in ("auto", "jax", "kernel"):
        raise ValueError(f"{ENV} must be 'auto', 'jax' or 'kernel', got {value!r}")
    return value


@contextlib.contextmanager
def forced(value: str):
    """Set ``JAXFRIC_EVENT_KERNEL`` to `value` (``auto``, ``jax``, ``kernel``) inside the
    block (for benchmarks and tests: it applies to what is traced there)."""
    old = os.environ.get(ENV)
    os.environ[ENV] = value
    try:
        mode()
        yield
    finally:
        if old is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = old


def source(name: str = "events.cc") -> str:
    """The C++ source `name` (one of `SOURCES`)."""
    return resources.files(__package__).joinpath(name).read_text()


def find_compiler() -> str | None:
    """Path of the C++ compiler: ``$CXX``, else the first of ``c++``, ``g++``, ``clang++``."""
    for name in (os.environ.get("CXX"), "c++", "g++", "clang++"):
        if name and (path := shutil.which(name)):
            return path
    return None


def cache_dir() -> Path:
    """Where built kernels are kept (module docstring): the folder ``JAXFRIC_CACHE_DIR``
    names, else (also when it turns the compilation cache off) `jaxfric._config.cache_home`."""
    return Path(cache_env() or cache_home())


def _compiler_id(cxx: str) -> str:
    run = subprocess.run([cxx, "--version"], capture_output=True, text=True, timeout=60)
    return run.stdout.splitlines()[0] if run.stdout else cxx


def build(directory: Path | None = None) -> Path:
    """The shared library of the kernel: the cached one, else compiled now (atomically, so
    that processes building at once do not see a half-written file). Raises
    `RuntimeError` with the reason when there is no compiler or compilation fails."""
    cxx = find_compiler()
    if cxx is None:
        raise RuntimeError("no C++ compiler found (set CXX, or install g++ or clang++)")
    texts = {name: source(name) for name in SOURCES}
    include = jax.ffi.include_dir()
    key = hashlib.sha256("\0".join(
        [*texts.values(), jax.__version__, _jaxlib_version(),
         cxx, _compiler_id(cxx), " ".join(FLAGS)]).encode()).hexdigest()[:16]
    folder = Path(directory) if directory is not None else cache_dir()
    library = folder / f"kernels-{key}.so"
    if library.exists():
        return library
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        for name, text in texts.items():
            (Path(tmp) / name).write_text(text)
        out = Path(tmp) / library.name
        # Each source compiled on its own, all at once (they take seconds each, and the
        # first run on a machine waits for them), then linked.
        sources = [Path(tmp) / name for name in SOURCES if name.endswith(".cc")]
        objects = [src.with_suffix(".o") for src in sources]
        _run_all([[cxx, *FLAGS, "-c", "-isystem", include, "-o", str(obj), str(src)]
                  for src, obj in zip(sources, objects)])
        _run_all([[cxx, *FLAGS, "-o", str(out), *map(str, objects)]])
        os.replace(out, library)
    return library


def _run_all(cmds) -> None:
    """Run the commands `cmds` at once; `RuntimeError` naming the first that fails."""
    procs = [(cmd, subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                    text=True)) for cmd in cmds]
    failed = None
    for cmd, proc in procs:
        try:
            _, err = proc.communicate(timeout=600)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
        if proc.returncode != 0 and failed is None:
            last = (err.strip().splitlines() or ["(no message)"])[-1]
            failed = f"{' '.join(cmd)} failed: {last}"
    if failed:
        raise RuntimeError(failed)


def _jaxlib_version() -> str:
    try:
        import jaxlib

        return jaxlib.__version__
    except Exception:  # pragma: no cover - jaxlib always comes with jax
        return ""


def _register() -> None:
    library = build()
    lib = ctypes.cdll.LoadLibrary(str(library))
    for target, symbol in ((TARGET, SYMBOL), (FORWARD_TARGET, FORWARD_SYMBOL),
                           (FORWARD_JACOBIAN_TARGET, FORWARD_JACOBIAN_SYMBOL),
                           (GMS_TARGET, GMS_SYMBOL),
                           (GMS_JACOBIAN_TARGET, GMS_JACOBIAN_SYMBOL)):
        jax.ffi.register_ffi_target(target, jax.ffi.pycapsule(getattr(lib, symbol)),
                                    platform="cpu")
    _state["lib"] = lib  # keep it loaded


def available() -> bool:
    """Whether the kernel is built and registered (building and registering it on the
    first call). With ``JAXFRIC_EVENT_KERNEL=kernel`` a failure raises; otherwise it is
    logged once and False is returned."""
    with _lock:
        if "ok" not in _state:
            try:
                _register()
                _state["ok"] = True
            except Exception as err:  # no compiler, failed build, failed load
                _state["ok"], _state["error"] = False, f"{type(err).__name__}: {err}"
                if mode() != "kernel":
                    _logger.warning("jaxfric: the compiled event kernel is unavailable (%s); "
                                    "using the pure-JAX event pass", _state["error"])
        if not _state["ok"] and mode() == "kernel":
            raise RuntimeError(f"{ENV}=kernel but the event kernel is unavailable: "
                               f"{_state['error']}")
        return _state["ok"]


def prepare() -> threading.Thread | None:
    """Build (or load) the kernels in a background thread, so that the first program that
    uses them does not wait for the C++ compiler (about 13 s on the 2-core machine on a
    first run; `build`): what the command line does as it starts a command that simulates,
    while it reads the data. `available` then waits for that thread's answer (its lock).
    None, and nothing started, when ``JAXFRIC_EVENT_KERNEL=jax`` or when that is decided
    already."""
    try:
        if mode() == "jax" or "ok" in _state:
            return None
    except ValueError:  # a wrong JAXFRIC_EVENT_KERNEL: raised where the kernels are used
        return None

    def run():
        with contextlib.suppress(Exception):  # a failure is logged or raised by `available`
            available()

    thread = threading.Thread(target=run, name="jaxfric-kernels", daemon=True)
    thread.start()
    return thread


def is_float64(a) -> bool:
    """Whether `a` (an array, a tracer or a Python number) is float64; an array's dtype is
    read directly (`jnp.result_type` costs microseconds, and `jaxfric.simulate` asks this
    for every parameter at every call)."""
    dtype = getattr(a, "dtype", None)
    if dtype is not None:
        return dtype == np.float64
    return jnp.result_type(a) == jnp.float64


def use_kernel(*arrays) -> bool:
    """Whether the event pass of these arrays runs in the kernel (module docstring)."""
    chosen = mode()
    if chosen == "jax":
        return False
    floats = all(is_float64(a) for a in arrays)
    if chosen == "auto" and (jax.default_backend() != "cpu" or not floats):
        return False
    if not floats:
        raise ValueError(f"{ENV}=kernel needs float64 inputs")
    return available()


def threads() -> int:
    """The most threads the kernel uses for a batch: the CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def event_pass(x, s, reversal, x_prev, s_r, l1, stack_size: int):
    """The records of one trajectory's events (see events.cc): ``table`` (n + 1, 4),
    ``popped`` (n + stack_size,), ``overflow`` (), ``filled`` (n, 3), all int32. The
    caller stops the gradients of the inputs."""
    n = x.shape[-1]
    i32 = jnp.int32
    out = (
        jax.ShapeDtypeStruct((n + 1, 4), i32),
        jax.ShapeDtypeStruct((n + stack_size,), i32),
        jax.ShapeDtypeStruct((), i32),
        jax.ShapeDtypeStruct((n, 3), i32),
    )
    call = jax.ffi.ffi_call(TARGET, out, vmap_method="expand_dims")
    return call(x, s, jnp.asarray(reversal, bool), x_prev, s_r,
                jnp.asarray(l1, jnp.float64), stack_size=np.int64(stack_size),
                threads=np.int64(threads()))
