"""What an identified curve predicts on the working range, with the uncertainty the campaign leaves
(:mod:`solenoid_fmu.identification.prediction`): the band narrows where the data are, and a campaign without
data where the grid needs them is warned about."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from solenoid_fmu.field import load_geometry, load_material
from solenoid_fmu.identification.joint import stage2_nodes
from solenoid_fmu.identification.parametrization import fit_to_curve
from solenoid_fmu.identification.point_model import PointModel
from solenoid_fmu.identification.prediction import (
    GOAL_F_REL,
    band_prior_std,
    prediction_band,
    prediction_grid,
    prediction_warnings,
)

MESH = 3.0
GRID_I = (0.25, 1.0, 2.0)
GRID_X = (1.0e-3, 2.5e-3)


def test_the_grid_spans_the_working_range_and_the_currents_up_to_the_largest():
    g = load_geometry()
    i_A, x_m = prediction_grid(g)
    np.testing.assert_allclose(i_A, [0.25, 0.5, 1.0, 1.5, 2.0])  # PS45: max_current_A 2
    np.testing.assert_allclose(x_m[[0, -1]], [g.stroke.working_min_m, g.stroke.working_max_m])
    assert len(x_m) == 4 and np.all(np.diff(x_m) > 0)


def _fit(currents, sigma_rel=2e-3):
    """A fit-like record at the literature curve in the node parametrization, with the weighted Jacobian of
    flux and force points at two strokes and ``currents`` (sigma ``sigma_rel`` of each value)."""
    lit = load_material()
    model, theta = fit_to_curve(lit, H_nodes=stage2_nodes(lit))
    pts = [(k, float(i), x) for x in GRID_X for i in currents for k in ("psi", "force")]
    pm = PointModel(load_geometry(), pts, model.curve, MESH, lit, workers=1)
    v = pm.values(theta)
    J_w = pm.jacobian(theta) / (sigma_rel * np.abs(v))[:, None]
    return SimpleNamespace(model=model, theta=theta, theta_stage1=theta, J_w=J_w, curve=model.curve(theta))


def test_the_band_narrows_where_the_campaign_has_data_and_warns_where_it_has_none():
    """Data at 1-2 A only: the force at 0.25 A is left to the prior (its band several times the one at 2 A, and
    wider than the goal, warned); the same campaign with points at 0.2 and 0.3 A narrows it there, and the band
    where both have data hardly changes."""
    geom = load_geometry()
    high = prediction_band(_fit((1.0, 1.5, 2.0)), geom, MESH, 1.0, GRID_I, GRID_X)
    both = prediction_band(_fit((0.2, 0.3, 1.0, 1.5, 2.0)), geom, MESH, 1.0, GRID_I, GRID_X)
    F_hi, F_both = high["F_sigma_rel"], both["F_sigma_rel"]
    assert F_hi.shape == (len(GRID_I), len(GRID_X))
    assert np.all(F_hi[0] > 3.0 * F_hi[-1]), F_hi
    assert np.all(F_both[0] < 0.5 * F_hi[0]), (F_both, F_hi)
    np.testing.assert_allclose(F_both[-1], F_hi[-1], rtol=0.5)
    assert np.all(both["psi_sigma_rel"][0] < high["psi_sigma_rel"][0])
    warned = prediction_warnings(high)
    assert 2.0 * F_hi.max() > GOAL_F_REL and any("force" in w and "0.25 A" in w for w in warned), (F_hi, warned)
    assert prediction_warnings(both) == []
    # more noise, wider band: the scale on the sigmas (the held-out RMS) enters as it should
    noisy = prediction_band(_fit((1.0, 1.5, 2.0), sigma_rel=8e-3), geom, MESH, 1.0, GRID_I, GRID_X)
    assert np.all(noisy["F_sigma_rel"][-1] > 1.5 * F_hi[-1])
    np.testing.assert_allclose(noisy["F_N"], high["F_N"], rtol=1e-6)  # the values do not depend on the sigmas


def test_the_prior_widens_where_the_fit_moved_the_curve_far_from_stage_1():
    """:func:`band_prior_std`: the fixed +-0.3 in ln chi where the chosen curve is stage 1's; where stage 2 moved ln
    chi by 1.2 RMS from it, 1.2, and the band widens where the prior sets it (0.25 A: no data) several times more
    than where the data do (2 A)."""
    from solenoid_fmu.identification.uncertainty import PRIOR_LN_CHI_STD

    geom = load_geometry()
    fit = _fit((1.0, 1.5, 2.0))
    assert band_prior_std(fit) == PRIOR_LN_CHI_STD
    moved = SimpleNamespace(**vars(fit))
    moved.theta_stage1 = np.array(fit.theta, dtype=float)
    moved.theta_stage1[0] += 1.2  # the same increments: ln chi 1.2 higher at every node
    assert abs(band_prior_std(moved) - 1.2) < 1e-12
    near = prediction_band(fit, geom, MESH, 1.0, GRID_I, GRID_X)
    wide = prediction_band(moved, geom, MESH, 1.0, GRID_I, GRID_X)
    assert abs(wide["prior_ln_chi_std"] - 1.2) < 1e-12 and near["prior_ln_chi_std"] == PRIOR_LN_CHI_STD
    grow = wide["F_sigma_rel"] / near["F_sigma_rel"]
    assert np.all(grow[0] > 2.0) and np.all(grow[0] > 1.5 * grow[-1]), grow
    np.testing.assert_allclose(wide["F_N"], near["F_N"], rtol=1e-9)  # the band, not the prediction
