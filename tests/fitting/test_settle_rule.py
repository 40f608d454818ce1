"""The settle rule of `fitting._stopping` (`Stopping.moved`, `fitting._chunked._halted`): a
fit stops when its last steps moved no linear combination of the parameters by more than
``sqrt(2 decrease)`` of its standard error, even while the cost still falls (a crawl along
directions the data do not determine)."""

import types

import jax.numpy as jnp
import numpy as np
import optimistix as optx

import jaxfric  # noqa: F401  (float64)
from fitting._chunked import _chance_bound, _halted
from fitting._solve import default_solver
from fitting._stopping import decrease_left, STALL_STEPS, Stopping, Tolerances


def _stopping(n, p, mask=None, inv_d=None, budget=100):
    mask = jnp.ones(p) if mask is None else jnp.asarray(mask, float)
    inv_d = jnp.ones(p) if inv_d is None else jnp.asarray(inv_d, float)
    return Stopping(default_solver(), jnp.asarray(budget), jnp.zeros(()), jnp.asarray(0.01),
                    jnp.asarray(1.0), inv_d, mask, jnp.asarray(float(n)))


def test_moved_bounds_the_move_of_every_linear_combination():
    """``moved = |J dz|^2 / s^2`` over the free coordinates, and no linear combination
    ``a^T dz`` moves by more than ``sqrt(moved)`` of its standard error (Cauchy-Schwarz);
    inf until `STALL_STEPS` steps are in the ring."""
    rng = np.random.default_rng(0)
    n, p = 50, 4
    jac, resid = rng.normal(size=(n, p)), rng.normal(size=n)
    mask = np.array([1.0, 1.0, 1.0, 0.0])  # the last coordinate held
    old, new = rng.normal(size=p), rng.normal(size=p)
    stop = _stopping(n, p, mask)
    count = jnp.asarray(3 * STALL_STEPS + 2, jnp.int32)
    points = jnp.zeros((STALL_STEPS, p)).at[int(count) % STALL_STEPS].set(old)
    points = points.at[(int(count) - 1) % STALL_STEPS].set(new)  # the newest
    state = (None, count, jnp.zeros(STALL_STEPS), points)
    moved = float(stop.moved(state, jnp.asarray(jac), jnp.asarray(resid)))
    jf, dz = jac[:, :3], (new - old)[:3]
    s2 = resid @ resid / (n - 3)
    assert np.isclose(moved, np.sum((jf @ dz) ** 2) / s2, rtol=1e-12)
    cov = s2 * np.linalg.inv(jf.T @ jf)
    for a in rng.normal(size=(200, 3)):
        assert abs(a @ dz) <= np.sqrt(moved) * np.sqrt(a @ cov @ a) * (1 + 1e-12)
    early = (None, jnp.asarray(STALL_STEPS - 1, jnp.int32), jnp.zeros(STALL_STEPS), points)
    assert np.isinf(float(stop.moved(early, jnp.asarray(jac), jnp.asarray(resid))))


def test_halted_settled_converged_or_kink():
    """Steps that still gain cost (not stalled) but move nothing the data can tell stop
    the fit: converged where the decrease left is within chance, a kink beyond."""
    tol = Tolerances()
    out = types.SimpleNamespace(gained=0.5, moved=0.015)
    why, kind = _halted(out, 0.4, 4.6, tol)
    assert kind == "converged" and "settled" in why
    why, kind = _halted(out, 9.0, 4.6, tol)
    assert kind == "kink" and why.startswith("NOT converged")
    assert _halted(types.SimpleNamespace(gained=0.5, moved=0.03), 0.4, 4.6, tol) is None
    assert _halted(out, 0.4, 4.6, Tolerances(decrease=0.0)) is None


def test_crawl_along_an_undetermined_direction_stops_settled():
    """A synthetic fit: ``z0`` determined, through a kink at 0.3 (a V in the cost, as a GMS
    element switching between sticking and slipping), ``z1`` undetermined (its column's
    norm 0.3, under the noise's 1: a standard error above 1) with its optimum 20 away.
    Steps across the kink keep the trust region small; near the kink the last steps
    still gain more than `decrease` noise variances (the stall rule waits: it stops this
    fit 4 steps later, 38 against 34), but move no estimate by more than
    ``sqrt(2 decrease)`` standard errors. The settle rule stops it there, with the
    decrease left over the determined direction within chance."""
    rng = np.random.default_rng(3)
    n = 200
    e = jnp.asarray(rng.normal(size=n))
    t = jnp.linspace(0.0, 1.0, n)
    u = jnp.asarray(rng.normal(size=n)) / np.sqrt(n)

    def fn(z, _):
        return e + 3.0 * jnp.abs(z[0] - 0.3) * t + 0.3 * (z[1] - 20.0) * u, None

    budget = 200
    stop = _stopping(n, 2, budget=budget)
    sol = optx.least_squares(fn, stop, jnp.asarray([1.0, 0.0]), has_aux=True,
                             max_steps=budget + 1, throw=False)
    steps = int(sol.stats["num_steps"])
    inner = sol.state[0]
    jac, resid = inner.f_info.jac.as_matrix(), inner.f_info.residual
    left, undetermined = decrease_left(jac, resid, jnp.ones(2), float(n), 1.0)
    assert steps < budget
    assert int(undetermined) == 1
    assert float(left) > 0.01  # not stopped by the statistical rule
    assert float(stop.gained(sol.state, resid)) > 0.01  # nor by the stall rule
    assert float(stop.moved(sol.state, jac, resid)) <= 0.02
    assert float(left) <= _chance_bound(jac)
