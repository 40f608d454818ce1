"""`benchmarks/bench_diff.py`: two bench runs compared file by file."""

import json

from benchmarks.bench_diff import compare, main, screen_changes


def _row(hidden, added, err, truth="lugre", offset_t=4.0):
    return {"truth": truth, "noise": 0.03, "dt": 0.01, "hidden": hidden, "added": added,
            "first": added[0] if added else None, "rmse_holdout_after": err,
            "rankings": [[{"name": "offset", "score": 0.5, "t": offset_t},
                          {"name": "drift", "score": 0.1, "t": None}]]}


def test_outcomes_errors_and_missing_files_are_told_apart(tmp_path, capsys):
    old = [_row(["drift"], ["drift"], 0.30), _row(["offset"], ["offset"], 0.20),
           _row([], [], 0.10), _row(["cogging"], ["cogging"], 0.5, truth="gms_power")]
    new = [_row(["drift"], ["drift"], 0.30 * (1 + 1e-6)), _row(["offset"], ["offset"], 0.25),
           _row([], ["drift"], 0.10), _row(["mass"], [], 0.4)]
    out = compare(old, new)
    assert [r["file"][3] for r in out["same"]] == [["drift"], ["offset"]]
    assert [r["file"][3] for r in out["error_moved"]] == [["offset"]]
    assert [r["file"][3] for r in out["changed"]] == [[]]
    assert out["only_old"] == [["gms_power", 0.03, 0.01, ["cogging"]]]
    assert out["only_new"] == [["lugre", 0.03, 0.01, ["mass"]]]
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"files": old}))
    b.write_text(json.dumps({"files": new}))
    assert main([str(a), str(b)]) == 0
    printed = capsys.readouterr().out
    assert "3 files in both runs: 2 the same outcome" in printed
    assert "1 changed; of the same, 1 with the held-out error moved" in printed
    assert "changed     lugre 0.03 N 10 ms clean" in printed


def test_the_screens_largest_change_is_found():
    old = [_row(["drift"], ["drift"], 0.3), _row(["offset"], ["offset"], 0.2)]
    new = [_row(["drift"], ["drift"], 0.3), _row(["offset"], ["offset"], 0.2, offset_t=6.5)]
    moved = screen_changes(old, new)
    assert moved["score"]["largest"] == 0.0 and moved["score"]["count"] == 4
    assert moved["t"]["count"] == 2  # drift's t is None in both
    assert moved["t"]["largest"] == 2.5 and moved["t"]["median"] == 1.25
    assert moved["t"]["where"] == [["lugre", 0.03, 0.01, ["offset"]], "offset"]


def test_a_candidate_refitted_in_the_first_round_is_left_out():
    """Its ranking entry holds its refit's verdict (a confirmed candidate's t is the
    refit's), so a change there is not the screen's."""
    old = [_row(["offset"], ["offset"], 0.2)]
    new = [_row(["offset"], ["offset"], 0.2, offset_t=6.5)]
    new[0]["trials"] = [{"round": 0, "effects": ["offset"]}]
    moved = screen_changes(old, new)
    assert moved["score"]["count"] == 1 and moved["score"]["where"][1] == "drift"
    assert "t" not in moved  # drift's t is None in both: nothing left to compare
