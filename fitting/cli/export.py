"""``jaxfric export RESULT.json --c DIR``: the fitted model of a fit or diagnosis result (or
a saved model) as dependency-free C99 for a controller (`jaxfric.export.to_c`)."""

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

It reproduces jaxfric's simulate sample by sample. Effects with no causal per-sample form
are refused by name.

examples:
  jaxfric fit run1.csv --json fit.json && jaxfric export fit.json --c controller/
  jaxfric diagnose run1.csv --json diag.json && jaxfric export diag.json --c out/
  cc -O2 -std=c99 -c out/jaxfric_model.c -o jaxfric_model.o
"""


def add_parser(sub) -> None:
    """Register the ``export`` command on the subparsers `sub` of `build_parser`."""
    import argparse

    p = sub.add_parser("export", help="write a fitted model as C code for a controller",
                       description=EXPORT_HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("result", metavar="RESULT.json",
                   help="a fit or diagnosis result (--json), or a saved model")
    p.add_argument("--c", metavar="DIR", dest="c_dir", required=True,
                   help="folder for jaxfric_model.h and jaxfric_model.c (made if missing)")
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
    from jaxfric.export import c_code, ExportError

    from ._output import atomic_file

    model = _load(args.result)
    try:
        texts = c_code(model)
    except ExportError as e:
        raise DataError(f"{args.result}: {e}") from None
    folder = Path(args.c_dir)
    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / "jaxfric_model.h", folder / "jaxfric_model.c"]
    for path, text in zip(paths, texts):
        with atomic_file(path) as f:
            f.write(text)
    if not args.quiet:
        for path in paths:
            print(f"wrote {path}")
        print(f"model: {texts[0].splitlines()[0].split('(', 1)[1].rsplit(')', 1)[0]}")
    return 0
