r"""Identify the steel's initial magnetization curve from a measured commutation curve (paper section 4).

Fit (:func:`identify_bh`)
-------------------------
Residuals: FEM flux minus measured commutation curve Psi(i) at one stroke, relative to the
measured peak flux, weighted down where the hysteresis loop is wide (there the branch mean is a
biased estimate of the magnetization curve). Error reported: the mean absolute flux error (the
evident meaning of the paper's garbled eq. 7) and the RMS, before (start curve) and after.

- ``gn`` (default): stage 1 scales the start curve's polarization and stretches it along H
  (:func:`~solenoid_fmu.identification.parametrization.scaled_curve`, 2 parameters); stage 2, only
  when stage 1 leaves a flux RMS above the noise floor, runs a projected Levenberg-Marquardt on all
  parameters with a weak prior and is kept only if it lowers the RMS clearly. Jacobians by the
  adjoint method (:class:`~solenoid_fmu.identification.flux_model.FluxModel`): one linear solve per
  current at the converged solution, about a third of a warm sweep for any number of parameters.
- ``auglag``: the paper's method, nlopt AUGLAG around LN_BOBYQA (derivative-free) on the mean
  absolute flux error with the constraints as inequalities
  (:func:`~solenoid_fmu.identification.parametrization.constraint_values`); the return code is
  reported as its nlopt name (:data:`NLOPT_CODES`).

The parameterization is in :mod:`solenoid_fmu.identification.parametrization`; the H range the data
identify follows from a linearized Bayesian analysis
(:func:`~solenoid_fmu.identification.uncertainty.B_uncertainty`); outside it the curve keeps the
start curve's shape.

Mesh: default :data:`DEFAULT_MESH_SIZE` = 2.0. The curve identified from the PS45 demo campaign
at mesh 2.0 and at mesh 1.0 differ by at most 0.23 % in B (the FEM flux of mesh 2.0 is 0.17 %
above mesh 1.0's at 0.2 A and within 0.05 % above 0.6 A); mesh 2.0 is 1.4x faster.
Units: SI throughout (H in A/m, B in T, Psi in Wb, i in A, x in m).
"""

from __future__ import annotations

import time
from typing import NamedTuple

import nlopt
import numpy as np

from ..errors import SolenoidError
from ..field import BHCurve
from .flux_model import FluxModel
from .parametrization import (
    constraint_residuals,
    constraint_values,
    fit_to_curve,
    scaled_curve,
    smoothness_matrix,
)
from .result import IdentificationResult
from .uncertainty import FLUX_NOISE_FLOOR, identified_range

__all__ = [
    "NLOPT_CODES",
    "DEFAULT_MESH_SIZE",
    "DEFAULT_N_CURRENTS",
    "PRIOR_RIDGE",
    "DEFAULT_REGULARIZATION",
    "IDENTIFIABLE_SENSITIVITY",
    "STAGE2_GAIN",
    "nlopt_code_name",
    "choose_currents",
    "identify_bh",
    "projected_lm",
    "LMResult",
]

#: nlopt's return codes in words (``nlopt.opt.last_optimize_result()``).
NLOPT_CODES = {
    1: "SUCCESS", 2: "STOPVAL_REACHED", 3: "FTOL_REACHED", 4: "XTOL_REACHED", 5: "MAXEVAL_REACHED",
    6: "MAXTIME_REACHED", -1: "FAILURE", -2: "INVALID_ARGS", -3: "OUT_OF_MEMORY", -4: "ROUNDOFF_LIMITED",
    -5: "FORCED_STOP",
}

#: Default FEM mesh size of the identification (see the module docstring: bias vs mesh 1.0 < 0.2 %).
DEFAULT_MESH_SIZE = 2.0
#: Default number of measured currents the fit uses (equally spaced from imax/10 to imax).
DEFAULT_N_CURRENTS = 10
#: Relative weight, inside the prior, of the parameters' distance to stage 1's (beside the curvature).
PRIOR_RIDGE = 0.3
#: Weight of the smoothness prior (second differences of ln chi relative to the start curve).
DEFAULT_REGULARIZATION = 3e-3
#: A node of the log-H grid counts as identified when an e-fold change of chi there moves the
#: flux at some current by more than this fraction of the peak flux.
IDENTIFIABLE_SENSITIVITY = 0.02


def nlopt_code_name(code: int) -> str:
    """nlopt's integer return code as its name (e.g. 4 -> ``XTOL_REACHED``)."""
    return NLOPT_CODES.get(int(code), f"UNKNOWN_{int(code)}")

_LSQ_STATUS = {-1: "improper input", 0: "evaluation budget reached", 1: "gradient small (gtol)",
               2: "cost converged (ftol)", 3: "step small (xtol)", 4: "ftol and xtol"}
#: Stage 2 replaces stage 1 only when it lowers the flux RMS below this fraction of stage 1's.
STAGE2_GAIN = 0.7


#: :func:`projected_lm`'s absolute ``min_decrease`` ends a fit only where it is also below this share of the cost:
#: a fit already inside its noise (cost a few sigma^2: few points, wide sigma) is then judged by ``ftol`` alone.
#: Measured: a data-starved campaign (random-2, heating + hysteresis, one flux stroke at 3 % sigma; seed 110 of
#: ``bench_identify_campaigns.py --fresh``) stopped its weaker-prior fit at cost 1.8 after one step of 0.09 sigma^2
#: with F 5.3 % off the truth; run on (relative decrease 1e-4), 2.1 %.
MIN_DECREASE_SHARE = 0.01


class LMResult:
    def __init__(self, x, status, message, nfev):
        self.x, self.status, self.message, self.nfev = x, status, message, nfev


def projected_lm(residual, jac, x0, lo, hi, max_nfev: int, ftol: float = 1e-4, project=None,
                 max_step: float | None = None, min_decrease: float = 0.0, solve_step=None,
                 futile=None) -> LMResult:
    """Levenberg-Marquardt with the step projected onto the bounds (a box), or by ``project(x)``
    when given: one residual evaluation (FEM sweep) per trial step and one Jacobian (adjoint solves)
    per accepted step. Status as scipy's least_squares: 0 budget, 2 cost converged (relative
    decrease < ftol, or an absolute decrease below ``min_decrease`` that is also below :data:`MIN_DECREASE_SHARE`
    of the cost: for residuals in units of their standard deviation, a step that lowers the cost by less than
    ``min_decrease`` sigma^2 changes nothing the data can tell).

    Damping (Marquardt's diagonal scaling) adapted by the gain ratio rho (actual over predicted
    decrease of the cost, Nielsen's rule: mu *= max(1/3, 1 - (2 rho - 1)^3) after a success, mu *= 2^k
    after the k-th failure in a row). ``max_step`` caps the largest parameter change of a step (in
    the parameters' units): a fit far from its start does not spend its first evaluations on steps
    the linearization cannot take: it is a trust radius, halved (below the failed step) after a
    failure, doubled (up to 4 ``max_step``) after a step the linear model predicted well (rho > 0.75).
    ``solve_step(x, J, r, damping, radius)``, when given, returns the damped step itself (a constrained
    subproblem, e.g. :func:`~.cone_step.cone_step`, within the trust radius, None without one) in place of the
    unconstrained ``-(J^T J + diag(damping))^-1 J^T r``. ``futile(r, decrease)``, when given, is asked after every
    accepted step (its residuals and the cost it took off): True stops the fit there (status 4), for a caller that
    knows the fit cannot reach what it is run for (:data:`~.joint.FUTILE_STEPS`)."""
    if project is None:
        def project(v):
            return np.clip(v, lo, hi)
    x = project(np.asarray(x0, dtype=float))
    r = residual(x)
    cost = float(r @ r)
    J = jac(x)
    mu, nu = 1e-3, 2.0
    radius = max_step
    nfev = 1
    while nfev < max_nfev:
        A = J.T @ J
        dA = np.diag(A).copy() + 1e-12
        if solve_step is None:
            step = -np.linalg.solve(A + mu * np.diag(dA), J.T @ r)
        else:
            step = solve_step(x, J, r, mu * dA, radius)
        big = float(np.max(np.abs(step))) if step.size else 0.0
        if radius is not None and big > radius:
            step *= radius / big
        xn = project(x + step)
        d = xn - x
        pred = cost - float(np.sum((r + J @ d) ** 2))  # the linear model's decrease
        rn = residual(xn)
        nfev += 1
        cn = float(rn @ rn)
        if cn < cost:
            done = (cost - cn) < max(ftol * cost, min(min_decrease, MIN_DECREASE_SHARE * cost))
            rho = (cost - cn) / pred if pred > 0 else 0.0
            cost_before = cost
            x, r, cost = xn, rn, cn
            mu = max(mu * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 1e-8)
            nu = 2.0
            if radius is not None and rho > 0.75:
                radius = min(max(radius, 2.0 * float(np.max(np.abs(d)))), 4.0 * max_step)
            if done:
                return LMResult(x, 2, "cost converged (ftol)", nfev)
            if futile is not None and futile(rn, cost_before - cn):
                return LMResult(x, 4, "stopped: cannot reach its target (futile)", nfev)
            J = jac(x)
        else:
            mu *= nu
            nu *= 2.0
            if radius is not None:
                radius = 0.5 * min(radius, max(float(np.max(np.abs(d))), 1e-6))
            if mu > 1e8:
                return LMResult(x, 3, "step small (xtol)", nfev)
    return LMResult(x, 0, "evaluation budget reached", nfev)


def choose_currents(i_A, psi_Wb, n: int = DEFAULT_N_CURRENTS) -> tuple[np.ndarray, np.ndarray]:
    """The currents [A] the fit uses, and the measured flux there (linear interpolation).

    Spaced geometrically from 1/40 of the peak to the peak (at least three): as many points per factor of
    current at low field (where the flux is most sensitive to the initial permeability) as around the knee.
    (Evenly spaced above 1/10 of the peak, as before, a campaign's four strokes at five currents each had
    no point between 0.1 and 0.55 of the peak, where the steel's knee sits at the longer strokes.)
    """
    i_A = np.asarray(i_A, dtype=float)
    psi_Wb = np.asarray(psi_Wb, dtype=float)
    imax = float(np.max(i_A))
    frac = np.geomspace(0.025, 1.0, max(n, 3))
    i_sel = frac * imax
    i_sel = i_sel[i_sel >= np.min(i_A[i_A > 0])]
    return i_sel, np.interp(i_sel, i_A, psi_Wb)


def identify_bh(i_A, psi_Wb, x_m: float, geometry, start_curve: BHCurve, mesh_size: float = DEFAULT_MESH_SIZE,
                max_nfev: int = 15, m: int = 13, method: str = "gn", regularization: float = DEFAULT_REGULARIZATION,
                progress=None, max_eval_auglag: int = 400, stage2: bool = True, sigma_Wb=None) -> IdentificationResult:
    """Fit B(H) so that the FEM's Psi(i) at gap ``x_m`` matches the measured one (paper sec. 4).

    Parameters
    ----------
    i_A, psi_Wb : array-like, shape (n,)
        Measured commutation curve: currents [A] (> 0; zeros are dropped) and flux linkage [Wb].
    x_m : float
        The gap of the measurement [m].
    geometry : Geometry
    start_curve : BHCurve
        Start (the literature curve); its shape also fills the H range the data do not constrain.
    mesh_size : float
        FEM mesh size (default :data:`DEFAULT_MESH_SIZE`).
    max_nfev : int
        ``gn``: budget of residual evaluations of the full fit (one FEM sweep each; the Jacobians
        are adjoint solves).
    m : int
        Nodes of the log-H grid (parameters: m + 1).
    method : {"gn", "auglag"}
        ``gn`` (default): (1) scale the start curve's polarization and stretch it along H (two
        parameters, :func:`scaled_curve`, scipy ``least_squares``), then (2) projected
        Levenberg-Marquardt (:func:`projected_lm`) on all parameters of :class:`SusceptibilityModel`, residuals =
        flux errors relative to the peak flux plus a weak prior holding the curvature of ln chi
        near stage 1's; adjoint Jacobians in both stages. ``auglag``: the paper's method, nlopt
        AUGLAG around LN_BOBYQA minimising the mean absolute flux error (eq. 7 as meant) under the
        constraints of :func:`constraint_values`, from the start curve.
    regularization : float
        Weight of the prior of stage 2 (units of the relative flux residual per unit of ln chi
        curvature).
    progress : callable, optional
        Called as ``progress(sweeps, rms_rel)`` after every FEM sweep.
    max_eval_auglag : int
        ``auglag``: budget of objective evaluations (one FEM sweep each).
    stage2 : bool
        ``gn``: allow stage 2 (it runs only when stage 1 leaves a flux RMS above
        :data:`FLUX_NOISE_FLOOR` and is kept only when it lowers the RMS by :data:`STAGE2_GAIN`).
    sigma_Wb : array-like, shape (n,), optional
        Uncertainty of each measured flux [Wb] beyond the noise floor, e.g. half the hysteresis
        width (the commutation curve is a biased estimate of the magnetization curve where the loop
        is wide). Residuals are weighted by s0 / sqrt(s0^2 + sigma^2), s0 = floor * peak flux.

    Raises
    ------
    SolenoidError
        Mismatched or too few points, an unknown method.
    """
    from scipy.optimize import least_squares  # heavy (about 0.5 s): loaded on first use

    i_A, psi_meas, sig = _measured_points(i_A, psi_Wb, sigma_Wb, method)
    model0, theta_lit = fit_to_curve(start_curve, m=m)
    scale = float(np.max(np.abs(psi_meas)))
    t0 = time.perf_counter()
    fm = FluxModel(geometry, x_m, i_A, model0.curve, mesh_size, start_curve)
    flux_res = _FluxResiduals(fm, psi_meas, scale, sig, progress)
    # the error before: the start curve itself
    fm.curve_fn = lambda p: start_curve
    psi0 = fm.psi(np.zeros(1))
    extra: dict = {}
    if method == "gn":
        fitted = _fit_gn(flux_res, start_curve, m, max_nfev, regularization, stage2, extra, least_squares)
    else:
        fitted = _fit_auglag(flux_res, model0, theta_lit, m, max_eval_auglag, extra)
    psi1 = fm.psi(fitted.theta)
    wall = time.perf_counter() - t0
    return _result(flux_res, fitted, start_curve, method, psi0, psi1, wall, x_m, mesh_size, extra)


def _measured_points(i_A, psi_Wb, sigma_Wb, method: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The measured points :func:`identify_bh` fits, checked: positive currents ascending, their fluxes and
    uncertainties."""
    i_A = np.asarray(i_A, dtype=float)
    psi_meas = np.asarray(psi_Wb, dtype=float)
    if i_A.shape != psi_meas.shape or i_A.ndim != 1 or np.count_nonzero(i_A > 0) < 3:
        raise SolenoidError(f"identify_bh needs matching 1-D arrays with at least 3 positive currents, got "
                            f"shapes {i_A.shape} and {psi_meas.shape}")
    if not (np.all(np.isfinite(i_A)) and np.all(np.isfinite(psi_meas))):
        raise SolenoidError("identify_bh: currents and fluxes must be finite")
    if method not in ("gn", "auglag"):
        raise SolenoidError(f"identify_bh: unknown method {method!r} (use 'gn' or 'auglag')")
    sig = np.zeros_like(i_A) if sigma_Wb is None else np.abs(np.asarray(sigma_Wb, dtype=float))
    if sig.shape != i_A.shape or not np.all(np.isfinite(sig)):
        raise SolenoidError(f"identify_bh: sigma_Wb must be finite with shape {i_A.shape}")
    keep = i_A > 0
    i_A, psi_meas, sig = i_A[keep], psi_meas[keep], sig[keep]
    order = np.argsort(i_A)
    return i_A[order], psi_meas[order], sig[order]


class _FluxResiduals:
    """The fit's flux residuals: FEM minus measured flux relative to the peak flux, weighted (one FEM sweep per
    call; the unweighted RMS of each is appended to ``history`` and reported to ``progress``)."""

    def __init__(self, fm: FluxModel, psi_meas: np.ndarray, scale: float, sig: np.ndarray, progress):
        self.fm, self.psi_meas, self.scale, self.progress = fm, psi_meas, scale, progress
        s0 = FLUX_NOISE_FLOOR
        self.weights = s0 / np.sqrt(s0**2 + (sig / scale) ** 2)
        self.history: list = []

    def __call__(self, theta):
        r = (self.fm.psi(theta) - self.psi_meas) / self.scale
        self.history.append(float(np.sqrt(np.mean(r**2))))
        if self.progress is not None:
            self.progress(self.fm.sweeps, self.history[-1])
        return r * self.weights

    def wrms(self, r):
        """Weighted RMS of weighted residuals ``r``."""
        return float(np.sqrt(np.sum(r**2) / np.sum(self.weights**2)))


class _Fitted(NamedTuple):
    """What a method of :func:`identify_bh` found: the parameterization, the start and final parameters, the
    final curve, the status in words and whether it counts as a success."""

    model: object
    theta0: np.ndarray
    theta: np.ndarray
    curve: BHCurve
    status: str
    success: bool


def _fit_gn(flux_res: _FluxResiduals, start_curve: BHCurve, m: int, max_nfev: int, regularization: float,
            stage2: bool, extra: dict, least_squares) -> _Fitted:
    """Method ``gn`` of :func:`identify_bh`: stage 1 (scale and stretch), then stage 2 (all parameters) if it
    pays; ``extra`` gains ``stage1`` and ``stage2``."""
    fm, weights, scale, wrms = flux_res.fm, flux_res.weights, flux_res.scale, flux_res.wrms
    # stage 1: polarization scale and H stretch of the start curve
    fm.curve_fn = lambda p: scaled_curve(start_curve, p[0], p[1])
    st1 = least_squares(flux_res, np.zeros(2), jac=lambda p: fm.jacobian(p, h=1e-3) * (weights / scale)[:, None],
                        bounds=([np.log(0.7), np.log(0.2)], [np.log(1.3), np.log(5.0)]), method="trf",
                        x_scale=1.0, max_nfev=12, xtol=1e-4, ftol=1e-4)
    curve1 = scaled_curve(start_curve, *st1.x, name="identified")
    rms_stage1 = wrms(flux_res(st1.x))
    extra["stage1"] = {"polarization_scale": float(np.exp(st1.x[0])), "H_stretch": float(np.exp(st1.x[1])),
                       "rms_rel_peak": rms_stage1, "sweeps": fm.sweeps}
    model, theta1 = fit_to_curve(curve1, m=m)
    lo, hi = model.bounds()
    theta1 = np.clip(theta1, lo + 1e-9, hi - 1e-9)
    theta0 = theta1
    status = "stage 1 (scale and stretch): " + _LSQ_STATUS.get(st1.status, st1.message)
    success = bool(st1.status > 0)
    final_curve, theta = curve1, theta1
    if stage2 and rms_stage1 > FLUX_NOISE_FLOOR and max_nfev > 0:
        # stage 2: every parameter; prior = curvature of ln chi and the parameters near stage 1's
        fm.curve_fn = model.curve
        D = np.vstack([smoothness_matrix(model), PRIOR_RIDGE * np.eye(len(theta1))])
        prior0 = D @ theta1
        w = float(regularization)

        def residual(theta):
            return np.concatenate([flux_res(theta), w * (D @ theta - prior0)])

        def jac(theta):
            return np.vstack([fm.jacobian(theta) * (weights / scale)[:, None], w * D])

        res = projected_lm(residual, jac, theta1, lo, hi, max_nfev)
        rms2 = wrms(flux_res(res.x))
        extra["stage2"] = {"rms_rel_peak": rms2, "accepted": bool(rms2 < STAGE2_GAIN * rms_stage1),
                           "status": _LSQ_STATUS.get(res.status, res.message)}
        if rms2 < STAGE2_GAIN * rms_stage1:
            final_curve, theta = model.curve(res.x), res.x
            status = "stage 2 (all parameters): " + _LSQ_STATUS.get(res.status, res.message)
            success = bool(res.status >= 0)
    fm.curve_fn = lambda p: final_curve
    return _Fitted(model, theta0, theta, final_curve, status, success)


def _fit_auglag(flux_res: _FluxResiduals, model, theta_lit: np.ndarray, m: int, max_eval_auglag: int,
                extra: dict) -> _Fitted:
    """Method ``auglag`` of :func:`identify_bh` (the paper's): nlopt AUGLAG around LN_BOBYQA from the start
    curve; the best feasible point seen if the optimizer ends elsewhere."""
    fm, weights = flux_res.fm, flux_res.weights
    lo, hi = model.bounds()
    theta0 = np.clip(theta_lit, lo + 1e-9, hi - 1e-9)
    fm.curve_fn = model.curve
    P = model.n_params
    best = {"f": np.inf, "x": theta0.copy()}

    def objective(theta, grad):
        f = float(np.sum(np.abs(flux_res(np.asarray(theta)))) / np.sum(weights))
        extra.setdefault("auglag_mae_at_start_parameters", f)
        if f < best["f"] and constraint_values(model, theta).max() <= 1e-6:
            best.update(f=f, x=np.array(theta))
        return f

    def constraints(result, theta, grad):
        result[:] = constraint_values(model, theta)

    opt = nlopt.opt(nlopt.AUGLAG, P)
    local = nlopt.opt(nlopt.LN_BOBYQA, P)
    local.set_xtol_rel(1e-4)
    opt.set_local_optimizer(local)
    box_lo = np.where(np.isfinite(lo), lo, -10.0)
    box_hi = np.where(np.isfinite(hi), hi, 10.0)
    box_lo[1:m], box_hi[1:m] = -10.0, 10.0  # the monotonicity is a constraint here, not a bound
    box_lo[m], box_hi[m] = -6.0, 0.0
    opt.set_lower_bounds(box_lo)
    opt.set_upper_bounds(box_hi)
    opt.set_min_objective(objective)
    opt.add_inequality_mconstraint(constraints, np.full(m, 1e-6))
    opt.set_maxeval(int(max_eval_auglag))
    opt.set_xtol_rel(1e-4)
    opt.set_initial_step(0.05)
    try:
        theta = np.asarray(opt.optimize(np.clip(theta0, box_lo, box_hi)))
        code = opt.last_optimize_result()
    except nlopt.RoundoffLimited:
        theta, code = best["x"], -4
    f_end = np.sum(np.abs(flux_res(theta))) / np.sum(weights)
    if constraint_values(model, theta).max() > 1e-6 or best["f"] < f_end:
        theta = best["x"]  # the best feasible point seen
    final_curve = model.curve(theta)
    fm.curve_fn = model.curve
    return _Fitted(model, theta0, theta, final_curve, nlopt_code_name(code), code > 0)


def _result(flux_res: _FluxResiduals, fitted: _Fitted, start_curve: BHCurve, method: str, psi0: np.ndarray,
            psi1: np.ndarray, wall: float, x_m: float, mesh_size: float, extra: dict) -> IdentificationResult:
    """The :class:`IdentificationResult` of :func:`identify_bh`: errors before and after, the identified H range
    and the uncertainty of B (sensitivities in the nodal parameterization)."""
    fm, psi_meas, scale, weights = flux_res.fm, flux_res.psi_meas, flux_res.scale, flux_res.weights
    model, theta, i_A = fitted.model, fitted.theta, fm.i_A
    e0, e1 = (psi0 - psi_meas) / scale, (psi1 - psi_meas) / scale
    fm.curve_fn = model.curve  # sensitivities in the nodal parameterization (a close fit of the final curve)
    J = fm.jacobian(theta) * (weights / scale)[:, None]
    H_steel, vol = fm.steel_H(theta, float(i_A.max()))
    order_h = np.argsort(H_steel)
    cum = np.cumsum(vol[order_h]) / vol.sum()
    H_max = float(H_steel[order_h][np.searchsorted(cum, 0.995)])  # the 0.5 % most loaded volume aside
    rms1 = float(np.sqrt(np.mean(e1**2)))
    rng, H_u, unc = identified_range(model, theta, J, flux_res.wrms(e1 * weights), H_max)
    extra["weights"] = [float(v) for v in weights]
    extra["B_uncertainty"] = {"H_A_per_m": [float(v) for v in H_u], "rel_1sigma": [float(v) for v in unc]}
    return IdentificationResult(
        curve=fitted.curve, start_curve=start_curve, theta=theta, theta_start=fitted.theta0,
        model=model, method=method, success=fitted.success, status=fitted.status, fem_solves=fm.solves,
        newton_steps=fm.newton_steps, adjoint_solves=fm.adjoint_solves, sweeps=fm.solves / len(i_A),
        equivalent_sweeps=fm.equivalent_sweeps, wall_time_s=wall, x_m=float(x_m), i_A=i_A, psi_meas_Wb=psi_meas,
        psi_before_Wb=psi0, psi_after_Wb=psi1,
        mae_before=float(np.mean(np.abs(e0))), rms_before=float(np.sqrt(np.mean(e0**2))),
        mae_after=float(np.mean(np.abs(e1))), rms_after=rms1, mesh_size=float(mesh_size),
        identified_H_range_A_per_m=rng, H_max_steel_A_per_m=H_max,
        constraint_residuals=constraint_residuals(model, theta), history=flux_res.history, extra=extra)
