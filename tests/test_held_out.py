"""Held-out prediction of the joint identification (joint.held_out_residuals), on linear least squares
where the leave-group-out refit is known exactly."""

import numpy as np

from solenoid_fmu.identification.joint import held_out_residuals

RNG = np.random.default_rng(20)
#: Agreement asked of the exact refits: held_out_residuals regularizes its normal matrices by 1e-9 of their
#: mean diagonal, which moves these predictions by ~5e-11 (rounding: ~1e-16); the rules it replaced were off
#: by 1e-2 and more.
EXACT = 1e-8
J = RNG.normal(size=(12, 3))
GROUPS = np.repeat(np.array(["a", "b", "c", "d"]), 3)
PRIOR = 0.3 * np.eye(3)


def _fit(J_rows, y_rows, prior=PRIOR):
    """Least squares of J theta = y with the prior rows pulling theta towards 0."""
    A = np.vstack([J_rows, prior])
    b = np.concatenate([y_rows, np.zeros(prior.shape[0])])
    return np.linalg.lstsq(A, b, rcond=None)[0]


def _prior_r(theta):
    return PRIOR @ theta


def test_at_the_optimum_it_is_the_exact_leave_group_out_refit():
    theta_true = np.array([0.05, -0.02, 0.03])
    y = J @ theta_true + 0.01 * RNG.normal(size=12)
    theta = _fit(J, y)
    r = J @ theta - y
    got = held_out_residuals(J, r, GROUPS, PRIOR, _prior_r(theta))
    for g in np.unique(GROUPS):
        sel = GROUPS == g
        refit = _fit(J[~sel], y[~sel])
        np.testing.assert_allclose(got[sel], J[sel] @ refit - y[sel], rtol=0, atol=EXACT)
    assert np.sqrt(np.mean(got**2)) > 1.05 * np.sqrt(np.mean(r**2))  # held out is worse than in-sample


def test_where_the_fit_stands_adds_no_step():
    """A fit held against a bound, or stopped on its budget, stands off the minimizer: only the group's
    removal moves the prediction. On a linear problem held-out minus in-sample residuals are the same
    wherever the fit stands, and equal to the exact refit's change."""
    y = J @ np.array([0.05, -0.02, 0.03]) + 0.02 * RNG.normal(size=12)
    opt = _fit(J, y)
    off = opt + np.array([0.2, -0.15, 0.1])  # far from the minimizer: a large gradient is left
    r_opt, r_off = J @ opt - y, J @ off - y
    assert np.linalg.norm(J.T @ r_off + PRIOR.T @ _prior_r(off)) > 0.5
    at_opt = held_out_residuals(J, r_opt, GROUPS, PRIOR, _prior_r(opt)) - r_opt
    at_off = held_out_residuals(J, r_off, GROUPS, PRIOR, _prior_r(off)) - r_off
    np.testing.assert_allclose(at_off, at_opt, rtol=0, atol=EXACT)
    for g in np.unique(GROUPS):
        sel = GROUPS == g
        np.testing.assert_allclose(at_off[sel], J[sel] @ (_fit(J[~sel], y[~sel]) - opt), rtol=0, atol=EXACT)


def test_the_b_band_widens_with_the_held_out_rms():
    """The B(H) band (identified_range) is scaled by max(in-sample RMS, held-out RMS, 1) sigma: a curve that
    predicts the left-out recordings worse than it fits them gets a wider band and a narrower identified range."""
    from solenoid_fmu.field import load_material
    from solenoid_fmu.identification.joint_result import band_noise_scale
    from solenoid_fmu.identification.parametrization import fit_to_curve
    from solenoid_fmu.identification.uncertainty import identified_range

    assert band_noise_scale({"rms_in": 0.5, "rms_out": 2.5}) == 2.5
    assert band_noise_scale({"rms_in": 1.5, "rms_out": 1.2}) == 1.5
    assert band_noise_scale({"rms_in": 0.3, "rms_out": 0.7}) == 1.0
    model, theta = fit_to_curve(load_material(), m=9)
    Jb = np.random.default_rng(3).normal(size=(30, len(theta))) * 100.0  # flux data seeing every parameter
    rng1, H1, sd1 = identified_range(model, theta, Jb, 1.0, 6e4)
    rng3, H3, sd3 = identified_range(model, theta, Jb, 3.0, 6e4)
    np.testing.assert_array_equal(H1, H3)
    assert np.all(sd3 >= sd1) and np.max(sd3 / sd1) > 2.0  # data-dominated there: about the factor 3
    assert rng3[1] > rng3[0] and rng1[0] <= rng3[0] and rng3[1] <= rng1[1]
    assert (rng3[1] - rng3[0]) < (rng1[1] - rng1[0])
