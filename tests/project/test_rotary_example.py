"""The rotary worked example (`examples/rotary_joint.py`, docs/rotary.md): the log is what
a robot records (angle in encoder counts, noisy torque, rad and N m in the header, read as
a rotary file), and (slow) its quick run goes from the CSV through ``jaxfric diagnose`` to
a saved model that ``jaxfric simulate --params`` reuses on another log."""

import math
import re

import numpy as np
import pytest

from jaxfric import data

from ..helpers import load_example


rj = load_example("rotary_joint")


def test_log_is_a_rotary_file_in_encoder_counts(tmp_path):
    t, q, tau = rj.record(20.0, seed=5)
    assert np.allclose(np.diff(t), 1 / rj.RATE)
    counts = q / (2 * math.pi / rj.COUNTS)
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
    # Dwells (the angle held for a while) and point-to-point moves up to about 1.2 rad/s.
    v = np.diff(q) / np.diff(t)
    assert np.mean(v == 0) > 0.1
    assert 0.3 < np.max(np.abs(v)) < 1.5
    m = data.load(rj.write_csv(tmp_path / "joint.csv", t, q, tau))
    assert m.kind == "rotary" and m.unit("x") == "rad" and m.unit("F") == "N m"


@pytest.mark.slow
def test_quick_run_finds_gravity_and_the_saved_model_predicts(tmp_path):
    r = rj.run(tmp_path, quick=True)
    f = r["found"]
    assert f["added"][0] == "angle_load", r["diagnose_output"]
    assert abs(f["gravity_amplitude"] - rj.GRAVITY[0]) < 0.1 * rj.GRAVITY[0]
    assert abs(f["gravity_phase"] - rj.GRAVITY[1]) < 0.1
    h = r["holdout_rmse"]
    assert h["final"] < 0.3 * h["baseline"]
    # The saved model on the second log predicts about as well as it fitted.
    assert r["check_rmse"] < 1.5 * h["final"]
    words = r["diagnose_output"] + r["simulate_output"]
    clean = re.sub(r"N m\b", "", words)
    assert not re.findall(r"\bN\b|\bmm\b|\bmm/s|\bum\b", clean), words
