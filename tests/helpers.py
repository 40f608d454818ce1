"""Motions and glue shared by the tests."""

import importlib.util
import itertools
import sys
from pathlib import Path

import numpy as np

import jaxfric
from jaxfric import GMS, LuGre, PaperShape, PowerShape, Tustin, TwoState


def waypoint_path(waypoints, speed, dt, dwell=0.0, t0=0.0):
    """Piecewise-constant-velocity motion through `waypoints` (m) at `speed` (m/s).

    Samples every `dt` seconds; the reversal points are hit exactly. With `dwell` > 0 the
    motion rests that long at every waypoint. Returns (t, x).
    """
    xs = [waypoints[0]]
    for a, b in itertools.pairwise(waypoints):
        n = max(round(abs(b - a) / speed / dt), 1)
        xs.extend(np.linspace(a, b, n + 1)[1:])
        xs.extend([b] * round(dwell / dt))
    x = np.asarray(xs, dtype=np.float64)
    return t0 + dt * np.arange(x.size), x


UM = 1e-6

#: Nested presliding loops (um): inner loops closing onto outer ones, then a return to
#: the virgin curve and beyond, then sliding strokes with small loops at the ends.
NESTED = [0, 80, 20, 60, 35, 50, 40, 70, 10, 90, -100, -20, -60, -30, -70, 100, 20, 60, 30, 160]
STROKES = [0, 2000, 1900, 1960, 1930, 1990, -1500, -1450, -1490, 500]


def nested_path(dt=2e-3, speed=20 * UM, dwell=0.0):
    return waypoint_path(np.asarray(NESTED) * UM, speed, dt, dwell)


def strokes_path(dt=1e-3):
    return waypoint_path(np.asarray(STROKES) * UM, 0.6e-3, dt, dwell=0.05)


def sine_path(n=6000, dt=1e-3, irregular=False, seed=0):
    """Decaying sine plus a faster one: many nested loops, smooth velocity (returned)."""
    rng = np.random.default_rng(seed)
    steps = np.full(n, dt)
    if irregular:
        steps = dt * rng.uniform(0.3, 1.7, n)
    t = np.concatenate([[0.0], np.cumsum(steps[1:])])
    w1, w2 = 2 * np.pi / 2.0, 2 * np.pi * 1.7
    x = 150 * UM * np.sin(w1 * t) * np.exp(-t / 4) + 30 * UM * np.sin(w2 * t)
    v = 150 * UM * np.exp(-t / 4) * (w1 * np.cos(w1 * t) - np.sin(w1 * t) / 4)
    v = v + 30 * UM * w2 * np.cos(w2 * t)
    return t, x, v


def ref_kwargs(model):
    """Keyword arguments for tests/reference.py equivalent to a jaxfric model."""
    st = model.stribeck
    kw = {"Fs": float(st.Fs), "Fc": float(st.Fc), "Vs": float(st.Vs), "delta": float(st.delta)}
    if isinstance(model, TwoState):
        sh = model.shape
        if isinstance(sh, PaperShape):
            shape = "paper"
            sp = {k: float(getattr(sh, k)) for k in ("a", "b", "c", "alpha", "beta", "l1")}
        elif isinstance(sh, PowerShape):
            shape = "power"
            sp = {"l1": float(sh.l1), "n": float(sh.n)}
        else:
            raise TypeError(sh)
        kw.update(sigma2=float(model.sigma2), C=float(model.C), shape=shape, shape_params=sp,
                  K=model.stack_size)
    elif isinstance(model, GMS):
        kw.update(sigma2=float(model.sigma2), C=float(model.C), nu=np.asarray(model.nu),
                  k=np.asarray(model.k))
    elif isinstance(model, LuGre):
        kw.update(sigma0=float(model.sigma0), sigma1=float(model.sigma1),
                  sigma2=float(model.sigma2))
    elif isinstance(model, Tustin):
        kw.update(sigma2=float(model.sigma2))
    else:
        raise TypeError(model)
    return kw


def strokes_with_loops(n=1500, seed=0):
    """Presliding loops (60 um) riding on strokes at several speeds (1.5 mm, slowly
    modulated), irregularly sampled at 2-6 ms: ``(t, x)``, s and m."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(2e-3, 6e-3, n))
    x = (60e-6 * np.sin(2 * np.pi * t / 1.5)
         + 1.5e-3 * np.sin(2 * np.pi * t / 4.0) * np.sin(2 * np.pi * t / 9.0))
    return t, x


def power_two_state():
    """The paper's two-state model with a `PowerShape` presliding curve (n = 2.5)."""
    from jaxfric import paper

    return TwoState(stribeck=paper.stribeck(), shape=PowerShape(l1=4e-6, n=2.5),
                    sigma2=paper.SIGMA2, C=paper.C)


def flat_stribeck_two_state(shape=None, C=10.8, stack_size=16):
    """Paper model with Fc = Fs: |s| is constant, so Masing's rules hold exactly."""
    p = jaxfric.paper
    st = jaxfric.Stribeck(Fs=26.1, Fc=26.1, Vs=3.1e-3, delta=0.6)
    return TwoState(stribeck=st, shape=shape or p.shape(), sigma2=0.0, C=C, stack_size=stack_size)


def load_example(name: str):
    """The script ``examples/<name>.py`` as a module (the examples are scripts, not a
    package), loaded once per test process, with ``examples/`` on the import path as when
    the script runs (an example may import its sibling modules, e.g. ``tribometer_data``)."""
    key = f"examples_{name}"
    if key in sys.modules:
        return sys.modules[key]
    folder = Path(__file__).resolve().parents[1] / "examples"
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
    path = folder / f"{name}.py"
    spec = importlib.util.spec_from_file_location(key, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[key] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


def standstill_motion(seed: int, quantum: float = 0.0):
    """Moves of 2 mm separated by 1 s standstills, sampled at 1 ms, with 1 um position
    noise (and, if `quantum` > 0, encoder quantisation): the true reversals are known (3)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 7.0, 1e-3)
    knots_t = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    knots_x = [0.0, 2e-3, 2e-3, 0.0, 0.0, 2e-3, 2e-3, 0.0]
    x_true = np.interp(t, knots_t, knots_x)
    x = x_true + 1e-6 * rng.standard_normal(t.size)
    if quantum:
        x = quantum * np.round(x / quantum)
    return t, x, x_true


def count_reversals(x):
    from jaxfric.motion import reversals
    return int(np.count_nonzero(reversals(np.sign(np.r_[0.0, np.diff(x)]))[0]))
