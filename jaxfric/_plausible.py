"""Are the units right? Rules that read the likely unit of an undeclared column from the data.

A column whose unit the file does not declare is taken as SI (s, m or rad, N or N m). Most
unit mistakes leave numbers that are possible but implausible for a friction measurement;
`unit_warnings` names them with the likely unit and the option that fixes it. Declaring a
unit (in the header, ``--units``, ``units=``) confirms it and silences the rule for that
column. The rules and thresholds (documented in docs/data.md, tested in tests/core/test_units.py):

=====  ===================================================================================
t      median sampling interval >= `SLOW_SAMPLING_S` (0.5 s, below 2 Hz): ms read as s
x      linear: travel >= `LONG_TRAVEL_M` (0.5 m; above 2 m it is an error): mm read as m;
       rotary: travel > `LONG_TURN_RAD` (2 pi, a full turn): deg read as rad
F, u   99th percentile of ``|F|`` > `LARGE_FORCE` (1000 N or N m): mN (mN m) read as N
v      v against dx/dt (least squares over the moving samples, when they correlate):
       a ratio beyond 3 (or below 1/3) is a unit mismatch, named when it is within 25 %
       of 1000 (v in mm/s or t in ms), 1/1000 (x in mm), 180/pi (v in deg/s),
       pi/180 (x in deg) or 60/(2 pi) (v in rpm); a correlation below -0.5 is a sign
       mismatch
=====  ===================================================================================
"""

import math

import numpy as np


SLOW_SAMPLING_S = 0.5
LONG_TRAVEL_M = 0.5
LONG_TURN_RAD = 2 * math.pi
LARGE_FORCE = 1000.0
#: v / (dx/dt) beyond this factor either way is a unit mismatch.
RATIO_OFF = 3.0
#: A ratio within this factor of a known one is named.
RATIO_MATCH = 1.25


def _ratios(kind: str) -> list[tuple[float, str]]:
    common = [(1e3, "v looks in mm/s (--units v=mm/s) or t in ms (--units t=ms)"),
              (1e-3, "x looks in mm (--units x=mm) while v is in m/s")]
    if kind == "rotary":
        common = [(1e3, "v looks in mrad/s (--units v=mrad/s) or t in ms (--units t=ms)"),
                  (1e-3, "x looks in mrad (--units x=mrad) while v is in rad/s"),
                  (180 / math.pi, "v looks in deg/s (--units v=deg/s)"),
                  (math.pi / 180, "x looks in deg (--units x=deg) while v is in rad/s"),
                  (60 / (2 * math.pi), "v looks in rpm (--units v=rpm)")]
    return common


def _velocity_rule(t, x, v, kind: str) -> str | None:
    g = np.gradient(x, t)
    scale = np.percentile(np.abs(g), 99)
    moving = np.abs(g) > 0.05 * scale
    if scale == 0 or moving.sum() < 5 or np.std(v[moving]) == 0:
        return None
    corr = float(np.corrcoef(v[moving], g[moving])[0, 1])
    if corr < -0.5:
        return (f"column 'v' has the opposite sign to dx/dt (correlation {corr:.2f}): "
                "is it recorded with the opposite convention?")
    if corr < 0.5:
        return None
    ratio = float(np.dot(v[moving], g[moving]) / np.dot(g[moving], g[moving]))
    if 1 / RATIO_OFF < ratio < RATIO_OFF:
        return None
    for known, what in _ratios(kind):
        if abs(math.log(ratio / known)) < math.log(RATIO_MATCH):
            return f"column 'v' is {ratio:.4g} times dx/dt: {what}"
    return (f"column 'v' is {ratio:.4g} times dx/dt: the units of t, x and v do not agree; "
            "declare them (e.g. --units t=s,x=m,v=m/s)")


def unit_warnings(m, declared: set[str]) -> list[str]:
    """Messages for the undeclared columns of `m` (a `jaxfric.data.Measurement` in SI) whose
    values look like another unit; `declared` holds the columns whose unit was given."""
    rotary = m.kind == "rotary"
    out = []
    dt = float(np.median(np.diff(m.t)))
    if "t" not in declared and dt >= SLOW_SAMPLING_S:
        out.append(f"column 't': median sampling interval {dt:.4g} s ({1 / dt:.3g} Hz) is "
                   "slow for a friction measurement: if t is in ms, pass --units t=ms "
                   "(t=s to confirm)")
    span = float(np.ptp(m.x))
    if "x" not in declared and rotary and span > LONG_TURN_RAD:
        out.append(f"column 'x' spans {span:.4g} rad ({span / (2 * math.pi):.3g} turns): if "
                   "it is in degrees, pass --units x=deg (x=rad to confirm)")
    elif "x" not in declared and not rotary and span >= LONG_TRAVEL_M:
        out.append(f"column 'x' spans {span:.4g} m: if it is in mm, pass --units x=mm "
                   "(x=m to confirm)")
    for col in ("F", "u"):
        f = getattr(m, col)
        if f is None or col in declared:
            continue
        level = float(np.percentile(np.abs(f), 99))
        if level > LARGE_FORCE:
            unit, milli = ("N m", "mNm") if rotary else ("N", "mN")
            out.append(f"column {col!r} reaches {level:.4g} {unit} (99th percentile of "
                       f"|{col}|), large for friction: if it is in {milli}, pass "
                       f"--units {col}={milli} ({col}={unit.replace(' ', '')} to confirm)")
    if m.v is not None:
        msg = _velocity_rule(np.asarray(m.t), np.asarray(m.x), np.asarray(m.v), m.kind)
        if msg:
            out.append(msg)
    return out
