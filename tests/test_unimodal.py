"""The unimodal projection (:func:`solenoid_fmu.field.unimodal_fit`): the physical check of every B(H) table
and stage 2's projection of the identification stand on it."""

from __future__ import annotations

import numpy as np
from scipy.optimize import lsq_linear

from solenoid_fmu.field import unimodal_fit


def _best_unimodal_sse(y):
    """The least-squares unimodal fit by brute force: for every peak index a bounded linear least
    squares problem (y = c + cumsum(d), d >= 0 up to the peak, <= 0 after)."""
    n = len(y)
    A = np.tril(np.ones((n, n)))
    best = np.inf
    for p in range(n):
        lo = np.array([-np.inf] + [0.0 if k <= p else -np.inf for k in range(1, n)])
        hi = np.array([np.inf] + [np.inf if k <= p else 0.0 for k in range(1, n)])
        sol = lsq_linear(A, y, bounds=(lo, hi), method="bvls")
        best = min(best, float(np.sum((A @ sol.x - y) ** 2)))
    return best


def test_unimodal_fit_is_the_least_squares_projection():
    rng = np.random.default_rng(7)
    for trial in range(60):
        n = int(rng.integers(2, 14))
        y = rng.normal(size=n) if trial % 2 else np.cumsum(rng.normal(size=n))
        fit, peak = unimodal_fit(y)
        assert np.all(np.diff(fit[: peak + 1]) >= 0) and np.all(np.diff(fit[peak:]) <= 0), (y, fit)
        assert float(np.sum((fit - y) ** 2)) <= _best_unimodal_sse(y) * (1 + 1e-9) + 1e-12, y


def test_a_unimodal_sequence_is_left_alone_and_edge_cases():
    y = np.array([0.0, 1.0, 3.0, 2.0, -1.0])
    fit, peak = unimodal_fit(y)
    assert np.array_equal(fit, y) and peak == 2  # bit for bit
    assert unimodal_fit(np.array([2.0]))[0].tolist() == [2.0]
    fit, _ = unimodal_fit(np.array([1.0, 0.0, 1.0]))  # a valley: one side is flattened
    assert float(np.sum((fit - [1.0, 0.0, 1.0]) ** 2)) == 0.5
