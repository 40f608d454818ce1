"""examples/sensitivity.py runs, and its band means what it says (slow: a fit of 1e4
samples)."""

import json

import numpy as np
import pytest

from ..helpers import load_example


pytestmark = pytest.mark.slow


def test_sensitivity_example_writes_its_band_and_figure(tmp_path):
    ex = load_example("sensitivity")
    assert ex.main(["--num", "8", "--repeats", "1", "--out", str(tmp_path)]) == 0
    out = json.loads((tmp_path / "sensitivity.json").read_text())
    assert (tmp_path / "sensitivity.png").stat().st_size > 10_000
    band = out["band_90_N"]
    # A band from the fit's covariance: positive, and nowhere near zero width everywhere.
    assert 0.0 < band["median"] <= band["max"]
    assert out["draws"] == 8 and out["samples"] > 1000
    assert np.isfinite(out["fit"]["rmse_N"])
    assert out["monte_carlo_seconds"]["warm_median"] > 0
