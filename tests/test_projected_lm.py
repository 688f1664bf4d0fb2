"""The identification's Levenberg-Marquardt (:func:`solenoid_fmu.identification.fit.projected_lm`): gain-ratio
damping, the trust radius ``max_step``, the box."""

from __future__ import annotations

import numpy as np

from solenoid_fmu.identification.fit import projected_lm


def _rosenbrock():
    """Residuals of Rosenbrock's valley (minimum 0 at (1, 1)), each call recorded."""
    seen = []

    def res(x):
        seen.append(np.array(x, dtype=float))
        return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])

    def jac(x):
        return np.array([[-20.0 * x[0], 10.0], [-1.0, 0.0]])

    return res, jac, seen


def test_lm_follows_a_curved_valley_to_its_minimum():
    res, jac, seen = _rosenbrock()
    out = projected_lm(res, jac, np.array([-1.2, 1.0]), None, None, 200, ftol=1e-14,
                       project=lambda v: v)
    assert np.max(np.abs(out.x - 1.0)) < 1e-6, out
    assert len(seen) < 60


def test_trust_radius_caps_every_step():
    res, jac, seen = _rosenbrock()
    cap = 0.05
    out = projected_lm(res, jac, np.array([-1.2, 1.0]), None, None, 400, ftol=1e-14, project=lambda v: v,
                       max_step=cap)
    steps = np.abs(np.diff(np.array(seen), axis=0)).max(axis=1)
    # a trial point lies within 4 caps of the last accepted one, so two trials in a row within 8 caps
    assert np.all(steps <= 8 * cap + 1e-12), steps.max()
    assert np.max(np.abs(out.x - 1.0)) < 1e-4, out  # still gets there, in small steps


def test_box_bounds_hold_at_every_evaluation():
    res, jac, seen = _rosenbrock()
    lo, hi = np.array([-2.0, -2.0]), np.array([0.5, 2.0])
    out = projected_lm(res, jac, np.array([-1.2, 1.0]), lo, hi, 100, ftol=1e-14)
    pts = np.array(seen)
    assert np.all(pts >= lo) and np.all(pts <= hi)
    assert abs(out.x[0] - 0.5) < 1e-6 and abs(out.x[1] - 0.25) < 1e-3  # the constrained minimum on x0 = 0.5


def test_min_decrease_stops_at_the_first_step_that_gains_less():
    """``min_decrease``: the fit goes on while each accepted step lowers the cost by at least that much, or by at
    least :data:`~solenoid_fmu.identification.fit.MIN_DECREASE_SHARE` of the cost, and stops at the first that gains
    less than both (stage 2's crawl along a valley, :data:`~solenoid_fmu.identification.joint.STAGE2_MIN_DECREASE`);
    without it, Rosenbrock's valley runs to its minimum."""
    from solenoid_fmu.identification.fit import MIN_DECREASE_SHARE

    def valley():
        """Rosenbrock's valley beside a residual no step can lower (cost 20 at the minimum (1, 1))."""
        rosen, rosen_jac, seen = _rosenbrock()

        def res(x):
            return np.concatenate([rosen(x), [np.sqrt(20.0)]])

        def jac(x):
            return np.vstack([rosen_jac(x), [[0.0, 0.0]]])
        return res, jac, seen

    def cost(x):
        return float(10.0**2 * (x[1] - x[0] ** 2) ** 2 + (1.0 - x[0]) ** 2 + 20.0)

    res, jac, seen = valley()
    full = projected_lm(res, jac, np.array([-1.2, 1.0]), None, None, 200, ftol=1e-14, project=lambda v: v)
    n_full = len(seen)
    res, jac, seen = valley()
    out = projected_lm(res, jac, np.array([-1.2, 1.0]), None, None, 200, ftol=1e-14, project=lambda v: v,
                       min_decrease=0.1)
    assert out.status == 2 and len(seen) < n_full and np.max(np.abs(full.x - 1.0)) < 1e-6
    # the accepted steps (each trial that lowers the best cost so far): what each gained, and its threshold
    best, gains, limits = cost(seen[0]), [], []
    for x in seen[1:]:
        if cost(x) < best:
            gains.append(best - cost(x))
            limits.append(min(0.1, MIN_DECREASE_SHARE * best))
            best = cost(x)
    assert gains[-1] < limits[-1] and all(g >= t for g, t in zip(gains[:-1], limits[:-1], strict=True)), (gains, limits)
    assert best == cost(out.x) and best > 20.0 + 1e-3  # stopped short of the minimum, where the steps gain little


def test_futile_stops_at_the_first_accepted_step_it_names_and_is_asked_only_there():
    """``futile(r, decrease)`` is asked after every accepted step, with that step's residuals and the cost it took
    off, and True stops the fit there (status 4); never True, the fit is the one without it, evaluation by
    evaluation (stage 2's stronger priors, :data:`~solenoid_fmu.identification.joint.FUTILE_STEPS`)."""
    res, jac, seen = _rosenbrock()
    full = projected_lm(res, jac, np.array([-1.2, 1.0]), None, None, 200, ftol=1e-14, project=lambda v: v)
    n_full = len(seen)
    asked = []

    def never(r, decrease):
        asked.append((float(r @ r), decrease))
        return False

    res, jac, seen = _rosenbrock()
    same = projected_lm(res, jac, np.array([-1.2, 1.0]), None, None, 200, ftol=1e-14, project=lambda v: v,
                        futile=never)
    n_same = len(seen)
    assert n_same == n_full and np.array_equal(same.x, full.x) and same.status == full.status
    # asked once per accepted step but the last (which converged), with what that step took off the cost
    costs = [float(res(seen[0]) @ res(seen[0]))] + [c for c, _ in asked]
    assert asked and all(d == costs[k] - costs[k + 1] > 0 for k, (_, d) in enumerate(asked)), asked
    # a predicate true below cost 1 stops at the first accepted step that gets there
    res, jac, seen = _rosenbrock()
    out = projected_lm(res, jac, np.array([-1.2, 1.0]), None, None, 200, ftol=1e-14, project=lambda v: v,
                       futile=lambda r, d: float(r @ r) < 1.0)
    n_out = len(seen)
    first = next(c for c, _ in asked if c < 1.0)
    assert out.status == 4 and float(res(out.x) @ res(out.x)) == first and n_out < n_full
