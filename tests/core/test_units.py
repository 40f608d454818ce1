"""Unit plausibility (issue 21, item 5) and the unit vocabulary of `jaxfric.units`: each
common unit mistake in a file that declares no units is named, with the unit it likely is
and the option that fixes it; declared units and right data give no warning."""

import math
import warnings

import numpy as np
import pytest

import jaxfric
from jaxfric import data, paper, units
from jaxfric.data import DataError, DataWarning


def _stage(n=4000, rate=1000.0):
    """A 2 mm travel at 1 kHz in SI (s, m, m/s, N), friction from the paper's Tustin model."""
    t = np.arange(n) / rate
    x = 1e-3 * np.sin(2 * np.pi * t / 2.0)
    v = np.gradient(x, t)
    F = np.asarray(jaxfric.simulate(paper.tustin(), t, x, v))
    return {"t": t, "x": x, "v": v, "F": F}


def _joint(n=4000, rate=500.0):
    """A joint swinging over 1.2 rad at 500 Hz (s, rad, rad/s, N m)."""
    t = np.arange(n) / rate
    x = 0.6 * np.sin(2 * np.pi * t / 4.0)
    v = np.gradient(x, t)
    F = 3.0 * np.tanh(v / 0.01) + 0.5 * v
    return {"t": t, "x": x, "v": v, "F": F}


def _messages(columns, **kw) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        data.load(columns, **kw)
    assert all(issubclass(w.category, DataWarning) for w in caught), caught
    return [str(w.message) for w in caught]


def _only(messages, *fragments):
    assert len(messages) == 1, messages
    for fragment in fragments:
        assert fragment in messages[0], messages[0]


def _all_name(messages, fragment):
    assert messages and all(fragment in m for m in messages), messages


def test_right_data_gives_no_warning():
    assert _messages(_stage()) == []
    assert _messages(_joint(), kind="rotary") == []


def test_time_in_ms():
    s = _stage()
    cols = {"t": s["t"] * 1e3, "x": s["x"], "F": s["F"]}
    _only(_messages(cols), "column 't': median sampling interval 1 s", "--units t=ms")
    assert _messages(cols, units={"t": "ms"}) == []


def test_x_in_mm_over_a_2_mm_travel():
    s = _stage()
    cols = {"t": s["t"], "x": s["x"] * 1e3, "F": s["F"]}
    _only(_messages(cols), "column 'x' spans 2 m", "--units x=mm")
    assert _messages({"t": s["t"], "x[mm]": s["x"] * 1e3, "F": s["F"]}) == []


def test_force_in_mN():
    s = _stage()
    cols = {"t": s["t"], "x": s["x"], "F": s["F"] * 1e3}
    _only(_messages(cols), "column 'F' reaches", "--units F=mN")
    assert _messages(cols, units={"F": "N"}) == []  # declared: confirmed


def test_velocity_in_mm_per_s():
    s = _stage()
    _only(_messages({**s, "v": s["v"] * 1e3}), "column 'v' is 1000 times dx/dt",
          "--units v=mm/s")


def test_x_in_mm_with_v_in_m_per_s():
    s = _stage(rate=1000.0)
    s["x"] = s["x"] * 0.2  # a 0.4 mm travel: within the travel rule, found by v against dx/dt
    s["v"] = np.gradient(s["x"], s["t"])
    _only(_messages({**s, "x": s["x"] * 1e3}), "0.001 times dx/dt", "--units x=mm")


def test_velocity_with_the_opposite_sign():
    s = _stage()
    _only(_messages({**s, "v": -s["v"]}, check_sign=False),
          "column 'v' has the opposite sign to dx/dt")


@pytest.mark.parametrize(("change", "fragment"), [
    (lambda j: {**j, "x": np.degrees(j["x"])}, "--units x=deg"),      # spans 69 "rad"
    (lambda j: {**j, "v": np.degrees(j["v"])}, "--units v=deg/s"),
    (lambda j: {**j, "v": j["v"] * 60 / (2 * math.pi)}, "--units v=rpm"),
    (lambda j: {**j, "F": j["F"] * 1e3}, "--units F=mNm"),
])
def test_rotary_mistakes(change, fragment):
    _all_name(_messages(change(_joint()), kind="rotary"), fragment)


def test_x_in_deg_over_a_small_swing_is_found_by_the_velocity():
    j = _joint()
    small = {**j, "x": j["x"] / 20, "v": j["v"] / 20}  # 3.4 degrees
    _only(_messages({**small, "x": np.degrees(small["x"])}, kind="rotary"), "--units x=deg")


# ---- the unit vocabulary -----------------------------------------------------------------


@pytest.mark.parametrize("spelling", ["N m", "N*m", "Nm", "N·m", "N.m", "N ⋅ m"])
def test_torque_spellings(spelling):
    j = _joint()
    m = data.load({"t": j["t"], "x[rad]": j["x"], f"F[{spelling}]": j["F"]})
    assert m.kind == "rotary" and m.unit("F") == "N m"
    np.testing.assert_array_equal(m.F, j["F"])
    m = data.load({"t": j["t"], "x[deg]": np.degrees(j["x"]),
                   f"F[m{spelling}]": j["F"] * 1e3})
    np.testing.assert_allclose(m.F, j["F"], rtol=1e-15)
    np.testing.assert_allclose(m.x, j["x"], rtol=1e-15)


@pytest.mark.parametrize(("unit", "factor"), [
    ("rad", 1.0), ("mrad", 1e-3), ("deg", math.pi / 180), ("arcsec", math.pi / 648000)])
def test_angle_units(unit, factor):
    j = _joint()
    m = data.load({"t": j["t"], f"x[{unit}]": j["x"] / factor, "F[Nm]": j["F"]})
    np.testing.assert_allclose(m.x, j["x"], rtol=1e-14)


@pytest.mark.parametrize(("unit", "factor"), [
    ("rad/s", 1.0), ("deg/s", math.pi / 180), ("rpm", 2 * math.pi / 60)])
def test_angular_velocity_units(unit, factor):
    j = _joint()
    m = data.load({"t": j["t"], "x[rad]": j["x"], f"v[{unit}]": j["v"] / factor,
                   "F[Nm]": j["F"], "a[deg/s^2]": np.degrees(np.gradient(j["v"], j["t"]))})
    np.testing.assert_allclose(m.v, j["v"], rtol=1e-14)
    np.testing.assert_allclose(m.a, np.gradient(j["v"], j["t"]), rtol=1e-14)


def test_kind_from_units_flag_and_contradictions():
    j = {k: v / 10 if k in "xv" else v for k, v in _joint().items()}  # 0.12 m or rad
    assert data.load({"t": j["t"], "x": j["x"], "F": j["F"]}).kind == "linear"
    assert data.load({"t": j["t"], "x": j["x"], "F": j["F"]}, kind="rotary").kind == "rotary"
    with pytest.raises(DataError, match="mixes linear and rotary units"):
        data.load({"t": j["t"], "x[rad]": j["x"], "F[N]": j["F"]})
    with pytest.raises(DataError, match="asked for a linear file, but its units are rotary"):
        data.load({"t": j["t"], "x[deg]": j["x"], "F": j["F"]}, kind="linear")
    with pytest.raises(DataError, match="unknown unit 'furlong' for an angle"):
        data.load({"t": j["t"], "x[furlong]": j["x"], "F": j["F"]}, kind="rotary")


@pytest.mark.parametrize(("linear", "rotary"), [
    ("N", "N m"), ("m", "rad"), ("m/s", "rad/s"), ("N/m", "N m/rad"), ("N s/m", "N m s/rad"),
    ("m/N", "rad/(N m)"), ("N/m^4", "N m/rad^4"), ("m^-alpha", "rad^-alpha"),
    ("N s^2/m^2", "N m s^2/rad^2"), ("N/s", "N m/s"), ("kg", "kg m^2"), ("1/s", "1/s"),
    ("s", "s"), ("-", "-")])
def test_rotary_names_of_the_model_units(linear, rotary):
    assert units.rotary_unit(linear) == rotary


def test_every_declared_model_unit_has_a_rotary_name_without_metres_or_newtons_alone():
    from fitting._params import natural_units
    from jaxfric import effects

    model = paper.two_state() + (effects.Viscous(), effects.QuadraticDrag(),
                                 effects.StribeckHump(), effects.Inertia(), effects.Offset(),
                                 effects.Cogging(), effects.Drift(), effects.Presliding())
    for unit in natural_units(model).values():
        said = units.rotary_unit(unit)
        tokens = said.replace("(", " ").replace(")", " ").replace("/", " ").split()
        assert "m" not in tokens or "N" in tokens, (unit, said)  # a metre only in N m
        assert "N" not in tokens or "m" in tokens, (unit, said)


def test_speak_rewrites_units_after_numbers_only():
    said = units.speak("RMSE 0.43 N (held out 0.5 N, 12 %); sliding |v| < 1.5 mm/s; "
                       "viscous 4 N s/m; period 1.7 mm; [N]; 2 models", "rotary")
    assert said == ("RMSE 0.43 N m (held out 0.5 N m, 12 %); sliding |v| < 1.5 mrad/s; "
                    "viscous 4 N m s/rad; period 1.7 mrad; [N m]; 2 models")
    assert units.speak("0.43 N", "linear") == "0.43 N"
