"""The ``jaxfric`` command line."""

import argparse
import json
import sys
import time
from pathlib import Path


DEMO_HELP = """\
Run the built-in example end to end and write a report.

The example: a seeded identification motion (slow nested presliding loops, strokes at
0.1..20 mm/s, a varying-velocity segment); its "measured" friction comes from a
200-element GMS discretising the paper's presliding shape, plus 0.05 N of noise. The
paper's models (two-state, GMS-5, GMS-10, Tustin) and a LuGre model are compared with it,
overall and per regime, and figures are written.

examples:
  jaxfric demo
  jaxfric demo --out /tmp/report --quiet
"""


def _demo(args) -> int:
    from . import _demo

    out = Path(args.out)
    t0 = time.perf_counter()
    summary = _demo.run(out, log=(lambda *a: None) if args.quiet else print)
    elapsed = time.perf_counter() - t0
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=2))
    if not args.quiet:
        print(f"\nreport written to {out.resolve()}/ ({elapsed:.1f} s)")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="jaxfric",
        description="Differentiable dynamic friction models (SI units: s, m, m/s, N).",
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
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
