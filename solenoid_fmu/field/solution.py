"""One operating point of the FEM (:class:`~solenoid_fmu.field.fem.Solver`): current, gap, flux and forces."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Solution"]


@dataclass
class Solution:
    """One operating point: current, gap, the nodal flux function and the results (SI)."""

    i_A: float
    x_m: float
    u: np.ndarray
    psi_Wb: float
    force_coenergy_N: float
    force_stress_N: float
    coenergy_J: float
    newton_iterations: int
    residual_history: list = field(default_factory=list)
    #: eps | |K_s| |u| + |f| | / |f| at the last iterate: the relative residual's rounding floor (see NEWTON_RTOL)
    residual_floor: float = 0.0
    note: str = ""  # how Newton got there when not by the plain tolerance (a stall accepted, a retry)

    @property
    def force_N(self) -> float:
        """The force the maps carry: the co-energy derivative (paper eq. 3) [N]."""
        return self.force_coenergy_N

    def as_dict(self) -> dict:
        """JSON-ready summary (the keys of ``solenoid-fmu solve --json``)."""
        return {
            "psi_Wb": self.psi_Wb,
            "force_N": self.force_coenergy_N,
            "force_coenergy_N": self.force_coenergy_N,
            "force_stress_N": self.force_stress_N,
            "coenergy_J": self.coenergy_J,
            "newton_iterations": self.newton_iterations,
            "x_mm": self.x_m * 1e3,
            "i_A": self.i_A,
        }
