"""The machine a benchmark ran on, for its JSON: CPU, cores, memory, library versions,
precision and git state (`machine_facts`)."""

import os
import platform
import subprocess
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np


REPO = Path(__file__).resolve().parents[1]


def machine_facts() -> dict:
    """CPU, cores, memory, versions, precision and git state of this run."""
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        cpu = platform.processor() or "unknown"
    mem_gib = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                mem_gib = round(int(line.split()[1]) / 2**20, 1)
    except OSError:
        pass

    def version(mod):
        try:
            return __import__(mod).__version__
        except Exception:
            return None

    def git(*args):
        try:
            return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True,
                                  timeout=10).stdout.strip()
        except Exception:
            return None

    try:
        import numba
    except ImportError:  # the Numba baseline is optional
        numba = None

    return {
        "cpu": cpu,
        "logical_cores": os.cpu_count(),
        "usable_cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
        else os.cpu_count(),
        "memory_gib": mem_gib,
        "load_average_start": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "jax": jax.__version__,
        "jaxlib": version("jaxlib"),
        "numba": numba and numba.__version__,
        "numba_threads": numba and numba.get_num_threads(),
        "numpy": np.__version__,
        "equinox": version("equinox"),
        "optimistix": version("optimistix"),
        "jax_devices": [str(d) for d in jax.devices()],
        "jax_x64": bool(jax.config.jax_enable_x64),
        "float_dtype": str(jnp.asarray(0.0).dtype),
        "xla_flags": os.environ.get("XLA_FLAGS"),
        "git_commit": git("rev-parse", "HEAD"),
        "git_dirty": bool(git("status", "--porcelain", "--untracked-files=no")),
    }
