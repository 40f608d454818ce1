"""What every step of a diagnosis shares (`fitting._diagnose`): the checked inputs and
rules (`_Context`, made by `_context`), the effects it screens (`effect_names`), and one
refit of a model on the training samples with its errors (`_step`, a `Step`).
"""

import dataclasses
from collections.abc import Callable

import jax
import numpy as np

from jaxfric import effects as fx

from . import _params
from ._candidates import DRIFT_SPAN_RATIO
from ._derivatives import describe, estimate_acceleration, estimate_derivatives
from ._fit import fit
from ._regimes import holdout_mask, regime_errors, regimes
from ._result import FitResult
from ._transforms import ParamProps, Sigmoid


@dataclasses.dataclass
class Step:
    """After adding `added` and refitting: the fit, RMSE on all data and held out (N)."""

    added: list[str]
    fit: FitResult
    rmse: float
    rmse_holdout: float
    regimes: dict
    rel_error: float = float("nan")  # rmse / RMS of the measured force


#: Most warm restarts of a refit that stops at its step limit (see `_step`).
_RESTARTS = 5


def _refit_props(model, t):
    """The fit's parameter properties for a diagnosis's fits (None: the defaults), with
    a drift's settling rate held to about the range the screen searches
    (`_candidates._grid`: settling times from a tenth to twice the record; here
    ``-1/span < drift_decay < 10.5/span``: settling times from a tenth of the record, or
    a slow growth). A drift is slow by definition; left free, a refit made it settle in
    half a second to fit the start of a record (the first loading from rest, where the
    model's virgin curve is not the truth's: on a LuGre-made file, +138 % in 0.54 s,
    which removed 44 % of the training SSE and 7 % of the held-out)."""
    fit_model = _params.to_fit_representation(model)
    names = _params.leaf_names(fit_model)
    if "drift_decay" not in names:
        return None
    span = max(float(t[-1] - t[0]), 1e-9)
    # 5 % beyond the grid's fastest point, which a refit may start from.
    low, high = -1.0 / span, 1.05 * DRIFT_SPAN_RATIO / span
    props = _params.default_props(fit_model)
    values = jax.tree.leaves(_params.parameters(fit_model)[0])
    # A start outside the range (a user's own drift) keeps the default, unbounded.
    leaves = [ParamProps(Sigmoid(low, high), free=p.free, scale=p.scale)
              if n == "drift_decay" and low < float(value) < high else p
              for p, n, value in zip(_params.props_leaves(props), names, values)]
    return jax.tree.unflatten(jax.tree.structure(props, is_leaf=_params._is_props), leaves)


def _step(model, added, t, x, v, F, train, test, masks, log, max_steps, fixed=(),
          restart=False, load=None, a=None):
    names = _params.leaf_names(_params.to_fit_representation(model))
    free = [n for n in names if n not in fixed] if fixed else None
    props = _refit_props(model, t)
    res = fit(model, t, x, F, v, weights=train.astype(float), max_steps=max_steps, free=free,
              load=load, props=props, a=a)
    # A refit with a new effect starts from the screen's values, often far from its
    # optimum; a warm restart (fresh damping) gets it unstuck more often than more steps.
    # Restart while the fit stops at its step limit and each restart still lowers the
    # training RMSE by more than 1 % (slow but steady fits, e.g. a friction lag of twice
    # the nominal size, need about five rounds of 300 steps), at most `_RESTARTS` times.
    for _ in range(_RESTARTS if restart else 0):
        if bool(res.converged):
            break
        again = fit(res.model, t, x, F, v, weights=train.astype(float), max_steps=max_steps,
                    free=free, load=load, props=props, a=a)
        progress = float(again.rmse) < 0.99 * float(res.rmse)
        if float(again.rmse) <= float(res.rmse):
            res = again
        if not progress:
            break
    resid = np.asarray(res.prediction) - F
    return Step(
        added=list(added), fit=res,
        rmse=float(np.sqrt(np.mean(resid**2))),
        rmse_holdout=float(np.sqrt(np.mean(resid[test] ** 2))),
        regimes=regime_errors(resid, masks),
        rel_error=float(np.sqrt(np.mean(resid**2) / np.mean(F**2))),
    ), -resid


@dataclasses.dataclass
class _Context:
    """What every step of one diagnosis shares: the start model, the data, the held-out
    split and the rules."""

    model: object
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray  # the velocity every fit and screen uses (m/s)
    v_arr: np.ndarray  # the same
    F: np.ndarray
    train: np.ndarray
    test: np.ndarray
    block: np.ndarray
    masks: dict
    log: Callable[[str], None]
    max_steps: int
    fixed: tuple[str, ...]
    min_score: float
    min_t: float
    velocity: str  # how `v` was obtained, in words
    load: np.ndarray | None = None  # the transmitted load (N or N m), if the data have one
    blocks: int = 24  # time blocks of the held-out split (`fitting._regimes.holdout_mask`)
    a: np.ndarray | None = None  # the acceleration (m/s^2); None: the model's backward one

    def step(self, model, added, restart=False):
        return _step(model, added, self.t, self.x, self.v, self.F, self.train, self.test,
                     self.masks, self.log, self.max_steps, self.fixed, restart=restart,
                     load=self.load, a=self.a)


def _contained(model, fixed) -> set[str]:
    """Effects the model's own free parameters already are: ``viscous`` (``c_visc * v``,
    not negative) when the model fits its own ``sigma2`` (positive): their sum is one
    viscous coefficient, so adding it enlarges nothing and a refit that then does better
    has only found another optimum of the same model (seen on a LuGre-made file: a
    viscous term and a quadratic drag of size 0 credited with 41 % of the held-out
    residual). Screened by default only when ``sigma2`` is held with `fixed`."""
    names = set(_params.leaf_names(model)) - set(fixed)
    return {"viscous"} if "sigma2" in names else set()


def effect_names(effects, present, rotary: bool, has_load: bool = False) -> list[str]:
    """The effects a diagnosis screens: `effects` (default every effect, those of an angle,
    `jaxfric.effects.ROTARY_EFFECTS`, only if `rotary`, those of the load,
    `jaxfric.effects.LOAD_EFFECTS`, only if `has_load`) not in `present`. A load effect
    asked for without a load signal raises `ValueError`."""
    default = [n for n in fx.EFFECTS if (rotary or n not in fx.ROTARY_EFFECTS)
               and (has_load or n not in fx.LOAD_EFFECTS)]
    if effects and not has_load and set(effects) & set(fx.LOAD_EFFECTS):
        raise ValueError(f"effect(s) {sorted(set(effects) & set(fx.LOAD_EFFECTS))} need the "
                         "load signal (a 'load' column, or diagnose(..., load=...))")
    return [n for n in (effects or default) if n not in present]


def _context(model, t, x, F, v, *, blocks, max_steps, fixed, min_score, min_t, log,
             derivatives, velocity_window, load=None, a=None) -> _Context:
    """Check the inputs and set a diagnosis up (see `diagnose`)."""
    fixed = tuple(fixed)
    # Work in the fit representation throughout (a `PaperShape` as a `NormalizedPaperShape`):
    # a round trip through the paper's symbols is singular for a nearly straight shape.
    model = _params.to_fit_representation(model)
    unknown = set(fixed) - set(_params.leaf_names(model))
    if unknown:
        raise ValueError(f"fixed: {type(model).__name__} has no parameter(s) "
                         f"{sorted(unknown)}; it has {_params.leaf_names(model)}")
    t, x, F = (np.asarray(a, dtype=np.float64) for a in (t, x, F))
    how = describe(derivatives, velocity_window, column=v is not None,
                   acceleration_column=a is not None)
    if v is None:
        v, a_est = estimate_derivatives(t, x, derivatives, velocity_window)
    else:
        v = np.asarray(v, np.float64)
        a_est = estimate_acceleration(t, v, derivatives, velocity_window)
    v = np.asarray(v, np.float64)
    if a is None:
        a = a_est
    else:
        a = np.asarray(a, np.float64)
        if a.shape != t.shape:
            raise ValueError(f"a has shape {a.shape}, t has {t.shape}")
    if load is not None:
        load = np.asarray(load, np.float64)
        if load.shape != t.shape:
            raise ValueError(f"load has shape {load.shape}, t has {t.shape}")
    test, block = holdout_mask(t, blocks)
    return _Context(model=model, t=t, x=x, v=v, v_arr=v, F=F, train=~test, test=test,
                    block=block, masks=regimes(t, x, v), log=log or (lambda *_: None),
                    max_steps=max_steps, fixed=fixed, min_score=min_score, min_t=min_t,
                    velocity=how, load=load, blocks=blocks, a=a)
