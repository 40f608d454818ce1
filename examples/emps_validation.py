"""EMPS: estimation -> validation. The model the diagnosis found on the estimation file
(``docs/figures/emps_diagnosis.json``, from ``jaxfric diagnose``) refitted there and used on
the validation file, which it was not fitted on:

    jaxfric fit ../shared/data/emps_estimation.csv --params docs/figures/emps_diagnosis.json \\
        --validate ../shared/data/emps_validation.csv --json emps_fit.json

and the same with ``--known-force pulse`` (the validation file's external force pulses
subtracted from its motor force ``u``). Then, does each effect the diagnosis added hold on
the validation file? The same command with the effects added one at a time, in the order
the diagnosis added them (each refitted on the estimation file, the validation file only
predicted). Writes ``docs/figures/emps_validation.json``:
the commands, each run's RMSE (N) and RMSE relative to the RMS of its force, overall and
per regime, and the rows of effects added. Prints a note and exits 0 when
``../shared/data`` is absent.

Run from the repository root: ``python examples/emps_validation.py`` (about five minutes).
"""

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from fitting.cli.main import main
from jaxfric import data as _data
from jaxfric.effects import EFFECTS


ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
DIAGNOSIS = ROOT / "docs" / "figures" / "emps_diagnosis.json"
OUT = ROOT / "docs" / "figures" / "emps_validation.json"


def _rms(path: Path) -> float:
    return float(np.sqrt(np.mean(_data.load(path).u ** 2)))


def _command(extra: list[str], out: Path) -> list[str]:
    return ["fit", str(DATA / "emps_estimation.csv"), "--params", str(DIAGNOSIS),
            "--validate", str(DATA / "emps_validation.csv"), *extra, "--json", str(out),
            "--quiet"]


def run(extra: list[str], params: dict | None = None) -> dict:
    """One ``jaxfric fit`` command; its runs' errors, relative to their RMS force. `params`:
    a model (as saved) to start from instead of the diagnosed one."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "fit.json"
        argv = _command(extra, out)
        if params is not None:
            start = Path(tmp) / "start.json"
            start.write_text(json.dumps(params))
            argv[argv.index(str(DIAGNOSIS))] = str(start)
        if main(argv) != 0:
            raise SystemExit(f"jaxfric {' '.join(argv)} failed")
        saved = json.loads(out.read_text())
    rows = []
    for row in saved["runs"] + saved["validation"]:
        rms = _rms(Path(row["file"]))
        rows.append({"file": Path(row["file"]).name, "role": row["role"],
                     "rmse": row["rmse"], "relative": row["rmse"] / rms, "rms_force": rms,
                     "regimes": {k: v["rmse"] for k, v in row["regimes"].items()}})
    shown = [a.replace(str(DATA), "../shared/data").replace(str(ROOT) + "/", "")
             for a in argv if a != "--quiet"]
    return {"command": "jaxfric " + " ".join(shown).replace(str(out), "emps_fit.json"),
            "converged": saved["converged"], "runs": rows}


def effects_added(diagnosis: dict) -> list[dict]:
    """The diagnosed model with its first k effects (k = 1 .. all, in the order they were
    added; ``fit`` needs the inertia to fit a drive force), each refitted on the
    estimation file from the diagnosed values and predicting the validation file: the
    names added and both runs' RMSE (N)."""
    model, added = diagnosis["fitted_model"], diagnosis["after"]["added"]
    # the model keeps its effects in an order of its own, not the order they were added
    name = {EFFECTS[n].__name__: n for n in added}
    rows = []
    for k in range(1, len(added) + 1):
        params = {**model, "effects": [e for e in model["effects"]
                                       if name[e["class"]] in added[:k]]}
        fitted, validation = run([], params)["runs"]
        rows.append({"added": added[:k], "estimation": fitted["rmse"],
                     "validation": validation["rmse"]})
        print(f"  + {', '.join(added[:k]):<45} estimation RMSE "
              f"{fitted['rmse']:.4g} N, validation {validation['rmse']:.4g} N", flush=True)
    return rows


def main_() -> int:
    if not (DATA / "emps_validation.csv").exists():
        print(f"{DATA} is absent: nothing to do")
        return 0
    result = {"unit": "N", "diagnosis": "docs/figures/emps_diagnosis.json",
              "in_sample_of_diagnosis": json.loads(DIAGNOSIS.read_text())["after"]["rmse"],
              "plain": run([]), "known_force_pulse": run(["--known-force", "pulse"])}
    print("each effect, in the order the diagnosis added it:")
    result["effects_added"] = effects_added(json.loads(DIAGNOSIS.read_text()))
    OUT.write_text(json.dumps(result, indent=2) + "\n")
    for name in ("plain", "known_force_pulse"):
        print(result[name]["command"])
        for r in result[name]["runs"]:
            print(f"  {r['file']:<22}{r['role']:<12}RMSE {r['rmse']:.4g} N  "
                  f"({100 * r['relative']:.3g} % of the RMS force {r['rms_force']:.4g} N)")
    print(f"written to {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main_())
