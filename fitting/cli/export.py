"""``jaxfric export RESULT.json --c DIR | --mujoco OUT.xml``: the fitted model of a fit or
diagnosis result (or a saved model) as dependency-free C99 for a controller
(`jaxfric.export.to_c`), or as a MuJoCo model with a passive ``dcmotor`` actuator
(`jaxfric.export.to_mujoco`, LuGre models only)."""

import json
from pathlib import Path

from jaxfric.data import DataError


EXPORT_HELP = """\
Write the model of a fit or diagnosis result (jaxfric fit/diagnose --json, or a model saved
with jaxfric.save_model) as C99 for a real-time loop: DIR/jaxfric_model.h and
DIR/jaxfric_model.c, only <math.h>, no allocation, double precision, the fitted values as
named constants with their units. Interface (SI: s, m, m/s; force N, or N m for a rotary
axis):

  jaxfric_state s;
  jaxfric_init(&s, t0, x0);
  F = jaxfric_step(&s, t, x, v);   /* every sample, in time order */

It reproduces jaxfric's simulate sample by sample. A model with load-dependent friction
(load_friction) has jaxfric_step_load(&s, t, x, v, load) instead, load in N (N m).
Effects with no causal per-sample form are refused by name.

--mujoco writes an MJCF with one joint (--joint slide or hinge) and a passive dcmotor
actuator (MuJoCo 4) carrying LuGre friction, viscous damping and cogging; other models
and effects are refused with the reason (fit a LuGre model instead: --model lugre).

examples:
  jaxfric fit run1.csv --json fit.json && jaxfric export fit.json --c controller/
  jaxfric diagnose run1.csv --json diag.json && jaxfric export diag.json --c out/
  cc -O2 -std=c99 -c out/jaxfric_model.c -o jaxfric_model.o
  jaxfric fit run1.csv --model lugre --json l.json && jaxfric export l.json --mujoco axis.xml
"""


def add_parser(sub) -> None:
    """Register the ``export`` command on the subparsers `sub` of `build_parser`."""
    import argparse

    p = sub.add_parser("export", help="write a fitted model as C code for a controller",
                       description=EXPORT_HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("result", metavar="RESULT.json",
                   help="a fit or diagnosis result (--json), or a saved model")
    p.add_argument("--c", metavar="DIR", dest="c_dir",
                   help="folder for jaxfric_model.h and jaxfric_model.c (made if missing)")
    p.add_argument("--mujoco", metavar="OUT.xml", help="write a MuJoCo MJCF (LuGre models)")
    p.add_argument("--joint", choices=["slide", "hinge"], default="slide",
                   help="the MJCF's joint: slide (m, N) or hinge (rad, N m); default: slide")
    p.add_argument("--timestep", type=float, default=1e-3,
                   help="the MJCF's simulation time step, s (default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="print only errors")
    p.set_defaults(func=run)


def _load(path: str):
    import jaxfric

    source = Path(path)
    if not source.is_file():
        raise DataError(f"{path}: no such file")
    try:
        data = json.loads(source.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise DataError(f"{path}: not a readable JSON file ({e})") from None
    try:
        return jaxfric.load_model(data)
    except (ValueError, TypeError, KeyError) as e:
        raise DataError(f"{path}: {e}") from None


def run(args) -> int:
    from jaxfric.export import c_code, ExportError, mjcf

    from ._output import atomic_file

    if not (args.c_dir or args.mujoco):
        raise DataError("nothing to write: give --c DIR and/or --mujoco OUT.xml")
    model = _load(args.result)
    try:
        texts = c_code(model) if args.c_dir else None
        xml = mjcf(model, args.joint, args.timestep) if args.mujoco else None
    except ExportError as e:
        raise DataError(f"{args.result}: {e}") from None
    if xml is not None:
        with atomic_file(args.mujoco) as f:
            f.write(xml)
        if not args.quiet:
            print(f"wrote {args.mujoco}")
    if texts is not None:
        _write_c(args, texts, atomic_file)
    return 0


def _write_c(args, texts, atomic_file) -> None:
    from ._output import output_folder

    folder = Path(args.c_dir)
    paths = [folder / "jaxfric_model.h", folder / "jaxfric_model.c"]
    with output_folder(folder):  # a folder made here goes again if interrupted
        for path, text in zip(paths, texts):
            with atomic_file(path) as f:
                f.write(text)
    if not args.quiet:
        for path in paths:
            print(f"wrote {path}")
        print(f"model: {texts[0].splitlines()[0].split('(', 1)[1].rsplit(')', 1)[0]}")
        if "#define JAXFRIC_NEEDS_LOAD 1" in texts[0]:
            print("step: jaxfric_step_load(&s, t, x, v, load), load in N (N m on a rotary "
                  "axis): the model reads the transmitted load")
