"""The signals the commands take from a file besides the motion: the deadband played on
the positions (``--deadband``, `jaxfric.motion.play`) and the ``load`` column a model with
load-dependent friction needs; shared by the one-file commands and those of several
joints."""

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
    `jaxfric.motion.play`; ``deadband``: a number, 'auto' to estimate it, or None for
    none, then ``b`` is None). Fit and simulate use the same, so that ``simulate --params``
    reproduces the fit."""
    if deadband is None:
        return m, None
    import equinox as eqx

    from jaxfric.motion import estimate_deadband, play

    b = estimate_deadband(m.x) if deadband == "auto" else float(deadband)
    log(f"deadband: {b:.4g} {m.unit('x')} (play on the position against noisy standstill)")
    if b == 0:
        return m, b
    return eqx.tree_at(lambda mm: mm.x, m, np.asarray(play(np.asarray(m.x), b))), b


def _deadband_option(text, params):
    """The `jaxfric.simulate` deadband from ``--deadband`` (a number in SI, 'auto',
    'none'), else from the ``deadband`` saved in the `params` JSON, else None."""
    if text is None and params:
        with open(params) as f:
            text = json.load(f).get("deadband")
    if text is None or str(text).lower() == "none":
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
