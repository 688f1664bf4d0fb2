"""Map columns between FEM positions, interpolated in x at fixed flux linkage before the maps are inverted.

The real-time model reads its maps linearly in x between columns (:mod:`solenoid_fmu.realtime.model`, the
C FMUs alike), and that error falls with the square of the column spacing: on 12 positions over PS45's
stroke it is visible to the loop (a force residual wavy in x, about 0.2 N between columns, which a
hysteresis term then absorbed on a campaign without hysteresis). :func:`refine_tables` puts ``factor - 1``
columns evenly into each interval of the FEM positions, so that maps from ``n`` FEM positions carry
``factor (n - 1) + 1`` columns, for the FEM cost of ``n``.

**At fixed flux, not at fixed current.** At a fixed current the flux and the force change character
along x where the iron saturates (a small gap saturates it, a large one does not), and a spline in x
through that knee overshoots: on test_maps' magnetic circuit (a steep saturation) it was worse than the
linear reading of the FEM columns. At a fixed flux linkage the iron's state hardly depends on x: that
circuit's ``i_f = (Phi R_gap(x) + l H(Phi / A)) / N`` and ``F = Phi^2 R_gap'(x) / 2`` are as smooth in x as
the gap's reluctance. So each FEM column is read as ``i_j(Psi)``, ``F_j(Psi)`` and the Maxwell-stress force
(monotone cubic along the column, linear beyond its top current as the inversion extends it), a
not-a-knot cubic spline in x through the columns at fixed Psi (:func:`spline_weights`) gives them at the
inserted positions, and the inserted (i, x) columns are their inverse at the sweep's currents: ``Psi(i)``
by bisection, then the forces at that flux. Where a column the spline leans on (weight at least
:data:`SUPPORT_WEIGHT` of the largest) has no data of its own at that flux (above its top current: the
columns at large gaps reach less flux), the two FEM columns either side are read linearly instead, as
the maps without refinement would be. The FEM columns are kept exactly; :func:`solenoid_fmu.maps.invert.invert_maps`
then inverts all columns alike and checks each (an inserted column whose ``Psi(i)`` did not rise would be
named there).

Measured (stop 38) against a 47-position FEM (0.2-2 A, the model's reading of the maps at the FEM's
fluxes): 12 FEM positions refined 3x gave F RMS 0.050 N and i_f RMS 0.09 mA on random-1's identified steel
(24 FEM positions read linearly: 0.071 N, 0.09 mA; 12: 0.30 N, 0.41 mA), 0.031 N and 0.06 mA on
Permenorm's (24: 0.047 N, 0.08 mA; 12: 0.20 N, 0.35 mA).
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline, PchipInterpolator

from ..errors import MapsError
from .invert import check_fem_tables

__all__ = ["MAX_REFINE_X", "SUPPORT_WEIGHT", "refine_tables", "refined_positions", "spline_weights"]

#: Most columns put into each FEM interval, plus one.
MAX_REFINE_X = 8
#: A column counts as support of an inserted one where its spline weight is at least this share of the largest.
SUPPORT_WEIGHT = 0.01
#: Bisection steps for Psi(i) at an inserted column: the bracket [0, 2 Psi_max] to 2^-60 of it.
_BISECTION_STEPS = 60


def refined_positions(x_m, factor: int) -> np.ndarray:
    """The FEM positions ``x_m`` [m] with ``factor - 1`` positions evenly inside each interval."""
    x_m = np.asarray(x_m, dtype=float)
    _check_factor(factor, x_m.size)
    s = np.arange(factor) / factor
    inner = x_m[:-1, None] + s[None, :] * np.diff(x_m)[:, None]
    return np.concatenate([inner.ravel(), x_m[-1:]])


def spline_weights(x_m, x_new) -> np.ndarray:
    """Weights ``W`` (shape ``(len(x_new), len(x_m))``) of the not-a-knot cubic spline through values at the
    columns ``x_m``: the spline at ``x_new`` is ``W @ values`` (it is linear in the values)."""
    x_m = np.asarray(x_m, dtype=float)
    return CubicSpline(x_m, np.eye(x_m.size), axis=0, bc_type="not-a-knot")(np.asarray(x_new, dtype=float))


class _Column:
    """One FEM column read along its flux: ``values(Psi)`` of a table, monotone cubic inside the column's
    flux range, linear from its last two points beyond it (as the inversion extends the maps)."""

    def __init__(self, psi, values):
        self.psi, self.values = psi, values
        self.pchip = PchipInterpolator(psi, values, extrapolate=False)
        self.slope = (values[-1] - values[-2]) / (psi[-1] - psi[-2])

    def __call__(self, p):
        out = self.pchip(np.clip(p, self.psi[0], self.psi[-1]))
        beyond = p > self.psi[-1]
        out[beyond] = self.values[-1] + self.slope * (p[beyond] - self.psi[-1])
        return out


def refine_tables(x_m, i_A, psi_ix_Wb, force_ix_N, stress_ix_N, factor: int) -> tuple:
    """The FEM's (i, x) tables on the refined positions (module docstring): ``(x_fine_m, psi_ix_Wb, force_ix_N,
    stress_ix_N)``, each table of shape ``(len(i_A), len(x_fine_m))``; currents [A], flux [Wb], forces [N]."""
    x_m = np.asarray(x_m, dtype=float)
    i_A = np.asarray(i_A, dtype=float)
    tables = [np.asarray(t, dtype=float) for t in (psi_ix_Wb, force_ix_N, stress_ix_N)]
    x_fine = refined_positions(x_m, factor)
    if factor == 1:
        return (x_fine, *tables)
    psi, force, stress = tables
    check_fem_tables(x_m, i_A, psi, force, stress)  # each column is read along its flux: it must rise
    inserted = np.flatnonzero(np.arange(x_fine.size) % factor)
    xi = x_fine[inserted]
    W = spline_weights(x_m, xi)
    # the columns a value leans on: the spline's weights fall about fourfold per interval away from x
    support = np.abs(W) >= SUPPORT_WEIGHT * np.max(np.abs(W), axis=1, keepdims=True)
    j = inserted // factor  # the FEM interval [x_j, x_j+1] of each inserted column
    lin = np.zeros_like(W)
    lin[np.arange(xi.size), j] = (x_m[j + 1] - xi) / (x_m[j + 1] - x_m[j])
    lin[np.arange(xi.size), j + 1] = (xi - x_m[j]) / (x_m[j + 1] - x_m[j])
    top = psi[-1]  # each FEM column's flux at the sweep's top current [Wb]
    columns = {key: [_Column(psi[:, c], values) for c, values in enumerate(table.T)]
               for key, table in (("i", np.repeat(i_A[:, None], x_m.size, axis=1)), ("F", force), ("S", stress))}

    def at(key, p):  # (n_inserted, n_i) values at fixed flux p (same shape): the spline in x where the columns
        # it leans on reach p with their own data, else linear between the two FEM columns either side
        vals = np.stack([col(p.ravel()).reshape(p.shape) for col in columns[key]], axis=-1)  # (n_ins, n_i, n_x)
        inside = np.all((p[:, :, None] <= top[None, None, :]) | ~support[:, None, :], axis=2)
        return np.where(inside, np.einsum("cx,cix->ci", W, vals), np.einsum("cx,cix->ci", lin, vals))

    lo = np.zeros((inserted.size, i_A.size))
    hi = np.full_like(lo, 2.0 * float(np.max(psi)))
    target = np.broadcast_to(i_A, lo.shape)
    for _ in range(_BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        below = at("i", mid) < target
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    p = 0.5 * (lo + hi)
    p[:, i_A == 0.0] = 0.0
    out = []
    for table, values in ((psi, p), (force, at("F", p)), (stress, at("S", p))):
        fine = np.empty((i_A.size, x_fine.size))
        fine[:, ::factor] = table
        fine[:, inserted] = values.T
        out.append(fine)
    return (x_fine, *out)


def _check_factor(factor, n: int) -> None:
    if not isinstance(factor, int | np.integer) or isinstance(factor, bool) or not 1 <= factor <= MAX_REFINE_X:
        raise MapsError(f"refine_x must be a whole number from 1 to {MAX_REFINE_X}, got {factor!r}")
    if factor > 1 and n < 4:
        raise MapsError(f"refine_x > 1 needs at least 4 FEM positions for a cubic spline, got {n}")
