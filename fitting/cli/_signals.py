"""The signals the commands take from a file besides the positions: the velocity and
acceleration for identification (the file's columns or zero-phase estimates,
``--derivatives``; a result's JSON says which, so that ``simulate --params`` takes them the
same way), the deadband played on the positions (``--deadband``, default 'auto':
`jaxfric.motion.deadband_choice`) and the ``load`` column a model with load-dependent
friction needs; shared by the one-file commands and those of several joints."""

import json
from pathlib import Path

import numpy as np

from jaxfric import data as _data


def _load_json(m) -> dict:
    """What a result's JSON says of the load signal: ``{"load": {"column": "load",
    "unit": ...}}`` when the file had one, else nothing."""
    return {} if m.load is None else {"load": {"column": "load", "unit": m.unit("load")}}


def _load_of(m, model):
    """`m`'s load column for `model`; `DataError` naming the file when `model` has a
    load-dependent effect (`jaxfric.effects.LOAD_EFFECTS`) and `m` no ``load`` column."""
    from jaxfric import effects as fx

    needs = [e.name for e in getattr(model, "effects", ()) if e.name in fx.LOAD_EFFECTS]
    if needs and m.load is None:
        raise _data.DataError(f"{m.source}: the model has {', '.join(needs)}, which reads the "
                              "transmitted load: the file needs a 'load' column "
                              f"(load[{m.unit('F')}])")
    return m.load


def played_measurement(m, deadband, log):
    """``(m, b)``: `m` with its positions through the play of half-width ``b`` (SI;
    `jaxfric.motion.play`) and a velocity column made to agree with them
    (`jaxfric.motion.played_velocity`). ``deadband``: a number; 'auto' (the default of
    every command) to estimate it and apply it only when the data show noise-made
    reversals (`jaxfric.motion.deadband_choice`); or None for none. ``b`` is None when
    no play was applied. The log says which and why. Fit and simulate use the same, so
    that ``simulate --params`` reproduces the fit."""
    if deadband is None:
        return m, None
    import equinox as eqx

    from jaxfric.motion import deadband_choice, play, played_velocity

    unit = m.unit("x")
    if deadband == "auto":
        choice = deadband_choice(m.x, m.v, m.t)
        if choice.deadband is None:
            log(f"deadband: none needed ({choice.reason}; band {choice.estimate:.4g} {unit})")
            return m, None
        b = choice.deadband
        log(f"deadband: {b:.4g} {unit} applied: {choice.reason}")
    else:
        b = float(deadband)
        log(f"deadband: {b:.4g} {unit} (play on the position against noisy standstill)")
    if b == 0:
        return m, b
    p = np.asarray(play(np.asarray(m.x), b))
    m = eqx.tree_at(lambda mm: mm.x, m, p)
    if m.v is not None:
        m = eqx.tree_at(lambda mm: mm.v, m, np.asarray(played_velocity(p, np.asarray(m.v))))
    return m, b


def _deadband_option(text, params):
    """The deadband for `played_measurement` from ``--deadband`` (a number in SI, 'auto',
    'none'); without it, the one saved in the `params` JSON (a result without
    ``"deadband"`` was played through none), else 'auto'."""
    if text is None and params:
        with open(params) as f:
            spec = json.load(f)
        text = spec.get("deadband") if isinstance(spec, dict) else None
        if text is None:
            return None
    if text is None:
        return "auto"
    if str(text).lower() == "none":
        return None
    if str(text).lower() == "auto":
        return "auto"
    try:
        value = float(text)
    except ValueError:
        raise _data.DataError(
            f"--deadband must be a number, 'auto' or 'none', got {text!r}") from None
    if not value >= 0:
        raise _data.DataError(f"--deadband must be >= 0, got {value}")
    return value


def identification_derivatives(m, args, log):
    """``(v, a, words)``: the file's velocity column or the estimate `args.derivatives` asks
    for (`fitting._derivatives`), the acceleration the same way (the file's column, or
    None: the model's backward difference), and how both were obtained."""
    from .._derivatives import estimate_acceleration, estimate_derivatives

    window = args.velocity_window
    v, a = m.v, m.a
    try:
        if v is None:
            v, estimate = estimate_derivatives(m.t, m.x, args.derivatives, window)
            a = estimate if a is None else a
        elif a is None:
            a = estimate_acceleration(m.t, v, args.derivatives, window)
    except ValueError as e:
        raise _data.DataError(str(e)) from None
    words = velocity_words(m, args)
    if m.v is None or m.a is None:
        log(f"velocity: {words}")
    return v, a, words


def velocity_words(m, args) -> str:
    """How `identification_derivatives` obtains the velocity and acceleration of `m`."""
    from .._derivatives import describe as words

    return words(args.derivatives, args.velocity_window, column=m.v is not None,
                 acceleration_column=m.a is not None)


def derivatives_json(m, args) -> dict | None:
    """How the velocity and acceleration were estimated, for a result's JSON (`simulate
    --params` reads it back); None when the file had both columns (nothing estimated)."""
    if m.v is not None and m.a is not None:
        return None
    return {"method": args.derivatives, "window_s": args.velocity_window}


def _saved_derivatives(path) -> dict:
    """The ``"derivatives"`` entry of a result JSON (already checked by `model_from_json`),
    or an empty dict."""
    try:
        spec = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {}
    return saved_derivatives(spec)


def saved_derivatives(spec) -> dict:
    """The ``"derivatives"`` entry of a parsed result (or of one joint's entry), or an empty
    dict."""
    entry = spec.get("derivatives") if isinstance(spec, dict) else None
    return entry if isinstance(entry, dict) else {}


def derivatives_as_saved(args, saved: dict):
    """`args` with the velocity estimate of a result's ``"derivatives"`` entry `saved`
    where the command line chose none (so that a model's force is its fit's prediction),
    else ``"central"``; a copy, `args` is left alone."""
    import argparse

    out = argparse.Namespace(**vars(args))
    if out.derivatives is None and saved.get("method"):
        out.derivatives = saved["method"]
        if out.velocity_window is None:
            out.velocity_window = saved.get("window_s")
    out.derivatives = out.derivatives or "central"
    return out
