"""The ``jaxfric`` command line."""

import argparse
import glob
import signal
import sys
import threading
import time
from pathlib import Path

from .._diagnose import SEARCH_SAMPLES


DEMO_HELP = """\
Run the built-in example end to end and write a report.

The example: a seeded identification motion (slow nested presliding loops, strokes at
1..20 mm/s over 10 mm, a varying-velocity segment) through a simulated stage whose friction
has one hidden effect, sampled every 20 ms as a sensor would (a 0.1 um encoder, 0.05 N of
noise, no velocity column). The two-state model is fitted, the diagnosis
refits it with each candidate effect, cross-validates the best and adds the one that holds
up, and a
report (report.html with figures and tables) is written.

examples:
  jaxfric demo
  jaxfric demo --out /tmp/report --quiet
"""


def _demo(args) -> int:
    from . import demo

    out = Path(args.out)
    t0 = time.perf_counter()
    summary = demo.run(out, log=(lambda *a: None) if args.quiet else print)
    elapsed = time.perf_counter() - t0
    if args.json:
        from ._output import write_json

        write_json(args.json, summary)
    if not args.quiet:
        print(f"\nreport: {(out / 'report.html').resolve()} ({elapsed:.1f} s)")
    return 0


FIT_HELP = """\
Fit one friction model to a measurement and print its parameters with units and standard
errors (SI: s, m, m/s, N).

FILE is a CSV (header row: t, x, F; optional v, normal, load; units in brackets such as x[mm],
F[mN]) or an NPZ with those arrays. F is the friction force with the sign of the velocity;
if the file uses the opposite sign you will be warned, and --flip-force corrects it.
The starting values are estimated from the data; all parameters are fitted jointly.
A rotary file (a joint: x[rad] or x[deg], v[rad/s] or v[rpm], F[N m]; --rotary when the
header has no units) is fitted the same way and reported in rad, rad/s and N m.
A file of several joints (q1..qN, dq1..dqN, tau1..tauN, or a joint column) is fitted
joint by joint, with a table of all joints at the end.

Several files are runs of one machine (rates, units and columns may differ): one model is
fitted to all of them; --validate FILE... gives the error on runs not fitted, per run and
regime.

examples:
  jaxfric fit run1.csv --model two-state
  jaxfric fit run1.csv run2.csv --validate run3.csv --json fit.json
  jaxfric fit tribometer.csv --model two-state --flip-force --json fit.json --plot fit.png
  jaxfric fit data.csv --model gms --elements 10 --units x=mm,F=mN
  jaxfric fit joint.csv --units x=deg,v=deg/s,F=Nm
"""


DIAGNOSE_HELP = """\
Fit a model, refit it with each physical effect it may be missing, and add, one at a
time, the effect that predicts held-out time blocks better by more than chance (blocked
cross-validation) with physical values; report the error per regime before and after
(SI: s, m, m/s, N). The rule and its thresholds: docs/diagnosis.md.

A file with the drive force u instead of F is diagnosed from a friction-only model:
inertia and offset are then among the effects it should find.

Several files are runs of one machine, diagnosed together: every fit fits all of them
(shared parameters, per-run offsets), and the held-out data are the runs (leave one run
out): an effect is added only when it predicts runs it was not fitted on better.
--validate FILE... gives the error of the baseline and diagnosed models on runs not used.

examples:
  jaxfric diagnose run1.csv
  jaxfric diagnose slow.csv mid.csv fast.csv --validate other.csv --json diag.json
  jaxfric diagnose run1.csv --model gms --elements 10 --json diag.json --report diag/
"""


SIMULATE_HELP = """\
Simulate a model along the motion of a file (t, x and optionally v; SI or units in the
header) and write the model force as CSV. Without --params the paper's values are used.
Without a v column the velocity is estimated from x, and without an a column the
acceleration a mass term reads from the velocity (--derivatives; with --params, the way
that fit estimated them, so the force is the fit's prediction).

examples:
  jaxfric simulate motion.csv --model two-state --out forces.csv
  jaxfric fit run1.csv --json fit.json && jaxfric simulate run2.csv --params fit.json
  jaxfric fit a.csv b.csv --json fit.json && jaxfric simulate a.csv b.csv c.csv \\
      --params fit.json --out forces/
"""

COMPARE_HELP = """\
Fit several models to one measurement (or each to several runs at once) and print their
errors overall and per regime (presliding, reversal windows, sliding by speed,
accelerating, rest).

examples:
  jaxfric compare run1.csv
  jaxfric compare run1.csv --models two-state,gms,tustin --elements 10 --json cmp.json
  jaxfric compare run1.csv run2.csv --validate run3.csv
"""


def _simulate(args) -> int:
    from . import commands

    return commands.run_simulate(args)


def _compare(args) -> int:
    from . import commands

    return commands.run_compare(args)


def _diagnose(args) -> int:
    from . import commands

    return commands.run_diagnose(args)


def _fit(args) -> int:
    from . import commands

    return commands.run_fit(args)


def _add_data_options(p, files: str = "one") -> None:
    """The file and its reading options. `files`: ``"one"`` file, ``"runs"`` (several
    files fitted with one model, ``--validate``, ``--known-force``) or ``"list"`` (several
    files accepted by the parser; the command says how many it takes)."""
    if files == "one":
        p.add_argument("file", metavar="FILE", help="measurement: .csv (header row) or .npz")
    else:
        p.add_argument("file", metavar="FILE", nargs="+",
                       help="measurement: .csv (header row) or .npz"
                            + ("; several files are runs of one machine, fitted with one "
                               "model" if files == "runs" else ""))
    if files == "runs":
        p.add_argument("--validate", metavar="FILE", nargs="+",
                       help="runs not used for fitting: their error per run and regime is "
                            "printed and saved (give it after the files)")
        p.add_argument("--known-force", metavar="COLUMN",
                       help="a column of known force (N, or N m; e.g. EMPS's pulse) in the "
                            "measured force: subtracted, not fitted")
    p.add_argument("--units", action="append", metavar="COL=UNIT",
                   help="units of columns without one in the header, e.g. x=mm,F=mN")
    p.add_argument("--flip-force", action="store_true",
                   help="multiply the force by -1 (data recorded with the opposite sign)")
    _add_kind_options(p)
    p.add_argument("--json", metavar="OUT", help="write the result as JSON")
    p.add_argument("--quiet", action="store_true", help="print only errors")


def _add_derivative_options(p, default_window: str = "none", default="central") -> None:
    p.add_argument("--derivatives", default=default, choices=["central", "savgol", "backward"],
                   help="velocity (and acceleration) from the position when the file has no "
                        "v (a) column: central difference (zero phase; default), "
                        "Savitzky-Golay, or the backward difference a causal controller "
                        "computes"
                        + ("" if default else "; with --params, the one the fit used"))
    p.add_argument("--velocity-window", type=float, metavar="S",
                   help=f"smooth the velocity estimate over S seconds (default: {default_window})")


def _add_kind_options(p) -> None:
    p.add_argument("--kind", choices=["linear", "rotary"],
                   help="linear (m, N) or rotary (rad, N m) for a file whose header has no "
                        "units (default: from the units, else linear)")
    p.add_argument("--rotary", action="store_true", help="same as --kind rotary")


def _add_deadband_option(p, default: str) -> None:
    p.add_argument("--deadband", metavar="B|auto|none",
                   help="play on the position against noisy standstill, in SI (m or rad), "
                        "'auto' (estimated from the positions, applied only when 4 or more "
                        "reversals in a row are within the noise band) or 'none' "
                        f"(default: {default})")


def build_parser() -> argparse.ArgumentParser:
    """The ``jaxfric`` argument parser (also used to print the help into the docs)."""
    parser = argparse.ArgumentParser(
        prog="jaxfric",
        description="Differentiable dynamic friction models (SI units: s, m, m/s, N).",
        epilog="Compiled programs are kept in $XDG_CACHE_HOME/jaxfric/xla (default "
               "~/.cache/jaxfric/xla), so a second run of the same fit skips most of its "
               "compilation; set JAXFRIC_CACHE_DIR to use another folder, or to an empty "
               "value to turn the cache off (a JAX_COMPILATION_CACHE_DIR you set is used "
               "instead of either).",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser(
        "demo",
        help="run the built-in example and write a report",
        description=DEMO_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--out", default="jaxfric-demo", help="report folder (default: %(default)s)")
    p.add_argument("--json", help="also write the summary as JSON to this file")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_demo)

    p = sub.add_parser(
        "fit",
        help="fit a model to a measurement file",
        description=FIT_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_data_options(p, files="runs")
    p.add_argument("--model", choices=["two-state", "two_state", "gms", "lugre", "tustin"],
                   help="model to fit (default: the model of --params, else two-state); "
                        "with --params it must be that model")
    p.add_argument("--elements", type=int, default=5, help="GMS elements (default: 5)")
    p.add_argument("--max-steps", type=int, default=200, help="solver iteration limit")
    _add_deadband_option(p, "auto; the value used is saved in --json")
    p.add_argument("--plot", metavar="PNG", help="write measured vs fitted force (PNG)")
    p.add_argument("--params", metavar="JSON",
                   help="start from this model (a fit, a diagnosis or a saved model; its "
                        "effects included) instead of values estimated from the data")
    _add_derivative_options(p)
    p.set_defaults(func=_fit)

    _add_simulate(sub)

    p = sub.add_parser(
        "compare",
        help="fit several models and compare their errors per regime",
        description=COMPARE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_data_options(p, files="runs")
    p.add_argument("--models", default="two-state,gms,lugre,tustin",
                   help="comma-separated (default: %(default)s)")
    p.add_argument("--elements", type=int, default=5, help="GMS elements (default: 5)")
    p.add_argument("--max-steps", type=int, default=200, help="solver iteration limit")
    _add_deadband_option(p, "auto; the value used is saved in --json")
    _add_derivative_options(p)
    p.set_defaults(func=_compare)

    p = sub.add_parser(
        "diagnose",
        help="find the physical effects a model is missing",
        description=DIAGNOSE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_data_options(p, files="runs")
    p.add_argument("--model", default="two-state",
                   choices=["two-state", "two_state", "gms", "lugre", "tustin"],
                   help="model to start from (default: %(default)s)")
    p.add_argument("--elements", type=int, default=5, help="GMS elements (default: 5)")
    p.add_argument("--max-steps", type=int, default=300, help="solver iterations per fit")
    p.add_argument("--search-samples", type=int, default=SEARCH_SAMPLES, metavar="N",
                   help="a record of 2N samples or more: search the effects on about N "
                        "(where the base model needs them), refit on all (default: %(default)s; "
                        "0: every sample throughout)")
    p.add_argument("--report", metavar="DIR", help="write figures and diagnosis.json here")
    _add_deadband_option(p, "auto; the value used is saved in --json")
    _add_derivative_options(p, default_window="none; 0.01 s for drive-force data u")
    p.set_defaults(func=_diagnose)

    from . import export

    export.add_parser(sub)
    return parser


def _add_simulate(sub) -> None:
    """The ``simulate`` command's parser."""
    p = sub.add_parser(
        "simulate",
        help="simulate a model along a file's motion",
        description=SIMULATE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("file", metavar="FILE", nargs="+",
                   help="motion: .csv (header row) or .npz; several files are simulated one "
                        "by one into the --out folder")
    p.add_argument("--units", action="append", metavar="COL=UNIT",
                   help="units of columns without one in the header, e.g. x=mm")
    _add_kind_options(p)
    p.add_argument("--model", choices=["two-state", "two_state", "gms", "lugre", "tustin"],
                   help="model (default: the model of --params, else two-state with the "
                        "paper's values); with --params it must be that model")
    p.add_argument("--params", metavar="JSON", help="parameters from 'jaxfric fit --json'")
    p.add_argument("--stack-size", type=int, metavar="N",
                   help="memory stack slots of a two-state model (default: the model's)")
    _add_deadband_option(p, "the value saved in --params, else auto")
    p.add_argument("--run", type=int, metavar="K",
                   help="with --params from a fit to several files: the model of the K-th "
                        "file, its per-run parameters included (default: their mean over "
                        "the runs, the model for a run not fitted)")
    p.add_argument("--out", help="CSV to write (default: simulated.csv); with several files "
                                 "a folder (default: simulated/) that gets one CSV per file, "
                                 "named as the file")
    p.add_argument("--quiet", action="store_true", help="print only errors")
    _add_derivative_options(p, default=None)
    p.set_defaults(func=_simulate)


def main(argv=None) -> int:
    """Run the ``jaxfric`` command with `argv` (default: the process's arguments); returns
    the exit code (0, also for a fit that did not converge: its status says so; 2 for bad
    input or outputs, 130 interrupted, 143 terminated)."""
    args = build_parser().parse_args(argv)
    from jaxfric import enable_compilation_cache
    from jaxfric.data import DataError

    from . import _interrupt

    enable_compilation_cache()
    signal.signal(signal.SIGTERM, _interrupt.terminate)
    # The command line as a process stops within about a second of Ctrl-C or SIGTERM, even
    # in compiled code; an in-process call (argv given) gets the exit code back instead.
    hard = argv is None and threading.current_thread() is threading.main_thread()
    if hard:
        _interrupt.arm(args.command)
    try:
        from ._io import check_options

        check_options(args)
        _several_files(args)
        _check_outputs(args)
        if _uses_kernels(args):
            from jaxfric._kernel import prepare

            prepare()  # the C++ kernels build while the data are read
        return args.func(args)
    except DataError as e:
        print(f"jaxfric {args.command}: error: {e}", file=sys.stderr)
        return 2
    except _interrupt.Terminated:
        return _interrupt.stop(args.command, signal.SIGTERM, hard)
    except KeyboardInterrupt:
        return _interrupt.stop(args.command, signal.SIGINT, hard)


def _uses_kernels(args) -> bool:
    """Whether the command simulates a model of the compiled kernels (`jaxfric._kernel`:
    the two-state model and the GMS, not LuGre or Tustin; no ``--model``: the two-state
    model); a diagnosis and the demo try a GMS whatever their model."""
    if args.command in ("demo", "diagnose"):
        return True
    if args.command not in ("fit", "simulate", "compare"):
        return False
    models = (args.models.split(",") if args.command == "compare"
              else [args.model or "two-state"])
    return any(m.strip() not in ("lugre", "tustin") for m in models)


#: The outputs of each command: (option, attribute, file or folder), checked before work.
_OUTPUTS = {
    "demo": (("--out", "out", "folder"), ("--json", "json", "file")),
    "fit": (("--json", "json", "file"), ("--plot", "plot", "file")),
    "simulate": (("--out", "out", "file"), ("--out", "out_dir", "folder")),
    "compare": (("--json", "json", "file"),),
    "diagnose": (("--json", "json", "file"), ("--report", "report", "folder")),
    "export": (("--c", "c_dir", "folder"), ("--mujoco", "mujoco", "file")),
}
#: The files a folder output writes into its folder (name patterns), by attribute.
_FOLDER_FILES = {
    "report": ("report.html", "diagnosis.json", "*.png", "joint_*/report.html",
               "joint_*/diagnosis.json", "joint_*/*.png"),  # one folder per joint
    "c_dir": ("jaxfric_model.h", "jaxfric_model.c"),
    "out": ("report.html", "diagnosis.json", "summary.json", "example.csv", "*.png"),
}
#: The input files of each command: (what, attribute).
_INPUTS = {
    "demo": (),
    "fit": (("FILE", "files"), ("--validate", "validate"), ("--params", "params")),
    "simulate": (("FILE", "files"), ("--params", "params")),
    "compare": (("FILE", "files"), ("--validate", "validate")),
    "diagnose": (("FILE", "files"), ("--validate", "validate")),
    "export": (("RESULT.json", "result"),),
}


def _check_outputs(args) -> None:
    """Every output path can be written, and replaces neither an input nor another output,
    before any work (`fitting.cli._output`)."""
    from ._output import check_clashes, check_file, check_folder

    outputs = []
    for option, attr, kind in _OUTPUTS[args.command]:
        path = getattr(args, attr, None)
        if path:
            (check_file if kind == "file" else check_folder)(path, option)
            names = getattr(args, f"{attr}_files", None) or _FOLDER_FILES.get(attr)
            outputs.append((option, path, () if kind == "file" else names))
    inputs = []
    for what, attr in _INPUTS[args.command]:
        value = getattr(args, attr, None)
        inputs += [(what, p) for p in value] if isinstance(value, list) else [(what, value)]
    check_clashes(inputs, outputs)


def _several_files(args) -> None:
    """``args.files``: the list of FILE arguments (``args.file`` is the first, what the
    one-file code reads)."""
    if not isinstance(getattr(args, "file", None), list):
        return
    args.files = args.file
    args.file = args.files[0]
    if args.command == "simulate":
        _simulate_outputs(args)


def _simulate_outputs(args) -> None:
    """``simulate`` writes one file to ``--out``, or with several files one CSV per file
    (named as the file) into the folder ``--out`` (``args.out_dir``, ``args.out_dir_files``)."""
    from jaxfric.data import DataError

    if len(args.files) == 1:
        args.out = args.out or "simulated.csv"
        return
    names = [Path(f).stem + ".csv" for f in args.files]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise DataError(f"several files would be written to {', '.join(twice)} in the --out "
                        "folder (files of the same name): rename or simulate them separately")
    args.out_dir, args.out = args.out or "simulated", None
    args.out_dir_names = names
    args.out_dir_files = tuple(glob.escape(n) for n in names)  # as patterns, for the checks

