r"""Identify the steel's initial magnetization curve from measured flux (paper section 4).

Parameterization (physical by construction, paper 4.2)
------------------------------------------------------
The differential susceptibility :math:`\chi(H) = (dB/dH)/\mu_0 - 1` is described on a grid of
``m`` field strengths equally spaced in :math:`u = \ln H`: :math:`\ln\chi_j = c + \sum_{k\le j} d_k`
with increments :math:`d_k \ge 0` up to a fixed peak index and :math:`d_k \le 0` after it, and a
last slope :math:`\le -1.2` (in :math:`\ln\chi` per :math:`\ln H`) that continues beyond the grid.
So :math:`\chi` rises to one maximum (the inflection point of B(H)) and then falls towards 0, i.e.
the permeability towards :math:`\mu_0`, and :math:`B = \mu_0 H + \mu_0\int_0^H\chi\,dh` rises and
saturates: the paper's constraints become simple bounds on the increments. Below the first node
:math:`\chi` is constant (the initial permeability).

Fit (:func:`identify_bh`)
-------------------------
Residuals: FEM flux minus measured commutation curve Psi(i) at one stroke, relative to the
measured peak flux, weighted down where the hysteresis loop is wide (there the branch mean is a
biased estimate of the magnetization curve). Error reported: the mean absolute flux error (the
evident meaning of the paper's garbled eq. 7) and the RMS, before (start curve) and after.

- ``gn`` (default): stage 1 scales the start curve's polarization and stretches it along H
  (:func:`scaled_curve`, 2 parameters); stage 2, only when stage 1 leaves a flux RMS above the
  noise floor, runs a projected Levenberg-Marquardt on all parameters with a weak prior and is
  kept only if it lowers the RMS clearly. Jacobians by the adjoint method (:class:`_FluxModel`):
  one linear solve per current at the converged solution, about a third of a warm sweep for any
  number of parameters.
- ``auglag``: the paper's method, nlopt AUGLAG around LN_BOBYQA (derivative-free) on the mean
  absolute flux error with the constraints as inequalities (:func:`constraint_values`); the
  return code is reported as its nlopt name (:data:`NLOPT_CODES`).

The H range the data identify follows from a linearized Bayesian analysis
(:func:`B_uncertainty`); outside it the curve keeps the start curve's shape.

Mesh: default :data:`DEFAULT_MESH_SIZE` = 2.0. The curve identified from the PS45 demo campaign
at mesh 2.0 and at mesh 1.0 differ by at most 0.23 % in B (the FEM flux of mesh 2.0 is 0.17 %
above mesh 1.0's at 0.2 A and within 0.05 % above 0.6 A); mesh 2.0 is 1.4x faster.
Units: SI throughout (H in A/m, B in T, Psi in Wb, i in A, x in m).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import RecordingError, SolenoidError
from ..field import MU_0, MU_R_MAX, BHCurve

#: Last log-log slope of chi: saturation law chi ~ H^-1.2 or faster (keeps B bounded-slope).
MAX_TAIL_SLOPE = -1.2


@dataclass(frozen=True)
class SusceptibilityModel:
    """The unimodal log-susceptibility parameterization on a log-H grid.

    Attributes
    ----------
    H_nodes : ndarray, shape (m,)
        Grid of field strengths [A/m], log-spaced.
    peak : int
        Index of the node where chi peaks (fixed from the start curve).
    """

    H_nodes: np.ndarray
    peak: int

    @property
    def n_params(self) -> int:
        return len(self.H_nodes) + 1  # c, d_1 .. d_{m-1}, tail slope

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the parameter vector (c, d_1..d_{m-1}, tail)."""
        m = len(self.H_nodes)
        lo = np.full(m + 1, -np.inf)
        hi = np.full(m + 1, np.inf)
        lo[0], hi[0] = np.log(1.0), np.log(1e5)  # chi at the first node: 1 .. 1e5
        for k in range(1, m):
            if k <= self.peak:
                lo[k], hi[k] = 0.0, 10.0
            else:
                lo[k], hi[k] = -10.0, 0.0
        lo[m], hi[m] = -6.0, MAX_TAIL_SLOPE
        return lo, hi

    def log_chi_nodes(self, theta: np.ndarray) -> np.ndarray:
        return theta[0] + np.concatenate([[0.0], np.cumsum(theta[1 : len(self.H_nodes)])])

    def chi(self, H: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """Differential susceptibility at H [A/m] (H >= 0)."""
        u = np.log(np.maximum(H, 1e-12))
        un = np.log(self.H_nodes)
        lc = self.log_chi_nodes(theta)
        inside = np.interp(u, un, lc)  # constant below the first node
        tail = lc[-1] + theta[-1] * (u - un[-1])
        # clipped so that parameters outside the bounds (AUGLAG explores them) still give a curve
        # the FEM can use: 0 < chi < MU_R_MAX
        return np.exp(np.clip(np.where(u > un[-1], tail, inside), -30.0, np.log(MU_R_MAX - 1.0)))

    def table(self, theta: np.ndarray, H_max: float = 2e6, n: int = 160) -> tuple[np.ndarray, np.ndarray]:
        """(H [A/m], B [T]) table of the curve, integrated exactly on a fine log grid."""
        H = np.concatenate([[0.0], np.geomspace(self.H_nodes[0] * 1e-2, H_max, n - 1)])
        Hf = np.concatenate([[0.0], np.geomspace(self.H_nodes[0] * 1e-3, H_max, 40 * n)])
        c = self.chi(Hf, theta)
        J = np.concatenate([[0.0], np.cumsum(0.5 * (c[1:] + c[:-1]) * np.diff(Hf))])  # int chi dh
        B = MU_0 * (H + np.interp(H, Hf, J))
        return H, B

    def curve(self, theta: np.ndarray, name: str = "identified") -> BHCurve:
        """The :class:`BHCurve` of a parameter vector, built directly (no smoothing fit needed: the
        differential reluctivity 1/(mu0 (1 + chi)) is known exactly at the knots; physical by
        construction, so no check). About 1 ms."""
        H, B = self.table(theta)
        nu = 1.0 / (MU_0 * (1.0 + self.chi(H, theta)))
        nu[-1] = 1.0 / MU_0  # continues with slope mu0 beyond the last knot
        Hk = np.concatenate([[0.0], np.cumsum(0.5 * (nu[1:] + nu[:-1]) * np.diff(B))])
        return BHCurve(B_T=B, nu_d=nu, H_A_per_m=Hk, table_H_A_per_m=H, table_B_T=B, name=name)


def fit_to_curve(curve: BHCurve, m: int = 13, H_range=(50.0, 2e5)) -> tuple[SusceptibilityModel, np.ndarray]:
    """The parameterization and parameters closest to a given curve (e.g. the literature one).

    Start: least squares on ln chi at the nodes under the bounds (the peak index is where the
    curve's chi peaks); then bounded least squares on B(H) itself at 200 field strengths.
    """
    from scipy.optimize import least_squares, lsq_linear

    H_nodes = np.geomspace(*H_range, m)
    B = curve.B_of_H(H_nodes)
    chi = np.maximum(curve.mu_r_differential(B) - 1.0, 1e-6)
    peak = int(np.argmax(chi))
    model = SusceptibilityModel(H_nodes, peak)
    # ln chi_j = c + sum_{k<=j} d_k : a lower-triangular linear system for (c, d)
    A = np.zeros((m, m))
    A[:, 0] = 1.0
    for j in range(1, m):
        A[j, 1 : j + 1] = 1.0
    lo, hi = model.bounds()
    sol = lsq_linear(A, np.log(chi), bounds=(lo[:m], hi[:m]))
    # tail slope from the curve's chi beyond the last node
    H2 = H_nodes[-1] * 4
    chi2 = max(curve.mu_r_differential(curve.B_of_H(H2)) - 1.0, 1e-9)
    tail = np.clip(np.log(chi2 / chi[-1]) / np.log(4.0), lo[m], hi[m])
    theta = np.clip(np.concatenate([sol.x, [tail]]), lo + 1e-9, hi - 1e-9)
    Hs = np.geomspace(H_range[0] / 5, H_range[1] * 5, 200)
    Bs = curve.B_of_H(Hs)

    def res(th):
        H, B = model.table(th)
        return np.interp(Hs, H, B) / Bs - 1.0

    theta = least_squares(res, theta, bounds=(lo, hi), method="trf", x_scale=1.0).x
    return model, theta


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


@dataclass
class IdentificationResult:
    """Outcome of :func:`identify_bh` (SI units).

    Attributes
    ----------
    curve : BHCurve
        The identified curve (physical by construction).
    start_curve : BHCurve
        The start (literature) curve in the same parameterization.
    method : str
        ``"gn"`` (bounded Gauss-Newton with adjoint Jacobians) or ``"auglag"`` (nlopt AUGLAG around
        LN_BOBYQA, derivative-free, the paper's method).
    status : str
        The optimizer's outcome in words (nlopt's code name for ``auglag``).
    fem_solves : int
        Nonlinear operating-point solves (Newton, warm-started).
    newton_steps, adjoint_solves : int
        Linear solves inside Newton and for adjoint Jacobians (one per current per Jacobian).
    sweeps : float
        Full Psi(i) sweeps (nonlinear solves / currents).
    equivalent_sweeps : float
        All linear solves (Newton + adjoint) divided by the linear solves of the first sweep: the
        cost in units of one full Psi(i) sweep from a warm start of the previous current.
    mae_*, rms_* : float
        Mean absolute and RMS flux error relative to the measured peak flux (paper eq. 7 as meant).
    identified_H_range_A_per_m : (float, float)
        The H range the measurement constrains (outside it the curve is shaped by the constraints
        and the start curve's shape).
    constraint_residuals : dict
        Largest violation of each physical constraint by the final parameters (0 = satisfied).
    """

    curve: BHCurve
    start_curve: BHCurve
    theta: np.ndarray
    theta_start: np.ndarray
    model: SusceptibilityModel
    method: str
    success: bool
    status: str
    fem_solves: int
    newton_steps: int
    adjoint_solves: int
    sweeps: float
    equivalent_sweeps: float
    wall_time_s: float
    x_m: float
    i_A: np.ndarray
    psi_meas_Wb: np.ndarray
    psi_before_Wb: np.ndarray
    psi_after_Wb: np.ndarray
    mae_before: float
    rms_before: float
    mae_after: float
    rms_after: float
    mesh_size: float
    identified_H_range_A_per_m: tuple = ()
    H_max_steel_A_per_m: float = float("nan")
    constraint_residuals: dict = field(default_factory=dict)
    history: list = field(default_factory=list)
    extra: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """JSON-able summary (the report's ``identification.json``)."""
        lo, hi = self.identified_H_range_A_per_m
        out = {
            "method": self.method,
            "success": self.success,
            "status": self.status,
            "x_mm": self.x_m * 1e3,
            "mesh_size": self.mesh_size,
            "currents_A": [float(v) for v in self.i_A],
            "fem_solves": self.fem_solves,
            "newton_steps": self.newton_steps,
            "adjoint_solves": self.adjoint_solves,
            "sweeps": self.sweeps,
            "equivalent_sweeps": self.equivalent_sweeps,
            "wall_time_s": self.wall_time_s,
            "flux_error_before": {"mae_rel_peak": self.mae_before, "rms_rel_peak": self.rms_before},
            "flux_error_after": {"mae_rel_peak": self.mae_after, "rms_rel_peak": self.rms_after},
            "identified_H_range_A_per_m": [float(lo), float(hi)],
            "H_max_steel_A_per_m": self.H_max_steel_A_per_m,
            "constraint_residuals": self.constraint_residuals,
            "parameters": [float(v) for v in self.theta],
            "H_nodes_A_per_m": [float(v) for v in self.model.H_nodes],
            "peak_node": self.model.peak,
        }
        out.update(self.extra)
        w = np.asarray(self.extra.get("weights", np.ones(len(self.i_A))), dtype=float)
        peak = float(np.max(np.abs(self.psi_meas_Wb)))
        for key, psi in (("flux_error_before", self.psi_before_Wb), ("flux_error_after", self.psi_after_Wb)):
            e = (psi - self.psi_meas_Wb) / peak * w
            out[key]["rms_weighted_rel_peak"] = float(np.sqrt(np.sum(e**2) / np.sum(w**2)))
        return out


def constraint_values(model: SusceptibilityModel, theta) -> np.ndarray:
    """The paper's constraints (sec. 4.2) as values c <= 0 on the parameters.

    Rising ln chi up to the peak node (-d_k <= 0), falling after it (d_k <= 0), and a saturation
    tail falling at least as fast as H^-1.2 (tail - MAX_TAIL_SLOPE <= 0).
    """
    theta = np.asarray(theta, dtype=float)
    m = len(model.H_nodes)
    d = theta[1:m]
    k = np.arange(1, m)
    return np.concatenate([np.where(k <= model.peak, -d, d), [theta[m] - MAX_TAIL_SLOPE]])


def constraint_residuals(model: SusceptibilityModel, theta) -> dict:
    """Largest violation of each constraint group [in ln chi units] (0 when all hold)."""
    c = constraint_values(model, theta)
    m = len(model.H_nodes)
    k = np.arange(1, m)
    rise, fall = c[:-1][k <= model.peak], c[:-1][k > model.peak]
    return {
        "permeability_rises_to_inflection": float(max(0.0, rise.max(initial=0.0))),
        "permeability_falls_after_inflection": float(max(0.0, fall.max(initial=0.0))),
        "saturation_tail": float(max(0.0, c[-1])),
    }


class _FluxModel:
    """Psi(i) at one gap for a parameter vector, by warm-started FEM solves, and its Jacobian
    d Psi / d theta by one adjoint linear solve per current (counts every solve).

    Adjoint: at the converged solution u_k of current i_k the residual R(u, theta) = 0, so
    K_t du/dtheta = -dR/dtheta and dPsi/dtheta = w . du/dtheta = -lambda . dR/dtheta with
    K_t lambda = w (K_t is symmetric; w = psi_weights). dR/dtheta only involves the steel's
    reluctivity: dR_j/dtheta = int (grad phi_j . grad u) dnu/dtheta / r dA, hence
    dPsi/dtheta = -int (grad lambda . grad u) dnu/dtheta / r dA over the steel, with dnu/dtheta
    at the solution's B^2 by central differences of the (1 ms) curve. Checked against finite
    differences of full sweeps in the tests.
    """

    def __init__(self, geometry, x_m, i_A, curve_fn, mesh_size, start_curve):
        from ..field import Solver

        self.solver = Solver(geometry, start_curve, mesh_size)
        self.x_m = float(x_m)
        self.i_A = np.asarray(i_A, dtype=float)
        self._version = 0
        self.curve_fn = curve_fn  # parameters -> BHCurve (switchable between stages)
        self.u = [None] * len(self.i_A)
        self.solves = 0
        self.newton_steps = 0
        self.adjoint_solves = 0
        self.first_sweep_steps = 0
        self.sweeps = 0
        self._cache: tuple = (None, None, None)

    @property
    def curve_fn(self):
        """parameters -> BHCurve; setting it invalidates the cache."""
        return self._curve_fn

    @curve_fn.setter
    def curve_fn(self, fn):
        self._curve_fn = fn
        self._version += 1

    def psi(self, theta) -> np.ndarray:
        """Psi [Wb] at the currents for parameters ``theta`` (cached for the last theta)."""
        theta = np.asarray(theta, dtype=float)
        key = (self._version, theta.tobytes())
        if self._cache[0] == key:
            return self._cache[1].copy()
        self.solver.material = self.curve_fn(theta)
        out = np.empty(len(self.i_A))
        us = []
        u_prev = None
        steps = 0
        for k, i in enumerate(self.i_A):
            start = self.u[k] if self.u[k] is not None else u_prev
            sol = self.solver.solve(float(i), self.x_m, u0=start)
            self.solves += 1
            steps += max(sol.newton_iterations, 1)
            out[k] = sol.psi_Wb
            u_prev = sol.u
            us.append(sol.u)
        if self.sweeps == 0:
            self.first_sweep_steps = steps
        self.newton_steps += steps
        self.u = us
        self.sweeps += 1
        self._cache = (key, out.copy(), us)
        return out

    @property
    def equivalent_sweeps(self) -> float:
        return (self.newton_steps + self.adjoint_solves) / max(self.first_sweep_steps, 1)

    def jacobian(self, theta, h: float = 1e-4) -> np.ndarray:
        """d Psi / d theta [Wb per parameter unit], shape (currents, parameters)."""
        from threadpoolctl import threadpool_limits

        theta = np.asarray(theta, dtype=float)
        self.psi(theta)
        us = self._cache[2]
        s = self.solver
        cfg = s.config(self.x_m)
        steel = s.steel
        P = len(theta)
        w = cfg.psi_weights.copy()
        w[s._isdir] = 0.0
        pairs = []
        for p in range(P):
            e = np.zeros(P)
            e[p] = h
            pairs.append((self.curve_fn(theta + e), self.curve_fn(theta - e)))
        J = np.zeros((len(self.i_A), P))
        wr = cfg.w_over_r[steel]
        r2 = cfg.r[steel] ** 2
        with threadpool_limits(limits=1):
            for k, i in enumerate(self.i_A):
                u = us[k]
                K, _ = s._tangent(cfg, u, float(i) * cfg.f_coil + cfg.f_fixed)
                lam = s._spd.solve(K.data, K.indices, K.indptr, w)
                self.adjoint_solves += 1
                g = s._grad(cfg, u)[:, steel]
                gl = s._grad(cfg, lam)[:, steel]
                b2 = (g[0] ** 2 + g[1] ** 2) / r2
                dot = (g[0] * gl[0] + g[1] * gl[1]) * wr
                for p, (cp, cm) in enumerate(pairs):
                    J[k, p] = -np.sum(dot * (cp.nu_of_b2(b2)[0] - cm.nu_of_b2(b2)[0])) / (2 * h)
        return J

    def steel_H(self, theta, i_A: float) -> tuple[np.ndarray, np.ndarray]:
        """H [A/m] at the steel's quadrature points and their volumes [m^3] at current ``i_A``."""
        s = self.solver
        s.material = self.curve_fn(theta)
        k = int(np.argmin(np.abs(self.i_A - i_A)))
        sol = s.solve(float(i_A), self.x_m, u0=self.u[k])
        cfg = s.config(self.x_m)
        g = s._grad(cfg, sol.u)[:, s.steel]
        B = np.sqrt(g[0] ** 2 + g[1] ** 2) / cfg.r[s.steel]
        vol = 2 * np.pi * cfg.dx[s.steel] * cfg.r[s.steel]
        return s.material.H_of_B(B).ravel(), vol.ravel()


def _smoothness_matrix(model: SusceptibilityModel) -> np.ndarray:
    """Rows D with D @ theta = second differences of ln chi at the nodes, and the tail slope."""
    m = len(model.H_nodes)
    A = np.zeros((m, m + 1))  # ln chi nodes = A @ theta
    A[:, 0] = 1.0
    for j in range(1, m):
        A[j, 1 : j + 1] = 1.0
    D2 = np.zeros((m - 2, m))
    for j in range(m - 2):
        D2[j, j : j + 3] = (1.0, -2.0, 1.0)
    tail = np.zeros((1, m + 1))
    tail[0, m] = 1.0
    return np.vstack([D2 @ A, tail])


_LSQ_STATUS = {-1: "improper input", 0: "evaluation budget reached", 1: "gradient small (gtol)",
               2: "cost converged (ftol)", 3: "step small (xtol)", 4: "ftol and xtol"}
#: Stage 2 replaces stage 1 only when it lowers the flux RMS below this fraction of stage 1's.
STAGE2_GAIN = 0.7


class _LMResult:
    def __init__(self, x, status, message, nfev):
        self.x, self.status, self.message, self.nfev = x, status, message, nfev


def _projected_lm(residual, jac, x0, lo, hi, max_nfev: int, ftol: float = 1e-4) -> _LMResult:
    """Levenberg-Marquardt with the step projected onto the bounds (a box): one residual
    evaluation (FEM sweep) per trial step and one Jacobian (adjoint solves) per accepted step.
    Status as scipy's least_squares: 0 budget, 2 cost converged (relative decrease < ftol)."""
    x = np.clip(np.asarray(x0, dtype=float), lo, hi)
    r = residual(x)
    cost = float(r @ r)
    J = jac(x)
    mu = 1e-3
    nfev = 1
    while nfev < max_nfev:
        A = J.T @ J
        g = J.T @ r
        dA = np.diag(A).copy() + 1e-12
        step = -np.linalg.solve(A + mu * np.diag(dA), g)
        xn = np.clip(x + step, lo, hi)
        rn = residual(xn)
        nfev += 1
        cn = float(rn @ rn)
        if cn < cost:
            done = (cost - cn) < ftol * cost
            x, r, cost = xn, rn, cn
            mu = max(mu / 5.0, 1e-8)
            if done:
                return _LMResult(x, 2, "cost converged (ftol)", nfev)
            J = jac(x)
        else:
            mu *= 8.0
            if mu > 1e8:
                return _LMResult(x, 3, "step small (xtol)", nfev)
    return _LMResult(x, 0, "evaluation budget reached", nfev)


def scaled_curve(curve: BHCurve, log_a: float, log_s: float, name: str = "scaled") -> BHCurve:
    """The curve with its polarization J = B - mu0 H scaled by a = exp(log_a) and stretched along
    H by s = exp(log_s): B'(H) = mu0 H + a J(H / s). Stays physical for any a, s > 0 (the classic
    one-knob corrections of a catalogue curve: saturation polarization and knee field).

    Built directly on the curve's knots (about 0.1 ms): dB'/dH' = mu0 + (a/s) (dB/dH - mu0) at
    H' = s H, so the differential reluctivity is known exactly there and the last one stays 1/mu0.
    """
    s, a = float(np.exp(log_s)), float(np.exp(log_a))
    H0, B0, nu0 = curve.H_A_per_m, curve.B_T, curve.nu_d
    B = MU_0 * s * H0 + a * (B0 - MU_0 * H0)
    nu = 1.0 / (MU_0 + (a / s) * (1.0 / nu0 - MU_0))
    nu[-1] = 1.0 / MU_0
    H = np.concatenate([[0.0], np.cumsum(0.5 * (nu[1:] + nu[:-1]) * np.diff(B))])
    return BHCurve(B_T=B, nu_d=nu, H_A_per_m=H, table_H_A_per_m=H, table_B_T=B, name=name)


#: Prior of the identifiability analysis: ln chi at each node known to +-0.3 (35 %) beforehand.
PRIOR_LN_CHI_STD = 0.3
#: Flux noise floor (relative to the peak) assumed for the uncertainty when the fit is better.
FLUX_NOISE_FLOOR = 1e-3
#: B counts as identified where the data shrink its prior uncertainty to this fraction or less
#: and its posterior 1-sigma is below IDENTIFIED_B_STD (relative).
IDENTIFIED_SHRINK = 0.25
IDENTIFIED_B_STD = 0.01


def B_uncertainty(model, theta, J_rel, sigma_rel, H) -> tuple[np.ndarray, np.ndarray]:
    """Relative 1-sigma uncertainty of B at field strengths H [A/m], before and after the data.

    Linearized Bayesian analysis: prior on ln chi at the nodes, independent with std
    :data:`PRIOR_LN_CHI_STD` (and on the tail slope); the flux data (Jacobian ``J_rel`` of the flux
    relative to the peak, noise ``sigma_rel``) give the posterior covariance
    (J^T J / sigma^2 + Lambda)^-1, mapped to B(H) by finite differences of the table.

    Returns
    -------
    prior_rel, posterior_rel : ndarray, shape (len(H),)
    """
    P = len(theta)
    m = len(model.H_nodes)
    A = np.zeros((m + 1, P))  # ln chi nodes and the tail slope as linear functions of theta
    A[:m, 0] = 1.0
    for j in range(1, m):
        A[j, 1 : j + 1] = 1.0
    A[m, m] = 1.0
    Lam = A.T @ A / PRIOR_LN_CHI_STD**2
    B0 = np.interp(H, *model.table(theta))
    G = np.empty((len(H), P))
    for p in range(P):
        e = np.zeros(P)
        e[p] = 1e-4
        G[:, p] = (np.interp(H, *model.table(theta + e)) - np.interp(H, *model.table(theta - e))) / 2e-4
    prior = np.linalg.inv(Lam)
    post = np.linalg.inv(J_rel.T @ J_rel / sigma_rel**2 + Lam)
    sd = [np.sqrt(np.maximum(np.einsum("hp,pq,hq->h", G, c, G), 0.0)) / B0 for c in (prior, post)]
    return sd[0], sd[1]


def _identified_range(model, theta, J_rel, rms_rel, H_max) -> tuple[tuple[float, float], np.ndarray, np.ndarray]:
    """H range [A/m] the flux measurement identifies: the longest run of field strengths (up to the
    largest H the steel sees) where the data shrink the prior uncertainty of B to
    :data:`IDENTIFIED_SHRINK` or less and to :data:`IDENTIFIED_B_STD` (1 sigma, relative), with the
    flux noise max(fit RMS, noise floor)."""
    H = np.geomspace(model.H_nodes[0] / 5, max(H_max, model.H_nodes[0]), 80)
    prior, post = B_uncertainty(model, theta, J_rel, max(rms_rel, FLUX_NOISE_FLOOR), H)
    ok = (post < IDENTIFIED_SHRINK * prior) & (post < IDENTIFIED_B_STD)
    if not ok.any():
        return (0.0, 0.0), H, post
    best, run = (0, -1), None
    for k, flag in enumerate(ok):
        if flag and run is None:
            run = k
        if run is not None and (not flag or k == len(ok) - 1):
            end = k if flag else k - 1
            if end - run > best[1] - best[0]:
                best = (run, end)
            run = None
    return (float(H[best[0]]), float(H[best[1]])), H, post


def choose_currents(i_A, psi_Wb, n: int = DEFAULT_N_CURRENTS) -> tuple[np.ndarray, np.ndarray]:
    """The currents [A] the fit uses, and the measured flux there (linear interpolation).

    Dense at low currents (where the flux is most sensitive to the initial permeability): the
    fractions 1/40, 1/20, 1/10 of the peak, then evenly spaced to the peak.
    """
    i_A = np.asarray(i_A, dtype=float)
    psi_Wb = np.asarray(psi_Wb, dtype=float)
    imax = float(np.max(i_A))
    frac = np.concatenate([[0.025, 0.05], np.linspace(0.1, 1.0, max(n - 2, 2))])
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
        parameters, :func:`scaled_curve`), then (2) bounded Gauss-Newton / trust-region reflective
        (scipy ``least_squares``) on all parameters of :class:`SusceptibilityModel`, residuals =
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
    from scipy.optimize import least_squares

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
    i_A, psi_meas, sig = i_A[order], psi_meas[order], sig[order]
    model0, theta_lit = fit_to_curve(start_curve, m=m)
    scale = float(np.max(np.abs(psi_meas)))
    t0 = time.perf_counter()
    history: list = []
    fm = _FluxModel(geometry, x_m, i_A, model0.curve, mesh_size, start_curve)

    s0 = FLUX_NOISE_FLOOR
    weights = s0 / np.sqrt(s0**2 + (sig / scale) ** 2)

    def flux_res(theta):
        r = (fm.psi(theta) - psi_meas) / scale
        history.append(float(np.sqrt(np.mean(r**2))))
        if progress is not None:
            progress(fm.sweeps, history[-1])
        return r * weights

    def wrms(r):
        return float(np.sqrt(np.sum(r**2) / np.sum(weights**2)))

    # the error before: the start curve itself
    fm.curve_fn = lambda p: start_curve
    psi0 = fm.psi(np.zeros(1))
    extra: dict = {}
    if method == "gn":
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
            D = np.vstack([_smoothness_matrix(model), PRIOR_RIDGE * np.eye(len(theta1))])
            prior0 = D @ theta1
            w = float(regularization)

            def residual(theta):
                return np.concatenate([flux_res(theta), w * (D @ theta - prior0)])

            def jac(theta):
                return np.vstack([fm.jacobian(theta) * (weights / scale)[:, None], w * D])

            res = _projected_lm(residual, jac, theta1, lo, hi, max_nfev)
            rms2 = wrms(flux_res(res.x))
            extra["stage2"] = {"rms_rel_peak": rms2, "accepted": bool(rms2 < STAGE2_GAIN * rms_stage1),
                               "status": _LSQ_STATUS.get(res.status, res.message)}
            if rms2 < STAGE2_GAIN * rms_stage1:
                final_curve, theta = model.curve(res.x), res.x
                status = "stage 2 (all parameters): " + _LSQ_STATUS.get(res.status, res.message)
                success = bool(res.status >= 0)
        fm.curve_fn = lambda p: final_curve
    else:
        import nlopt

        model = model0
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
        status = nlopt_code_name(code)
        success = code > 0
        final_curve = model.curve(theta)
        fm.curve_fn = model.curve
    psi1 = fm.psi(theta)
    wall = time.perf_counter() - t0
    e0, e1 = (psi0 - psi_meas) / scale, (psi1 - psi_meas) / scale
    fm.curve_fn = model.curve  # sensitivities in the nodal parameterization (a close fit of the final curve)
    J = fm.jacobian(theta) * (weights / scale)[:, None]
    H_steel, vol = fm.steel_H(theta, float(i_A.max()))
    order_h = np.argsort(H_steel)
    cum = np.cumsum(vol[order_h]) / vol.sum()
    H_max = float(H_steel[order_h][np.searchsorted(cum, 0.995)])  # the 0.5 % most loaded volume aside
    rms1 = float(np.sqrt(np.mean(e1**2)))
    rng, H_u, unc = _identified_range(model, theta, J, wrms(e1 * weights), H_max)
    extra["weights"] = [float(v) for v in weights]
    extra["B_uncertainty"] = {"H_A_per_m": [float(v) for v in H_u], "rel_1sigma": [float(v) for v in unc]}
    return IdentificationResult(
        curve=final_curve, start_curve=start_curve, theta=theta, theta_start=theta0,
        model=model, method=method, success=success, status=status, fem_solves=fm.solves,
        newton_steps=fm.newton_steps, adjoint_solves=fm.adjoint_solves, sweeps=fm.solves / len(i_A),
        equivalent_sweeps=fm.equivalent_sweeps, wall_time_s=wall, x_m=float(x_m), i_A=i_A, psi_meas_Wb=psi_meas,
        psi_before_Wb=psi0, psi_after_Wb=psi1,
        mae_before=float(np.mean(np.abs(e0))), rms_before=float(np.sqrt(np.mean(e0**2))),
        mae_after=float(np.mean(np.abs(e1))), rms_after=rms1, mesh_size=float(mesh_size),
        identified_H_range_A_per_m=rng, H_max_steel_A_per_m=H_max,
        constraint_residuals=constraint_residuals(model, theta), history=history, extra=extra)


# -- from recordings --------------------------------------------------------------------------------
def _as_geometry(geometry):
    from ..field import load_geometry

    if geometry is None or isinstance(geometry, (str, Path)):
        return load_geometry(geometry)
    return geometry


def _as_curve(material) -> BHCurve:
    from ..field import load_material

    if material is None or isinstance(material, (str, Path)):
        return load_material(material)
    return material


def _absolute_flux(recs) -> tuple[list, list[str]]:
    """The flux recordings whose eq.-4 flux is absolute (start at zero current, a rest for the
    voltage offset), and a reason for each one left out."""
    from ..measure import flux_linkage

    keep, reasons = [], []
    for rec in recs:
        fr = flux_linkage(rec)
        if not fr.starts_at_rest:
            reasons.append(f"{rec._where()}: starts energized ({fr.current_A[0]:.4g} A), its flux has an unknown "
                           "integration constant")
        elif not fr.offset_measured:
            reasons.append(f"{rec._where()}: no zero-current rest, the voltage offset of eq. 4 is unknown")
        else:
            keep.append(rec)
    return keep, reasons


def _group_flux(recs) -> tuple[list, list[list]]:
    """Flux recordings grouped by stroke (1 um); the identification group first: the most
    recordings, then the highest peak current."""
    groups: dict[int, list] = {}
    for rec in recs:
        groups.setdefault(int(round(float(np.median(rec.positions_m())) * 1e6)), []).append(rec)
    ordered = sorted(groups.values(), key=lambda g: (-len(g), -max(float(np.max(r.current_A)) for r in g)))
    return ordered[0], ordered[1:]


def hysteresis_half_width(cc, i_A) -> np.ndarray:
    """Half the width of the hysteresis loop [Wb] (descending minus ascending branch, averaged
    over the peaks reaching each level) of a commutation curve at currents ``i_A`` [A]: how far the
    branch mean may sit from the magnetization curve the FEM computes."""
    from ..measure import peak_curves

    branches = [b for r in cc.results for b in r.branches]
    grid = np.linspace(0.0, max(b.peak_A for b in branches), 101)
    _, widths = peak_curves(branches, grid)
    stack = np.vstack(widths)
    ok = np.isfinite(stack).any(axis=0)
    with np.errstate(all="ignore"):
        W = np.nanmean(stack[:, ok], axis=0)
    return 0.5 * np.abs(np.interp(i_A, grid[ok], W))


def force_stroke_curve(rec, bin_m: float = 0.1e-3) -> dict:
    """Measured force vs stroke of a ``force_stroke`` recording, friction averaged out.

    Samples with the current on (above half its peak) and the armature moving are binned by
    position (``bin_m`` [m]); in each bin the mean force of the closing and of the opening pass
    are averaged (dry friction has opposite signs in the two passes). Returns ``x_m``, ``force_N``
    (bins seen in both directions) and ``i_A`` (median current while on).
    """
    x = rec.positions_m()
    i = rec.current_A
    F = rec.force_N
    on = i > 0.5 * np.max(i)
    t = rec.time_s
    k = max(3, int(round(0.02 / max(np.median(np.diff(t)), 1e-9))))
    xs = np.convolve(x, np.ones(k) / k, mode="same")
    v = np.gradient(xs, t)
    moving = np.abs(v) > 0.2 * np.percentile(np.abs(v[on]), 90) if on.any() else np.zeros_like(on)
    sel = on & moving
    if np.count_nonzero(sel) < 10:
        raise RecordingError(rec._where(), ["force_stroke recording: no moving samples with the current on"])
    edges = np.arange(x[sel].min(), x[sel].max() + bin_m, bin_m)
    idx = np.digitize(x, edges) - 1
    xc, fc = [], []
    for b in range(len(edges) - 1):
        inb = sel & (idx == b)
        up, down = inb & (v > 0), inb & (v < 0)
        if np.count_nonzero(up) >= 2 and np.count_nonzero(down) >= 2:
            xc.append(0.5 * (edges[b] + edges[b + 1]))
            fc.append(0.5 * (np.mean(F[up]) + np.mean(F[down])))
    if len(xc) < 2:
        raise RecordingError(rec._where(), ["force_stroke recording: fewer than two positions passed in both "
                                            "directions (a one-way stroke): friction cannot be averaged out"])
    return {"x_m": np.array(xc), "force_N": np.array(fc), "i_A": float(np.median(i[on]))}


def fem_force_vs_stroke(geometry, curve: BHCurve, i_A: float, x_m, mesh_size: float) -> np.ndarray:
    """Co-energy force [N] (paper eq. 3) at current ``i_A`` [A] and gaps ``x_m`` [m] (FEM)."""
    from ..field import Solver

    solver = Solver(geometry, curve, mesh_size)
    out = []
    u = None
    for x in np.asarray(x_m, dtype=float):
        sol = solver.solve(float(i_A), float(x), u0=u)
        u = sol.u
        out.append(sol.force_N)
    return np.array(out)


def fem_flux(geometry, curve: BHCurve, i_A, x_m: float, mesh_size: float) -> np.ndarray:
    """Psi [Wb] at currents ``i_A`` [A] and gap ``x_m`` [m] (FEM, warm-started sweep)."""
    from ..field import Solver

    solver = Solver(geometry, curve, mesh_size)
    out = []
    u = None
    for i in np.asarray(i_A, dtype=float):
        sol = solver.solve(float(i), float(x_m), u0=u)
        u = sol.u
        out.append(sol.psi_Wb)
    return np.array(out)


def write_curve_files(result: IdentificationResult, out_csv, sources=()) -> list[Path]:
    """Write the identified curve: ``out_csv`` (H_A_per_m,B_T, loadable by ``load_material``) and,
    beside it, ``.bh`` (FEMM style, "B H" per line, T and A/m) and ``.tab`` ("H B"), atomically."""
    from ..field import write_bh_csv
    from ..fileio import atomic_write_text

    out_csv = Path(out_csv)
    out_csv.parent.mkdir(parents=True, exist_ok=True)
    H, B = result.curve.table(n=200)
    lo, hi = result.identified_H_range_A_per_m
    comment = (f"B(H) identified by solenoid-fmu identify ({result.method}) at x = {result.x_m * 1e3:g} mm\n"
               f"identified H range {lo:.4g} .. {hi:.4g} A/m (outside: shape of the start curve)\n"
               f"flux RMS error {result.rms_before * 100:.3g} % -> {result.rms_after * 100:.3g} % of peak\n"
               + (f"recordings: {', '.join(Path(str(s)).name for s in sources)}" if sources else ""))
    paths = [write_bh_csv(out_csv, H, B, comment=comment)]
    bh = "\n".join(f"{b:.9g}\t{h:.9g}" for h, b in zip(H, B, strict=True)) + "\n"
    tab = "\n".join(f"{h:.9g}\t{b:.9g}" for h, b in zip(H, B, strict=True)) + "\n"
    paths.append(atomic_write_text(out_csv.with_suffix(".bh"), bh))
    paths.append(atomic_write_text(out_csv.with_suffix(".tab"), tab))
    return paths


def identify_from_recordings(paths, *, geometry=None, start_material=None, mesh_size=None, out_csv=None,
                             report_dir=None, progress=True, method: str = "gn", n_currents: int = DEFAULT_N_CURRENTS,
                             **kwargs) -> IdentificationResult:
    """Identify B(H) from test-rig recordings (the pipeline's entry point).

    Parameters
    ----------
    paths : iterable of path
        Recordings (CSV, format v1) of any kinds; the ``flux`` ones (by header kind) are used: the
        stroke with the most of them is identified, flux at other strokes and ``force_stroke``
        recordings validate (report). Other kinds are ignored.
    geometry : Geometry or path, optional
        Default: packaged PS45.
    start_material : BHCurve or path, optional
        Start curve (default: the literature curve).
    mesh_size : float, optional
        FEM mesh size (default :data:`DEFAULT_MESH_SIZE`).
    out_csv : path, optional
        Write the curve there (+ ``.bh`` and ``.tab`` beside it).
    report_dir : path, optional
        Write figures (paper figs. 10, 11, 15-17) and ``identification.json``.
    progress : bool
        Progress bar on stderr.
    method : {"gn", "auglag"}
    n_currents : int
        Currents of the measured commutation curve used by the fit (:func:`choose_currents`).
    **kwargs
        Passed to :func:`identify_bh`.

    Raises
    ------
    RecordingError
        No ``flux`` recording among ``paths`` (or unreadable recordings).
    """
    from ..measure import commutation_curve, read_recording

    paths = [Path(p) for p in paths]
    recs = [read_recording(p) for p in paths]
    flux = [r for r in recs if r.kind == "flux"]
    if not flux:
        raise RecordingError("identify", [f"no 'flux' recording among {len(paths)} file(s): "
                                          + ", ".join(f"{p.name} ({r.kind})"
                                                      for p, r in zip(paths, recs, strict=True))])
    flux, unusable = _absolute_flux(flux)
    if not flux:
        raise RecordingError("identify", unusable)
    for why in unusable:
        print(f"identify: left out {why}", file=sys.stderr)
    geom = _as_geometry(geometry)
    start = _as_curve(start_material)
    mesh_size = DEFAULT_MESH_SIZE if mesh_size is None else float(mesh_size)
    main, others = _group_flux(flux)
    cc = commutation_curve(main)
    i_sel, psi_sel = choose_currents(cc.i_A, cc.psi_Wb, n_currents)
    sigma = hysteresis_half_width(cc, i_sel)
    bar = None
    cb = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(desc=f"identify B(H) ({method})", unit="sweep", file=sys.stderr)

        def cb(n, rms):
            bar.update(1)
            bar.set_postfix_str(f"flux RMS {rms * 100:.3f} %")
    try:
        res = identify_bh(i_sel, psi_sel, cc.position_m, geom, start, mesh_size=mesh_size, method=method,
                          progress=cb, sigma_Wb=sigma, **kwargs)
    finally:
        if bar is not None:
            bar.close()
    res.extra["recordings"] = [str(r.path) for r in main]
    res.extra["measured_commutation"] = {"i_A": [float(v) for v in cc.i_A], "psi_Wb": [float(v) for v in cc.psi_Wb]}
    if out_csv is not None:
        write_curve_files(res, out_csv, sources=[r.path for r in main])
    if report_dir is not None:
        write_report(res, report_dir, geometry=geom, other_flux=others,
                     force_recordings=[r for r in recs if r.kind == "force_stroke"])
    return res


def _rel_rms(a, b, scale) -> float:
    return float(np.sqrt(np.mean(((np.asarray(a) - np.asarray(b)) / scale) ** 2)))


def write_report(result: IdentificationResult, report_dir, *, geometry=None, other_flux=(),
                 force_recordings=()) -> dict:
    """Figures like the paper's 10, 11 and 15-17 and ``identification.json`` into ``report_dir``.

    - ``fig10_flux.png``: measured commutation Psi(i), FEM with the start and the identified curve.
    - ``fig11_bh.png``: B(H) before and after, identified H range shaded, 1-sigma band of B.
    - ``fig15_force_stroke.png``: force vs stroke per ``force_stroke`` recording (friction averaged
      out), FEM with both curves (if any such recording).
    - ``fig16_flux_other_strokes.png``: Psi(i) at the other strokes with flux recordings (if any).
    The JSON is :meth:`IdentificationResult.summary` plus the validation errors (relative RMS).
    Returns the summary dict.
    """
    import json

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..fileio import atomic_write_text
    from ..measure import commutation_curve

    out = Path(report_dir)
    out.mkdir(parents=True, exist_ok=True)
    geom = _as_geometry(geometry)
    r = result
    summary = r.summary()
    summary.pop("measured_commutation", None)
    ms = r.mesh_size
    # fig. 10
    fig, ax = plt.subplots(figsize=(6, 4.5))
    mc = r.extra.get("measured_commutation")
    if mc:
        ax.plot(mc["i_A"], np.array(mc["psi_Wb"]) * 1e3, "k-", lw=1, label="measured (commutation curve)")
    def errs(key):
        e = summary[key]
        return f"RMS {e['rms_rel_peak'] * 100:.2f} %, weighted {e['rms_weighted_rel_peak'] * 100:.2f} %"

    ax.plot(r.i_A, r.psi_before_Wb * 1e3, "s--", ms=4, label=f"FEM, start curve ({errs('flux_error_before')})")
    ax.plot(r.i_A, r.psi_after_Wb * 1e3, "o-", ms=4, label=f"FEM, identified ({errs('flux_error_after')})")
    w = np.asarray(r.extra.get("weights", np.ones(len(r.i_A))))
    low = w < 0.5
    if low.any():
        ax.plot(r.i_A[low], r.psi_meas_Wb[low] * 1e3, "o", mfc="none", mec="k", ms=8,
                label="weight < 0.5 (wide hysteresis loop)")
    ax.set_xlabel("i [A]")
    ax.set_ylabel("Psi [mWb]")
    ax.set_title(f"Flux linkage at x = {r.x_m * 1e3:g} mm (cf. paper fig. 10)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "fig10_flux.png", dpi=110)
    plt.close(fig)
    # fig. 11
    fig, ax = plt.subplots(figsize=(6, 4.5))
    H = np.geomspace(10.0, 3e5, 300)
    B1 = r.curve.B_of_H(H)
    ax.semilogx(H, r.start_curve.B_of_H(H), "--", label=f"start ({r.start_curve.name})")
    ax.semilogx(H, B1, "-", label="identified")
    unc = r.extra.get("B_uncertainty")
    if unc:
        sd = np.interp(H, unc["H_A_per_m"], unc["rel_1sigma"], left=np.nan, right=np.nan)
        ax.fill_between(H, B1 * (1 - sd), B1 * (1 + sd), color="C1", alpha=0.2, lw=0, label="1-sigma (linearized)")
    lo, hi = r.identified_H_range_A_per_m
    if hi > 0:
        ax.axvspan(max(lo, 10.0), hi, color="0.85", zorder=0, label="identified H range")
    ax.set_xlabel("H [A/m]")
    ax.set_ylabel("B [T]")
    ax.set_ylim(0, max(2.4, float(B1.max()) * 1.05))
    ax.set_title("B(H) before and after identification (cf. paper fig. 11)")
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(out / "fig11_bh.png", dpi=110)
    plt.close(fig)
    # figs. 15-17: force vs stroke
    validation: dict = {}
    if force_recordings:
        fig, ax = plt.subplots(figsize=(6, 4.5))
        rows = []
        for k, rec in enumerate(force_recordings):
            try:
                fc = force_stroke_curve(rec)
            except RecordingError as err:
                rows.append({"file": str(rec.path), "error": str(err)})
                continue
            x = fc["x_m"]
            xs = np.linspace(x.min(), x.max(), 8)
            f0 = fem_force_vs_stroke(geom, r.start_curve, fc["i_A"], xs, ms)
            f1 = fem_force_vs_stroke(geom, r.curve, fc["i_A"], xs, ms)
            fm_ = np.interp(xs, x, fc["force_N"])
            sc = float(np.max(np.abs(fm_)))
            rows.append({"file": Path(str(rec.path)).name, "i_A": fc["i_A"], "rms_rel_before": _rel_rms(f0, fm_, sc),
                         "rms_rel_after": _rel_rms(f1, fm_, sc)})
            c = f"C{k % 10}"
            ax.plot(x * 1e3, fc["force_N"], "-", color=c, lw=1, label=f"measured {fc['i_A']:.2g} A")
            ax.plot(xs * 1e3, f0, "x--", color=c, lw=0.8, ms=4)
            ax.plot(xs * 1e3, f1, "o:", color=c, lw=0.8, ms=4)
        ax.plot([], [], "kx--", label="FEM, start curve")
        ax.plot([], [], "ko:", label="FEM, identified")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("F [N]")
        ax.set_title("Force vs stroke (cf. paper figs. 15-17)")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(out / "fig15_force_stroke.png", dpi=110)
        plt.close(fig)
        validation["force_stroke"] = rows
    if other_flux:
        fig, ax = plt.subplots(figsize=(6, 4.5))
        rows = []
        for k, group in enumerate(other_flux):
            cc = commutation_curve(group)
            i_sel, psi_m = choose_currents(cc.i_A, cc.psi_Wb, 8)
            p0 = fem_flux(geom, r.start_curve, i_sel, cc.position_m, ms)
            p1 = fem_flux(geom, r.curve, i_sel, cc.position_m, ms)
            sc = float(np.max(np.abs(psi_m)))
            rows.append({"x_mm": cc.position_m * 1e3, "rms_rel_before": _rel_rms(p0, psi_m, sc),
                         "rms_rel_after": _rel_rms(p1, psi_m, sc)})
            c = f"C{k % 10}"
            ax.plot(cc.i_A, cc.psi_Wb * 1e3, "-", color=c, lw=1, label=f"measured x = {cc.position_m * 1e3:g} mm")
            ax.plot(i_sel, p0 * 1e3, "x--", color=c, ms=4)
            ax.plot(i_sel, p1 * 1e3, "o:", color=c, ms=4)
        ax.plot([], [], "kx--", label="FEM, start curve")
        ax.plot([], [], "ko:", label="FEM, identified")
        ax.set_xlabel("i [A]")
        ax.set_ylabel("Psi [mWb]")
        ax.set_title("Flux linkage at other strokes (cf. paper figs. 15-17)")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(out / "fig16_flux_other_strokes.png", dpi=110)
        plt.close(fig)
        validation["flux_other_strokes"] = rows
    summary["validation"] = validation
    atomic_write_text(out / "identification.json", json.dumps(summary, indent=2) + "\n")
    return summary


# -- command line -----------------------------------------------------------------------------------
def add_cli(sub) -> None:
    """Register ``solenoid-fmu identify``."""
    p = sub.add_parser("identify",
                       help="identify the steel's B(H) from flux recordings (FEM + optimizer, paper sec. 4)")
    p.add_argument("recordings", nargs="+", help="recordings (CSV, format v1); flux ones are used, others ignored "
                   "(force_stroke ones validate in the report)")
    p.add_argument("--geometry", help="solenoid TOML (default: packaged PS45)")
    p.add_argument("--start-material", help="start B(H) CSV H_A_per_m,B_T (default: literature 9SMnPb28)")
    p.add_argument("-o", "--output", required=True, help="identified curve CSV (also writes .bh and .tab beside it)")
    p.add_argument("--report", help="directory for figures and identification.json")
    p.add_argument("--method", choices=("gn", "auglag"), default="gn",
                   help="gn: Gauss-Newton with adjoint Jacobians (default); auglag: nlopt AUGLAG+BOBYQA (paper)")
    p.add_argument("--mesh-size", type=float, default=None, help=f"FEM mesh size (default {DEFAULT_MESH_SIZE:g})")
    p.add_argument("--max-evals", type=int, default=None, help="budget of FEM sweeps of the optimizer")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=_cli)


def _cli(args) -> int:
    import json

    kw = {}
    if args.max_evals is not None and args.max_evals < 1:
        raise SolenoidError(f"--max-evals must be >= 1, got {args.max_evals}")
    if args.max_evals is not None:
        kw["max_nfev" if args.method == "gn" else "max_eval_auglag"] = args.max_evals
    from ..fileio import refuse_overwriting_inputs, require_directory

    inputs = [*args.recordings, args.geometry, args.start_material]
    out = Path(args.output)
    require_directory(out.parent, "-o")
    refuse_overwriting_inputs(out, inputs, written=[out, out.with_suffix(".bh"), out.with_suffix(".tab")])
    if args.report is not None:
        refuse_overwriting_inputs(require_directory(args.report, "--report"), inputs, written=[])
    res = identify_from_recordings(args.recordings, geometry=args.geometry, start_material=args.start_material,
                                   mesh_size=args.mesh_size, out_csv=args.output, report_dir=args.report,
                                   progress=not args.json, method=args.method, **kw)
    if args.json:
        s = res.summary()
        s.pop("measured_commutation", None)
        s.pop("B_uncertainty", None)
        print(json.dumps(s))
        return 0
    lo, hi = res.identified_H_range_A_per_m
    print(f"identified B(H) at x = {res.x_m * 1e3:g} mm ({res.method}: {res.status})")
    s = res.summary()
    wb, wa = s["flux_error_before"]["rms_weighted_rel_peak"], s["flux_error_after"]["rms_weighted_rel_peak"]
    print(f"  flux error   MAE {res.mae_before * 100:.3f} % -> {res.mae_after * 100:.3f} %, "
          f"RMS {res.rms_before * 100:.3f} % -> {res.rms_after * 100:.3f} % of peak "
          f"(weighted by the hysteresis width: {wb * 100:.3f} % -> {wa * 100:.3f} %)")
    print(f"  identified H range {lo:.4g} .. {hi:.4g} A/m (steel reaches {res.H_max_steel_A_per_m:.4g} A/m)")
    print(f"  FEM solves {res.fem_solves}, sweeps {res.sweeps:.1f}, equivalent sweeps {res.equivalent_sweeps:.1f}, "
          f"wall {res.wall_time_s:.1f} s")
    print(f"  constraint residuals {res.constraint_residuals}")
    print(f"  wrote {args.output} (+ .bh, .tab)" + (f", report in {args.report}" if args.report else ""))
    return 0
