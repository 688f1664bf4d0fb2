"""Lookups on the characteristic maps: Psi(i, x) and F(i, x) from the FEM tables, i_f(Psi, x) and F(Psi, x).

Interpolation conventions (written into ``maps.json`` under ``"interpolation"``,
:data:`solenoid_fmu.maps.tables.INTERPOLATION`):

- (i, x) tables: along i a monotone cubic Hermite interpolant for Psi (slopes from a not-a-knot
  cubic spline of the secant inductance Psi / i, limited by the Hyman filter
  ``0 <= d <= 3 min(adjacent secants)``, so Psi(i) stays strictly increasing); for F a not-a-knot
  cubic spline of F / i^2 times i^2 (exact F ~ i^2 at low currents, no ringing from the saturation
  knee); along x a not-a-knot cubic spline for both.
- (Psi, x) tables: bilinear (what a real-time model and Modelica ``CombiTable2D`` with
  ``LinearSegments`` do). Flux lookups up to ``FLUX_EXTRAPOLATION_LIMIT`` (5 %) of the flux span past
  the last node extrapolate linearly from the last flux interval, with one logged warning per lookup.

Units are SI (m, A, Wb, N); the force is positive when it closes the working gap x.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from ..errors import MapsError
from .tables import CharacteristicMaps

__all__ = [
    "FLUX_EXTRAPOLATION_LIMIT",
    "ForceColumns",
    "force_at",
    "force_psi_at",
    "i_f_at",
    "psi_at",
    "psi_columns",
]

#: Flux-linkage lookups (:func:`i_f_at`, :func:`force_psi_at`) up to this share of the flux table's span past
#: its last node are extrapolated linearly from the last flux interval, with one logged warning per lookup
#: (a measured flux a hair above the map's range must not stop a fit); further out they are refused.
FLUX_EXTRAPOLATION_LIMIT = 0.05

log = logging.getLogger(__name__)


def _psi_slopes(i_A: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """Node slopes dPsi/di for a monotone cubic Hermite interpolant of Psi(i) per column.

    The slopes come from a not-a-knot cubic spline of the secant inductance L = Psi / i
    (``L(0) := L(i_1)``; dPsi/di = L + i dL/di): L is flat in the linear-iron range and bends only
    at the saturation knee, so the spline does not ring between the origin and the knee as a spline
    of Psi itself does. The slopes are then limited to ``0 <= d_k <= 3 min(S_{k-1}, S_k)``
    (Hyman 1983, S the secants), which keeps every cubic piece increasing.

    Parameters
    ----------
    i_A : ndarray, shape (n,)
        Currents [A], strictly increasing, ``i_A[0] == 0``.
    psi : ndarray, shape (n, m)
        Flux linkage [Wb], each column strictly increasing.
    """
    L = np.empty_like(psi)
    L[1:] = psi[1:] / i_A[1:, None]
    L[0] = L[1]
    spline = CubicSpline(i_A, L, axis=0)
    d = spline(i_A) + i_A[:, None] * spline.derivative()(i_A)
    s = np.diff(psi, axis=0) / np.diff(i_A)[:, None]
    lim = np.empty_like(d)
    lim[0] = 3.0 * s[0]
    lim[-1] = 3.0 * s[-1]
    lim[1:-1] = 3.0 * np.minimum(s[:-1], s[1:])
    return np.clip(d, 0.0, lim)


def psi_columns(maps_or_arrays) -> CubicHermiteSpline:
    """Psi(i) per x column as one CubicHermiteSpline (values shape (nx,) per current), from a
    :class:`CharacteristicMaps` or a dict with ``i_A`` and ``psi_ix_Wb``."""
    i_A, psi = _get(maps_or_arrays, "i_A"), _get(maps_or_arrays, "psi_ix_Wb")
    return CubicHermiteSpline(i_A, psi, _psi_slopes(i_A, psi), axis=0)


class ForceColumns:
    """F(i) along each x column: a not-a-knot cubic spline of g = F / i^2, and F = i^2 g(i).

    At low currents F grows like i^2 (linear iron); g is smooth there and finite at i = 0
    (``g(0) := g(i_1)``), so F(0) = 0 exactly and the spline does not ring between the origin and
    the saturation knee. Calling with currents gives (n, nx).
    """

    def __init__(self, maps_or_arrays, name: str = "force_ix_N"):
        i_A, force_ix = _get(maps_or_arrays, "i_A"), _get(maps_or_arrays, name)
        g = np.empty_like(force_ix)
        g[1:] = force_ix[1:] / (i_A[1:, None] ** 2)
        g[0] = g[1]
        self.g = CubicSpline(i_A, g, axis=0)

    def __call__(self, i_A: np.ndarray) -> np.ndarray:
        i_A = np.asarray(i_A, dtype=np.float64)
        return i_A[:, None] ** 2 * self.g(i_A)


def _get(obj, name):
    return obj[name] if isinstance(obj, dict) else getattr(obj, name)


def _x_weights(x_grid: np.ndarray, x_q: np.ndarray, nu: int = 0) -> np.ndarray:
    """Weights w (n, nx) so that the not-a-knot cubic spline in x through values v is ``w @ v``."""
    spline = CubicSpline(x_grid, np.eye(len(x_grid)), axis=0)
    return spline(x_q, nu) if nu else spline(x_q)


def _flat_query(values, x_m, what: str) -> tuple[np.ndarray, np.ndarray, tuple]:
    """A query's values (``what``: current or flux) and positions broadcast together: both flat, and the shape."""
    v = np.asarray(values, dtype=np.float64)
    x = np.asarray(x_m, dtype=np.float64)
    try:
        v, x = np.broadcast_arrays(v, x)
    except ValueError:
        raise MapsError(f"{what} shape {v.shape} and position shape {x.shape} do not broadcast") from None
    return v.ravel(), x.ravel(), v.shape


def _query(maps: CharacteristicMaps, i_A, x_m) -> tuple[np.ndarray, np.ndarray, tuple]:
    i, x, shape = _flat_query(i_A, x_m, "current")
    _check_range(i, maps.i_A, "current", "A", 1.0)
    _check_range(x, maps.x_m, "position", "mm", 1e3)
    return i, x, shape


def _check_range(values: np.ndarray, grid: np.ndarray, what: str, unit: str, scale: float) -> None:
    if not np.isfinite(values).all():
        raise MapsError(f"{what} query contains NaN/inf")
    tol = 1e-9 * (grid[-1] - grid[0])
    bad = (values < grid[0] - tol) | (values > grid[-1] + tol)
    if bad.any():
        v = values[np.argmax(bad)]
        raise MapsError(
            f"{what} {v * scale:.6g} {unit} is outside the map's table "
            f"[{grid[0] * scale:.6g}, {grid[-1] * scale:.6g}] {unit}"
        )


def _check_flux_range(psi: np.ndarray, grid: np.ndarray, where: str) -> None:
    """Refuse flux linkage [Wb] outside the flux grid, except up to ``FLUX_EXTRAPOLATION_LIMIT`` of its span
    past the last node, which :func:`_bilinear` extrapolates linearly (one logged warning per call)."""
    prefix = f"{where}: " if where else ""
    if not np.isfinite(psi).all():
        raise MapsError(f"{prefix}flux linkage query contains NaN/inf")
    span = grid[-1] - grid[0]
    tol = 1e-9 * span
    top = grid[-1] + FLUX_EXTRAPOLATION_LIMIT * span
    far = (psi < grid[0] - tol) | (psi > top)
    if far.any():
        v = psi[np.argmax(far)]
        why = (f" by more than {FLUX_EXTRAPOLATION_LIMIT * 100:g} % of its span (lookups up to {top:.6g} Wb are "
               "extrapolated): sweep the maps to a higher current") if v > top else ""
        raise MapsError(f"{prefix}flux linkage {v:.6g} Wb is outside the map's table "
                        f"[{grid[0]:.6g}, {grid[-1]:.6g}] Wb{why}")
    over = psi > grid[-1] + tol
    if over.any():
        v = float(psi.max())
        log.warning("%s%d of %d flux-linkage lookups lie past the map's last flux node %.6g Wb (up to %.6g Wb, "
                    "%.3g %% of the table span): extrapolated linearly from the last flux interval",
                    prefix, int(over.sum()), psi.size, grid[-1], v, 100 * (v - grid[-1]) / span)


def psi_at(maps: CharacteristicMaps, i_A, x_m) -> np.ndarray:
    """Flux linkage Psi(i, x) [Wb] interpolated from the FEM table ``psi_ix_Wb``.

    Parameters
    ----------
    maps : CharacteristicMaps
    i_A : array-like
        Coil current [A], inside ``[maps.i_A[0], maps.i_A[-1]]``.
    x_m : array-like
        Working-gap position [m], inside ``[maps.x_m[0], maps.x_m[-1]]``; broadcast with ``i_A``.

    Returns
    -------
    ndarray
        Psi [Wb], broadcast shape of the inputs. Monotone cubic Hermite in i, cubic spline in x.

    Raises
    ------
    MapsError
        A query outside the table (named with its value) or NaN.
    """
    i, x, shape = _query(maps, i_A, x_m)
    cols = psi_columns(maps)(i)
    return np.sum(cols * _x_weights(maps.x_m, x), axis=1).reshape(shape)


def force_at(maps: CharacteristicMaps, i_A, x_m, stress: bool = False) -> np.ndarray:
    """Force F(i, x) [N] interpolated from ``force_ix_N`` (positive closes the gap).

    Parameters
    ----------
    maps : CharacteristicMaps
    i_A : array-like
        Coil current [A] inside the table.
    x_m : array-like
        Working-gap position [m] inside the table; broadcast with ``i_A``.
    stress : bool
        Interpolate the Maxwell-stress table ``force_stress_ix_N`` instead.

    Returns
    -------
    ndarray
        F [N]; per x column F = i^2 g(i) with a cubic spline g, then a cubic spline in x.
    """
    i, x, shape = _query(maps, i_A, x_m)
    cols = ForceColumns(maps, "force_stress_ix_N" if stress else "force_ix_N")(i)
    return np.sum(cols * _x_weights(maps.x_m, x), axis=1).reshape(shape)


def _bilinear(maps: CharacteristicMaps, table: np.ndarray, psi_Wb, x_m, allow_extrapolated: bool, where: str = ""):
    p, x, shape = _flat_query(psi_Wb, x_m, "flux")
    _check_flux_range(p, maps.psi_Wb, where)
    _check_range(x, maps.x_m, "position", "mm", 1e3)
    jp = np.clip(np.searchsorted(maps.psi_Wb, p, side="right") - 1, 0, len(maps.psi_Wb) - 2)
    jx = np.clip(np.searchsorted(maps.x_m, x, side="right") - 1, 0, len(maps.x_m) - 2)
    tp = (p - maps.psi_Wb[jp]) / (maps.psi_Wb[jp + 1] - maps.psi_Wb[jp])
    tx = (x - maps.x_m[jx]) / (maps.x_m[jx + 1] - maps.x_m[jx])
    if not allow_extrapolated:
        flags = maps.extrapolated
        used = np.maximum.reduce(
            [flags[jp, jx] * (1 - tp) * (1 - tx), flags[jp + 1, jx] * tp * (1 - tx),
             flags[jp, jx + 1] * (1 - tp) * tx, flags[jp + 1, jx + 1] * tp * tx]
        )
        if (used > 0).any():
            k = int(np.argmax(used > 0))
            raise MapsError(
                f"(psi = {p[k]:.6g} Wb, x = {x[k] * 1e3:.4g} mm) lies in the extrapolated part of the map"
            )
    v = (
        table[jp, jx] * (1 - tp) * (1 - tx)
        + table[jp + 1, jx] * tp * (1 - tx)
        + table[jp, jx + 1] * (1 - tp) * tx
        + table[jp + 1, jx + 1] * tp * tx
    )
    return v.reshape(shape)


def i_f_at(maps: CharacteristicMaps, psi_Wb, x_m, allow_extrapolated: bool = True, *, where: str = "") -> np.ndarray:
    """Field-generating current i_f(Psi, x) [A] (paper eq. 2), bilinear on the map.

    Parameters
    ----------
    maps : CharacteristicMaps
    psi_Wb : array-like
        Flux linkage [Wb] inside ``[0, maps.psi_Wb[-1]]``; up to ``FLUX_EXTRAPOLATION_LIMIT`` (5 %) of the
        flux span past the last node it is extrapolated linearly from the last flux interval, with one
        logged warning per call.
    x_m : array-like
        Working-gap position [m] inside the table; broadcast with ``psi_Wb``.
    allow_extrapolated : bool
        When False, raise MapsError if a query uses an extrapolated table node.
    where : str
        What the flux comes from (e.g. a recording's file name), to start the warning and error messages.
    """
    return _bilinear(maps, maps.i_f_A, psi_Wb, x_m, allow_extrapolated, where)


def force_psi_at(maps: CharacteristicMaps, psi_Wb, x_m, allow_extrapolated: bool = True, *,
                 where: str = "") -> np.ndarray:
    """Force F(Psi, x) [N] (paper eq. 3, positive closes the gap), bilinear on the map.

    Parameters are those of :func:`i_f_at`.
    """
    return _bilinear(maps, maps.force_N, psi_Wb, x_m, allow_extrapolated, where)


