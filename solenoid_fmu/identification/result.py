"""The outcome of an identification (:class:`IdentificationResult`) and its JSON summary."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..field import BHCurve
from .parametrization import SusceptibilityModel

__all__ = ["IdentificationResult", "h_range_text"]


def h_range_text(h_range) -> str:
    """The identified H range [A/m] in words: ``"LO .. HI A/m"``, or ``"none"`` where the data pin B(H) nowhere
    (:func:`~.uncertainty.identified_range` returns (0, 0) then)."""
    lo, hi = (float(v) for v in h_range)
    return f"{lo:.4g} .. {hi:.4g} A/m" if hi > 0.0 else "none (the data pin B(H) nowhere, see the warnings)"


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
    figures : dict of str to bytes
        The report's figures (file name -> PNG) once :func:`~solenoid_fmu.identification.write_report` drew
        them (empty before; not part of :meth:`summary`).
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
    figures: dict = field(default_factory=dict, repr=False)

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

