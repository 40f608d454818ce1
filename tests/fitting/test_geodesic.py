"""Levenberg-Marquardt with geodesic acceleration (`fitting._geodesic`,
`fitting.geodesic_solver`).

Rosenbrock's valley as a least-squares problem, ``r = (10 (y2 - y1^2), 1 - y1)``, is the
classic curved valley: from (-1.2, 1), against the same solver without the acceleration
and optimistix's Levenberg-Marquardt with the same trust region, all must reach the
minimum (1, 1), the accelerated one in fewer steps (measured: 21 against 23 and 23; 33
with optimistix's own trust region update). The acceleration must equal its formula
where the finite difference is exact (a quadratic residual), and is left out where it is
not small against the step.
"""

import json
import subprocess
import sys
from pathlib import Path

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from fitting._geodesic import _f_info, ACCEL_RATIO, GeodesicLevenbergMarquardt
from fitting._solve import default_solver, geodesic_solver


def _rosenbrock(y, args):
    return jnp.stack([10.0 * (y[1] - y[0] ** 2), 1.0 - y[0]]), None


def _steps(solver) -> int:
    sol = optx.least_squares(_rosenbrock, solver, jnp.array([-1.2, 1.0]), has_aux=True,
                             max_steps=1000, throw=False)
    assert sol.result == optx.RESULTS.successful
    np.testing.assert_allclose(np.asarray(sol.value), [1.0, 1.0], atol=1e-6)
    return int(sol.stats["num_steps"])


def test_the_acceleration_follows_a_curved_valley():
    geodesic = default_solver()
    assert isinstance(geodesic, GeodesicLevenbergMarquardt) and geodesic.accelerate
    plain = geodesic_solver(accelerate=False)
    reference = eqx.tree_at(lambda s: s.search, optx.LevenbergMarquardt(1e-6, 1e-6),
                            geodesic.search)
    assert plain.search == geodesic.search
    fast, slow, optimistix = _steps(geodesic), _steps(plain), _steps(reference)
    assert fast < slow, (fast, slow)
    # Without the acceleration the solver takes optimistix's steps (its Jacobian is only
    # materialised once per point).
    assert slow == optimistix, (slow, optimistix)


def _quadratic():
    """``r(y) = A y + (y^T B_k y)/2`` and its Jacobian and second directional derivative."""
    rng = np.random.default_rng(0)
    n, p = 7, 3
    a_mat = rng.normal(size=(n, p))
    b = 0.05 * rng.normal(size=(n, p, p))
    b = b + np.transpose(b, (0, 2, 1))

    def fn(y, args):
        return jnp.asarray(a_mat) @ y + 0.5 * jnp.einsum("i,kij,j->k", y, b, y), None

    def jac(y):
        return a_mat + np.einsum("kij,j->ki", b, y)

    def rvv(v):
        return np.einsum("i,kij,j->k", v, b, v)

    return fn, jac, rvv, rng.normal(size=p), 0.1 * rng.normal(size=p)


def test_the_acceleration_is_its_formula_on_a_quadratic_residual():
    """For a quadratic residual the finite difference gives ``r_vv = v^T B_k v`` exactly,
    so the step's acceleration is ``-(J^T J + lambda I)^-1 J^T r_vv / 2`` with
    ``lambda = 1/step_size``, taken only when small against the step."""
    fn, jac, rvv, y, v = _quadratic()
    solver = geodesic_solver()
    step_size = 2.0
    f_info, _ = _f_info(fn, jnp.asarray(y), None, frozenset())
    state = solver.descent.query(jnp.asarray(y), f_info, solver.descent.init(y, f_info))
    p = y.size
    for scale in (1.0, 300.0):
        vs = scale * v
        expected = -np.linalg.solve(jac(y).T @ jac(y) + np.eye(p) / step_size,
                                    jac(y).T @ rvv(vs))
        small = 2 * np.linalg.norm(expected) <= ACCEL_RATIO * np.linalg.norm(vs)
        assert small == (scale == 1.0)  # one case of each
        got = solver._acceleration(fn, jnp.asarray(y), None, f_info, jnp.asarray(vs),
                                   jnp.asarray(step_size), state)
        np.testing.assert_allclose(np.asarray(got), 0.5 * expected if small else 0.0,
                                   rtol=1e-6, atol=1e-12)


def test_the_comparison_script_runs_and_writes_json(tmp_path):
    """benchmarks/geodesic_steps.py as a user runs it, on one short cell (a smoke test: its
    timings are not checked)."""
    root = Path(__file__).resolve().parents[2]
    out = tmp_path / "geodesic.json"
    run = subprocess.run([sys.executable, str(root / "benchmarks" / "geodesic_steps.py"),
                          "--models", "tustin", "--motions", "p2p", "--sizes", "2000",
                          "--repeats", "1", "--json", str(out)],
                         capture_output=True, text=True, timeout=900, cwd=root)
    assert run.returncode == 0, run.stdout + run.stderr
    data = json.loads(out.read_text())
    (cell,) = data["cells"]
    assert all(cell[name]["steps"] > 0 for name in ("optimistix", "plain", "geodesic"))
    assert f"tustin | p2p | 2e+03 | {cell['optimistix']['steps']} |" in run.stdout
