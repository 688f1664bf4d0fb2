"""The FEM against analytic physics: long steel-cored solenoid, air-core coil, coil-coil force."""

import numpy as np
import pytest
from analytic import (
    air_coil_geometry,
    coil_coil_force,
    filament_mutual,
    long_solenoid_geometry,
    long_solenoid_psi,
    nagaoka_inductance,
    two_coil_geometry,
)

from solenoid_fmu.field.fem import Solver
from solenoid_fmu.field.material import linear_material, load_material


@pytest.fixture(scope="module")
def steel():
    return load_material()


@pytest.mark.parametrize("H0", [200.0, 1500.0, 20000.0], ids=["low", "mid", "saturating"])
def test_long_solenoid_with_nonlinear_core(steel, H0):
    """Axial slice, natural top/bottom: Psi of an infinitely long coil, exactly (< 0.2 %)."""
    rc, r1, r2, length, turns = 5e-3, 6e-3, 9e-3, 2e-3, 20.0
    solver = Solver(long_solenoid_geometry(), steel)
    i_A = H0 * length / turns
    sol = solver.solve(i_A, 0.5e-3)
    psi_ref, _ = long_solenoid_psi(steel, i_A, rc, r1, r2, length, turns)
    assert sol.psi_Wb == pytest.approx(psi_ref, rel=2e-3)
    # the core really is in the regime named: B(H0) from the curve
    if H0 > 10000:
        assert steel.B_of_H(H0) > 1.8


@pytest.mark.parametrize(("length_mm", "k_nagaoka"), [(20.0, 0.68842), (40.0, 0.81814)], ids=["2a/l=1", "2a/l=0.5"])
def test_air_core_coil_inductance_nagaoka(length_mm, k_nagaoka):
    """Thin single-layer coil (thickness a/250) against Nagaoka's formula, error < 0.5 %."""
    geom = air_coil_geometry(a=10.0, length=length_mm, thickness=0.04, turns=100.0, box=300.0)
    sol = Solver(geom, linear_material(), mesh_size=0.5).solve(1.0, 0.5e-3)
    L_ref = nagaoka_inductance(10e-3, length_mm * 1e-3, 100.0, k_nagaoka)
    assert sol.psi_Wb / 1.0 == pytest.approx(L_ref, rel=5e-3)


def test_filament_force_formula_matches_known_limit():
    """The reference itself: for d << a the mutual inductance of equal loops tends to
    mu0 a (ln(8a/d) - 2), so dM/dd -> -mu0 a / d."""
    a, d = 0.1, 1e-4
    h = 1e-8
    dM = (filament_mutual(a, a, d + h) - filament_mutual(a, a, d - h)) / (2 * h)
    assert dM == pytest.approx(-4e-7 * np.pi * a / d, rel=2e-3)


def test_force_between_two_coaxial_coils():
    """FEM force on the moving coil vs filament mutual-inductance gradient: error < 1 %."""
    c1 = (10.0, 14.0, 0.0, 6.0)
    c2 = (10.0, 14.0, 10.0, 16.0)
    geom = two_coil_geometry(c1, c2, turns1=100.0, at2=200.0)
    solver = Solver(geom, linear_material())
    for x_mm in (0.5, 1.5):
        sol = solver.solve(1.0, x_mm * 1e-3)
        c2_at = np.array(c2) + np.array([0, 0, x_mm, x_mm])
        fz_ref = coil_coil_force(np.array(c1) * 1e-3, c2_at * 1e-3, 100.0, 200.0)
        # the package's sign: positive closes the gap, i.e. pulls coil 2 towards -z
        assert -fz_ref > 0
        assert sol.force_coenergy_N == pytest.approx(-fz_ref, rel=1e-2)
        assert sol.force_stress_N == pytest.approx(-fz_ref, rel=1e-2)
