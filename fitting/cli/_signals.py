"""The signals the commands take from a file besides the motion: the deadband played on
the positions (``--deadband``, default 'auto': `jaxfric.motion.deadband_choice`) and the
``load`` column a model with load-dependent friction needs; shared by the one-file
commands and those of several joints."""

import json

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
