r"""Inversion of the FEM tables Psi(i, x), F(i, x) to the real-time maps i_f(Psi, x), F(Psi, x) (paper eqs. 2-3).

Each column Psi(i) at fixed x is inverted exactly at every node of a regular flux grid; the flux grid
is made fine enough (automatic ``npsi``) that the round trip Psi -> i_f -> Psi stays within
``ROUND_TRIP_TARGET`` (0.05 %) between its nodes (:func:`round_trip_error`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import MapsError
from .interpolate import ForceColumns, i_f_at, psi_at, psi_columns
from .tables import ARRAY_UNITS, INTERPOLATION, CharacteristicMaps, first_non_increasing, problem_message

__all__ = ["ROUND_TRIP_TARGET", "invert_maps", "round_trip_error"]

#: Target of the automatic flux-grid size: round trip Psi -> i_f -> Psi between nodes (relative).
ROUND_TRIP_TARGET = 5e-4
_NPSI_CANDIDATES = (101, 201, 401, 801, 1601, 3201)


def _check_monotone(x_m: np.ndarray, i_A: np.ndarray, psi_ix_Wb: np.ndarray) -> None:
    problems = []
    for j, x in enumerate(x_m):
        k = first_non_increasing(psi_ix_Wb[:, j])
        if k is not None:
            problems.append(
                f"at x = {x * 1e3:.4g} mm, Psi does not rise strictly with current between "
                f"i = {i_A[k]:.4g} A (Psi = {psi_ix_Wb[k, j]:.6g} Wb) and i = {i_A[k + 1]:.4g} A "
                f"(Psi = {psi_ix_Wb[k + 1, j]:.6g} Wb)"
            )
    if problems:
        raise MapsError(problem_message("flux linkage table Psi(i, x) cannot be inverted", problems))


def _invert_tables(x_m, i_A, psi_ix_Wb, force_ix_N, psi_Wb):
    """i_f, F and the extrapolation flags on the flux grid ``psi_Wb`` (see :func:`invert_maps`)."""
    arrays = {"i_A": i_A, "psi_ix_Wb": psi_ix_Wb, "force_ix_N": force_ix_N}
    psi_spline = psi_columns(arrays)
    force_columns = ForceColumns(arrays)
    npsi, nx = len(psi_Wb), len(x_m)
    i_f = np.empty((npsi, nx))
    force = np.empty((npsi, nx))
    flags = np.zeros((npsi, nx))
    for j in range(nx):
        col = psi_ix_Wb[:, j]
        tol = 1e-12 * max(col[-1], psi_Wb[-1])
        inside = (psi_Wb >= col[0] - tol) & (psi_Wb <= col[-1] + tol)
        p_in = np.clip(psi_Wb[inside], col[0], col[-1])
        k = np.clip(np.searchsorted(col, p_in, side="right") - 1, 0, len(col) - 2)
        lo, hi = i_A[k].copy(), i_A[k + 1].copy()
        coeffs = psi_spline.c[:, :, j]  # (4, ni-1) local power basis per interval
        for _ in range(64):  # bisection on the strictly increasing cubic: exact to rounding
            mid = 0.5 * (lo + hi)
            t = mid - i_A[k]
            val = ((coeffs[0, k] * t + coeffs[1, k]) * t + coeffs[2, k]) * t + coeffs[3, k]
            below = val < p_in
            lo = np.where(below, mid, lo)
            hi = np.where(below, hi, mid)
        i_in = 0.5 * (lo + hi)
        i_f[inside, j] = i_in
        force[inside, j] = force_columns(i_in)[:, j]
        for side in ("low", "high"):
            sel = (psi_Wb < col[0] - tol) if side == "low" else (psi_Wb > col[-1] + tol)
            if not sel.any():
                continue
            a, b = (0, 1) if side == "low" else (-2, -1)
            slope_i = (i_A[b] - i_A[a]) / (col[b] - col[a])
            slope_f = (force_ix_N[b, j] - force_ix_N[a, j]) / (col[b] - col[a])
            i_f[sel, j] = i_A[b] + slope_i * (psi_Wb[sel] - col[b])
            force[sel, j] = force_ix_N[b, j] + slope_f * (psi_Wb[sel] - col[b])
            flags[sel, j] = 1.0
    return i_f, force, flags


def _round_trip_on_columns(x_m, i_A, psi_ix_Wb, psi_Wb, i_f) -> float:
    """Max relative round-trip error at the grid columns, on flux nodes and midpoints (bilinear)."""
    spline = psi_columns({"i_A": i_A, "psi_ix_Wb": psi_ix_Wb})
    worst = 0.0
    mids = 0.5 * (psi_Wb[1:] + psi_Wb[:-1])
    for j in range(len(x_m)):
        psi_max = psi_ix_Wb[-1, j]
        for p, i in ((psi_Wb, i_f[:, j]), (mids, 0.5 * (i_f[1:, j] + i_f[:-1, j]))):
            sel = (p > 0) & (p <= psi_max)
            if not sel.any():
                continue
            back = spline(np.clip(i[sel], i_A[0], i_A[-1]))[:, j]
            worst = max(worst, float(np.max(np.abs(back - p[sel]) / p[sel])))
    return worst


def invert_maps(
    x_m, i_A, psi_ix_Wb, force_ix_N, force_stress_ix_N, metadata: dict | None = None, npsi: int | None = None
) -> CharacteristicMaps:
    """Build :class:`CharacteristicMaps` from FEM tables on the (i, x) grid (paper eqs. 2 and 3).

    Each column Psi(i) at fixed x is checked to rise strictly with i, interpolated by a monotone cubic
    Hermite interpolant and inverted exactly at every node of a regular flux grid ``psi_Wb`` (0 to the
    max over x of Psi(i_max, x)) to give i_f(Psi, x); F(Psi, x) is the force column's interpolant (see
    :func:`force_at`) evaluated at i_f along the same column. Flux nodes
    above a column's own data are filled by linear extrapolation from the column's last two sweep
    points and flagged in ``extrapolated``.

    Parameters
    ----------
    x_m : array-like, shape (nx,)
        Working-gap positions [m].
    i_A : array-like, shape (ni,)
        Currents [A], starting at 0.
    psi_ix_Wb, force_ix_N, force_stress_ix_N : array-like, shape (ni, nx)
        Flux linkage [Wb], co-energy force [N], Maxwell-stress force [N].
    metadata : dict, optional
        Stored with the maps (name, coil, provenance, ...).
    npsi : int, optional
        Flux-grid size; by default the smallest of 101, 201, 401, ... whose round trip
        Psi -> i_f -> Psi between nodes stays within 0.05 % on every column.

    Raises
    ------
    MapsError
        Psi does not rise strictly with i (names x and i), or malformed arrays.
    """
    x_m = np.asarray(x_m, dtype=np.float64)
    i_A = np.asarray(i_A, dtype=np.float64)
    psi_ix_Wb = np.asarray(psi_ix_Wb, dtype=np.float64)
    force_ix_N = np.asarray(force_ix_N, dtype=np.float64)
    force_stress_ix_N = np.asarray(force_stress_ix_N, dtype=np.float64)
    check_fem_tables(x_m, i_A, psi_ix_Wb, force_ix_N, force_stress_ix_N)
    psi_top = float(np.max(psi_ix_Wb[-1]))
    candidates = _NPSI_CANDIDATES if npsi is None else (int(npsi),)
    if npsi is not None and npsi < 2:
        raise MapsError(f"npsi must be at least 2, got {npsi}")
    for n in candidates:
        psi_Wb = np.linspace(0.0, psi_top, n)
        i_f, force, flags = _invert_tables(x_m, i_A, psi_ix_Wb, force_ix_N, psi_Wb)
        err = _round_trip_on_columns(x_m, i_A, psi_ix_Wb, psi_Wb, i_f)
        if err <= ROUND_TRIP_TARGET:
            break
    meta = dict(metadata or {})
    meta.setdefault("force_method", "coenergy")
    meta["units"] = dict(ARRAY_UNITS)
    meta["interpolation"] = dict(INTERPOLATION)
    meta["round_trip_max_rel_error"] = err
    maps = CharacteristicMaps(
        x_m=x_m, i_A=i_A, psi_ix_Wb=psi_ix_Wb, force_ix_N=force_ix_N, force_stress_ix_N=force_stress_ix_N,
        psi_Wb=psi_Wb, i_f_A=i_f, force_N=force, extrapolated=flags, metadata=meta,
    )
    meta["round_trip_max_rel_error_between_positions"] = round_trip_error(
        maps, 0.5 * (x_m[1:] + x_m[:-1])
    )
    return dataclasses.replace(maps, metadata=meta)


def check_fem_tables(x_m, i_A, psi_ix_Wb, force_ix_N, force_stress_ix_N) -> None:
    """MapsError naming what makes the FEM tables on the (i, x) grid unusable: shapes, NaN, grids, a Psi(i)
    column that does not rise strictly (with its x and i)."""
    problems = _table_problems(x_m, i_A, psi_ix_Wb, force_ix_N, force_stress_ix_N)
    if problems:
        raise MapsError(problem_message("FEM tables", problems))
    _check_monotone(x_m, i_A, psi_ix_Wb)


def _table_problems(x_m, i_A, psi, force, stress) -> list[str]:
    """Problems of the FEM tables on the (i, x) grid (shapes, NaN, grids); monotonicity is separate."""
    problems = []
    if x_m.ndim != 1 or len(x_m) < 2:
        problems.append(f"x_m must be 1-D with at least 2 positions, has shape {x_m.shape}")
    if i_A.ndim != 1 or len(i_A) < 3:
        problems.append(f"i_A must be 1-D with at least 3 currents, has shape {i_A.shape}")
    if problems:
        return problems
    for name, arr in (("psi_ix_Wb", psi), ("force_ix_N", force), ("force_stress_ix_N", stress)):
        if arr.shape != (len(i_A), len(x_m)):
            problems.append(f"{name} has shape {arr.shape}, expected {(len(i_A), len(x_m))}")
        elif not np.isfinite(arr).all():
            first = tuple(int(k) for k in np.argwhere(~np.isfinite(arr))[0])
            problems.append(f"{name} has NaN/inf at index {first}")
    for name, arr in (("x_m", x_m), ("i_A", i_A)):
        if not np.isfinite(arr).all() or (np.diff(arr) <= 0).any():
            problems.append(f"grid {name} must be finite and strictly increasing")
    if i_A[0] != 0.0:
        problems.append(f"i_A must start at 0 A, starts at {i_A[0]:.6g} A")
    return problems


def round_trip_error(maps: CharacteristicMaps, x_m=None, points_per_interval: int = 2) -> float:
    """Max relative error of the round trip Psi -> i_f(Psi, x) -> Psi(i_f, x).

    i_f comes from the (Psi, x) map (bilinear, :func:`i_f_at`), Psi back from the FEM table
    (:func:`psi_at`); test fluxes are the flux-grid nodes and ``points_per_interval - 1`` points
    between each pair, up to the column's own Psi(i_max, x) (no extrapolated part), Psi > 0.

    At the map's own positions (the default) the error comes only from the bilinear interpolation
    between flux-grid nodes (the nodes are exact inverses). Between positions it also contains the
    difference between linear interpolation of i_f and spline interpolation of Psi in x.

    Parameters
    ----------
    maps : CharacteristicMaps
    x_m : array-like, optional
        Positions [m] to test; default: the map's grid positions.
    points_per_interval : int
        Subdivisions of each flux-grid interval (2 = nodes and midpoints).

    Returns
    -------
    float
        max |Psi_back - Psi| / Psi over all test points.
    """
    if x_m is None:
        x_m = maps.x_m
    x_m = np.atleast_1d(np.asarray(x_m, dtype=np.float64))
    t = np.arange(points_per_interval) / points_per_interval
    p = (maps.psi_Wb[:-1, None] + t[None, :] * np.diff(maps.psi_Wb)[:, None]).ravel()
    p = np.append(p, maps.psi_Wb[-1])
    worst = 0.0
    for x in x_m:
        psi_max = float(psi_at(maps, maps.i_A[-1], x))
        sel = p[(p > 0) & (p <= psi_max)]
        i_f = i_f_at(maps, sel, x)
        back = psi_at(maps, np.clip(i_f, maps.i_A[0], maps.i_A[-1]), x)
        worst = max(worst, float(np.max(np.abs(back - sel) / sel)))
    return worst


