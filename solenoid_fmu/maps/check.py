"""Energy consistency of the maps: electrical energy against mechanical work around closed cycles (paper eq. 3)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import MapsError
from .interpolate import force_at, force_psi_at, i_f_at, psi_at
from .tables import CharacteristicMaps

__all__ = ["CycleEnergy", "cycle_energy_balance", "rectangle_cycle"]


@dataclasses.dataclass(frozen=True)
class CycleEnergy:
    """Energy balance around a closed quasi-static cycle (paper eq. 3).

    Attributes
    ----------
    electrical_J : float
        Net electrical energy drawn from the coil, closed integral of i dPsi [J].
    mechanical_J : float
        Net work done by the magnetic force on the armature, closed integral of -F dx [J]
        (F positive closes the gap x).
    relative_error : float
        ``|electrical_J - mechanical_J| / max(|electrical_J|, |mechanical_J|)``.
    throughput_J : float
        Sum of |i dPsi| around the cycle [J] (energy moved through the coil, for scale).
    """

    electrical_J: float
    mechanical_J: float
    relative_error: float
    throughput_J: float


def rectangle_cycle(i_low_A: float, i_high_A: float, x1_m: float, x2_m: float) -> np.ndarray:
    """Vertices (i [A], x [m]) of the rectangle: raise i at x1, move to x2, lower i, move back to x1."""
    return np.array([[i_low_A, x1_m], [i_high_A, x1_m], [i_high_A, x2_m], [i_low_A, x2_m]], dtype=np.float64)


def cycle_energy_balance(
    maps: CharacteristicMaps, cycle, tables: str = "i_x", n_per_segment: int = 400
) -> CycleEnergy:
    """Electrical energy vs mechanical work around a closed quasi-static cycle.

    For forces consistent with the flux linkage (paper eq. 3, F = -dW'/dx at constant i with the
    co-energy W' = integral of Psi di), energy conservation ``i dPsi = dW_field - F dx`` makes the
    closed integrals of ``i dPsi`` and ``-F dx`` equal.

    Parameters
    ----------
    maps : CharacteristicMaps
    cycle : array-like, shape (k, 2)
        Vertices of a closed polygon (the last connects back to the first), traversed along straight
        lines: (i [A], x [m]) when ``tables == "i_x"`` (uses :func:`psi_at`, :func:`force_at`),
        (Psi [Wb], x [m]) when ``tables == "psi_x"`` (uses :func:`i_f_at`, :func:`force_psi_at`).
    tables : {"i_x", "psi_x"}
        Which pair of maps to check.
    n_per_segment : int
        Trapezoid steps per polygon side.

    Returns
    -------
    CycleEnergy
    """
    v = np.asarray(cycle, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 2:
        raise MapsError(f"cycle must be an array of (k >= 2, 2) vertices, got shape {v.shape}")
    if tables not in ("i_x", "psi_x"):
        raise MapsError(f"tables must be 'i_x' or 'psi_x', got {tables!r}")
    closed = np.vstack([v, v[:1]])
    s = np.linspace(0.0, 1.0, n_per_segment + 1)[:-1]
    path = np.vstack([a + s[:, None] * (b - a) for a, b in zip(closed[:-1], closed[1:], strict=True)])
    path = np.vstack([path, path[:1]])
    u, x = path[:, 0], path[:, 1]
    if tables == "i_x":
        i, psi, F = u, psi_at(maps, u, x), force_at(maps, u, x)
    else:
        psi, i, F = u, i_f_at(maps, u, x), force_psi_at(maps, u, x)
    di_dpsi = 0.5 * (i[1:] + i[:-1]) * np.diff(psi)
    electrical = float(np.sum(di_dpsi))
    mechanical = float(np.sum(0.5 * (F[1:] + F[:-1]) * -np.diff(x)))
    scale = max(abs(electrical), abs(mechanical))
    rel = abs(electrical - mechanical) / scale if scale > 0 else 0.0
    return CycleEnergy(electrical, mechanical, rel, float(np.sum(np.abs(di_dpsi))))


