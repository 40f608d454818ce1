"""The profiling scripts of benchmarks/ run and write what they print (smoke tests on
short motions; their timings are not checked, performance goals live in the benchmarks)."""

import json

from benchmarks import fit_compile, profile_two_state


def test_profile_two_state_runs_and_writes_json(tmp_path, capsys):
    out = tmp_path / "profile.json"
    profile_two_state.main(["--n", "2000", "--repeats", "1", "--json", str(out)])
    printed = capsys.readouterr().out
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


def test_profile_two_state_batch_runs(tmp_path, capsys):
    out = tmp_path / "profile_batch.json"
    profile_two_state.main(["--n", "600", "--batch", "3", "--repeats", "1", "--json", str(out)])
    printed = capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["meta"]["batch"] == 3 and "ns/traj-step" in printed
    assert len(data["rows"]) == 6  # the stages; no jacfwd row for a batch


def test_fit_compile_runs_and_writes_json(tmp_path, capsys):
    out = tmp_path / "compile.json"
    fit_compile.main(["--n", "2000", "--batch", "2", "--json", str(out)])
    printed = capsys.readouterr().out
    data = json.loads(out.read_text())
    calls = data["calls"]
    assert len(calls) == 3 and all(name in printed for name in calls)
    assert all(c["wall_s"] > 0 and c["compilations"] >= 0 for c in calls.values())
    # The second, identical fit reuses everything the first one compiled.
    _, again, _ = calls.values()
    assert again["compilations"] == 0, again["events"]


def test_xla_costs_runs_and_writes_json(tmp_path, capsys):
    from benchmarks import xla_costs

    out = tmp_path / "costs.json"
    xla_costs.main(["--n", "3000", "--repeats", "1", "--json", str(out)])
    data = json.loads(out.read_text())
    assert len(data["rows"]) == 8 and all(r["value"] > 0 for r in data["rows"])
    ev = data["event_pass"]
    assert 0 < ev["reversals"] <= ev["events"] < ev["iterations"]
    assert "us per iteration" in capsys.readouterr().out
