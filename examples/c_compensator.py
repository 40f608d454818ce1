"""A friction compensator in C from an identified model: export, compile, run.

Exports a model (a fit or diagnosis JSON, a saved model, or by default the paper's
two-state model) with `jaxfric.export.to_c`, compiles it with the system C compiler
together with ``examples/c_compensator.c`` (a simulated linear axis under PD control whose
friction is the same model, tracking a sine with and without the model's friction
feedforward, computed by ``jaxfric_step`` every sample), runs it and prints the maximum
tracking errors. The plant's friction is the exported model itself, so this shows what a
model that fits the axis gives, and how the generated code is used; it is not a claim
about a real axis (examples/feedforward.py compares models on a plant none of them is).

Run ``python examples/c_compensator.py [--model RESULT.json] [--amplitude A] [--out DIR]``
(SI: the amplitude in m).
"""

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import jaxfric
from jaxfric import paper
from jaxfric.export import to_c


HERE = Path(__file__).resolve().parent


def build_and_run(model, folder: Path, amplitude: float, cc: str = "cc") -> str:
    """Export `model` into `folder`, compile the axis program there, run it; its output."""
    to_c(model, folder / "model")
    exe = folder / "axis"
    subprocess.run([cc, "-O2", "-std=c99", f"-I{folder / 'model'}", str(HERE / "c_compensator.c"),
                    str(folder / "model" / "jaxfric_model.c"), "-lm", "-o", str(exe)],
                   check=True)
    return subprocess.run([str(exe), repr(amplitude)], check=True, capture_output=True,
                          text=True).stdout


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", help="fit/diagnosis JSON or saved model (default: the paper's "
                                    "two-state model)")
    ap.add_argument("--amplitude", type=float, default=1e-4, help="sine amplitude, m")
    ap.add_argument("--out", help="folder for the code and the program (default: temporary)")
    args = ap.parse_args(argv)
    if shutil.which("cc") is None:
        print("no C compiler ('cc') on the PATH", file=sys.stderr)
        return 1
    model = jaxfric.load_model(args.model) if args.model else paper.two_state()
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        print(build_and_run(model, Path(args.out), args.amplitude), end="")
    else:
        with tempfile.TemporaryDirectory() as tmp:
            print(build_and_run(model, Path(tmp), args.amplitude), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
