"""Synthetic characteristic maps from an analytic magnetic circuit, in the shared maps format.

The circuit: a coil of ``N`` turns on a saturating iron path (cross-section ``A``, length
``l_fe``) in series with a working air gap whose effective length ``x_eff(x)`` grows with the
armature gap ``x`` (with fringing) plus a parasitic gap. With ``B = Psi / (N A)``::

    H_fe(B)  = B / (mu0 mu_r) + H1 sinh(B / B1)                 (monotone, saturating)
    x_eff(x) = x_par + x_f ln(1 + x / x_f)
    i_f(Psi, x) = (H_fe(B) l_fe + B x_eff(x) / mu0) / N          (Ampere's law)
    F(Psi, x)   = d/dx of W(Psi, x) = Psi^2 x_eff'(x) / (2 N^2 A mu0)

where ``W = int_0^Psi i_f dpsi`` is the magnetic energy, so the force is exactly consistent with
the co-energy (positive: closing the gap, since the energy at constant flux grows with x). The
numbers are PS45-like (1500 turns, 12 ohm, 2 A, saturation from about 1.3 A at small gaps).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

MU0 = 4e-7 * np.pi
N_TURNS = 1500
AREA_M2 = 1.13e-4
L_FE_M = 0.12
MU_R = 1500.0
H1_A_PER_M = 30.0
B1_T = 0.25
X_PAR_M = 0.2e-3
X_F_M = 2.0e-3
R_OHM = 12.0
I_MAX_A = 2.0


def x_eff_m(x_m):
    """Effective gap length [m] for the armature gap ``x_m`` [m]."""
    return X_PAR_M + X_F_M * np.log1p(np.asarray(x_m, dtype=float) / X_F_M)


def i_f_analytic(psi_Wb, x_m):
    """Field-generating current [A] of the analytic circuit (odd in Psi)."""
    b = np.asarray(psi_Wb, dtype=float) / (N_TURNS * AREA_M2)
    h = b / (MU0 * MU_R) + H1_A_PER_M * np.sinh(b / B1_T)
    return (h * L_FE_M + b * x_eff_m(x_m) / MU0) / N_TURNS


def force_analytic(psi_Wb, x_m):
    """Force [N] of the analytic circuit, positive closing the gap (co-energy consistent)."""
    dxe = 1.0 / (1.0 + np.asarray(x_m, dtype=float) / X_F_M)
    return np.asarray(psi_Wb, dtype=float) ** 2 * dxe / (2.0 * N_TURNS**2 * AREA_M2 * MU0)


def psi_analytic(i_A, x_m):
    """Inverse of :func:`i_f_analytic` in Psi [Wb] for ``i_A >= 0`` (vectorised bisection)."""
    i_A, x_m = np.broadcast_arrays(np.asarray(i_A, dtype=float), np.asarray(x_m, dtype=float))
    lo = np.zeros(i_A.shape)
    hi = np.full(i_A.shape, 2.5 * N_TURNS * AREA_M2)  # 2.5 T: far beyond saturation
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        below = i_f_analytic(mid, x_m) < i_A
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def write_maps(maps_dir, *, name: str = "synthetic", G_eddy_S: float | None = 0.02, n_x: int = 12,
               n_i: int = 21, n_psi: int = 41, x_min_m: float = 0.2e-3, x_max_m: float = 3.5e-3) -> Path:
    """Write ``maps.npz`` + ``maps.json`` of the analytic circuit into ``maps_dir``.

    Parameters
    ----------
    maps_dir : path-like
        Target directory (created).
    name : str
        Map name recorded in the sidecar.
    G_eddy_S : float or None
        Eddy-current conductance [S] recorded in the sidecar (None: not identified).
    n_x, n_i, n_psi : int
        Grid sizes (gap, current sweep, regular flux grid).
    x_min_m, x_max_m : float
        Gap range [m]; the gap grid is denser at small gaps.

    Returns
    -------
    pathlib.Path
        The maps directory.
    """
    maps_dir = Path(maps_dir)
    maps_dir.mkdir(parents=True, exist_ok=True)
    u = np.linspace(0.0, 1.0, n_x)
    x_m = x_min_m + (x_max_m - x_min_m) * u**1.5
    i_A = np.linspace(0.0, I_MAX_A, n_i)
    ii, xx = np.meshgrid(i_A, x_m, indexing="ij")
    psi_ix = psi_analytic(ii, xx)
    force_ix = force_analytic(psi_ix, xx)
    psi_top = float(np.max(psi_ix[-1]))
    psi_Wb = np.linspace(0.0, psi_top, n_psi)
    pp, xx2 = np.meshgrid(psi_Wb, x_m, indexing="ij")
    i_f = i_f_analytic(pp, xx2)
    force = force_analytic(pp, xx2)
    extrapolated = (pp > psi_ix[-1][None, :] * (1.0 + 1e-12)).astype(float)
    np.savez(maps_dir / "maps.npz", x_m=x_m, i_A=i_A, psi_ix_Wb=psi_ix, force_ix_N=force_ix,
             force_stress_ix_N=force_ix.copy(), psi_Wb=psi_Wb, i_f_A=i_f, force_N=force,
             extrapolated=extrapolated)
    units = {"x_m": "m", "i_A": "A", "psi_ix_Wb": "Wb", "force_ix_N": "N", "force_stress_ix_N": "N",
             "psi_Wb": "Wb", "i_f_A": "A", "force_N": "N", "extrapolated": "1"}
    meta = {
        "schema": "solenoid-fmu-maps",
        "schema_version": 1,
        "name": name,
        "force_method": "coenergy",
        "units": units,
        "coil": {"turns": N_TURNS, "resistance_ohm_20C": R_OHM, "temperature_coefficient_per_K": 0.00393,
                 "max_current_A": I_MAX_A},
        "eddy": {"G_eddy_S": G_eddy_S, "source": "synthetic test fixture"},
        "provenance": {
            "geometry": {"path": "analytic", "sha256": "0" * 64, "name": "analytic-circuit"},
            "material": {"path": "analytic", "sha256": "0" * 64},
            "mesh_size": None,
            "code_version": "tests/mapsfixture.py",
            "created_utc": "2024-01-01T00:00:00Z",
            "solver": {"kind": "analytic magnetic circuit"},
        },
    }
    (maps_dir / "maps.json").write_text(json.dumps(meta, indent=2), encoding="utf-8")
    return maps_dir
