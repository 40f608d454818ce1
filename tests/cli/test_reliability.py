"""Reliability (issues 21 and 35): every case a careful or hostile user found, with the test
that proves it is fixed. The tests of this module cover absurd outliers (refused with their line
and value, in files, the Python API, diagnosis and batches), moderate spikes (warned with
their rows), `fit_batch`'s exact round trip, and the file-line numbers of messages; the
other cases are tested beside the code they concern, listed in `CASES` (checked to exist
by `test_every_case_has_its_test`), and described in docs/reliability.md.
"""

import ast
import json
import os
import re
import subprocess
import sys
import warnings
from pathlib import Path

import hypothesis.strategies as st
import numpy as np
import pytest
from hypothesis import given, HealthCheck, settings

import fitting
import jaxfric
from jaxfric import _outliers, paper
from jaxfric.data import DataError, DataWarning

from ..helpers import strokes_with_loops


#: Each case of issues 21's and 35's "Why" -> the tests that fail without its fix.
CASES = {
    # Round trips and saved results
    "fit -> JSON -> simulate --params reproduces the fit (RMSE 0.425 vs 15.52 N)":
        ["test_round_trip.py::test_fit_json_simulates_the_fitted_prediction"],
    "JSON with Infinity/NaN (a = inf): valid RFC 8259, null where undefined":
        ["test_round_trip.py::test_fit_json_simulates_the_fitted_prediction",
         "test_cli_outputs.py::test_json_is_rfc8259_with_null_for_undefined_values"],
    "the model rebuilt from the JSON is the fitted one, bit for bit":
        ["test_round_trip.py::test_saved_fit_reproduces_its_prediction_bit_for_bit",
         "test_reliability.py::test_fit_batch_saved_models_reproduce_their_predictions"],
    # Statuses
    "--max-steps 0 is not 'successful after 0 steps'":
        ["test_termination.py::test_zero_steps_is_not_success",
         "test_termination.py::test_cli_zero_steps_is_reported_as_not_converged"],
    "moderate force spikes (10-50 times the noise) are named, not fitted silently":
        ["test_reliability.py::test_moderate_spikes_in_a_file_are_named_and_fitted_as_given",
         "test_reliability.py::test_spikes_are_found_at_their_rows_and_noise_is_not",
         "test_reliability.py::test_no_spikes_in_ordinary_data"],
    "a force sample of 1e154 / 1e300 is not 'successful' at the start values":
        ["test_reliability.py::test_absurd_sample_in_a_file_names_its_line",
         "test_reliability.py::test_absurd_sample_is_refused_by_fit_and_diagnose",
         "test_reliability.py::test_cli_refuses_an_absurd_sample_in_one_line"],
    "fit_batch: such a dataset is not 'successful' with RMSE inf":
        ["test_reliability.py::test_fit_batch_absurd_dataset_fails_alone"],
    # Outputs
    "missing/unwritable folder, --json/--out a directory: refused before the work":
        ["test_cli_outputs.py::test_bad_output_is_refused_before_any_work",
         "test_cli_outputs.py::test_demo_refuses_an_output_folder_that_is_a_file"],
    "demo: outputs checked before the work (unwritable or unreachable folder)":
        ["test_cli_outputs.py::test_demo_checks_its_outputs_before_any_work"],
    "demo writes example.csv/summary.json/figures/report atomically, even when interrupted":
        ["test_cli_outputs.py::test_an_interrupted_or_failing_demo_leaves_whole_files_only"],
    "temp files with O_EXCL, not following symlinks":
        ["test_cli_outputs.py::test_writes_do_not_follow_a_planted_symlink"],
    "interrupted writes leave no temp file and the target intact":
        ["test_cli_outputs.py::test_atomic_file_leaves_the_target_alone_when_interrupted",
         "test_cli_outputs.py::test_sigterm_during_a_fit_cleans_up_and_writes_nothing"],
    "Ctrl-C stops a fit within a second or two":
        ["test_termination.py::test_progress_is_reported_and_an_interrupt_stops_the_fit",
         "test_interrupts.py::test_ctrl_c_stops_a_long_fit_within_two_seconds",
         "test_interrupts.py::test_the_watcher_stops_a_command_that_does_not_stop"],
    # Inputs
    "unreadable file: one line, exit 2":
        ["test_inputs.py::test_unreadable_file_is_one_line"],
    ".npy renamed .npz, object npz, --elements 0, --velocity-window nan, --params list, "
    "/dev/zero, FIFO, a huge file, np.float64(...) in messages":
        ["test_inputs.py::test_bad_input_is_one_line_exit_2"],
    "a 1.5 MB npz that inflates to gigabytes":
        ["test_inputs.py::test_a_small_npz_that_inflates_is_refused_without_inflating_it"],
    "trailing comma accepted, text column ignored with a note":
        ["test_inputs.py::test_trailing_commas_are_accepted",
         "test_inputs.py::test_text_column_is_ignored_with_a_note"],
    # Units
    "t in ms, x in mm over 2 mm, F in mN are named":
        ["test_units.py::test_time_in_ms", "test_units.py::test_x_in_mm_over_a_2_mm_travel",
         "test_units.py::test_force_in_mN"],
    # Physics
    "a velocity column whose sign disagrees: hysteresis force within the Stribeck bounds":
        ["test_direction.py::test_paper_two_state_stays_within_stribeck_bounds",
         "test_direction.py::test_random_two_state_stays_within_stribeck_bounds"],
    "memory overflow: counted under jit/vmap, --stack-size, reported by CLI and JSON":
        ["test_cli_deadband.py::test_simulate_default_plays_a_noisy_standstill_and_none_overflows",
         "test_cli_deadband.py::test_fit_records_the_deadband_and_simulate_params_reuses_it"],
    "noisy standstill: the default deadband keeps the true reversals, no overflow; a clean "
    "file is left alone":
        ["test_deadband_choice.py::"
         "test_noisy_standstill_default_keeps_the_true_reversals_without_overflow",
         "test_deadband_choice.py::test_noisy_velocity_column_at_a_quantised_standstill",
         "test_cli_deadband.py::test_simulate_default_leaves_a_clean_encoder_file_alone"],
    "a too-small max_reversals under jit is reported, not a silent NaN":
        ["test_direction.py::test_too_small_max_reversals_is_counted_under_jit_and_vmap"],
    # Issue 35
    "an output on an input (path, hard or symbolic link, inside a report folder) or on "
    "another output: refused before any work, input unchanged":
        ["test_cli_guards.py::test_no_output_replaces_an_input_or_another_output",
         "test_cli_guards.py::test_an_input_in_a_report_folder_that_the_report_does_not_write"
         "_is_fine"],
    "force all zeros (fit, --model lugre, diagnose, compare): one line, not a traceback":
        ["test_cli_guards.py::test_a_force_of_zero_is_one_line_naming_the_file"],
    "a timestamp 1 ns after the previous, time scaled by 1e-8: refused by every command, "
    "simulate writes no force":
        ["test_cli_guards.py::test_an_impossible_time_step_is_refused_naming_its_row",
         "test_cli_guards.py::test_measured_records_pass_the_time_step_rules"],
    "fit --model tustin --params gms.json: refused; the saved 'model' is the one fitted":
        ["test_cli_guards.py::test_model_and_params_that_disagree_are_refused",
         "test_cli_guards.py::test_the_saved_model_name_is_the_model_of_params"],
    "export of an unconverged, undetermined or non-physical fit: refused unless --force; "
    "status, errors and MuJoCo's approximation said":
        ["test_cli_guards.py::test_export_refuses_what_should_not_be_exported_unless_forced",
         "test_cli_guards.py::test_exported_files_carry_the_fits_status_and_errors",
         "test_cli_guards.py::test_a_real_unconverged_fit_is_refused_then_forced"],
    "RankWarning on a presliding-only file; 3 million empty header cells; Latin-1 µm":
        ["test_cli_guards.py::test_presliding_only_file_fits_without_a_numpy_warning",
         "test_cli_guards.py::test_a_header_of_millions_of_empty_cells_is_refused",
         "test_cli_guards.py::test_a_micrometre_header_is_read_in_latin1_and_utf8"],
}


def test_every_case_has_its_test():
    tests_root = Path(__file__).resolve().parents[1]
    for case, tests in CASES.items():
        for ref in tests:
            module, name = ref.split("::")
            (path,) = tests_root.glob(f"*/{module}")
            tree = ast.parse(path.read_text())
            names = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
            assert name in names, f"{case}: {ref} does not exist"


# ---- Absurd outliers ---------------------------------------------------------------

def _signal(n=400, seed=0):
    t, x = strokes_with_loops(n, seed)
    F = np.asarray(jaxfric.simulate(paper.two_state(), t, x))
    return t, x, F + 0.02 * np.random.default_rng(seed).normal(size=n)


def _write(path, t, x, F, comments=0):
    lines = ["t,x,F"] + [f"{a:.17g},{b:.17g},{c:.17g}" for a, b, c in zip(t, x, F)]
    for k in range(comments):  # blank and comment lines move the data down the file
        lines.insert(1 + 7 * k, "# a comment" if k % 2 else "")
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(("column", "value", "fragment"), [
    ("F", 1e154, r"1e\+154 is absurd for a force in N"),
    ("F", 1e300, r"1e\+300 is absurd for a force in N"),
    ("F", -1e5, r"-100000 is [0-9.e+]+ times farther from the median than 99 % of the samples"),
    ("x", 1e10, r"1e\+10 is absurd for a length in m"),
])
def test_absurd_sample_in_a_file_names_its_line(tmp_path, column, value, fragment):
    t, x, F = _signal()
    row = 150
    cols = {"x": x.copy(), "F": F.copy()}
    cols[column][row - 1] = value
    path = _write(tmp_path / "m.csv", t, cols["x"], cols["F"], comments=4)
    text = path.read_text().splitlines()
    data_lines = [k + 1 for k, ln in enumerate(text) if ln and not ln.startswith("#")][1:]
    line = data_lines[row - 1]
    assert text[line - 1].startswith(f"{t[row - 1]:.17g},")
    with pytest.raises(DataError) as e:
        jaxfric.data.load(path)
    message = str(e.value)
    assert message.startswith(f"{path}:{line}: column '{column}', row {row}: "), message
    assert re.search(fragment, message) and "np.float64" not in message
    assert "delete that row" in message  # what to do


DATA = Path(__file__).resolve().parents[3] / "shared" / "data"


@pytest.mark.parametrize("name", ["emps_estimation", "emps_validation", "tribometer"])
def test_real_measurements_are_far_from_the_relative_rule(name):
    """Real records (../shared/data) load, and their farthest sample is within 5 times
    the spread of each column (the rule refuses beyond 1000)."""
    path = DATA / f"{name}.csv"
    if not path.exists():
        pytest.skip(f"{path} not found")
    m = jaxfric.data.load(path, check_sign=False)
    for column in ("x", "v", "F", "u", "normal"):
        a = getattr(m, column)
        if a is not None:
            assert np.abs(a - np.median(a)).max() < 5 * _outliers.spread(a)


def test_absurd_sample_of_one_joint_names_the_joint(tmp_path):
    t = np.linspace(0.0, 10.0, 500)
    q, tau = 0.3 * np.sin(t), np.tanh(50 * np.cos(t))
    bad = tau.copy()
    bad[200] = 1e200
    path = tmp_path / "j.csv"
    np.savetxt(path, np.column_stack([t, q, q, tau, bad]), delimiter=",",
               header="t,q1,q2,tau1,tau2", comments="")
    with pytest.raises(DataError, match=r"j.csv joint 2: column 'F', row 201: 1e\+200 is absurd"):
        jaxfric.data.load_joints(path)


def test_the_relative_rule_refuses_no_ordinary_measurement():
    """Synthetic records at any scale, with noise, a long rest or a single moderate spike
    (10 times the force) are not refused."""
    F = _signal(1000)[2]
    for scale in (1e-6, 1.0, 1e4):
        G = F * scale
        G[500] = 10 * np.max(np.abs(G))
        assert _outliers.relative_outlier(G) is None
    rest = np.r_[np.zeros(900), F[:100]]  # 90 % at rest, exactly
    assert _outliers.relative_outlier(rest) is None


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scale=st.floats(1e-9, 1e6), n=st.integers(20, 3000), where=st.floats(0, 1),
       factor=st.floats(1.5e3, 1e300), seed=st.integers(0, 10_000))
def test_one_glitch_is_found_where_it_is(scale, n, where, factor, seed):
    """Property: a noisy friction-like signal of any scale has no absurd outlier, and one
    sample put 1.5e3..1e300 times its spread away is found at its index (no overflow on
    the way, even at 1e300 * 1e6)."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0, 6 * np.pi, n)
    sig = scale * (np.tanh(5 * np.sin(s)) + 0.05 * rng.normal(size=n))
    assert _outliers.relative_outlier(sig) is None
    i = int(where * (n - 1))
    far = np.max(np.abs(sig - np.median(sig)))  # the clean signal's farthest sample
    sig[i] = np.median(sig) + factor * far * (1 if seed % 2 else -1)
    found = _outliers.relative_outlier(sig)
    assert found is not None and found[0] == i
    assert found[1] > 1e3


@pytest.mark.parametrize("value", [1e154, 1e300, 1e5])
def test_absurd_sample_is_refused_by_fit_and_diagnose(value):
    t, x, F = _signal()
    G = F.copy()
    G[123] = value
    start = fitting.initial_model("tustin", t, x, F)
    expected = rf"dataset 0: F\[123\] = {value:.6g}".replace("+", r"\+")
    with pytest.raises(ValueError, match=expected):
        fitting.fit(start, t, x, G, max_steps=3)
    with pytest.raises(ValueError, match=r"dataset 1: F\[123\]"):
        fitting.fit_datasets(start, [fitting.Dataset(t, x, F), fitting.Dataset(t, x, G)],
                             max_steps=3)
    with pytest.raises(ValueError, match=r"F\[123\] = .* weight 0"):
        fitting.diagnose(start, t, x, G, max_steps=3)
    y = x.copy()
    y[7] = 1e10
    with pytest.raises(ValueError, match=r"x\[7\] = 1e\+10 is beyond"):
        fitting.fit(start, t, y, F, max_steps=3)


def test_an_absurd_sample_of_weight_zero_is_not_judged():
    t, x, F = _signal()
    G = F.copy()
    G[123] = 1e300
    w = np.ones_like(t)
    w[123] = 0.0
    start = fitting.initial_model("tustin", t, x, F)
    res = fitting.fit(start, t, x, G, weights=w, max_steps=3)
    assert np.isfinite(float(res.rmse))


def test_cli_refuses_an_absurd_sample_in_one_line(tmp_path):
    t, x, F = _signal()
    F[99] = 1e300
    path = _write(tmp_path / "m.csv", t, x, F)
    r = subprocess.run([sys.executable, "-m", "fitting.cli", "fit", str(path)],
                       capture_output=True, text=True, timeout=300,
                       env={**os.environ, "JAXFRIC_CACHE_DIR": ""})
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr
    assert "m.csv:101: column 'F', row 100: 1e+300 is absurd" in lines[0]


# ---- fit_batch -----------------------------------------------------------------------

def _batch(lengths=(300, 240, 270), seed=0):
    ts, xs, Fs = [], [], []
    for k, n in enumerate(lengths):
        t, x, F = _signal(n, seed + k)
        ts.append(t), xs.append(x), Fs.append(F * (1 + 0.1 * k))
    return ts, xs, Fs


def test_fit_batch_absurd_dataset_fails_alone():
    ts, xs, Fs = _batch()
    bad = [F.copy() for F in Fs]
    bad[1][50] = 1e154
    start = fitting.initial_model("tustin", ts[0], xs[0], Fs[0])
    with pytest.warns(DataWarning, match=r"dataset 1: F\[50\] = 1e\+154 .* not fitted"):
        res = fitting.fit_batch(start, ts, xs, bad, max_steps=10)
    assert res.status[1] != "successful" and not bool(res.converged[1])
    clean = fitting.fit_batch(start, ts, xs, Fs, max_steps=10)
    assert np.isfinite(float(clean.rmse[1]))
    for i in (0, 2):  # the others as if the bad one were not there
        assert res.status[i] == clean.status[i]
        assert np.array_equal(res.prediction[i], clean.prediction[i])


@pytest.mark.parametrize("kind", ["tustin", pytest.param("two-state", marks=pytest.mark.slow),
                                  pytest.param("lugre", marks=pytest.mark.slow),
                                  pytest.param("gms", marks=pytest.mark.slow)])
@pytest.mark.parametrize("with_v", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_fit_batch_saved_models_reproduce_their_predictions(kind, with_v):
    """Each dataset of a batch (different lengths, so padded), saved as JSON and read
    back, simulates exactly its prediction and residuals: bit for bit."""
    ts, xs, Fs = _batch()
    vs = [fitting.estimate_velocity(t, x) for t, x in zip(ts, xs)] if with_v else None
    start = fitting.initial_model(kind, ts[0], xs[0], Fs[0])
    res = fitting.fit_batch(start, ts, xs, Fs, vs, max_steps=8)
    for i, (t, x, F) in enumerate(zip(ts, xs, Fs)):
        text = json.dumps(jaxfric.model_to_dict(res[i].fit_model), allow_nan=False)
        back = jaxfric.load_model(json.loads(text))
        again = np.asarray(jaxfric.simulate(back, t, x, None if vs is None else vs[i]))
        assert np.array_equal(again, np.asarray(res.prediction[i, : t.size]))
        assert np.array_equal(np.asarray(res.residuals[i, : t.size]), again - F)


# ---- Moderate outliers: warned, named, fitted as given -------------------------------

NOISE = 0.05  # N


def _strokes(seed=0):
    """Strokes of 5 mm at 5 mm/s with rests of 0.2 s, sampled at 1 ms, through the
    paper's two-state model plus 0.05 N of noise: ``(t, x, F)``."""
    from ..helpers import waypoint_path

    t, x = waypoint_path(np.array([0.0, 5e-3, 0.0, 5e-3, 0.0]), 5e-3, 1e-3, dwell=0.2)
    F = np.asarray(jaxfric.simulate(paper.two_state(), t, x))
    return t, x, F + NOISE * np.random.default_rng(seed).normal(size=t.size)


def test_moderate_spikes_in_a_file_are_named_and_fitted_as_given(tmp_path):
    """Three force spikes of 12, 25 and 50 times the noise in steady sliding: a
    `DataWarning` names their rows and the file's lines, their size and the noise; the
    data are loaded unchanged; the command line prints the warning and fits."""
    t, x, F = _strokes()
    rows = [501, 1501, 2901]  # 1-based data rows, mid-stroke
    spiked = F.copy()
    spiked[np.array(rows) - 1] += NOISE * np.array([12.0, -25.0, 50.0])
    path = _write(tmp_path / "m.csv", t, x, spiked, comments=2)
    text = path.read_text().splitlines()
    data_lines = [k + 1 for k, ln in enumerate(text) if ln and not ln.startswith("#")][1:]
    lines = [data_lines[r - 1] for r in rows]
    with pytest.warns(DataWarning) as caught:
        m = jaxfric.data.load(path)
    spikes = [str(w.message) for w in caught if "isolated spike" in str(w.message)]
    assert len(spikes) == 1, [str(w.message) for w in caught]
    assert spikes[0].startswith(
        f"{path}:{lines[0]}: column 'F', row(s) 501, 1501, 2901 (lines "
        f"{', '.join(map(str, lines))}): 3 isolated spike(s) of "), spikes[0]
    sizes = re.search(r"of (\d+) to (\d+) times the noise \((0\.0\d+) N\)", spikes[0])
    assert sizes, spikes[0]
    low, high, noise = int(sizes[1]), int(sizes[2]), float(sizes[3])
    assert 10 <= low <= 14 and 45 <= high <= 55 and abs(noise - NOISE) < 0.01
    assert np.array_equal(m.F, spiked)  # fitted as given
    with warnings.catch_warnings():  # the same file without the spikes: no warning
        warnings.simplefilter("error", DataWarning)
        jaxfric.data.load(_write(tmp_path / "clean.csv", t, x, F))
    r = subprocess.run([sys.executable, "-m", "fitting.cli", "fit", str(path), "--model",
                        "tustin", "--max-steps", "0"], capture_output=True, text=True,
                       timeout=300, env={**os.environ, "JAXFRIC_CACHE_DIR": ""})
    assert r.returncode == 0, r.stderr
    warned = [ln for ln in r.stderr.splitlines() if "isolated spike" in ln]
    assert len(warned) == 1 and warned[0].startswith(f"warning: {path}:{lines[0]}: ")


def test_spikes_are_found_at_their_rows_and_noise_is_not():
    """Twenty noise draws on the strokes (1.9e5 samples): no spike is reported in the
    noise alone; five spikes of 12 (50) times the noise put at random rows in steady
    motion, at least 10 rows apart, are found in at least 95 % of the cases, and nothing
    else is named. (Missed: a spike on the steep start of a presliding curve, or one that
    the noise made smaller.)"""
    t, x, _ = _strokes()
    base = np.asarray(jaxfric.simulate(paper.two_state(), t, x))
    steady = np.flatnonzero(~_outliers.motion_events(t, x))
    found = {12: 0, 50: 0}
    for seed in range(20):
        rng = np.random.default_rng(seed)
        G = base + NOISE * rng.normal(size=t.size)
        assert _outliers.spikes(G, t, x)[0].size == 0, seed
        for size in found:
            rows = np.sort(rng.choice(steady[10:-10], 5, replace=False))
            while np.diff(rows).min() < 10:  # isolated: five spikes, not a burst
                rows = np.sort(rng.choice(steady[10:-10], 5, replace=False))
            H = G.copy()
            H[rows] += size * NOISE * rng.choice([-1.0, 1.0], 5)
            named = set(_outliers.spikes(H, t, x)[0].tolist())
            assert named <= set(rows.tolist()), (seed, size)  # never a wrong row
            found[size] += len(named)
    assert found[12] >= 95 and found[50] >= 95, found


def test_no_spikes_in_ordinary_data():
    """Forces with real one-sample features are not taken for glitches: the demo's
    measurement (speed changes sampled at 20 ms), synthetic records with cogging sampled a
    few times per period and with inertia at the end of an acceleration, noise-free
    simulations, and the measured records of ../shared/data."""
    from fitting.cli.demo import example_measurement
    from jaxfric import synthetic

    from ..helpers import nested_path, strokes_path

    records = [example_measurement()[:3]]
    for truth, hidden, dt in (("gms_power", "cogging", 2e-2), ("lugre", "cogging", 2e-2),
                              ("lugre", "inertia", 1e-2), ("two_state_power", "inertia", 1e-2)):
        records.append(synthetic.measurement(truth, (hidden,), dt=dt, seed=1)[:3])
    for t, x in (nested_path(), strokes_path(), strokes_with_loops(2000)):
        for model in (paper.two_state(), paper.lugre(), paper.tustin()):
            records.append((t, x, np.asarray(jaxfric.simulate(model, t, x))))
    for name, force in (("emps_estimation", "u"), ("tribometer", "F")):
        if (DATA / f"{name}.csv").exists():
            m = jaxfric.data.load(DATA / f"{name}.csv", check_sign=False)
            records.append((m.t, m.x, getattr(m, force)))
    for k, (t, x, F) in enumerate(records):
        assert _outliers.spikes(F, t, x)[0].size == 0, k
