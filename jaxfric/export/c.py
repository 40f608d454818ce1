"""Export a jaxfric model as dependency-free C99 (`to_c`): a per-sample step for a
controller's real-time loop.

The generated ``jaxfric_model.h`` / ``jaxfric_model.c`` use only ``<math.h>``, allocate
nothing, keep all memory in a fixed-size ``jaxfric_state`` (the model's memory stack for the
two-state model), compute in double precision, and bake the fitted values in as named
constants with their units in comments. The interface::

    typedef struct { ... } jaxfric_state;
    void   jaxfric_init(jaxfric_state *s, double t0, double x0);
    double jaxfric_step(jaxfric_state *s, double t, double x, double v);
    double jaxfric_step_load(jaxfric_state *s, double t, double x, double v, double load);

``jaxfric_init(s, t[0], x[0])`` then ``jaxfric_step(s, t[n], x[n], v[n])`` for every sample
in order gives the force ``jaxfric.simulate(model, t, x, v)[n]`` (N, or N m for a rotary
axis; SI inputs s, m, m/s). ``jaxfric_step_load`` also takes the transmitted load (N or
N m: ``simulate(..., load=...)``), read by the `load_friction` effect only; a model with
that effect has no ``jaxfric_step`` (a call to it fails to link, so the load cannot be
forgotten) and ``JAXFRIC_NEEDS_LOAD`` is 1. The code is a line-by-line translation of
the models' JAX ``step`` (see `_models_c`, `_shapes_c`, `_effects_c`);
tests/export/test_export_c.py compiles it and checks it against `simulate`.
"""

from pathlib import Path

from .._atomic import output_folder, write_text
from .._models._base import AbstractFrictionModel
from ..effects import WithEffects
from ._effects_c import effect_part, reads_load
from ._models_c import model_part, stack_size
from ._parts import c_double, ExportError, Part


HEADER_NAME = "jaxfric_model.h"
SOURCE_NAME = "jaxfric_model.c"

_COMMON_FIELDS = [
    "double t0; /* time given to jaxfric_init [s] */",
    "double t_prev; /* time of the previous sample [s] */",
    "double x_prev; /* position of the previous sample [m] */",
    "double v_prev; /* velocity of the previous sample [m/s] */",
]

_BASICS = """\
static double jf_sign(double v) { return (double)((v > 0.0) - (v < 0.0)); }

/* a / b, and 0 where b == 0 (jaxfric._numerics.safe_div). */
static double jf_div(double a, double b) { return b == 0.0 ? 0.0 : a / b; }
"""


def _parts(model) -> tuple[AbstractFrictionModel, list[Part]]:
    if not isinstance(model, AbstractFrictionModel):
        raise ExportError(f"expected a jaxfric model, got a {type(model).__name__}")
    base, effects = (model.base, model.effects) if isinstance(model, WithEffects) else (model, ())
    parts = [model_part(base)]
    parts += [effect_part(e) for e in effects]
    return base, parts


def _describe(model) -> str:
    if isinstance(model, WithEffects):
        names = ", ".join(e.name for e in model.effects)
        return f"{type(model.base).__name__} + effects ({names})"
    return type(model).__name__


def _comment_lines(comment: str | None) -> str:
    """`comment` as extra lines of the header's opening comment (``*/`` defused)."""
    if not comment:
        return ""
    lines = comment.replace("*/", "* /").splitlines()
    return "".join(f"\n   {line}" for line in lines)


def _header(model, parts: list[Part], comment: str | None = None) -> str:
    fields = [*_COMMON_FIELDS, *(f for p in parts for f in p.fields)]
    body = "\n".join(f"    {f}" if f.startswith("/*") else _field_line(f) for f in fields)
    needs_load = int(isinstance(model, WithEffects) and reads_load(model.effects))
    extra = _comment_lines(comment)
    plain_decl = "" if needs_load else (
        "\n/* jaxfric_step_load with no load: for a model that does not read it. */\n"
        "double jaxfric_step(jaxfric_state *s, double t, double x, double v);\n")
    return f"""\
/* jaxfric_model.h: friction model exported by jaxfric ({_describe(model)}).
   Generated code: C99, needs only <math.h>, no allocation, double precision.
   Units SI: t [s], x [m], v [m/s], force [N] (torque [N m] for a rotary axis).{extra} */
#ifndef JAXFRIC_MODEL_H
#define JAXFRIC_MODEL_H

#ifdef __cplusplus
extern "C" {{
#endif

/* capacity of the reversal memory (TwoState.stack_size; 1 for models without one) */
#define JAXFRIC_STACK_SIZE {stack_size(model.without_effects())}

typedef struct {{
{body}
}} jaxfric_state;

/* The zero state (no force, no memory) at time t0 [s] and position x0 [m]. */
void jaxfric_init(jaxfric_state *s, double t0, double x0);

/* 1 if the model reads the transmitted load (the load_friction effect): then only
   jaxfric_step_load is defined. */
#define JAXFRIC_NEEDS_LOAD {needs_load}

/* Advance to the sample (t [s], x [m], v [m/s]), samples in time order (the first may be
   at t0); returns the friction force [N] (torque [N m] for a rotary axis). The direction
   of motion is sign(v). load: the transmitted load at the sample [N] ([N m] for a rotary
   axis; its size is what counts), read by the load_friction effect only. */
double jaxfric_step_load(jaxfric_state *s, double t, double x, double v, double load);
{plain_decl}
#ifdef __cplusplus
}}
#endif

#endif /* JAXFRIC_MODEL_H */
"""


def _field_line(decl: str) -> str:
    code, _, comment = decl.partition("/*")
    code = code.strip().rstrip(";")
    return f"    {code};" + (f" /*{comment}" if comment else "")


def _source(parts: list[Part], needs_load: bool) -> str:
    consts = "\n".join(f"#define {name} ({c_double(value)}) /* {comment} */"
                       for p in parts for name, value, comment in p.consts)
    helpers = "\n".join(p.helpers for p in parts if p.helpers)
    init = "".join(p.init for p in parts)
    effects = "".join(p.step for p in parts[1:])
    loop_var = "    int i;\n" if "for (i" in init else ""
    plain = "" if needs_load else (
        "\ndouble jaxfric_step(jaxfric_state *s, double t, double x, double v)\n"
        "{\n    return jaxfric_step_load(s, t, x, v, 0.0);\n}\n")
    return f"""\
/* jaxfric_model.c: generated by jaxfric.export.to_c; see jaxfric_model.h. */
#include <math.h>
#include "jaxfric_model.h"

/* fitted values (SI units in the comments) */
{consts}

{_BASICS}
{helpers}
void jaxfric_init(jaxfric_state *s, double t0, double x0)
{{
{loop_var}    s->t0 = t0;
    s->t_prev = t0;
    s->x_prev = x0;
    s->v_prev = 0.0;
{init}}}

double jaxfric_step_load(jaxfric_state *s, double t, double x, double v, double load)
{{
    double dt = t - s->t_prev, dx = x - s->x_prev;
    double a = jf_div(v - s->v_prev, dt);
    double f = jf_model(s, x, v, dt), total = f;
    double stat = jf_s(v);
    (void)dx; (void)a; (void)stat; (void)load;
{effects}    s->t_prev = t;
    s->x_prev = x;
    s->v_prev = v;
    return total;
}}
{plain}"""


def c_code(model, comment: str | None = None) -> tuple[str, str]:
    """The text of ``jaxfric_model.h`` and ``jaxfric_model.c`` for `model` (any
    `TwoState`, `GMS`, `LuGre` or `Tustin`, with the exportable effects of
    `jaxfric.effects`); `comment` (lines of text, such as the fit's status and standard
    errors) is added to the header's opening comment. Raises `ExportError` (a
    `ValueError`) naming what cannot be exported."""
    _, parts = _parts(model)
    needs_load = isinstance(model, WithEffects) and reads_load(model.effects)
    return _header(model, parts, comment), _source(parts, needs_load)


def to_c(model, directory) -> tuple[Path, Path]:
    """Write ``jaxfric_model.h`` and ``jaxfric_model.c`` for `model` into `directory`
    (made if missing); returns their paths. `model` may also be a path to a saved model or
    a fit or diagnosis JSON (`jaxfric.load_model`). See the module docstring."""
    if isinstance(model, str | Path):
        from .._serialize import load_model

        model = load_model(model)
    header, source = c_code(model)
    folder = Path(directory)
    paths = folder / HEADER_NAME, folder / SOURCE_NAME
    with output_folder(folder):  # a folder made here goes again if writing fails
        for path, text in zip(paths, (header, source)):
            write_text(path, text)
    return paths
