r"""The B(H) parameterization of the identification: physical by construction (paper 4.2).

The differential susceptibility :math:`\chi(H) = (dB/dH)/\mu_0 - 1` is described on a grid of
``m`` rising field strengths (log-spaced by default; the identification's stage 2 spaces them in B,
:func:`~.joint.stage2_nodes`), linear in :math:`u = \ln H` between them: :math:`\ln\chi_j = c + \sum_{k\le j} d_k`
with increments :math:`d_k \ge 0` up to a fixed peak index and :math:`d_k \le 0` after it, and a
last slope :math:`\le -1.2` (in :math:`\ln\chi` per :math:`\ln H`) that continues beyond the grid.
So :math:`\chi` rises to one maximum (the inflection point of B(H)) and then falls towards 0, i.e.
the permeability towards :math:`\mu_0`, and :math:`B = \mu_0 H + \mu_0\int_0^H\chi\,dh` rises and
saturates: the paper's constraints become simple bounds on the increments (and, for nlopt's
AUGLAG, the inequalities of :func:`constraint_values`). Below the first node :math:`\chi` is
constant (the initial permeability).

:func:`scaled_curve` is the two-parameter correction of a catalogue curve (stage 1 of the fit).
Units: SI (H in A/m, B in T).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..field import MU_0, MU_R_MAX, BHCurve, unimodal_fit

__all__ = [
    "MAX_TAIL_SLOPE",
    "SusceptibilityModel",
    "fit_to_curve",
    "node_value_bounds",
    "scaled_curve",
    "constraint_values",
    "constraint_residuals",
    "smoothness_matrix",
    "project_unimodal",
    "with_peak_of",
]

#: Last log-log slope of chi: saturation law chi ~ H^-1.2 or faster (keeps B bounded-slope).
MAX_TAIL_SLOPE = -1.2
#: Range of ln chi at any node: chi from 1e-6 (deep saturation: the steel's share of B below 1e-6 of
#: mu0 H) to 1e5 (above the permeability of any solenoid steel).
LOG_CHI_RANGE = (float(np.log(1e-6)), float(np.log(1e5)))
#: Relative cost decrease at which :func:`fit_to_curve` stops. Its fit is a start (stage 2's), not a result: at
#: scipy's default 1e-8 one stage-1 curve (random-2 of the tests, a knee within a factor 3 in H) took 2587
#: evaluations (20 s) for a cost 7.3e-5 -> 6.3e-5 with the largest B error unchanged at 0.31 %; at 1e-5, 110,
#: and on seven campaigns the largest B error is the same to 1e-5.
FIT_FTOL = 1e-5


@dataclass(frozen=True)
class SusceptibilityModel:
    """The unimodal log-susceptibility parameterization on a grid of field strengths.

    Attributes
    ----------
    H_nodes : ndarray, shape (m,)
        Grid of field strengths [A/m], rising (ln chi is linear in ln H between the nodes).
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


def fit_to_curve(curve: BHCurve, m: int = 13, H_range=(50.0, 2e5), H_nodes=None
                 ) -> tuple[SusceptibilityModel, np.ndarray]:
    """The parameterization and parameters closest to a given curve (e.g. the literature one).

    Nodes: ``m`` log-spaced over ``H_range`` [A/m], or ``H_nodes`` [A/m] (rising) when given.
    Start: least squares on ln chi at the nodes under the bounds, chi there being the chord of the curve
    over the node's cell (half-way to its neighbours in ln H: a sharp knee between two nodes keeps its
    share of B); the peak index is where that chi peaks. Then bounded least squares on B(H) itself at
    200 field strengths.
    """
    from scipy.optimize import least_squares, lsq_linear  # heavy (about 0.5 s): loaded on first use

    if H_nodes is None:
        H_nodes = np.geomspace(*H_range, m)
    H_nodes = np.asarray(H_nodes, dtype=float)
    m = len(H_nodes)
    u = np.log(H_nodes)
    half = 0.5 * np.diff(u)
    H_lo, H_hi = np.exp(u - np.concatenate([[half[0]], half])), np.exp(u + np.concatenate([half, [half[-1]]]))
    chord = (curve.B_of_H(H_hi) - curve.B_of_H(H_lo)) / (MU_0 * (H_hi - H_lo))
    chi = np.maximum(chord - 1.0, 1e-6)
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
    Hs = np.geomspace(H_nodes[0] / 5, H_nodes[-1] * 5, 200)
    Bs = curve.B_of_H(Hs)

    def res(th):
        H, B = model.table(th)
        return np.interp(Hs, H, B) / Bs - 1.0

    theta = least_squares(res, theta, bounds=(lo, hi), method="trf", x_scale=1.0, ftol=FIT_FTOL).x
    return model, theta



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


def smoothness_matrix(model: SusceptibilityModel) -> np.ndarray:
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



def project_unimodal(model: SusceptibilityModel, theta, floor=None) -> np.ndarray:
    """theta moved to the nearest (least squares in ln chi at the nodes) parameters whose chi rises to
    one peak, at any node, and then falls (paper sec. 4.2), within the model's other bounds.

    The projection step of the stage-2 fit: unlike the bounds of :meth:`SusceptibilityModel.bounds`
    it lets the peak (the B(H) inflection point) move to another node, which a steel unlike the
    start curve needs.
    """
    theta = np.asarray(theta, dtype=float)
    m = len(model.H_nodes)
    lo, hi = model.bounds()
    v = model.log_chi_nodes(theta)
    if floor is not None:  # ln chi at each node kept above ``floor`` (before the projection: it stays unimodal)
        v = np.maximum(v, floor)
    fit, _ = unimodal_fit(v)
    fit[0] = np.clip(fit[0], lo[0], hi[0])
    # node values within the susceptibility's physical range (not within some distance of the first
    # node: a steel with chi = 6000 at low field saturates to chi < 0.01, 13 in ln chi below it)
    fit = np.clip(fit, LOG_CHI_RANGE[0], LOG_CHI_RANGE[1])
    d = np.clip(np.diff(fit), lo[1:m].min(), hi[1:m].max())
    out = np.concatenate([[fit[0]], d, [np.clip(theta[m], lo[m], hi[m])]])
    return out


def node_value_bounds(model: SusceptibilityModel, floor) -> tuple[np.ndarray, np.ndarray, float]:
    """The bounds :func:`project_unimodal` keeps, on node values v = (ln chi at the m nodes, tail slope): lower and
    upper of v (chi within :data:`LOG_CHI_RANGE` and the model's range at the first node, ``floor`` below, the
    tail slope's range) and the largest rise or fall of ln chi between neighbouring nodes. For a step solved
    inside them (:func:`~.cone_step.cone_step`) rather than projected onto them afterwards."""
    m = len(model.H_nodes)
    lo, hi = model.bounds()
    lower = np.concatenate([np.maximum(np.asarray(floor, dtype=float), LOG_CHI_RANGE[0]), [lo[m]]])
    upper = np.concatenate([np.full(m, LOG_CHI_RANGE[1]), [hi[m]]])
    lower[0], upper[0] = max(lower[0], lo[0]), min(upper[0], hi[0])
    return lower, upper, float(max(hi[1:m].max(), -lo[1:m].min()))


def with_peak_of(model: SusceptibilityModel, theta) -> SusceptibilityModel:
    """The model with its peak node where chi of ``theta`` peaks (for its bounds and constraints)."""
    return SusceptibilityModel(model.H_nodes, int(np.argmax(model.log_chi_nodes(np.asarray(theta, dtype=float)))))
