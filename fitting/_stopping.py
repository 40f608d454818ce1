"""When a fit is done: the stopping policy shared by `fit`, `fit_datasets` and `fit_batch`.

**The statistical rule** (`Tolerances.decrease`). At the solver's current point, with
residuals ``r`` and Jacobian ``J`` (over the free coordinates ``y``), the Gauss-Newton
model predicts that a full step could still lower the cost ``sum(r^2)/2`` by

    pred = g^T (J^T J)^-1 g / 2,    g = J^T r,

the most any step can gain where the model is linear. With the noise variance estimated as
``s^2 = sum(r^2)/(n - p)`` (n samples of weight > 0, p free coordinates), ``2 pred / s^2``
is the squared length of the step left measured in standard errors (its Mahalanobis length
under ``cov(y) = s^2 (J^T J)^-1``): the bias that stopping leaves in any linear combination
of the parameters is at most ``sqrt(2 pred/s^2)`` of that combination's standard error. The
fit stops as converged when ``pred <= decrease * s^2``. With the default 0.01 that bias is
at most 0.14 standard errors, which raises the root-mean-square error of any estimate (bias
and noise together, ``sqrt(1 + 0.02)``) by at most 1 %: further steps cannot change
anything the data can tell. The rule is tested after every step, inside the compiled loop,
so a fit stops at the first step that satisfies it; it is invariant to the parameters'
units and to the solver's column scaling (it is the residual's projection onto the
Jacobian's column space).

**Directions the data do not determine** (`Tolerances.undetermined`). An eigen-direction of
``J^T J`` (in the solver's coordinates ``y``: log scale for positive parameters, so one unit
is a factor e) whose standard error ``sqrt(s^2 / eigenvalue)`` exceeds `undetermined` is
one the data fix to no better than a factor e. Its share of ``pred`` is left out of the
rule, so the fit does not crawl along it: those steps would lower the cost by amounts that
depend on values the data cannot fix (a Stribeck curve fitted to presliding data, say).
`fitting._chunked` then holds such parameters at their start and says so
(`FitResult.undetermined`).

**The settle rule** (`Stopping.moved`). A move ``dy`` changes any linear combination
``a^T y`` by at most ``|J dy| / s`` of that combination's standard error (Cauchy-Schwarz
with ``cov(y) = s^2 (J^T J)^-1``: ``|a^T dy| <= sqrt(a^T (J^T J)^-1 a) |J dy|``). The fit
stops when the last `STALL_STEPS` - 1 steps together moved it by ``|J dy|^2 <= 2 decrease
s^2``: no estimate moved by more than the bias the statistical rule leaves (0.14 standard
errors). Where the cost still falls, such steps crawl along undetermined directions: a move
there gains cost through the gradient while the prediction hardly changes (``|J dy|^2 =
eig c^2``, ``eig < s^2`` per unit), the gain `decrease_left` leaves out of the rule. The
stall rule below cannot see that (the cost keeps falling by more than `decrease` noise
variances per `STALL_STEPS`), and such a fit runs to its step limit (a GMS with more
elements than the data need, on presliding data: hundreds of steps, each a small fraction
of a noise variance, none moving an estimate visibly). The window is the stall rule's, so
the rule bounds the rate of the move, not the distance left: where the linear model still
predicts more than chance allows, the fit that stops so is reported as a kink, as for the
stall rule. `tests/fitting/test_settle_rule.py` checks the bound and a synthetic crawl.

MINPACK's lmder stops on a relative predicted reduction (``prered <= ftol``, a number
without a statistical meaning, hence its tiny default); scipy's trf on the relative change
of the cost or of ``x``. Both creep along a valley for many steps, each lowering the cost
by a small fraction of the noise variance. The rules of `Tolerances` other than `decrease`
keep that role for data without noise (an exact fit, where ``s^2`` is round-off).
"""

import dataclasses
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import optimistix as optx
from jaxtyping import Array

from ._descent import QRState


@dataclasses.dataclass(frozen=True)
class Tolerances:
    """When a fit is done; pass as ``fit(..., tol=Tolerances(...))``.

    - `decrease`: the statistical rule (module docstring): stop when the Gauss-Newton
      decrease of the cost left is at most this many noise variances (0.01: a bias of at
      most 0.14 standard errors), or the steps stall (`STALL_STEPS`), or they settle (no
      estimate moved by more than that bias over them); 0 turns all three off.
    - `undetermined`: standard error, in the solver's coordinates (a factor e for positive
      parameters), above which a direction or a parameter is undetermined: left out of the
      rule, and the parameter held at its start (`fit`, `fit_datasets`).
    - `ftol`: relative decrease of the cost over the last chunk of steps (32 or more);
    - `xtol`: change of the prediction by the last chunk's steps, linearised (``|J dy|``),
      relative to the norm of the residual;
    - `gtol`: largest cosine between a Jacobian column and the residual (MINPACK's test).

    The solver's own test (optimistix: the last step and every residual's change within
    ``atol + rtol*|value|``) applies as well. `fit`, `fit_datasets` and `fit_batch` apply
    them all (`fit_batch` per dataset, without holding parameters). Values are traced:
    changing them does not recompile.
    """

    decrease: float = 0.01
    undetermined: float = 1.0
    ftol: float = 1e-6
    xtol: float = 1e-6
    gtol: float = 1e-8


def decrease_left(jac, resid, mask, n_obs, undetermined):
    """``(pred / s^2, count)``: the Gauss-Newton decrease of the cost left over the
    determined directions in units of the noise variance, and how many free directions
    are undetermined (module docstring). `jac` is ``d resid / d y`` (any column scaling of
    the determined part gives the same value; the undetermined test reads ``y``'s units)."""
    jf = jac * mask
    return _decrease_left(jf.T @ jf, jf.T @ resid, jnp.sum(resid**2), mask, n_obs,
                          undetermined)


def _decrease_left(gram, jtr, rss, mask, n_obs, undetermined):
    """`decrease_left` from ``J^T J`` and ``J^T resid`` of the masked Jacobian and the sum
    of squared residuals (p x p and p numbers: from a QR factor, `Stopping.terminate`)."""
    n_free = jnp.sum(mask)
    s2 = rss / jnp.maximum(n_obs - n_free, 1.0)
    a = gram + jnp.diag(1.0 - mask)
    eig, vec = jnp.linalg.eigh(a)
    proj = vec.T @ jtr
    determined = (eig > 0) & (eig * undetermined**2 >= s2)
    pred = 0.5 * jnp.sum(jnp.where(determined, proj**2 / jnp.where(determined, eig, 1.0),
                                   0.0))
    ratio = jnp.where(s2 > 0, pred / jnp.where(s2 > 0, s2, 1.0), 0.0)
    # (Held coordinates have eigenvalue 1 and are counted as determined unless s^2 > 1.)
    count = jnp.sum((~determined) & (jnp.abs(vec.T @ mask) > 0.5))
    return ratio, count.astype(jnp.int32)


class Stopping(optx.AbstractLeastSquaresSolver):
    """`solver` with the statistical rule (`decrease_left`) tested after every step, a
    budget of `budget` steps, and a trust region (for a solver with one) starting at
    `step_size` when it is > 0 (the previous chunk's, so that a chunk goes on where the
    last one stopped). `inv_d` maps the solver's coordinates to ``y`` (``y = y_c + inv_d
    * z``); `mask` and `n_obs` are the free coordinates and the samples of weight > 0. All
    are arrays: new values do not recompile."""

    solver: Any
    budget: Array
    step_size: Array
    decrease: Array
    undetermined: Array
    inv_d: Array
    mask: Array
    n_obs: Array

    @property
    def rtol(self):
        return self.solver.rtol

    @property
    def atol(self):
        return self.solver.atol

    @property
    def norm(self):
        return self.solver.norm

    def init(self, fn, y, args, options, f_struct, aux_struct, tags):
        inner = self.solver.init(fn, y, args, options, f_struct, aux_struct, tags)
        if hasattr(inner, "search_state") and hasattr(inner.search_state, "step_size"):
            size = inner.search_state.step_size
            inner = eqx.tree_at(lambda s: s.search_state.step_size, inner,
                                jnp.where(self.step_size > 0, self.step_size, size))
        # The cost after each of the last `STALL_STEPS` steps (a ring; inf until filled),
        # and the point (the solver's coordinates) after each of them.
        costs = jnp.full((STALL_STEPS,), jnp.inf, y.dtype)
        points = jnp.zeros((STALL_STEPS,) + jnp.shape(y), y.dtype)
        return inner, jnp.zeros((), jnp.int32), costs, points

    def step(self, fn, y, args, options, state, tags):
        inner, count, costs, points = state
        y, inner, aux = self.solver.step(fn, y, args, options, inner, tags)
        f_info = getattr(inner, "f_info", None)
        if isinstance(f_info, optx.FunctionInfo.ResidualJac):
            costs = costs.at[count % STALL_STEPS].set(0.5 * jnp.sum(f_info.residual**2))
        points = points.at[count % STALL_STEPS].set(y)
        return y, (inner, count + 1, costs, points), aux

    def terminate(self, fn, y, args, options, state, tags):
        inner, count, costs, _ = state
        done, result = self.solver.terminate(fn, y, args, options, inner, tags)
        settled = jnp.asarray(False)
        f_info = getattr(inner, "f_info", None)
        if isinstance(f_info, optx.FunctionInfo.ResidualJac):
            # After the first step the state holds the residual and Jacobian at the last
            # accepted point (before it, zeros: `count` guards that).
            resid = f_info.residual.ravel()
            factor = _qr_factor(inner)
            if factor is None:  # J itself (n x p)
                jz = f_info.jac.as_matrix()
                ratio, _ = decrease_left(jz / self.inv_d, resid, self.mask, self.n_obs,
                                         self.undetermined)
            else:  # J = Q R at that point: J^T J = R^T R, J^T r = R^T Q^T r, |J dz| = |R dz|
                jz, qtr = factor
                jf = jz / self.inv_d * self.mask
                ratio, _ = _decrease_left(jf.T @ jf, jf.T @ qtr, jnp.sum(resid**2), self.mask,
                                          self.n_obs, self.undetermined)
            s2 = self.noise_variance(resid)
            # The ring's oldest entry (the next to be overwritten) is the cost
            # STALL_STEPS - 1 steps ago; the newest is now.
            achieved = costs[count % STALL_STEPS] - 0.5 * jnp.sum(resid**2)
            stalled = (self.decrease > 0) & (achieved <= self.decrease * s2)
            still = (self.decrease > 0) & (self.moved(state, jz, resid) <= 2.0 * self.decrease)
            settled = (count >= 1) & ((ratio <= self.decrease) | stalled | still)
        return done | settled | (count >= self.budget), result

    def noise_variance(self, resid):
        """``s^2``: the sum of squared residuals over the residual degrees of freedom."""
        return jnp.sum(resid**2) / jnp.maximum(self.n_obs - jnp.sum(self.mask), 1.0)

    def moved(self, state, jac, resid):
        """The squared length, in standard errors, of the move over the last
        `STALL_STEPS` - 1 steps of `state` (inf if fewer were taken): ``|J dz|^2 / s^2``
        over the free coordinates, `jac` being ``d resid / d z`` at the last point (the
        settle rule, module docstring; `jac` may be its QR factor R instead: the same
        length). The points are the ring's (optimistix passes
        `terminate` the point before the step, with the state after it)."""
        _, count, _, points = state
        s2 = self.noise_variance(resid)
        dz = (points[(count - 1) % STALL_STEPS] - points[count % STALL_STEPS]) * self.mask
        move = jnp.sum((jac @ dz) ** 2)
        length = jnp.where(s2 > 0, move / jnp.where(s2 > 0, s2, 1.0),
                           jnp.where(move > 0, jnp.inf, 0.0))
        return jnp.where(count >= STALL_STEPS, length, jnp.inf)

    def gained(self, state, resid):
        """The decrease of the cost over the last `STALL_STEPS` steps of `state` (inf if
        fewer were taken), in noise variances of `resid`."""
        _, count, costs, _ = state
        s2 = self.noise_variance(resid)
        achieved = costs[count % STALL_STEPS] - 0.5 * jnp.sum(resid**2)
        return jnp.where(s2 > 0, achieved / jnp.where(s2 > 0, s2, 1.0), jnp.inf)

    def postprocess(self, fn, y, aux, args, options, state, tags, result):
        return self.solver.postprocess(fn, y, aux, args, options, state[0], tags, result)


def _qr_factor(inner):
    """``(R, Q^T resid)`` of the Jacobian at the solver state `inner`'s last accepted
    point, where its descent keeps them (`fitting._descent`), else None."""
    ds = getattr(inner, "descent_state", None)
    return (ds.r, ds.qtr) if isinstance(ds, QRState) else None


#: The stall rule (achieved): the fit also stops when the last `STALL_STEPS` steps together
#: lowered the cost by at most `decrease` noise variances, whatever the linear model
#: predicts. Where it predicts at most `STALL_PREDICTED` noise variances (a step of at most
#: 1.4 standard errors), the rest is in a curved valley, out of reach of the solver's
#: steps and, being under one noise variance, of the data's interest. Where it predicts
#: more, eight steps that gain nothing (rejected, or accepted at a tiny fraction of their
#: prediction, the trust region shrinking) show that the linear model is wrong there: the
#: cost has a kink (GMS elements switching between sticking and slipping), and the point
#: is a local minimum of the cost as it is (`fitting._chunked` says so in `stopped`).
#: A smooth cost cannot do that: small enough steps achieve their prediction.
STALL_STEPS = 8
STALL_PREDICTED = 1.0
