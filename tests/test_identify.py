"""Tests of the B(H) parameterization used by the identification (fast, no FEM)."""

import numpy as np
import pytest

from solenoid_fmu.errors import SolenoidError
from solenoid_fmu.identify import SusceptibilityModel, fit_to_curve, identify_bh
from solenoid_fmu.material import MU_0, load_material


@pytest.fixture(scope="module")
def fitted():
    lit = load_material()
    model, theta = fit_to_curve(lit)
    return lit, model, theta


def test_fit_reproduces_literature_curve(fitted):
    lit, model, theta = fitted
    H = np.geomspace(100.0, 1e5, 40)
    err = np.abs(model.curve(theta).B_of_H(H) / lit.B_of_H(H) - 1.0)
    assert err.max() < 0.05


def test_parameterization_is_physical_for_any_parameters_within_bounds():
    model = SusceptibilityModel(np.geomspace(50.0, 2e5, 7), peak=3)
    lo, hi = model.bounds()
    rng = np.random.default_rng(1)
    for _ in range(5):
        theta = rng.uniform(np.maximum(lo, -8.0), np.minimum(hi, 8.0))
        H, B = model.table(theta)
        assert np.all(np.diff(B) > 0)
        chi = model.chi(H[1:], theta)
        k = int(np.argmax(chi))
        assert np.all(np.diff(chi[: k + 1]) >= -1e-12 * chi.max())
        assert np.all(np.diff(chi[k:]) <= 1e-12 * chi.max())
        # slope tends to mu0 at high field
        slope = (B[-1] - B[-2]) / (H[-1] - H[-2])
        assert slope / MU_0 < 1.0 + 0.05 * chi.max()


def test_bad_input_raises():
    lit = load_material()
    with pytest.raises(SolenoidError):
        identify_bh([1.0, 2.0], [0.1, 0.2], 0.0005, None, lit)
