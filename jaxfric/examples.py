"""Built-in example motions and synthetic measurements (seeded, SI units)."""

import numpy as np


def _segment(x0, x1, speed, dt):
    n = max(round(abs(x1 - x0) / speed / dt), 1)
    return np.linspace(x0, x1, n + 1)[1:]


def excitation(dt: float = 1e-3, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A realistic identification motion: positions (m) sampled every `dt` seconds.

    Three parts, like the experiments of the paper's Sec. 5: slow saw-tooth reversals
    inside presliding with nested inner loops (+-20 .. 100 um at 20 um/s), strokes of 2 mm
    at several speeds (0.1 .. 20 mm/s) with small loops at the turning points, and a
    sinusoidally varying positive velocity (friction lag). Returns ``(t, x)``.
    """
    rng = np.random.default_rng(seed)
    um = 1e-6
    xs = [np.zeros(50)]
    pos = 0.0

    def go(target, speed):
        nonlocal pos
        xs.append(_segment(pos, target, speed, dt))
        pos = target

    # presliding: nested loops with slightly random turning points
    for amp in (100, 60, 30):
        jitter = rng.uniform(-5, 5)
        go((amp + jitter) * um, 20 * um)
        go((-amp + 0.4 * amp) * um, 20 * um)
        go((0.7 * amp) * um, 20 * um)
        go((-amp - jitter) * um, 20 * um)
    # sliding strokes at several speeds, with a small loop at each end
    for speed in (1e-4, 5e-4, 2e-3, 5e-3, 2e-2):
        go(pos + 2e-3, speed)
        go(pos - 40 * um, 20 * um)
        go(pos + 25 * um, 20 * um)
        go(pos - 2e-3, speed)
    # varying positive velocity: v = 2 mm/s * (1 + 0.8 sin(2 pi 1 Hz t)) for 4 s
    t_var = np.arange(1, int(4.0 / dt) + 1) * dt
    v_var = 2e-3 * (1 + 0.8 * np.sin(2 * np.pi * t_var))
    xs.append(pos + np.cumsum(v_var) * dt)
    x = np.concatenate(xs)
    return dt * np.arange(x.size), x
