"""Published steels (Modelica FluxTubes Roschke records) and randomized steels: tabulation and checks."""

import numpy as np
import pytest

from solenoid_fmu.errors import MaterialError
from solenoid_fmu.field import MU_0, STEELS, load_material, roschke_curve, roschke_mu_r, steel_curve, steel_names
from solenoid_fmu.field.material import check_bh_table
from solenoid_fmu.field.steels import B_LAST_T, B_STEP_T, EXCLUDED_STEELS, MAX_TABLE_MISFIT, roschke_table
from solenoid_fmu.rig import RigError, random_steel, random_steel_parameters
from solenoid_fmu.rig.steels import ROSCHKE_RANGES


def test_9SMnPb28_tabulates_the_hand_computed_value():
    # B = 1 T: B_N = 1/1.488 = 0.672043, B_N^12.5 = 0.0069577,
    # mu_r = 1 + (399 + 1200 * 0.672043) / (1 + 3 * 0.672043 + 0.0069577) = 399.749, H = 1 / (mu0 mu_r) = 1990.69 A/m
    H, B = roschke_table(STEELS["9SMnPb28"])
    k = int(np.argmin(np.abs(B - 1.0)))
    assert B[k] == pytest.approx(1.0)
    assert H[k] == pytest.approx(1990.69, rel=2e-6)
    assert roschke_mu_r(1.0, STEELS["9SMnPb28"]) == pytest.approx(399.749, rel=2e-6)


def test_DC03_at_its_peak_flux_density():
    # B = B_myMax = 1.05 T: B_N = 1, mu_r = 1 + (0 - 1 + 27790) / (1 + 16 + 1) = 1544.83, H = 540.876 A/m
    p = STEELS["DC03"]
    assert roschke_mu_r(1.05, p) == pytest.approx(1 + 27789 / 18, rel=1e-12)
    H, B = roschke_table(p)
    k = int(np.argmin(np.abs(B - 1.05)))
    assert H[k] == pytest.approx(540.876, rel=2e-6)
    assert steel_curve("DC03").H_of_B(1.05) == pytest.approx(540.876, rel=MAX_TABLE_MISFIT)


def test_shipped_literature_curve_is_the_9SMnPb28_record():
    lit, rec = load_material(), steel_curve("9SMnPb28")
    B = np.linspace(0.0, 3.0, 601)
    np.testing.assert_allclose(rec.H_of_B(B), lit.H_of_B(B), rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(rec.table_B_T, lit.table_B_T)  # the same grid, 0 ... 2.30 T


@pytest.mark.parametrize("name", steel_names())
def test_published_tables_rise_pass_the_checks_and_end_in_saturation(name):
    p = STEELS[name]
    H, B = roschke_table(p, name)
    check_bh_table(H, B, where=name)  # the project's checks, unweakened
    grid = B_STEP_T * np.arange(1, round(B_LAST_T / B_STEP_T) + 1)
    np.testing.assert_allclose(B[1:], grid[: len(B) - 1])
    np.testing.assert_allclose(H[1:], B[1:] / (MU_0 * roschke_mu_r(B[1:], p)), rtol=1e-12)
    chord = np.diff(B) / np.diff(H) / MU_0
    assert np.all(chord >= 1.0)
    if len(B) - 1 < len(grid):  # cut: the formula's next chord falls below mu0
        b_next = grid[len(B) - 1]
        h_next = b_next / (MU_0 * roschke_mu_r(b_next, p))
        assert (b_next - B[-1]) / (h_next - H[-1]) / MU_0 < 1.0
    curve = steel_curve(name)
    assert np.max(np.abs(curve.H_of_B(B[1:]) - H[1:]) / H[1:]) <= MAX_TABLE_MISFIT
    assert curve.mu_r_differential(B[-1] + 0.5) == pytest.approx(1.0)


@pytest.mark.parametrize("name", list(EXCLUDED_STEELS))
def test_left_out_records_are_refused_for_the_stated_reason(name):
    p, reason = EXCLUDED_STEELS[name]
    with pytest.raises(MaterialError) as exc:
        roschke_curve(p, name)
    if "MU_R_MAX" in reason and "misses" not in reason:
        assert "exceeds" in str(exc.value)
    else:
        assert "misses the Roschke table" in str(exc.value)
        assert roschke_mu_r(B_LAST_T, p) > 10  # not saturated at the end of the grid
    with pytest.raises(MaterialError, match="left out"):
        steel_curve(name)


def test_unknown_steel_names_the_known_ones():
    with pytest.raises(MaterialError, match="9SMnPb28"):
        steel_curve("St37")


def test_random_steels_are_reproducible_checked_and_in_range():
    curves = [random_steel(np.random.default_rng(seed)) for seed in range(4)]
    again = random_steel(np.random.default_rng(2))
    np.testing.assert_array_equal(again.H_A_per_m, curves[2].H_A_per_m)
    for seed, c in enumerate(curves):
        check_bh_table(c.table_H_A_per_m, c.table_B_T, where=f"seed {seed}")
        p = random_steel_parameters(np.random.default_rng(seed))
        for key, (lo, hi, _) in ROSCHKE_RANGES.items():
            assert lo <= getattr(p, key) <= hi
    H1 = [c.H_of_B(1.0) for c in curves]
    assert len(set(np.round(H1, 6))) == len(curves)  # different seeds, different steels


def test_random_steel_wants_a_generator():
    with pytest.raises(RigError, match="default_rng"):
        random_steel(3)
