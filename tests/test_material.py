"""B(H) curves: physics checks with the failing point named, Newton-safe smoothing."""

import numpy as np
import pytest

from solenoid_fmu.errors import MaterialError
from solenoid_fmu.field.material import (
    MU_0,
    MU_R_MAX,
    bh_curve_from_table,
    check_bh_table,
    default_material_path,
    load_material,
    read_bh_csv,
)


@pytest.fixture(scope="module")
def lit():
    return load_material()


def test_literature_curve_is_reproduced(lit):
    H, B = read_bh_csv(default_material_path())
    rel = np.abs(lit.H_of_B(B[1:]) - H[1:]) / H[1:]
    assert rel.max() < 3e-3
    assert lit.mu_r_differential(0.0) == pytest.approx(400, rel=0.01)  # mu_i of the Roschke fit


def test_slopes_bounded_between_mu0_and_max(lit):
    B = np.linspace(0, 4, 4001)
    mu = lit.mu_r_differential(B)
    assert mu.min() >= 1.0 - 1e-12 and mu.max() <= MU_R_MAX
    # beyond the last point the slope is exactly mu0
    assert lit.mu_r_differential(3.0) == pytest.approx(1.0)


def test_reluctivity_derivative_is_consistent(lit):
    b2 = np.linspace(0.01, 6.0, 500)
    nu, dnu = lit.nu_of_b2(b2)
    h = 1e-6
    nu_p, _ = lit.nu_of_b2(b2 + h)
    nu_m, _ = lit.nu_of_b2(b2 - h)
    np.testing.assert_allclose(dnu, (nu_p - nu_m) / (2 * h), rtol=1e-4, atol=1e-3)


def test_energy_density_and_inverse(lit):
    B = np.linspace(0, 2.6, 30001)
    H = lit.H_of_B(B)
    from scipy.integrate import trapezoid

    assert lit.energy_density(2.6) == pytest.approx(trapezoid(H, B), rel=1e-6)
    Hs = np.geomspace(1, 3e5, 50)
    np.testing.assert_allclose(lit.H_of_B(lit.B_of_H(Hs)), Hs, rtol=1e-9)


def test_noisy_real_table_passes():
    H, B = read_bh_csv(default_material_path())
    rng = np.random.default_rng(1)
    Hn = H * (1 + 0.002 * rng.standard_normal(H.size))  # 0.2 % scatter: ~4 % in chord slopes
    Hn[0] = 0.0
    curve = bh_curve_from_table(np.maximum.accumulate(Hn), B)
    assert curve.mu_r_differential(0.5) > 300


def test_falling_B_is_refused_with_the_point():
    H = [0, 100, 200, 300, 400]
    B = [0, 0.1, 0.2, 0.19, 0.3]
    with pytest.raises(MaterialError, match=r"point 4 \(H = 300 A/m, B = 0.19 T\): B does not rise"):
        check_bh_table(H, B, where="steel.csv")


def test_two_permeability_peaks_are_refused():
    H = np.array([0, 100, 200, 300, 400, 500, 600, 700, 800.0])
    mu = np.array([500, 1000, 1500, 800, 400, 1200, 300, 100]) * MU_0
    B = np.concatenate([[0], np.cumsum(mu * 100)])
    with pytest.raises(MaterialError, match=r"point 6 .*off the best curve with one inflection point \(after"):
        check_bh_table(H, B, where="steel.csv")


def test_slope_below_mu0_is_refused():
    H = np.array([0, 100, 1000, 1e5, 2e5])
    B = np.array([0, 0.1, 1.0, 2.0, 2.0 + 0.5 * MU_0 * 1e5])
    with pytest.raises(MaterialError, match="slope below mu0"):
        check_bh_table(H, B)


def test_bad_csv_names_file_and_line(tmp_path):
    f = tmp_path / "m.csv"
    f.write_text("H_A_per_m,B_T\n0,0\n100,abc\n")
    with pytest.raises(MaterialError, match=r"m.csv:3: not a number"):
        load_material(f)
    f.write_text("H,B\n0,0\n")
    with pytest.raises(MaterialError, match=r"m.csv:1: header"):
        load_material(f)
