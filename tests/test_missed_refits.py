"""`benchmarks/missed_refits.py`: which null refits stand in the way of a looser rule."""

import json

from benchmarks.missed_refits import dominating, main, refits


def _file(hidden, added, trials):
    return {"truth": "lugre", "hidden": hidden, "added": added, "trials": [
        {"round": r, "effects": [e], "removed": rem, "t": t, "batches": 9, "added": a}
        for r, e, rem, t, a in trials]}


def test_a_miss_is_blocked_only_by_rejected_null_refits_at_least_as_strong(tmp_path,
                                                                          capsys):
    run = tmp_path / "diagnosis_bench_x.json"
    run.write_text(json.dumps({"files": [
        # the miss: a hidden lag, 19 % with t 2.7, rejected
        _file(["friction_lag"], [], [(0, "friction_lag", 0.19, 2.7, False)]),
        # null refits: stronger on both (blocks), stronger on one only (does not), and a
        # strong one that lost a close call in a round where another effect was added
        _file(["stribeck"], ["stribeck"], [(0, "stribeck", 0.6, 5.0, True),
                                           (0, "offset", 0.5, 4.0, False),
                                           (1, "cogging", 0.21, 2.8, False),
                                           (1, "drift", 0.3, 1.0, False)]),
    ]}))
    rows = refits([run])
    null = [r for r in rows if not r["hidden"] and r["rejected"]]
    assert [r["effect"] for r in null] == ["cogging", "drift"]
    (miss,) = [r for r in rows if r["hidden"] and not r["found"]]
    assert [r["effect"] for r in dominating(miss, null)] == ["cogging"]
    assert main([str(run)]) == 0
    printed = capsys.readouterr().out
    assert "friction_lag removed 19.0 %, t 2.70; rejected not-hidden refits with at least " \
        "both: 1" in printed and "cogging 21.0 %, t 2.80" in printed
    assert "without a false addition: 0 of 1" in printed
