"""docs/validation.md, and the bench table of docs/diagnosis.md, are what
`benchmarks/make_validation.py` makes of the committed benchmark JSONs: no number on them
can be edited by hand."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.make_validation import (
    bench_by_truth,
    BENCH_MARKS,
    render,
    SOURCES,
    with_bench_table,
)


ROOT = Path(__file__).resolve().parents[2]
HEADINGS = ["## Diagnosis bench", "## Diagnosis bench: another run", "## Fit speed",
            "## Throughput", "## Monte-Carlo", "## Real data", "## C step",
            "## Diagnose speed", "## Compiler options"]


def test_the_committed_page_is_the_generated_one():
    page = (ROOT / "docs" / "validation.md").read_text()
    assert page == render(ROOT), "run: python benchmarks/make_validation.py"
    # Other pages link to these anchors.
    assert [line for line in page.splitlines() if line.startswith("## ")] == HEADINGS


def test_the_diagnosis_page_carries_the_generated_bench_table():
    page = (ROOT / "docs" / "diagnosis.md").read_text()
    bench = json.loads((ROOT / SOURCES["diagnosis"]).read_text())
    assert page == with_bench_table(page, bench), "run: python benchmarks/make_validation.py"
    table = bench_by_truth(bench)
    assert f"{BENCH_MARKS[0]}\n{table}\n{BENCH_MARKS[1]}" in page
    # one row per motion and truth of every corner
    rows = sum(len(c["by_truth"]) for c in bench["corners"])
    assert len(table.splitlines()) == 2 + rows
    edited = page.replace(table.splitlines()[2], table.splitlines()[2].replace("|", "| 9", 2))
    assert with_bench_table(edited, bench) == page  # a hand edit is overwritten
    with pytest.raises(ValueError, match="marker"):
        with_bench_table(page.replace(BENCH_MARKS[1], ""), bench)


def _copy(tmp_path: Path) -> Path:
    for rel in SOURCES.values():
        if (ROOT / rel).is_file():
            (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(ROOT / rel, tmp_path / rel)
    return tmp_path


def test_a_changed_result_changes_the_page(tmp_path):
    """The page follows the JSONs: a goal's measured value and its verdict come from them."""
    root = _copy(tmp_path)
    before = render(root)
    path = root / SOURCES["c_step"]
    data = json.loads(path.read_text())
    row = data["rows"][0]
    row["c_ns_per_step"] = 1234.0
    path.write_text(json.dumps(data))
    after = render(root)
    assert after != before
    assert f"| C step, {row['model']} | 1234 ns | <= 100 ns | **MISSED** |" in after


def test_the_diagnosis_targets_are_judged_on_the_counts(tmp_path):
    root = _copy(tmp_path)
    path = root / SOURCES["diagnosis"]
    data = json.loads(path.read_text())
    for corner in data["corners"]:
        corner["added_on_clean"] = 1
    path.write_text(json.dumps(data))
    n = len(data["corners"])
    assert f"| effects added on clean files | {n} | 0 | **MISSED** |" in render(root)


def test_a_judged_run_predicted_worse_is_counted_and_shown(tmp_path):
    """The generalisation goal follows the judged runs: one run predicted worse after the
    diagnosis makes it missed and puts that file in the table."""
    root = _copy(tmp_path)
    path = root / SOURCES["diagnosis_runs"]
    data = json.loads(path.read_text())
    judged = data["corners"][0]["judged_runs"]
    judged[0]["rmse_after"] = 2 * judged[0]["rmse_before"]
    path.write_text(json.dumps(data))
    page = render(root)
    n = sum(len(c["judged_runs"]) for c in data["corners"])
    assert f"| judged runs predicted worse after the diagnosis | 1 / {n} | 0 | **MISSED** |" \
        in page
    assert f"| {judged[0]['truth']} | " in page


def test_a_missing_json_is_said_not_invented(tmp_path):
    root = _copy(tmp_path)
    (root / SOURCES["compiler_options"]).unlink()
    page = render(root)
    assert "## Compiler options\n\nNo results: `benchmarks/compiler_options.json` is missing" \
        in page


def test_check_mode_fails_on_a_stale_page(tmp_path):
    stale = tmp_path / "validation.md"
    stale.write_text(render(ROOT).replace("## Throughput", "## Throughput (edited)"))
    script = ROOT / "benchmarks" / "make_validation.py"
    run = subprocess.run([sys.executable, str(script), "--check", "--out", str(stale)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 1 and "differs" in run.stdout
    stale.write_text(render(ROOT))
    run = subprocess.run([sys.executable, str(script), "--check", "--out", str(stale)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout


def test_a_json_of_another_layout_is_said_unreadable(tmp_path):
    root = _copy(tmp_path)
    (root / SOURCES["montecarlo"]).write_text(json.dumps({"rows": [{"case": "x"}]}))
    page = render(root)
    assert "## Monte-Carlo\n\nCannot read `benchmarks/montecarlo_speed.json`: KeyError" in page
    # A script that judges its own goals is shown as it judged them.
    (root / SOURCES["montecarlo"]).write_text(json.dumps({"goals": [
        {"goal": "batch >= 2x Numba", "measured": 2.5, "target": 2.0, "unit": "x",
         "status": "PASS"}], "rows": []}))
    assert "| batch >= 2x Numba | 2.5x | 2x | met |" in render(root)
