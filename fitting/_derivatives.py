"""Velocity for identification: which derivative of the measured position a fit or a
diagnosis uses, and how to say so in a report.

A measurement has the position at each sample; the velocity (and from it the acceleration
that the effects see) has to be estimated. `jaxfric.simulate` and a controller's per-sample
``step`` take the backward difference, the only causal choice, which lags the true
velocity by half a sample (and its difference, the acceleration, by a whole sample). For
identification the whole record is known, so a zero-phase estimate is better:

- ``"central"`` (the default): ``v_n = (x_{n+1} - x_{n-1}) / (t_{n+1} - t_{n-1})``, one-sided
  at the ends; with `window_s`, over ``+-h`` samples (``h`` = half the window in sample
  steps), which smooths a quantised position;
- ``"savgol"``: a Savitzky-Golay differentiator of order 3 over `window_s` (default 7
  samples), for noisy positions at fine sampling; needs uniform sampling;
- ``"backward"``: what `jaxfric.simulate` does without a velocity; right for data that
  `simulate` itself made, and for checking what a causal controller would see.

A velocity column in the file is used as it is (`derivatives` is then not applied).
"""

import numpy as np

from jaxfric.motion import smooth_derivatives, velocity


DERIVATIVES = ("central", "savgol", "backward")


def estimate_velocity(t, x, method: str = "central", window_s: float | None = None
                      ) -> np.ndarray:
    """The velocity (m/s) of position `x` (m) at times `t` (s) by `method` (see the module
    docstring)."""
    t, x = np.asarray(t, np.float64), np.asarray(x, np.float64)
    if method not in DERIVATIVES:
        raise ValueError(f"derivatives: {method!r} is not one of {', '.join(DERIVATIVES)}")
    if window_s is not None and not (np.isfinite(window_s) and window_s > 0):
        raise ValueError(f"velocity window: {float(window_s):g} s is not a positive number")
    if method == "backward":
        return velocity(t, x)
    if method == "central":
        if window_s is None:
            return np.gradient(x, t, edge_order=1) if x.size > 1 else np.zeros_like(x)
        return velocity(t, x, window_s)
    h = float(np.median(np.diff(t)))
    return smooth_derivatives(t, x, 7 * h if window_s is None else window_s)[0]


def describe(method: str, window_s: float | None = None, column: bool = False) -> str:
    """How the velocity was obtained, in words for a report."""
    if column:
        return "the file's velocity column"
    if method == "backward":
        return "backward difference of the position (causal, as a controller's step)"
    if method == "central":
        return ("central difference of the position (zero phase)" if window_s is None else
                f"central difference of the position over {1e3 * window_s:.3g} ms (zero phase)")
    return ("Savitzky-Golay derivative of the position (order 3, "
            + ("7 samples" if window_s is None else f"{1e3 * window_s:.3g} ms")
            + ", zero phase)")
