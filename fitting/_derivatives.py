"""Velocity and acceleration for identification: which derivatives of the measured position
a fit or a diagnosis uses, and how to say so in a report.

A measurement has the position at each sample; the velocity, and the acceleration that
`jaxfric.effects.Inertia` reads, have to be estimated. `jaxfric.simulate` and a
controller's per-sample ``step`` take the backward difference, the only causal choice,
which lags the true velocity by half a sample (and its difference, the acceleration, by a
whole sample). For identification the whole record is known, so a zero-phase estimate is
better:

- ``"central"`` (the default): ``v_n = (x_{n+1} - x_{n-1}) / (t_{n+1} - t_{n-1})``, one-sided
  at the ends; with `window_s`, over ``+-h`` samples (``h`` = half the window in sample
  steps), which smooths a quantised position;
- ``"savgol"``: a Savitzky-Golay differentiator of order 3 over `window_s` (default 7
  samples), for noisy positions at fine sampling; needs uniform sampling;
- ``"backward"``: what `jaxfric.simulate` does without a velocity; right for data that
  `simulate` itself made, and for checking what a causal controller would see.

The acceleration (`estimate_derivatives`) follows the same method: the central difference
of the velocity estimate over `ACCELERATION_WINDOW_S` (or the velocity's window if
longer), the Savitzky-Golay second derivative, or ``None`` for ``"backward"`` (the model
then takes the backward difference of the velocity, as `jaxfric.simulate` and a
controller's step do, which lags by a whole sample). Differencing twice amplifies the
position's quantisation, and the noise falls with the span of the difference: at 1 ms
sampling a central difference over 10 ms carries about a third of the backward
difference's noise, about what 10 ms sampling gives. A difference over 10 ms passes a mass term's
acceleration up to 10 Hz within 1.6 % (``sinc``) and changes nothing at a sampling of
5 ms or slower, where it is the difference of the neighbouring samples.

A velocity column in the file is used as it is (`derivatives` is then not applied to it;
the acceleration is then the central difference of that column, or ``None`` for
``"backward"``); an acceleration column is used as it is.
"""

import numpy as np

from jaxfric.motion import central_difference, smooth_derivatives, velocity


DERIVATIVES = ("central", "savgol", "backward")

#: The acceleration is the velocity's central difference over at least this window (s).
ACCELERATION_WINDOW_S = 0.01


def estimate_velocity(t, x, method: str = "central", window_s: float | None = None
                      ) -> np.ndarray:
    """The velocity (m/s) of position `x` (m) at times `t` (s) by `method` (see the module
    docstring)."""
    t, x = np.asarray(t, np.float64), np.asarray(x, np.float64)
    _check(method, window_s)
    if method == "backward":
        return velocity(t, x)
    if method == "central":
        if window_s is None:
            return central_difference(t, x)
        return velocity(t, x, window_s)
    h = float(np.median(np.diff(t)))
    return smooth_derivatives(t, x, 7 * h if window_s is None else window_s)[0]


def _check(method, window_s) -> None:
    if method not in DERIVATIVES:
        raise ValueError(f"derivatives: {method!r} is not one of {', '.join(DERIVATIVES)}")
    if window_s is not None and not (np.isfinite(window_s) and window_s > 0):
        raise ValueError(f"velocity window: {float(window_s):g} s is not a positive number")


def estimate_acceleration(t, v, method: str = "central", window_s: float | None = None
                          ) -> np.ndarray | None:
    """The zero-phase acceleration (m/s^2) of velocity `v` (m/s) at times `t` (s): its
    central difference over ``+-h`` samples, ``h`` half of `window_s` or of
    `ACCELERATION_WINDOW_S`, whichever is longer, in sample steps (at least 1; see
    `jaxfric.motion.velocity`), or ``None`` for ``"backward"`` (the model's own backward
    difference). ``"savgol"`` here (a velocity column) is the central difference too."""
    _check(method, window_s)
    if method == "backward":
        return None
    t, v = np.asarray(t, np.float64), np.asarray(v, np.float64)
    if v.size < 2:
        return np.zeros_like(v)
    return velocity(t, v, _acceleration_window(window_s))


def _acceleration_window(window_s: float | None) -> float:
    return max(window_s or 0.0, ACCELERATION_WINDOW_S)


def estimate_derivatives(t, x, method: str = "central", window_s: float | None = None
                         ) -> tuple[np.ndarray, np.ndarray | None]:
    """``(v, a)``: the velocity (m/s) and acceleration (m/s^2) of position `x` (m) at times
    `t` (s) by `method` (see the module docstring); ``a`` is ``None`` for ``"backward"``
    (what the model derives itself)."""
    if method == "savgol":
        _check(method, window_s)
        h = float(np.median(np.diff(np.asarray(t, np.float64))))
        return smooth_derivatives(t, x, 7 * h if window_s is None else window_s)
    v = estimate_velocity(t, x, method, window_s)
    return v, estimate_acceleration(t, v, method, window_s)


def describe(method: str, window_s: float | None = None, column: bool = False,
             acceleration_column: bool = False) -> str:
    """How the velocity (and the acceleration) were obtained, in words for a report."""
    if column:
        return "the file's velocity column" + _acceleration_words(
            "central" if method == "savgol" else method, window_s, acceleration_column,
            "of that column")
    return _velocity_words(method, window_s) + _acceleration_words(
        method, window_s, acceleration_column, "of that velocity")


def _acceleration_words(method, window_s, column, of) -> str:
    if column:
        return "; acceleration: the file's column"
    if method == "backward":
        return "; acceleration: its backward difference (causal)"
    if method == "savgol":
        return "; acceleration: the same filter's second derivative"
    return (f"; acceleration: central difference {of} over "
            f"{1e3 * _acceleration_window(window_s):.3g} ms")


def _velocity_words(method: str, window_s: float | None) -> str:
    if method == "backward":
        return "backward difference of the position (causal, as a controller's step)"
    if method == "central":
        return ("central difference of the position (zero phase)" if window_s is None else
                f"central difference of the position over {1e3 * window_s:.3g} ms (zero phase)")
    return ("Savitzky-Golay derivative of the position (order 3, "
            + ("7 samples" if window_s is None else f"{1e3 * window_s:.3g} ms")
            + ", zero phase)")
