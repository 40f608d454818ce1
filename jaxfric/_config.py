"""Floating-point precision policy.

Presliding displacements are micrometres on strokes of metres and presliding forces change
by millinewtons over nanometres: float32 (about 7 significant digits) loses most of that.
jaxfric therefore turns on JAX's 64-bit mode when it is imported, unless the environment
variable ``JAXFRIC_NO_X64`` is set to a non-empty value other than ``0``. The switch is
global to JAX (it is how JAX works), so import jaxfric before creating any JAX arrays.
Everything in jaxfric also runs in float32 if x64 is left off; BENCHMARKS.md reports how
much accuracy that costs.
"""

import os

import jax


def _want_x64() -> bool:
    flag = os.environ.get("JAXFRIC_NO_X64", "")
    return flag in ("", "0")


if _want_x64():
    jax.config.update("jax_enable_x64", True)


def x64_enabled() -> bool:
    """Whether JAX currently computes in 64-bit by default."""
    return bool(jax.config.jax_enable_x64)
