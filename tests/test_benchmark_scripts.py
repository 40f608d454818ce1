"""The profiling scripts of benchmarks/ run and write what they print (smoke tests on
short motions; their timings are not checked, performance goals live in the benchmarks).
Each runs as a script, as a user runs it: the tests never import the benchmarks."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest


ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.slow  # about a minute together: compilation dominates


def _run(script: str, *args) -> str:
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / script), *map(str, args)],
                         capture_output=True, text=True, timeout=900, cwd=ROOT)
    assert run.returncode == 0, run.stdout + run.stderr
    return run.stdout


def test_profile_two_state_runs_and_writes_json(tmp_path):
    out = tmp_path / "profile.json"
    printed = _run("profile_two_state.py", "--n", "2000", "--repeats", "1", "--json", out)
    data = json.loads(out.read_text())
    assert data["meta"]["n"] == 2000
    stages = [r["stage"] for r in data["rows"]]
    assert len(stages) == 7 and all(s in printed for s in stages)
    assert all(r["ns_per_sample"] > 0 for r in data["rows"])
    # Stage costs are the differences of the cumulative rows (the jacfwd row has none).
    rows = data["rows"]
    assert abs(rows[1]["stage_ns_per_sample"]
               - (rows[1]["ns_per_sample"] - rows[0]["ns_per_sample"])) < 1e-9
    assert rows[-1]["stage_ns_per_sample"] is None


def test_profile_two_state_batch_runs(tmp_path):
    out = tmp_path / "profile_batch.json"
    printed = _run("profile_two_state.py", "--n", "600", "--batch", "3", "--repeats", "1",
                   "--json", out)
    data = json.loads(out.read_text())
    assert data["meta"]["batch"] == 3 and "ns/traj-step" in printed
    assert len(data["rows"]) == 6  # the stages; no jacfwd row for a batch


def test_fit_compile_runs_and_writes_json(tmp_path):
    out = tmp_path / "compile.json"
    printed = _run("fit_compile.py", "--n", "2000", "--batch", "2", "--json", out)
    calls = json.loads(out.read_text())["calls"]
    assert len(calls) == 3 and all(name in printed for name in calls)
    assert all(c["wall_s"] > 0 and c["compilations"] >= 0 for c in calls.values())
    # The second, identical fit reuses everything the first one compiled.
    _, again, _ = calls.values()
    assert again["compilations"] == 0, again["events"]


def test_xla_costs_runs_and_writes_json(tmp_path):
    out = tmp_path / "costs.json"
    printed = _run("xla_costs.py", "--n", "3000", "--repeats", "1", "--json", out)
    data = json.loads(out.read_text())
    assert len(data["rows"]) == 8 and all(r["value"] > 0 for r in data["rows"])
    ev = data["event_pass"]
    assert 0 < ev["reversals"] <= ev["events"] < ev["iterations"]
    assert "us per iteration" in printed


def test_diagnosis_bench_runs_and_writes_json(tmp_path):
    out = tmp_path / "bench.json"
    printed = _run("diagnosis_bench.py", "--quick", "--only", "offset", "--json", out)
    data = json.loads(out.read_text())
    assert [f["hidden"] for f in data["files"]] == [[], ["offset"]]
    assert data["complete"] and list(data["by_truth"]) == ["gms_power"]
    assert "confusion" in printed and data["summary"]["singles"] == 1
    assert "| single hidden effect named first (>= 90 %) | 1 of 1 | 1 of 1 (100 %): met |" \
        in printed, printed  # the targets' table for the docs
    # The clean twin (same motion and noise, no offset) fits better than the file with it.
    row = data["files"][1]
    assert row["rmse_holdout_clean"] < 0.9 * row["rmse_holdout_before"]
    assert data["summary"]["singles_absorbed_by_base"] == []
    # --update re-runs the files selected (here exactly one, --files) into the earlier run;
    # each re-run is listed, with the commit it ran at.
    again = tmp_path / "again.json"
    _run("diagnosis_bench.py", "--quick", "--files", "gms_power:offset", "--update", out,
         "--json", again)
    updated = json.loads(again.read_text())
    assert [r["files"] for r in updated["rerun"]] == [[["gms_power", ["offset"]]]]
    assert "commit" in updated["rerun"][0]
    assert [f["added"] for f in updated["files"]] == [f["added"] for f in data["files"]]
    assert updated["files"][0] == data["files"][0]  # the clean file was not re-run
    # A file the bench does not have is refused before anything runs.
    bad = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "diagnosis_bench.py"),
                          "--quick", "--files", "gms_power:offset+nope"],
                         capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert bad.returncode != 0 and "--files" in bad.stderr


def test_c_step_runs_and_writes_json(tmp_path):
    import shutil

    if shutil.which("cc") is None:
        pytest.skip("no C compiler: 'cc' is not on the PATH")
    out = tmp_path / "c_step.json"
    printed = _run("c_step.py", "--n", "3000", "--repeats", "1", "--step-calls", "50",
                   "--json", out)
    data = json.loads(out.read_text())
    assert data["meta"]["n"] == 3000
    assert {r["model"] for r in data["rows"]} >= {"two_state", "gms5", "lugre", "tustin"}
    assert all(r["model"] in printed for r in data["rows"])
    assert all(r["c_ns_per_step"] > 0 and r["c_max_error_rel_to_max_force"] < 1e-9
               for r in data["rows"])


def test_profile_two_state_params_runs(tmp_path):
    out = tmp_path / "profile_params.json"
    printed = _run("profile_two_state.py", "--n", "600", "--params", "3", "--repeats", "1",
                   "--json", out)
    data = json.loads(out.read_text())
    assert data["meta"]["params"] == 3 and "ns/set-step" in printed
    assert len(data["rows"]) == 6  # the stages; no jacfwd row for parameter sets


def test_montecarlo_speed_quick_runs_and_renders(tmp_path):
    pytest.importorskip("numba")
    out = tmp_path / "mc.json"
    printed = _run("montecarlo_speed.py", "--quick", "--json", out)
    data = json.loads(out.read_text())
    assert data["quick"] is True
    cases = [r["case"] for r in data["rows"]]
    assert len(cases) == 3 and all(c in printed for c in cases)
    # Same forces as the Numba baseline (its own check is < 1e-9 N), positive timings.
    assert all(r["max_abs_diff_N"] < 1e-9 and r["jaxfric_s"] > 0 and r["numba_s"] > 0
               for r in data["rows"])
    assert {o["op"] for o in data["ops"]} >= {"x ** p (XLA power)", "exp(p * log(x))"}
    md = tmp_path / "B.md"
    _run("make_benchmarks_md.py", ROOT / "benchmarks" / "throughput.json", "--montecarlo", out,
         "--out", md, "--docs", "")
    text = md.read_text()
    assert "## Monte-Carlo, batch and single trajectory against Numba prange" in text
    assert "smoke run" in text and all(c in text for c in cases)


def test_fit_speed_runs_and_writes_json(tmp_path):
    out = tmp_path / "fit_speed.json"
    printed = _run("fit_speed.py", "--quick", "--json", out)
    data = json.loads(out.read_text())
    (row,) = data["rows"]
    assert row["n"] == 2000 and "x warm" in printed
    # Same start for both: 11 free parameters, each moved by 15 %; c held.
    assert len(data["start_factors"]) == 11 and "c" not in data["start_factors"]
    assert set(data["start_factors"].values()) <= {0.85, 1.15}
    for side in ("jaxfric", "scipy"):
        assert row[side]["warm_s"] > 0 and row[side]["steps"] > 0
        assert np.isfinite(row[side]["rmse"])
    assert row["scipy"]["first_s"] >= row["scipy"]["warm_s"]  # + the Numba compilation
    assert {g["goal"] for g in data["goals"]} == {"steps", "warm speed-up",
                                                  "first-call speed-up", "RMSE vs scipy"}
    assert data["cells"] == data["rows"] and not data["partial"]


def test_interrupt_latency_runs_and_writes_json(tmp_path):
    out = tmp_path / "interrupt.json"
    printed = _run("interrupt_latency.py", "--n", "3000", "--delays", "0.3", "--json", out)
    data = json.loads(out.read_text())
    (row,) = data["rows"]
    assert row["exit"] == 130 and row["one_line"] and row["left"] == [], row
    assert data["summary"]["runs_with_expected_exit"] == 1 and "median" in printed


def test_diagnose_speed_runs_and_writes_json(tmp_path):
    out = tmp_path / "speed.json"
    printed = _run("diagnose_speed.py", "--sizes", "1500", "--repeats", "1", "--json", out)
    data = json.loads(out.read_text())
    rows = data["rows"]
    assert [r["cache"] for r in rows] == ["empty", "filled"] and len(data["runs"]) == 2
    assert all(abs(r["samples"] - 1500) <= 15 and r["wall_s"] > 0 and r["runs"] == 1
               for r in rows)
    assert all(0 < r["diagnosis_s"] <= r["wall_s"] and r["cpu_s"] > 0.5 * r["diagnosis_s"]
               for r in rows)
    assert "wall [s]" in printed and "cores" in printed


def test_diagnose_speed_medians():
    """The table's row per size and cache state is the median of its runs, and runs that
    added different effects are an error, not a median."""
    from benchmarks.diagnose_speed import _medians

    def run(cache, wall, added=("cogging",)):
        return {"samples": 100, "cache": cache, "wall_s": wall, "diagnosis_s": wall - 1,
                "cpu_s": 1.5 * wall, "added": list(added)}

    runs = [run("empty", 9.0), run("filled", 4.0), run("empty", 7.0), run("filled", 5.0),
            run("empty", 30.0), run("filled", 3.0)]
    empty, filled = _medians(runs)
    assert (empty["cache"], empty["runs"], empty["wall_s"], empty["diagnosis_s"]) == (
        "empty", 3, 9.0, 8.0)
    assert (empty["wall_min_s"], empty["wall_max_s"]) == (7.0, 30.0)
    assert (filled["wall_s"], filled["added"], filled["cpu_s"]) == (4.0, ["cogging"], 6.0)
    with pytest.raises(RuntimeError, match="different effects"):
        _medians([run("empty", 1.0), run("empty", 2.0, ())])


def test_compiler_options_compares_both_settings(tmp_path):
    out = tmp_path / "options.json"
    printed = _run("compiler_options.py", "--n", "2000", "--rounds", "1", "--json", out)
    data = json.loads(out.read_text())
    assert data["options"]["jaxfric"] and data["options"]["XLA defaults"] == {}
    assert [r["case"] for r in data["rows"]][-1] == "fit two-state, 50 steps"
    for r in data["rows"]:
        assert r["jaxfric: compile_s"] > 0 and r["XLA defaults: compile_s"] > 0
        assert r["max_dF_N"] < 1e-6  # only the generated code differs
        assert r["case"] in printed
