"""Stage 2's step inside the unimodal cone (:mod:`solenoid_fmu.identification.cone_step`): the constrained
linearized subproblem solved exactly, checked against an independent solver (SLSQP with the unimodality as
linear inequalities, every peak node tried), and the Levenberg-Marquardt that uses it."""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from solenoid_fmu.field.material import unimodal_fit
from solenoid_fmu.identification.cone_step import cone_step
from solenoid_fmu.identification.fit import projected_lm


def _is_unimodal(v, tol=1e-9) -> bool:
    d = np.diff(v)
    k = int(np.argmax(v))
    return bool(np.all(d[:k] >= -tol) and np.all(d[k:] <= tol))


def _cost(J, r, damping, d) -> float:
    return float(np.sum((r + J @ d) ** 2) + np.sum(damping * d**2))


def _slsqp_best(v, J, r, damping, bounds=None) -> float:
    """The subproblem's least cost by SLSQP, peak fixed at each node in turn (the tail slope free); ``bounds``:
    (lower, upper) of the step d."""
    m = len(v) - 1
    best = np.inf
    for k in range(m):
        rows = [np.eye(m + 1)[j + 1] - np.eye(m + 1)[j] for j in range(k)]  # rises before k
        rows += [np.eye(m + 1)[j] - np.eye(m + 1)[j + 1] for j in range(k, m - 1)]  # falls after
        cons = [{"type": "ineq", "fun": lambda d, a=a: a @ (v + d), "jac": lambda d, a=a: a} for a in rows]
        out = minimize(lambda d: _cost(J, r, damping, d), np.zeros(m + 1),
                       jac=lambda d: 2 * J.T @ (r + J @ d) + 2 * damping * d, constraints=cons, method="SLSQP",
                       bounds=None if bounds is None else list(zip(*bounds, strict=True)),
                       options={"ftol": 1e-14, "maxiter": 500})
        if all(c["fun"](out.x) >= -1e-7 for c in cons):
            best = min(best, _cost(J, r, damping, out.x))
    return best


def test_the_step_is_the_least_cost_unimodal_step_an_independent_solver_finds():
    rng = np.random.default_rng(3)
    for _ in range(6):
        m = 8
        v = np.concatenate([unimodal_fit(rng.normal(0, 1, m))[0], [-1.5]])  # a unimodal start
        J = rng.normal(0, 1, (25, m + 1))
        r = rng.normal(0, 3, 25)
        damping = 1e-3 * np.diag(J.T @ J)
        d = cone_step(v, J, r, damping, np.full(m + 1, -np.inf), np.full(m + 1, np.inf))
        assert _is_unimodal((v + d)[:m])
        ref = _slsqp_best(v, J, r, damping)
        assert _cost(J, r, damping, d) <= ref * (1 + 1e-7) + 1e-9, (_cost(J, r, damping, d), ref)
        # and never worse than the unconstrained step projected back (what stage 2 did before)
        free = -np.linalg.solve(J.T @ J + np.diag(damping), J.T @ r)
        proj = np.concatenate([unimodal_fit((v + free)[:m])[0], [(v + free)[m]]]) - v
        assert _cost(J, r, damping, d) <= _cost(J, r, damping, proj) + 1e-9


def test_bounds_and_the_trust_radius_are_inside_the_step():
    """A deep-saturation node on its lower bound that the linear model wants lower still (DC03 of the tests):
    the step keeps it there and moves the others, as far as the trust radius lets every entry go; the same
    least cost as SLSQP with those bounds, and well below the step solved without them, then cut to the radius
    and clipped (the last node took the whole radius, the clip took it away)."""
    rng = np.random.default_rng(5)
    m = 8
    v = np.concatenate([[6.0, 6.5, 6.0, 5.0, 3.5, 1.5, -1.0, -9.0], [-1.5]])
    lower = np.concatenate([np.full(m, -9.0), [-6.0]])
    upper = np.concatenate([np.full(m, 11.5), [-1.2]])
    J = rng.normal(0, 1, (25, m + 1))
    J[:, m - 1] *= 5.0  # the bound node dominates the gradient
    r = 3.0 * J[:, m - 1] + rng.normal(0, 1, 25)  # |r + J d| falls as d_{m-1} falls below the bound
    damping = 1e-3 * np.diag(J.T @ J)
    radius = 0.3
    d = cone_step(v, J, r, damping, lower, upper, radius)
    assert np.all(v + d >= lower - 1e-9) and np.all(v + d <= upper + 1e-9)
    assert np.max(np.abs(d)) <= radius + 1e-9 and _is_unimodal((v + d)[:m])
    ref = _slsqp_best(v, J, r, damping, (np.maximum(lower - v, -radius), np.minimum(upper - v, radius)))
    assert _cost(J, r, damping, d) <= ref * (1 + 1e-7) + 1e-9, (_cost(J, r, damping, d), ref)
    free = cone_step(v, J, r, damping, np.full(m + 1, -np.inf), np.full(m + 1, np.inf))
    cut = np.clip(v + free * min(1.0, radius / np.max(np.abs(free))), lower, upper) - v
    costs = (_cost(J, r, damping, d), _cost(J, r, damping, cut))
    assert costs[0] < costs[1] - 1.0, costs


def test_an_unconstrained_minimizer_inside_the_cone_is_taken_as_it_is():
    rng = np.random.default_rng(7)
    m = 10
    target = np.concatenate([np.minimum(np.arange(m), 2 * (m - 1) - 3 * np.arange(m)) * 0.4, [-2.0]])
    assert _is_unimodal(target[:m])
    v = np.zeros(m + 1)
    J = rng.normal(0, 1, (30, m + 1))
    r = J @ (v - target)  # the minimizer of |r + J d| is target - v
    d = cone_step(v, J, r, np.zeros(m + 1), np.full(m + 1, -np.inf), np.full(m + 1, np.inf))
    assert np.max(np.abs(v + d - target)) < 1e-8


def test_levenberg_marquardt_with_the_cone_step_reaches_the_constrained_minimum():
    """A linear least-squares problem whose constrained minimum has an active constraint (a flat stretch where
    the data want ln chi to dip before the peak): with the cone step the fit ends at the minimum SLSQP finds;
    a step projected onto the cone after it was computed does not get there within the same budget."""
    rng = np.random.default_rng(11)
    m = 12
    truth = np.concatenate([np.array([1, 2, 3, 2.5, 4, 5, 6, 5, 4, 2, 0, -3.0]), [-2.0]])  # not unimodal: a dip
    J = rng.normal(0, 1, (40, m + 1)) * np.linspace(1.0, 0.05, m + 1)  # poorly seen high-field nodes
    y = J @ truth

    def res(v):
        return J @ v - y

    def jac(v):
        return J

    def project(v):
        return np.concatenate([unimodal_fit(v[:m])[0], [v[m]]])

    v0 = project(np.zeros(m + 1))
    ref = _slsqp_best(v0, J, res(v0), np.zeros(m + 1))
    free = np.full(m + 1, np.inf)

    def step(x, Jx, r, damping, radius):
        return cone_step(x, Jx, r, damping, -free, free, radius)

    with_cone = projected_lm(res, jac, v0, None, None, 40, ftol=1e-12, project=project, max_step=1.0, solve_step=step)
    plain = projected_lm(res, jac, v0, None, None, 40, ftol=1e-12, project=project, max_step=1.0)
    c_cone = float(np.sum(res(with_cone.x) ** 2))
    c_plain = float(np.sum(res(plain.x) ** 2))
    assert _is_unimodal(with_cone.x[:m])
    assert c_cone <= ref * (1 + 1e-6) + 1e-9, (c_cone, ref)
    assert c_plain > 1.2 * c_cone, (c_plain, c_cone)  # 4.64 against 3.34 when written
