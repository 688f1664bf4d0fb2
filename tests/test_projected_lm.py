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
