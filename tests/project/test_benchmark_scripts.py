"""The benchmarks of benchmarks/ run and write what they print (smoke tests on short
motions; their timings are not checked, performance goals live in the benchmarks), and the
diagnosis bench's summary counts what it should. The scripts run as a user runs them."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fitting._result import STOPS


ROOT = Path(__file__).resolve().parents[2]


def _run(script: str, *args) -> str:
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / script), *map(str, args)],
                         capture_output=True, text=True, timeout=900, cwd=ROOT)
    assert run.returncode == 0, run.stdout + run.stderr
    return run.stdout


@pytest.mark.slow
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


@pytest.mark.slow
def test_montecarlo_speed_quick_runs(tmp_path):
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


@pytest.mark.slow
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
    assert row["jaxfric"]["stop"] in STOPS  # why the fit stopped, as a kind
    assert data["machine"]["cpu"] and data["date_utc"]  # the page names machine and date


@pytest.mark.slow
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


def test_diagnose_speed_compares_the_medians_of_two_codes_run_side_by_side():
    """``--against``: a row per code, and the ratio of this code's median to the other's
    for each size and cache state both ran."""
    from benchmarks.diagnose_speed import _medians, _ratios

    def run(code, cache, wall):
        return {"samples": 100, "cache": cache, "code": code, "wall_s": wall,
                "diagnosis_s": wall - 1, "cpu_s": wall, "added": []}

    runs = [run("this", "empty", 6.0), run("against", "empty", 4.0),
            run("this", "empty", 8.0), run("against", "empty", 5.0),
            run("this", "empty", 7.0), run("against", "empty", 40.0),
            run("this", "filled", 3.0)]
    rows = _medians(runs)
    assert [(r["code"], r["cache"], r["wall_s"]) for r in rows] == [
        ("this", "empty", 7.0), ("against", "empty", 5.0), ("this", "filled", 3.0)]
    assert _ratios(rows) == [{"samples": 100, "cache": "empty", "ratio": 7.0 / 5.0}]
    # scaled by the other code's own committed median: this code's time then
    then = {"commit": "abc1234", "wall_s": {(100, "empty"): 2.5, (100, "filled"): 1.0}}
    assert _ratios(rows, then) == [{"samples": 100, "cache": "empty", "ratio": 7.0 / 5.0,
                                    "then_s": 2.5, "scaled_s": 2.5 * 7.0 / 5.0}]


@pytest.mark.slow
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


@pytest.mark.slow
def test_diagnosis_bench_runs_and_writes_rows_and_summary(tmp_path):
    committed = (ROOT / "benchmarks" / "diagnosis_bench.json").read_text()
    rows = tmp_path / "rows.json"
    printed = _run("diagnosis_bench.py", "--quick", "--only", "offset", "--out", rows)
    data = json.loads(rows.read_text())
    # --only: the clean file and the files whose hidden effects are all listed.
    assert [f["hidden"] for f in data["files"]] == [[], ["offset"]]
    assert data["complete"] and data["date_utc"] and data["machine"]["cpu"]
    # The clean twin (same motion and noise, no offset) fits better than the file with it.
    row = data["files"][1]
    assert row["rmse_holdout_clean"] < 0.9 * row["rmse_holdout_before"]
    # A --only run's summary goes next to its rows, not over the committed one.
    (corner,) = json.loads((tmp_path / "rows_summary.json").read_text())["corners"]
    assert (corner["dt_s"], corner["noise_N"], corner["start"]) == (0.01, 0.03, "two-state")
    assert corner["files"] == 2 and corner["truths"] == ["gms_power"]
    assert corner["by_effect"]["offset"]["files"] == 1 and corner["clean_files"] == 1
    assert corner["singles"] == [int(row["first"] == "offset"), 1]
    assert "corner dt 10 ms, noise 0.03 N, start two-state" in printed
    assert (ROOT / "benchmarks" / "diagnosis_bench.json").read_text() == committed


def _bench():
    from benchmarks import diagnosis_bench

    return diagnosis_bench


def test_diagnosis_bench_pairs_added_later_keep_the_seeds_of_the_first():
    """A kind of pair added to the bench takes the next seed: the files made before it
    (their motion and noise are seeded by file) stay the same."""
    bench = _bench()
    seeds = {tuple(c["hidden"]): c["seed"] for c in bench.cases(quick=True)}
    assert seeds[()] == 0 and seeds[("quadratic_drag", "drift")] == 13
    assert [seeds[p] for p in bench.PAIRS] == list(range(11, 11 + len(bench.PAIRS)))
    assert {e for p in bench.PAIRS for e in p} == set(bench.SINGLES)


def test_diagnosis_bench_counts_only_the_hidden_effects_that_act():
    """A drag felt above 5 mm/s exerts no force on a sine sweep (top speed below 4 mm/s):
    that file is clean in fact; on point-to-point moves (about 20 mm/s) it acts."""
    bench = _bench()
    case = {"truth": "two_state_power", "noise": 0.03, "dt": 0.01, "seed": 13,
            "hidden": ["quadratic_drag", "drift"]}
    slow = {**case, "options": {"motion": "sine_sweep", "duration": 5.0}}
    fast = {**case, "options": {"motion": "point_to_point", "duration": 5.0}}
    assert bench.acting_effects(slow) == ["drift"]
    assert bench.acting_effects(fast) == ["quadratic_drag", "drift"]


def _row(hidden, added, before=0.2, after=0.1, clean=0.1, truth="lugre", dt=0.01):
    return {"truth": truth, "noise": 0.03, "dt": dt, "start": "two-state",
            "hidden": list(hidden), "added": list(added),
            "first": added[0] if added else None, "rmse_holdout_before": before,
            "rmse_holdout_after": after, "rmse_holdout_clean": clean if hidden else None}


def test_diagnosis_bench_summary_counts(tmp_path):
    """Found, absorbed, the pairs left when an effect is absorbed alone, the excess removed,
    and what was named instead, per corner; a later run's file replaces the earlier one's,
    and a run's corners replace theirs in the summary while the others are kept."""
    bench = _bench()
    first = [_row([], []), _row(["offset"], ["offset"], after=0.14),  # 60 % of the excess
             _row(["drift"], ["cogging"]),  # missed
             _row(["quadratic_drag"], [], before=0.105),  # absorbed (< 10 % over 0.1)
             _row(["quadratic_drag", "drift"], ["drift"]),  # the drag absorbed alone
             _row(["offset", "drift"], ["drift", "offset", "cogging"])]
    first += [_row([], ["GMS 20 from the data"], truth="stiction"),  # not an effect
              _row(["drift"], ["GMS with 20 elements", "drift"], truth="stiction")]
    first += [{**_row(["quadratic_drag"], [], truth="stiction"), "acting": []},  # clean
              {**_row(["quadratic_drag", "offset"], ["offset"], truth="stiction"),
               "acting": ["offset"]}]  # a single offset in fact, found
    later = [_row(["drift"], ["drift"], after=0.18)]  # re-run: found, 20 % removed
    other = [_row([], ["offset"], dt=0.005)]
    paths = []
    for k, rows in enumerate((first, later)):
        paths.append(tmp_path / f"run{k}.json")
        paths[-1].write_text(json.dumps({"files": rows, "date_utc": f"2030-01-0{k + 1}",
                                         "machine": {"cpu": "X", "usable_cores": 2}}))
    summary = tmp_path / "summary.json"
    summary.write_text(json.dumps(bench.summary(
        [{**r, "_run": "o"} for r in other], [{"name": "o", "cores": 2}])))
    rows, runs = bench.load_rows(paths)
    out = bench.write_summary(summary, rows, runs)
    c10, c5 = out["corners"]
    assert (c10["dt_s"], c5["dt_s"], c5["added_on_clean"]) == (0.01, 0.005, 1)
    assert c10["files"] == 10 and c10["singles"] == [4, 5]
    assert c10["singles_not_absorbed"] == [4, 4]
    assert c10["clean_files"] == 3 and c10["base_model_changed"] == [2, 10]
    assert c10["not_acting"] == [["quadratic_drag"], ["quadratic_drag", "offset"]]
    assert c10["pairs"] == [1, 2] and c10["pairs_not_absorbed"] == [1, 1]
    assert c10["added_on_clean"] == 0 and c10["not_hidden_added"] == 1
    assert c10["found_half_excess_removed"] == [4, 5]  # 60 %, 100 %, 100 %, 100 %, 20 %
    assert c10["median_excess_removed"] == pytest.approx(1.0)
    assert c10["by_effect"]["quadratic_drag"] == {"files": 1, "named_first": 0,
                                                  "absorbed": 1, "instead": {"nothing": 1}}
    assert c10["by_pair"]["offset + drift"] == {"files": 1, "both_found": 1}
    assert [r["date_utc"] for r in c10["runs"]] == ["2030-01-01", "2030-01-02"]


def test_diagnose_speed_summarise_remakes_the_table_from_recorded_runs(tmp_path, capsys):
    """``--summarise``: no diagnosis runs; the rows come from the recorded runs, the
    run's own date, command and machine are kept and the summarising command is added."""
    from benchmarks.diagnose_speed import main

    runs = [{"samples": 100, "cache": c, "code": "this", "wall_s": w, "diagnosis_s": w - 1,
             "cpu_s": w, "added": ["cogging"]} for c, w in (("empty", 9.0), ("empty", 7.0))]
    recorded = tmp_path / "recorded.json"
    recorded.write_text(json.dumps({"runs": runs, "date_utc": "then", "command": "run",
                                    "machine": {"cpu": "x"}, "repeats": 2}))
    out = tmp_path / "out.json"
    assert main(["--summarise", str(recorded), "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert [(r["cache"], r["wall_s"], r["runs"]) for r in data["rows"]] == [("empty", 8.0, 2)]
    assert (data["date_utc"], data["command"], data["machine"]) == ("then", "run", {"cpu": "x"})
    assert "--summarise" in data["summarised_by"] and "wall [s]" in capsys.readouterr().out
