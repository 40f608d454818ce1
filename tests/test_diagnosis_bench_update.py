"""`benchmarks/diagnosis_bench.py --update`: how re-run files go into an earlier run."""

from benchmarks.diagnosis_bench import _replaced, cases, PAIRS


def _row(truth, hidden, added, noise=0.03, dt=1e-2):
    return {"truth": truth, "hidden": list(hidden), "noise": noise, "dt": dt,
            "added": list(added)}


def test_rerun_rows_replace_theirs_and_new_kinds_of_file_come_after():
    old = [_row("lugre", (), ()), _row("lugre", ("offset",), ("offset",)),
           _row("lugre", ("offset",), (), noise=0.08)]
    new = [_row("lugre", ("offset",), ("offset", "cogging")),
           _row("lugre", ("stribeck", "position_load"), ("stribeck",))]
    merged = _replaced(old, new)
    assert [r["added"] for r in merged] == [[], ["offset", "cogging"], [],
                                            ["stribeck"]]
    assert merged[2]["noise"] == 0.08  # the same effects at another noise: another file
    assert _replaced(old, []) == old


def test_pairs_added_later_keep_the_seeds_of_the_first():
    """A kind of pair added to the bench takes the next seed: the files made before it
    (their motion and noise are seeded by file) stay the same."""
    seeds = {tuple(c["hidden"]): c["seed"] for c in cases(quick=True)}
    assert seeds[()] == 0 and seeds[("quadratic_drag", "drift")] == 13
    assert [seeds[p] for p in PAIRS] == list(range(11, 11 + len(PAIRS)))
    assert {e for p in PAIRS for e in p} >= {h for (h,) in
                                             (k for k in seeds if len(k) == 1)}
