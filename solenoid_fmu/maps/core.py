r"""Characteristic maps: FEM sweep over (i, x), inversion to i_f(Psi, x) and F(Psi, x), file format, exports.

The real-time model does not run the FEM; it runs on two characteristic maps (paper section 5,
figures 12 and 13):

.. math::

    U = R\,i + \frac{d\Psi}{dt} \quad (1), \qquad
    i = i_f(\Psi, x) + G_{eddy}\,\frac{d\Psi}{dt} \quad (2), \qquad
    F = F(\Psi, x) \quad (3)

This module

1. sweeps the FEM over a grid of armature working-gap positions ``x_m`` and coil currents ``i_A``
   (one task per position, warm-started along the current list inside
   :func:`solenoid_fmu.fem.sweep_currents`), in parallel on any :class:`concurrent.futures.Executor`;
2. inverts each column Psi(i) at fixed x to i_f(Psi, x) on a regular flux grid, and carries the
   co-energy force along to F(Psi, x);
3. stores everything as ``maps.npz`` (``allow_pickle=False``) plus a ``maps.json`` sidecar with
   schema version, units and provenance, and reads it back refusing anything malformed;
4. interpolates the (i, x) tables (:func:`psi_at`, :func:`force_at`) and the (Psi, x) tables
   (:func:`i_f_at`, :func:`force_psi_at`), checks energy consistency around closed cycles
   (:func:`cycle_energy_balance`), exports Modelica ``CombiTable2D`` text files and a MATLAB
   ``.mat`` file, and plots the maps.

Units are SI everywhere (m, A, Wb, N); the CLI takes millimetres for positions.
Force sign: positive when the magnetic force pulls the armature towards the pole (closes the
working gap x).

Interpolation conventions (written into ``maps.json`` under ``"interpolation"``):

- (i, x) tables: along i a monotone cubic Hermite interpolant for Psi (slopes from a not-a-knot
  cubic spline of the secant inductance Psi / i, limited by the Hyman filter
  ``0 <= d <= 3 min(adjacent secants)``, so Psi(i) stays strictly increasing); for F a not-a-knot
  cubic spline of F / i^2 times i^2 (exact F ~ i^2 at low currents, no ringing from the saturation
  knee); along x a not-a-knot cubic spline for both.
- (Psi, x) tables: bilinear (what a real-time model and Modelica ``CombiTable2D`` with
  ``LinearSegments`` do). ``i_f`` at the flux grid nodes is the exact inverse of the Psi(i)
  interpolant above, so the round trip Psi -> i_f -> Psi is exact on the nodes; the flux grid is made
  fine enough (automatic ``npsi``) that it stays within 0.05 % between them. Flux lookups up to
  ``FLUX_EXTRAPOLATION_LIMIT`` (5 %) of the flux span past the last node extrapolate linearly from the last
  flux interval, with one logged warning per lookup.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import dataclasses
import datetime as _dt
import hashlib
import io
import json
import logging
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..errors import MapsError, SolenoidError
from ..fileio import atomic_write_bytes

__all__ = [
    "SCHEMA",
    "SCHEMA_VERSION",
    "ARRAY_UNITS",
    "CharacteristicMaps",
    "CycleEnergy",
    "InlineExecutor",
    "build_maps",
    "default_positions",
    "default_currents",
    "invert_maps",
    "save_maps",
    "load_maps",
    "psi_at",
    "force_at",
    "i_f_at",
    "force_psi_at",
    "round_trip_error",
    "cycle_energy_balance",
    "rectangle_cycle",
    "export_combitable2d",
    "read_combitable2d",
    "export_mat",
    "plot_maps",
    "add_cli",
]

#: Schema name written into and required from ``maps.json``.
SCHEMA = "solenoid-fmu-maps"
#: The only schema version this reader accepts.
SCHEMA_VERSION = 1
#: Array names in ``maps.npz`` with their units (the ``"units"`` entry of the sidecar).
ARRAY_UNITS = {
    "x_m": "m",
    "i_A": "A",
    "psi_ix_Wb": "Wb",
    "force_ix_N": "N",
    "force_stress_ix_N": "N",
    "psi_Wb": "Wb",
    "i_f_A": "A",
    "force_N": "N",
    "extrapolated": "1",
}
#: Force methods a map may carry; the tables ``force_ix_N``/``force_N`` hold this one.
FORCE_METHODS = ("coenergy", "maxwell_stress")
NPZ_NAME = "maps.npz"
JSON_NAME = "maps.json"
#: Default grid: positions over the whole stroke, currents 0 .. 1.25 x the coil's max current.
DEFAULT_NX = 27
DEFAULT_NI = 26
DEFAULT_CURRENT_FACTOR = 1.25
#: Flux-linkage lookups (:func:`i_f_at`, :func:`force_psi_at`) up to this share of the flux table's span past
#: its last node are extrapolated linearly from the last flux interval, with one logged warning per lookup
#: (a measured flux a hair above the map's range must not stop a fit); further out they are refused.
FLUX_EXTRAPOLATION_LIMIT = 0.05
#: Target of the automatic flux-grid size: round trip Psi -> i_f -> Psi between nodes (relative).
ROUND_TRIP_TARGET = 5e-4
_NPSI_CANDIDATES = (101, 201, 401, 801, 1601, 3201)

INTERPOLATION = {
    "psi_ix_Wb": "monotone cubic Hermite in i (slopes from a spline of Psi / i, Hyman filter); "
                 "not-a-knot cubic spline in x",
    "force_ix_N": "per x column F = i^2 g(i), g a not-a-knot cubic spline of F / i^2 (g(0) = g(i_1)); "
                  "not-a-knot cubic spline in x",
    "i_f_A": "bilinear in (psi, x); nodes are the exact inverse of the psi_ix_Wb interpolant",
    "force_N": "bilinear in (psi, x); nodes = the force_ix_N interpolant at i_f along the column",
    "extrapolation": "linear from the last two sweep points of each x column (flagged in 'extrapolated')",
}

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------------------------
# The maps object
# --------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True, eq=False)
class CharacteristicMaps:
    """Characteristic maps of one solenoid (immutable; arrays are read-only float64).

    Parameters
    ----------
    x_m : ndarray, shape (nx,)
        Armature working-gap positions [m], strictly increasing.
    i_A : ndarray, shape (ni,)
        Coil currents [A], strictly increasing, ``i_A[0] == 0``.
    psi_ix_Wb : ndarray, shape (ni, nx)
        Flux linkage Psi(i, x) from the FEM [Wb].
    force_ix_N : ndarray, shape (ni, nx)
        Force F(i, x) by the method ``metadata["force_method"]`` [N]; positive closes the gap.
    force_stress_ix_N : ndarray, shape (ni, nx)
        Maxwell-stress force F(i, x) for reference [N].
    psi_Wb : ndarray, shape (npsi,)
        Regular flux-linkage grid from 0 to max over x of Psi(i_max, x) [Wb].
    i_f_A : ndarray, shape (npsi, nx)
        Field-generating current i_f(Psi, x) [A] (paper eq. 2, fig. 13).
    force_N : ndarray, shape (npsi, nx)
        Force F(Psi, x) [N] (paper eq. 3, fig. 12).
    extrapolated : ndarray, shape (npsi, nx)
        1.0 where (Psi, x) lies beyond the column's own FEM data, else 0.0.
    metadata : dict
        The JSON sidecar content except the arrays: name, force_method, units, coil, eddy,
        provenance, interpolation.
    """

    x_m: np.ndarray
    i_A: np.ndarray
    psi_ix_Wb: np.ndarray
    force_ix_N: np.ndarray
    force_stress_ix_N: np.ndarray
    psi_Wb: np.ndarray
    i_f_A: np.ndarray
    force_N: np.ndarray
    extrapolated: np.ndarray
    metadata: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        arrays = {}
        for name in ARRAY_UNITS:
            value = getattr(self, name)
            try:
                arr = np.array(value, dtype=np.float64)  # a private copy
            except (TypeError, ValueError) as exc:
                raise MapsError(f"CharacteristicMaps: array {name!r} is not numeric: {exc}") from None
            arr.setflags(write=False)
            arrays[name] = arr
        problems = _array_problems(arrays)
        if problems:
            raise MapsError(_problem_message("CharacteristicMaps", problems))
        for name, arr in arrays.items():
            object.__setattr__(self, name, arr)
        try:
            meta = json.loads(json.dumps(self.metadata, allow_nan=False))
        except (TypeError, ValueError) as exc:
            raise MapsError(f"CharacteristicMaps: metadata must be JSON data without NaN: {exc}") from None
        if not isinstance(meta, dict):
            raise MapsError("CharacteristicMaps: metadata must be a dict")
        object.__setattr__(self, "metadata", meta)

    @property
    def name(self) -> str:
        """The map's name (directory name under ``maps/``)."""
        return str(self.metadata.get("name", ""))

    @property
    def shape(self) -> tuple[int, int, int]:
        """Grid sizes ``(ni, nx, npsi)``."""
        return len(self.i_A), len(self.x_m), len(self.psi_Wb)

    def arrays(self) -> dict[str, np.ndarray]:
        """All arrays of the file format by name (read-only views)."""
        return {name: getattr(self, name) for name in ARRAY_UNITS}

    def with_eddy(self, G_eddy_S: float | None, source: str) -> CharacteristicMaps:
        """A copy with the eddy-current conductance of paper eq. (2) set.

        Parameters
        ----------
        G_eddy_S : float or None
            Eddy-current parameter [S] (A per V of induced voltage dPsi/dt); None = not identified.
        source : str
            Where the value comes from (recordings, fit), stored in the metadata.
        """
        if G_eddy_S is not None and not (math.isfinite(G_eddy_S) and G_eddy_S >= 0):
            raise MapsError(f"G_eddy_S must be a finite value >= 0 S, got {G_eddy_S!r}")
        meta = json.loads(json.dumps(self.metadata))
        meta["eddy"] = {"G_eddy_S": None if G_eddy_S is None else float(G_eddy_S), "source": str(source)}
        return dataclasses.replace(self, metadata=meta)


class InlineExecutor(cf.Executor):
    """An executor that runs each task at once in the calling thread (``--workers 1``, baselines)."""

    def submit(self, fn, /, *args, **kwargs):
        future: cf.Future = cf.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except Exception as exc:  # handed to the caller through the future, as other executors do
            future.set_exception(exc)
        return future


# --------------------------------------------------------------------------------------------
# Checks shared by the constructor and the reader
# --------------------------------------------------------------------------------------------


def _problem_message(what: str, problems: list[str]) -> str:
    lines = [f"{what}: {len(problems)} problem(s)"] + [f"  - {p}" for p in problems]
    return "\n".join(lines)


def _array_problems(arrays: dict[str, np.ndarray]) -> list[str]:
    """Every problem of a set of map arrays (missing, shape, NaN/inf, grids not monotone)."""
    problems: list[str] = []
    missing = [n for n in ARRAY_UNITS if n not in arrays]
    if missing:
        problems.append(f"missing array(s): {', '.join(missing)}")
        return problems
    a = arrays
    for name in ("x_m", "i_A", "psi_Wb"):
        if a[name].ndim != 1:
            problems.append(f"{name} must be 1-D, has shape {a[name].shape}")
    if problems:
        return problems
    nx, ni, npsi = len(a["x_m"]), len(a["i_A"]), len(a["psi_Wb"])
    if nx < 2:
        problems.append(f"x_m needs at least 2 positions, has {nx}")
    if ni < 3:
        problems.append(f"i_A needs at least 3 currents, has {ni}")
    if npsi < 2:
        problems.append(f"psi_Wb needs at least 2 points, has {npsi}")
    expected = {
        "psi_ix_Wb": (ni, nx),
        "force_ix_N": (ni, nx),
        "force_stress_ix_N": (ni, nx),
        "i_f_A": (npsi, nx),
        "force_N": (npsi, nx),
        "extrapolated": (npsi, nx),
    }
    for name, shape in expected.items():
        if a[name].shape != shape:
            problems.append(f"{name} has shape {a[name].shape}, expected {shape} from the grids")
    for name in ARRAY_UNITS:
        bad = ~np.isfinite(a[name])
        if bad.any():
            idx = tuple(int(k) for k in np.argwhere(bad)[0])
            problems.append(f"{name} has {int(bad.sum())} NaN/inf value(s), first at index {idx}")
    if problems:
        return problems
    for name, unit in (("x_m", "m"), ("i_A", "A"), ("psi_Wb", "Wb")):
        d = np.diff(a[name])
        if (d <= 0).any():
            k = int(np.argmax(d <= 0))
            problems.append(
                f"grid {name} is not strictly increasing: {name}[{k}] = {a[name][k]:.6g} {unit}, "
                f"{name}[{k + 1}] = {a[name][k + 1]:.6g} {unit}"
            )
    if a["i_A"][0] != 0.0:
        problems.append(f"i_A must start at 0 A, starts at {a['i_A'][0]:.6g} A")
    if a["psi_Wb"][0] != 0.0:
        problems.append(f"psi_Wb must start at 0 Wb, starts at {a['psi_Wb'][0]:.6g} Wb")
    if problems:
        return problems
    for j, x in enumerate(a["x_m"]):
        k = _first_non_increasing(a["psi_ix_Wb"][:, j])
        if k is not None:
            problems.append(
                f"psi_ix_Wb does not rise strictly with current at x = {x * 1e3:.4g} mm between "
                f"i = {a['i_A'][k]:.4g} A and {a['i_A'][k + 1]:.4g} A"
            )
        k = _first_non_increasing(a["i_f_A"][:, j])
        if k is not None:
            problems.append(
                f"i_f_A does not rise strictly with flux linkage at x = {x * 1e3:.4g} mm between "
                f"psi = {a['psi_Wb'][k]:.6g} Wb and {a['psi_Wb'][k + 1]:.6g} Wb"
            )
    flags = a["extrapolated"]
    if not np.isin(flags, (0.0, 1.0)).all():
        problems.append("extrapolated must hold only 0.0 and 1.0")
    return problems


def _first_non_increasing(values: np.ndarray) -> int | None:
    d = np.diff(values)
    bad = np.flatnonzero(~(d > 0))
    return int(bad[0]) if bad.size else None


# --------------------------------------------------------------------------------------------
# Interpolation on the (i, x) tables
# --------------------------------------------------------------------------------------------


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
    from scipy.interpolate import CubicSpline

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


def _psi_columns(maps_or_arrays) -> object:
    """Psi(i) per x column as one CubicHermiteSpline (values shape (nx,) per current)."""
    from scipy.interpolate import CubicHermiteSpline

    i_A, psi = _get(maps_or_arrays, "i_A"), _get(maps_or_arrays, "psi_ix_Wb")
    return CubicHermiteSpline(i_A, psi, _psi_slopes(i_A, psi), axis=0)


class _ForceColumns:
    """F(i) along each x column: a not-a-knot cubic spline of g = F / i^2, and F = i^2 g(i).

    At low currents F grows like i^2 (linear iron); g is smooth there and finite at i = 0
    (``g(0) := g(i_1)``), so F(0) = 0 exactly and the spline does not ring between the origin and
    the saturation knee. Calling with currents gives (n, nx).
    """

    def __init__(self, maps_or_arrays, name: str = "force_ix_N"):
        from scipy.interpolate import CubicSpline

        i_A, force_ix = _get(maps_or_arrays, "i_A"), _get(maps_or_arrays, name)
        g = np.empty_like(force_ix)
        g[1:] = force_ix[1:] / (i_A[1:, None] ** 2)
        g[0] = g[1]
        self.g = CubicSpline(i_A, g, axis=0)

    def __call__(self, i_A: np.ndarray) -> np.ndarray:
        i_A = np.asarray(i_A, dtype=np.float64)
        return i_A[:, None] ** 2 * self.g(i_A)


def _force_columns(maps_or_arrays, name: str = "force_ix_N") -> _ForceColumns:
    return _ForceColumns(maps_or_arrays, name)


def _get(obj, name):
    return obj[name] if isinstance(obj, dict) else getattr(obj, name)


def _x_weights(x_grid: np.ndarray, x_q: np.ndarray, nu: int = 0) -> np.ndarray:
    """Weights w (n, nx) so that the not-a-knot cubic spline in x through values v is ``w @ v``."""
    from scipy.interpolate import CubicSpline

    spline = CubicSpline(x_grid, np.eye(len(x_grid)), axis=0)
    return spline(x_q, nu) if nu else spline(x_q)


def _query(maps: CharacteristicMaps, i_A, x_m) -> tuple[np.ndarray, np.ndarray, tuple]:
    i = np.asarray(i_A, dtype=np.float64)
    x = np.asarray(x_m, dtype=np.float64)
    try:
        i, x = np.broadcast_arrays(i, x)
    except ValueError:
        raise MapsError(f"current shape {i.shape} and position shape {x.shape} do not broadcast") from None
    shape = i.shape
    i, x = i.ravel(), x.ravel()
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
    cols = _psi_columns(maps)(i)
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
    cols = _force_columns(maps, "force_stress_ix_N" if stress else "force_ix_N")(i)
    return np.sum(cols * _x_weights(maps.x_m, x), axis=1).reshape(shape)


def _bilinear(maps: CharacteristicMaps, table: np.ndarray, psi_Wb, x_m, allow_extrapolated: bool, where: str = ""):
    p = np.asarray(psi_Wb, dtype=np.float64)
    x = np.asarray(x_m, dtype=np.float64)
    try:
        p, x = np.broadcast_arrays(p, x)
    except ValueError:
        raise MapsError(f"flux shape {p.shape} and position shape {x.shape} do not broadcast") from None
    shape = p.shape
    p, x = p.ravel(), x.ravel()
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


# --------------------------------------------------------------------------------------------
# Inversion Psi(i, x) -> i_f(Psi, x), F(Psi, x)
# --------------------------------------------------------------------------------------------


def _check_monotone(x_m: np.ndarray, i_A: np.ndarray, psi_ix_Wb: np.ndarray) -> None:
    problems = []
    for j, x in enumerate(x_m):
        k = _first_non_increasing(psi_ix_Wb[:, j])
        if k is not None:
            problems.append(
                f"at x = {x * 1e3:.4g} mm, Psi does not rise strictly with current between "
                f"i = {i_A[k]:.4g} A (Psi = {psi_ix_Wb[k, j]:.6g} Wb) and i = {i_A[k + 1]:.4g} A "
                f"(Psi = {psi_ix_Wb[k + 1, j]:.6g} Wb)"
            )
    if problems:
        raise MapsError(_problem_message("flux linkage table Psi(i, x) cannot be inverted", problems))


def _invert_tables(x_m, i_A, psi_ix_Wb, force_ix_N, psi_Wb):
    """i_f, F and the extrapolation flags on the flux grid ``psi_Wb`` (see :func:`invert_maps`)."""
    arrays = {"i_A": i_A, "psi_ix_Wb": psi_ix_Wb, "force_ix_N": force_ix_N}
    psi_spline = _psi_columns(arrays)
    force_columns = _force_columns(arrays)
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
    spline = _psi_columns({"i_A": i_A, "psi_ix_Wb": psi_ix_Wb})
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
    problems = _table_problems(x_m, i_A, psi_ix_Wb, force_ix_N, force_stress_ix_N)
    if problems:
        raise MapsError(_problem_message("FEM tables", problems))
    _check_monotone(x_m, i_A, psi_ix_Wb)
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


# --------------------------------------------------------------------------------------------
# Sweep
# --------------------------------------------------------------------------------------------


def _default_sweep() -> Callable:
    from ..field import sweep_currents

    return sweep_currents


def _code_version() -> dict:
    from .. import __version__

    commit, dirty = "unknown", None
    here = Path(__file__).resolve().parent
    try:
        out = subprocess.run(
            ["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5
        )
        if out.returncode == 0 and out.stdout.strip():
            commit = out.stdout.strip()
            st = subprocess.run(
                ["git", "-C", str(here), "status", "--porcelain", "--untracked-files=no"],
                capture_output=True, text=True, timeout=5,
            )
            dirty = bool(st.stdout.strip()) if st.returncode == 0 else None
    except (OSError, subprocess.SubprocessError):
        pass
    short = commit[:12] if commit != "unknown" else "unknown"
    return {"code_version": f"{__version__}+{short}", "git_commit": commit, "git_dirty": dirty}


def _source(obj) -> dict:
    """Path (relative to the checkout when inside it, so shipped maps do not carry this machine's
    directories), sha256 and name of a geometry or material."""
    path = getattr(obj, "source_path", None)
    if path is not None:
        path = Path(path).resolve()
        root = Path(__file__).resolve().parent.parent
        path = path.relative_to(root).as_posix() if path.is_relative_to(root) else str(path)
    return {"path": path, "sha256": str(getattr(obj, "sha256", "") or ""),
            "name": str(getattr(obj, "name", "") or "")}


#: Most points of one sweep grid (positions or currents): 1000 x 1000 FEM solves is already days.
MAX_GRID_POINTS = 1000


def _grid(values, default, what: str, unit: str, scale: float) -> np.ndarray:
    if values is None:
        return default
    if np.size(values) > MAX_GRID_POINTS:
        raise MapsError(f"{what} grid has {np.size(values)} points, more than {MAX_GRID_POINTS}")
    try:
        arr = np.array(values, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise MapsError(f"{what} grid is not numeric: {values!r}") from None
    if arr.size < 2 or not np.isfinite(arr).all() or (np.diff(arr) <= 0).any():
        raise MapsError(
            f"{what} grid must hold at least 2 finite, strictly increasing values [{unit}], got "
            f"{np.array2string(arr * scale, precision=4)}"
        )
    return arr


def default_positions(x_min_m: float, x_max_m: float, n: int = DEFAULT_NX) -> np.ndarray:
    """Default sweep positions [m]: ``n`` points over [x_min, x_max], clustered at both stops.

    Cosine (Chebyshev-Lobatto) spacing: Psi and F bend most near the stops (at the small gap the
    field concentrates in the working gap; at full stroke the armature leaves the control cone),
    and the maps are read linearly in x between positions, whose error grows with the square of
    the spacing. With n = 27 over PS45's 3.3 mm stroke the steps run from 0.01 mm at the stops to
    0.2 mm mid-stroke, and the round trip Psi -> i_f -> Psi stays within 0.1 % between positions.
    """
    s = np.linspace(0.0, 1.0, n)
    x = x_min_m + (x_max_m - x_min_m) * 0.5 * (1.0 - np.cos(np.pi * s))
    x[0], x[-1] = x_min_m, x_max_m
    return x


def default_currents(i_top_A: float, n: int = DEFAULT_NI, power: float = 1.5) -> np.ndarray:
    """Default sweep currents [A]: ``i_top (k / (n - 1))^power``, k = 0 .. n - 1.

    Denser at low currents, where the iron leaves its linear range and Psi(i) and F(i) bend
    sharply (for PS45 with the literature curve the knee lies near 0.2 A); for n = 26 and
    ``i_top = 2.5 A`` the steps grow from 0.02 A to 0.15 A.
    """
    return i_top_A * (np.arange(n) / (n - 1)) ** power


def build_maps(
    geometry,
    material,
    x_m=None,
    i_A=None,
    mesh_size: float = 1.0,
    executor: cf.Executor | None = None,
    progress: bool = True,
    sweep: Callable | None = None,
    name: str | None = None,
    npsi: int | None = None,
) -> CharacteristicMaps:
    """Sweep the FEM over (i, x) and build the characteristic maps (paper section 5, eqs. 2-3).

    One task per position x runs ``sweep(geometry, material, x, i_A, mesh_size)`` (warm-started
    along the current list); tasks run on ``executor``. The result is inverted by
    :func:`invert_maps`.

    Parameters
    ----------
    geometry : Geometry
        Solenoid geometry (``solenoid_fmu.geometry.load_geometry``); uses ``name``, ``source_path``,
        ``sha256``, ``coil`` and ``stroke``.
    material : BHCurve
        B(H) curve (``solenoid_fmu.material.load_material``); uses ``source_path``, ``sha256``, ``name``.
    x_m : array-like, optional
        Working-gap positions [m], inside the stroke; default 27 positions (cosine spacing) over
        ``[stroke.min_m, stroke.max_m]``, graded towards small gaps (:func:`default_positions`).
    i_A : array-like, optional
        Currents [A], starting at 0; default 26 currents from 0 to 1.25 x ``coil.max_current_A``,
        denser at low currents (:func:`default_currents`).
    mesh_size : float
        Mesh-size factor handed to the sweep (1.0 = the FEM's default, larger = coarser).
    executor : concurrent.futures.Executor, optional
        Runs the per-position tasks: a ``ProcessPoolExecutor`` (default, ``os.cpu_count()`` workers),
        a ``ThreadPoolExecutor``, :class:`InlineExecutor`, or a Dask/Ray executor. An executor passed
        in is not shut down.
    progress : bool
        Show a tqdm progress bar with the time left on stderr.
    sweep : callable, optional
        ``sweep(geometry, material, x_m, i_A, mesh_size) -> dict`` with arrays ``psi_Wb``,
        ``force_N``, ``force_stress_N`` (and optionally ``newton_iterations``, ``newton_recovered``) of length
        ``len(i_A)``;
        default :func:`solenoid_fmu.fem.sweep_currents`. Must be picklable for process pools.
    name : str, optional
        Map name stored in the metadata; default the geometry's name.
    npsi : int, optional
        Flux-grid size (see :func:`invert_maps`).

    Returns
    -------
    CharacteristicMaps

    Raises
    ------
    MapsError
        Bad grids, a failed FEM task (naming x), non-monotone Psi(i) (naming x and i).
    """
    stroke, coil = geometry.stroke, geometry.coil
    x_default = default_positions(stroke.min_m, stroke.max_m, DEFAULT_NX)
    i_default = default_currents(DEFAULT_CURRENT_FACTOR * coil.max_current_A, DEFAULT_NI)
    x_m = _grid(x_m, x_default, "position", "mm", 1e3)
    i_A = _grid(i_A, i_default, "current", "A", 1.0)
    if i_A[0] != 0.0:
        raise MapsError(
            f"the current grid must start at 0 A (maps hold i_f from Psi = 0), starts at {i_A[0]:g} A"
        )
    if len(i_A) < 3:
        raise MapsError(f"the current grid needs at least 3 currents, got {len(i_A)}")
    tol = 1e-9
    outside = (x_m < stroke.min_m - tol) | (x_m > stroke.max_m + tol)
    if outside.any():
        raise MapsError(
            f"position {x_m[np.argmax(outside)] * 1e3:.4g} mm is outside the stroke of {geometry.name} "
            f"[{stroke.min_m * 1e3:.4g}, {stroke.max_m * 1e3:.4g}] mm"
        )
    if not (isinstance(mesh_size, int | float) and math.isfinite(mesh_size) and mesh_size > 0):
        raise MapsError(f"mesh_size must be a finite number > 0, got {mesh_size!r}")
    sweep = sweep if sweep is not None else _default_sweep()
    own_executor = executor is None
    if own_executor:
        executor = cf.ProcessPoolExecutor(max_workers=os.cpu_count() or 1)
    ni, nx = len(i_A), len(x_m)
    psi = np.empty((ni, nx))
    force = np.empty((ni, nx))
    stress = np.empty((ni, nx))
    newton = np.zeros((ni, nx))
    recovered = np.zeros((ni, nx))
    t0 = time.perf_counter()
    from tqdm.auto import tqdm

    bar = tqdm(total=ni * nx, desc="FEM sweep", unit="pt", file=sys.stderr, disable=not progress,
               dynamic_ncols=True)
    futures: dict[cf.Future, int] = {}
    pending: set[cf.Future] = set()

    def harvest(fut: cf.Future) -> None:
        j = futures[fut]
        try:
            result = fut.result()
        except SolenoidError as exc:
            raise MapsError(f"FEM sweep at x = {x_m[j] * 1e3:.4g} mm failed: {exc}") from exc
        psi[:, j], force[:, j], stress[:, j], newton[:, j], recovered[:, j] = _sweep_columns(result, ni, x_m[j])
        bar.update(ni)
        pending.discard(fut)

    try:
        for j, x in enumerate(x_m):
            fut = executor.submit(sweep, geometry, material, float(x), i_A.copy(), mesh_size)
            futures[fut] = j
            pending.add(fut)
            for done in [f for f in pending if f.done()]:  # inline executors: progress, early errors
                harvest(done)
        for fut in cf.as_completed(list(pending)):
            harvest(fut)
    except BaseException:
        for fut in futures:
            fut.cancel()
        raise
    finally:
        bar.close()
        if own_executor:
            executor.shutdown(wait=True, cancel_futures=True)
    wall = time.perf_counter() - t0
    workers = getattr(executor, "_max_workers", None)
    version = _code_version()
    sweep_name = f"{getattr(sweep, '__module__', '?')}.{getattr(sweep, '__qualname__', repr(sweep))}"
    solver = {
        "sweep": sweep_name,
        "mesh_size": float(mesh_size),
        "warm_start": "along the current list at each position",
        "executor": type(executor).__name__,
        "workers": workers,
        "wall_time_s": round(wall, 3),
        "operating_points": int(ni * nx),
        "newton_iterations_total": int(newton.sum()),
        "newton_iterations_max": int(newton.max()),
        # (x [mm], i [A]) of the points where Newton stalled (accepted) or was recovered by load stepping
        "newton_recovered_x_mm_i_A": [[float(x_m[j]) * 1e3, float(i_A[k])] for k, j in np.argwhere(recovered)],
    }
    fem_settings = getattr(sys.modules.get(getattr(sweep, "__module__", ""), None), "SOLVER_SETTINGS", None)
    if isinstance(fem_settings, dict):
        solver["fem_settings"] = json.loads(json.dumps(fem_settings, default=str))
    metadata = {
        "name": name or str(geometry.name),
        "force_method": "coenergy",
        "coil": {
            "turns": float(coil.turns),
            "resistance_ohm_20C": float(coil.resistance_ohm_20C),
            "temperature_coefficient_per_K": float(coil.temperature_coefficient_per_K),
            "max_current_A": float(coil.max_current_A),
        },
        "stroke": {
            "min_m": float(stroke.min_m), "max_m": float(stroke.max_m),
            "working_min_m": float(stroke.working_min_m), "working_max_m": float(stroke.working_max_m),
        },
        "eddy": {"G_eddy_S": None, "source": "not identified (the FEM is magnetostatic)"},
        "provenance": {
            "geometry": _source(geometry),
            "material": _source(material),
            "mesh_size": float(mesh_size),
            "code_version": version["code_version"],
            "git_commit": version["git_commit"],
            "git_dirty": version["git_dirty"],
            "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "solver": solver,
        },
    }
    return invert_maps(x_m, i_A, psi, force, stress, metadata=metadata, npsi=npsi)


def _sweep_columns(result, ni: int, x: float):
    where = f"FEM sweep at x = {x * 1e3:.4g} mm"
    if not isinstance(result, dict):
        raise MapsError(f"{where} returned {type(result).__name__}, expected a dict of arrays")
    cols = []
    for key in ("psi_Wb", "force_N", "force_stress_N"):
        if key not in result:
            raise MapsError(f"{where} returned no {key!r}")
        col = np.asarray(result[key], dtype=np.float64).ravel()
        if col.shape != (ni,):
            raise MapsError(f"{where}: {key!r} has {col.size} values for {ni} currents")
        if not np.isfinite(col).all():
            k = int(np.argmax(~np.isfinite(col)))
            raise MapsError(f"{where}: {key!r} has NaN/inf at current index {k}")
        cols.append(col)
    for key in ("newton_iterations", "newton_recovered"):
        extra = np.asarray(result.get(key, np.zeros(ni)), dtype=np.float64).ravel()
        cols.append(extra if extra.shape == (ni,) else np.zeros(ni))
    return cols


# --------------------------------------------------------------------------------------------
# File format
# --------------------------------------------------------------------------------------------


def _atomic_write(path: Path, data: bytes) -> None:
    atomic_write_bytes(path, data)


def save_maps(maps: CharacteristicMaps, directory) -> Path:
    """Write ``maps.npz`` + ``maps.json`` into ``directory`` (created) atomically; never pickle.

    Each file is written under a temporary name in the same directory and renamed into place; the
    sidecar records the npz file's sha256 (``"arrays"``) so a reader can tell a mismatched pair
    (files without that entry, written by other tools in the shared format, are accepted).

    Parameters
    ----------
    maps : CharacteristicMaps
    directory : path-like
        Target directory, e.g. ``maps/ps45-literature``.

    Returns
    -------
    Path
        The directory.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    np.savez(buf, **{k: np.ascontiguousarray(v, dtype=np.float64) for k, v in maps.arrays().items()})
    npz = buf.getvalue()
    meta = dict(maps.metadata)
    meta = {
        "schema": SCHEMA,
        "schema_version": SCHEMA_VERSION,
        **{k: v for k, v in meta.items() if k not in ("schema", "schema_version", "arrays")},
        "units": dict(ARRAY_UNITS),
        "arrays": {
            "file": NPZ_NAME,
            "sha256": hashlib.sha256(npz).hexdigest(),
            "shapes": {k: list(v.shape) for k, v in maps.arrays().items()},
        },
    }
    meta.setdefault("name", directory.name)
    text = json.dumps(meta, indent=2, allow_nan=False) + "\n"
    _atomic_write(directory / NPZ_NAME, npz)
    _atomic_write(directory / JSON_NAME, text.encode("utf-8"))
    return directory


def name_problem(name) -> str | None:
    """What is wrong with a maps name (None if nothing): it travels into modelDescription.xml,
    recording headers and C comments, so it must be one line of at most 200 characters."""
    if not isinstance(name, str):
        return "'name' must be a string"
    if any(ord(ch) < 32 or ord(ch) == 127 for ch in name) or len(name) > 200:
        return f"'name' must be one line of at most 200 characters without control characters, got {name[:60]!r}"
    return None


def _meta_problems(meta: dict) -> list[str]:
    problems = []
    if (problem := name_problem(meta.get("name"))) is not None:
        problems.append(problem)
    if meta.get("force_method") not in FORCE_METHODS:
        problems.append(
            f"'force_method' must be one of {list(FORCE_METHODS)}, got {meta.get('force_method')!r}"
        )
    units = meta.get("units")
    if not isinstance(units, dict):
        problems.append("'units' must be an object mapping array names to units")
    else:
        for name, unit in ARRAY_UNITS.items():
            if units.get(name) != unit:
                problems.append(f"units of {name} must be {unit!r}, file says {units.get(name)!r}")
    coil = meta.get("coil")
    if not isinstance(coil, dict):
        problems.append("'coil' must be an object")
    else:
        for key in ("turns", "resistance_ohm_20C", "temperature_coefficient_per_K", "max_current_A"):
            v = coil.get(key)
            if not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v):
                problems.append(f"coil.{key} must be a finite number, got {v!r}")
            elif key != "temperature_coefficient_per_K" and v <= 0:
                problems.append(f"coil.{key} must be > 0, got {v!r}")
    eddy = meta.get("eddy")
    if not isinstance(eddy, dict) or "G_eddy_S" not in eddy:
        problems.append("'eddy' must be an object with 'G_eddy_S' (number or null)")
    else:
        g = eddy["G_eddy_S"]
        if g is not None and (not isinstance(g, int | float) or isinstance(g, bool) or not math.isfinite(g)
                              or g < 0):
            problems.append(f"eddy.G_eddy_S must be null or a finite number >= 0 S, got {g!r}")
    if not isinstance(meta.get("provenance"), dict):
        problems.append("'provenance' must be an object")
    arrays = meta.get("arrays")
    if arrays is not None and (not isinstance(arrays, dict) or not isinstance(arrays.get("sha256"), str)):
        problems.append("'arrays', when present, must be an object with the sha256 of maps.npz")
    return problems


#: Most elements one array of a maps.npz may declare (a 1000 x 1000 grid is far beyond any sweep).
MAX_ARRAY_ELEMENTS = 10_000_000


def _check_npz_members(raw: bytes, npz_path, shapes) -> None:
    """Read every member's .npy header (not its data) and refuse, naming the member, a dtype that is not
    numeric or boolean, a shape other than maps.json's ``arrays.shapes`` says, or more than
    :data:`MAX_ARRAY_ELEMENTS` elements: a small file must not make the reader allocate gigabytes."""
    import zipfile

    problems = []
    try:
        with zipfile.ZipFile(io.BytesIO(raw)) as zf:
            for info in zf.infolist():
                name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
                with zf.open(info) as fh:
                    try:
                        version = np.lib.format.read_magic(fh)
                        if version == (1, 0):
                            shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
                        else:
                            shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
                    except ValueError as exc:
                        problems.append(f"member {name!r}: not a .npy array ({exc})")
                        continue
                if dtype.kind not in "fiub":
                    problems.append(f"member {name!r}: dtype {dtype} is not numeric")
                n = int(np.prod(shape, dtype=np.float64))
                if n > MAX_ARRAY_ELEMENTS:
                    problems.append(f"member {name!r}: declares {n} elements (shape {shape}), more than "
                                    f"{MAX_ARRAY_ELEMENTS}")
                elif isinstance(shapes, dict) and name in shapes and list(shape) != list(shapes[name]):
                    problems.append(f"{name} has shape {tuple(shape)}, expected {tuple(shapes[name])} "
                                    f"(maps.json arrays.shapes)")
    except zipfile.BadZipFile as exc:
        raise MapsError(f"{npz_path}: not a npz (zip) file: {exc}") from None
    if problems:
        raise MapsError(_problem_message(str(npz_path), problems))


def _first_non_finite(obj, where: str = ""):
    """(key path, value) of the first NaN or infinite number in parsed JSON ``obj``, or None."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return where or "(top level)", obj
    items = obj.items() if isinstance(obj, dict) else enumerate(obj) if isinstance(obj, list) else ()
    for key, value in items:
        found = _first_non_finite(value, f"{where}[{key}]" if isinstance(key, int) else
                                  f"{where}.{key}" if where else str(key))
        if found is not None:
            return found
    return None


def load_maps(directory) -> CharacteristicMaps:
    """Read maps written by :func:`save_maps`, refusing anything malformed.

    Parameters
    ----------
    directory : path-like
        The map directory (or its ``maps.json``/``maps.npz``).

    Returns
    -------
    CharacteristicMaps

    Raises
    ------
    MapsError
        Naming the file and every problem: missing file, invalid JSON, wrong schema name or version,
        missing arrays, wrong shapes, NaN/inf, non-monotone grids, wrong units, a npz that does not
        belong to the sidecar.
    """
    directory = Path(directory)
    if directory.is_file() and directory.name in (NPZ_NAME, JSON_NAME):
        directory = directory.parent
    json_path, npz_path = directory / JSON_NAME, directory / NPZ_NAME
    if not directory.is_dir():
        raise MapsError(f"{directory}: no such map directory")
    for p in (json_path, npz_path):
        if not p.is_file():
            raise MapsError(f"{p}: missing (a map directory holds {JSON_NAME} and {NPZ_NAME})")
    try:
        meta = json.loads(json_path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise MapsError(f"{json_path}:{exc.lineno}: not valid JSON: {exc.msg}") from None
    except UnicodeDecodeError:
        raise MapsError(f"{json_path}: not UTF-8 text") from None
    if not isinstance(meta, dict):
        raise MapsError(f"{json_path}: top level must be a JSON object")
    bad = _first_non_finite(meta)
    if bad is not None:
        raise MapsError(f"{json_path}: {bad[0]} = {bad[1]!r} is not a finite number (NaN and Infinity are not "
                        "JSON and would reach the FMU)")
    if meta.get("schema") != SCHEMA:
        raise MapsError(f"{json_path}: schema is {meta.get('schema')!r}, expected {SCHEMA!r}: not a map file")
    version = meta.get("schema_version")
    if version != SCHEMA_VERSION or isinstance(version, bool):
        raise MapsError(
            f"{json_path}: schema_version {version!r} is not supported; this reader reads schema_version "
            f"{SCHEMA_VERSION} (rebuild the maps with `solenoid-fmu maps`)"
        )
    problems = _meta_problems(meta)
    if problems:
        raise MapsError(_problem_message(str(json_path), problems))
    raw = npz_path.read_bytes()
    digest = hashlib.sha256(raw).hexdigest()
    if "arrays" in meta and digest != meta["arrays"]["sha256"]:
        raise MapsError(
            f"{npz_path}: sha256 {digest[:12]}... does not match the {meta['arrays']['sha256'][:12]}... "
            f"recorded in {JSON_NAME}; the two files were not written together"
        )
    _check_npz_members(raw, npz_path, (meta.get("arrays") or {}).get("shapes"))
    arrays: dict[str, np.ndarray] = {}
    problems = []
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as data:
            for name in data.files:
                if name not in ARRAY_UNITS:
                    continue
                arr = data[name]
                if arr.dtype.kind not in "fiu":
                    problems.append(f"array {name} has dtype {arr.dtype}, expected float64")
                    continue
                arrays[name] = arr.astype(np.float64)
    except ValueError as exc:  # object arrays refused by allow_pickle=False, corrupt members
        raise MapsError(f"{npz_path}: cannot read arrays without pickle: {exc}") from None
    except (OSError, EOFError) as exc:
        raise MapsError(f"{npz_path}: not a readable npz file: {exc}") from None
    except Exception as exc:  # zipfile.BadZipFile and friends
        raise MapsError(f"{npz_path}: not a readable npz file: {type(exc).__name__}: {exc}") from None
    problems += _array_problems(arrays) if not problems else []
    if problems:
        raise MapsError(_problem_message(str(npz_path), problems))
    metadata = {k: v for k, v in meta.items() if k not in ("schema", "schema_version", "arrays")}
    return CharacteristicMaps(**arrays, metadata=metadata)


# --------------------------------------------------------------------------------------------
# Energy consistency
# --------------------------------------------------------------------------------------------


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


# --------------------------------------------------------------------------------------------
# Exports
# --------------------------------------------------------------------------------------------


def _fmt(v: float) -> str:
    return repr(float(v))


def export_combitable2d(maps: CharacteristicMaps, directory) -> list[Path]:
    """Write i_f(Psi, x) and F(Psi, x) as Modelica ``CombiTable2D`` text files (``#1`` format).

    Files ``i_f_A.txt`` (table name ``i_f_A``) and ``force_N.txt`` (table name ``force_N``), each one
    ``double NAME(npsi + 1, nx + 1)`` matrix: row 0 = position grid x [m] (u2), column 0 = flux grid
    Psi [Wb] (u1), element [0, 0] unused (0). Use ``CombiTable2D(tableOnFile=true,
    tableName="i_f_A", fileName=..., u1 = Psi, u2 = x)``; ``smoothness=LinearSegments`` reproduces the
    bilinear interpolation of :func:`i_f_at`. Values in SI, written with full double precision.

    Returns
    -------
    list of Path
        The two files.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    out = []
    for name, table, what in (("i_f_A", maps.i_f_A, "field-generating current i_f(Psi, x) [A], paper eq. 2"),
                              ("force_N", maps.force_N, "magnetic force F(Psi, x) [N], + closes the gap")):
        npsi, nx = table.shape
        lines = [
            "#1",
            f"# {maps.name}: {what}; u1 = flux linkage Psi [Wb] (first column), "
            f"u2 = working gap x [m] (first row)",
            f"double {name}({npsi + 1},{nx + 1})",
            " ".join(["0"] + [_fmt(x) for x in maps.x_m]),
        ]
        for k in range(npsi):
            lines.append(" ".join([_fmt(maps.psi_Wb[k])] + [_fmt(v) for v in table[k]]))
        path = directory / f"{name}.txt"
        _atomic_write(path, ("\n".join(lines) + "\n").encode("ascii"))
        out.append(path)
    return out


#: Files derived from a map directory's arrays (``--mat``, ``--modelica``, ``--plot DIR/plots``).
DERIVED_FILES = ("maps.mat", "i_f_A.txt", "force_N.txt")
DERIVED_PLOTS = ("force_psi_x.png", "i_f_psi_x.png", "psi_i_per_x.png", "force_x_per_i.png")


def remove_stale_exports(directory) -> list[Path]:
    """Delete the exports and plots of an earlier build from a map directory that was just rebuilt
    (they would describe the old grid); returns what was removed. Only the known file names are
    touched (``plots/`` itself stays when it holds anything else)."""
    directory = Path(directory)
    removed = []
    for name in DERIVED_FILES:
        if (directory / name).is_file():
            (directory / name).unlink()
            removed.append(directory / name)
    plots = directory / "plots"
    for name in DERIVED_PLOTS:
        if (plots / name).is_file():
            (plots / name).unlink()
            removed.append(plots / name)
    if plots.is_dir() and not any(plots.iterdir()):
        plots.rmdir()
    return removed


def read_combitable2d(path, table_name: str) -> np.ndarray:
    """Read one ``double NAME(rows,cols)`` matrix from a Modelica ``#1`` text file.

    Parameters
    ----------
    path : path-like
    table_name : str

    Returns
    -------
    ndarray, shape (rows, cols)
        The table as written (row 0 / column 0 are the grids for CombiTable2D).
    """
    path = Path(path)
    lines = path.read_text(encoding="ascii").splitlines()
    if not lines or lines[0].strip() != "#1":
        raise MapsError(f"{path}:1: a Modelica table file must start with '#1'")
    k = 1
    while k < len(lines):
        head = lines[k].split("#", 1)[0].strip()
        k += 1
        if not head.startswith("double "):
            continue
        decl = head[len("double "):].replace(" ", "")
        name, _, dims = decl.partition("(")
        try:
            rows, cols = (int(t) for t in dims.rstrip(")").split(","))
        except ValueError:
            raise MapsError(f"{path}:{k}: bad matrix header {lines[k - 1]!r}") from None
        if name != table_name:
            k += rows
            continue
        data = []
        for r in range(rows):
            if k + r >= len(lines):
                raise MapsError(f"{path}: table {name} ends after {r} of {rows} rows")
            try:
                row = [float(t) for t in lines[k + r].split("#", 1)[0].split()]
            except ValueError:
                raise MapsError(f"{path}:{k + r + 1}: not a row of numbers") from None
            if len(row) != cols:
                raise MapsError(f"{path}:{k + r + 1}: {len(row)} values, header says {cols}")
            data.append(row)
        return np.array(data)
    raise MapsError(f"{path}: no table named {table_name!r}")


def export_mat(maps: CharacteristicMaps, path) -> Path:
    """Write a MATLAB ``.mat`` file (scipy.io.savemat, format 5) for Simulink and Simscape.

    Variables (SI units; tables have one row per current and one column per position):

    - ``i_A`` (1 x ni): current breakpoints [A]; ``x_m`` (1 x nx): working-gap breakpoints [m].
    - ``Phi_ix_Wb`` (ni x nx): flux linkage Psi(i, x) [Wb], ``Phi_ix_Wb(k, j)`` at ``i_A(k)``, ``x_m(j)``.
    - ``F_ix_N`` (ni x nx): force F(i, x) [N], positive pulls the armature towards the pole (closes x).
    - ``F_simscape_ix_N`` (ni x nx): ``-F_ix_N``; Simscape's FEM-Parameterized Linear Actuator wants the
      pulling force of a solenoid with air gap x negative.
    - ``dPhi_di_ix_H`` and ``dPhi_dx_ix_Wb_per_m`` (ni x nx): partial derivatives of Psi(i, x) from the
      interpolants of :func:`psi_at`, for the block's "dPhi/dx and dPhi/di" option.
    - ``psi_Wb`` (1 x npsi), ``i_f_psix_A`` and ``F_psix_N`` (npsi x nx): the real-time maps of paper
      eqs. 2 and 3 over (Psi, x); ``extrapolated_psix`` flags extrapolated nodes.
    - ``info``: a text with these conventions and the map's name.

    Simulink *2-D Lookup Table*: Table data ``Phi_ix_Wb``, Breakpoints 1 ``i_A`` (rows), Breakpoints 2
    ``x_m`` (columns). Simscape *FEM-Parameterized Linear Actuator*: current vector ``i_A``, extension
    vector ``x_m``, flux linkage matrix ``Phi_ix_Wb`` (or the partial derivatives), force matrix
    ``F_simscape_ix_N``.

    Returns
    -------
    Path
    """
    from scipy.interpolate import CubicSpline
    from scipy.io import savemat

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    spline = _psi_columns(maps)
    dpsi_di = spline.derivative()(maps.i_A)
    dpsi_dx = CubicSpline(maps.x_m, maps.psi_ix_Wb, axis=1).derivative()(maps.x_m)
    info = (
        f"solenoid-fmu characteristic maps '{maps.name}'. SI units. Tables (ni x nx): rows = i_A, "
        "columns = x_m (working gap). F_ix_N > 0 pulls the armature towards the pole; "
        "F_simscape_ix_N = -F_ix_N. i_f_psix_A, F_psix_N (npsi x nx): rows = psi_Wb."
    )
    variables = {
        "i_A": maps.i_A[None, :],
        "x_m": maps.x_m[None, :],
        "Phi_ix_Wb": np.array(maps.psi_ix_Wb),
        "F_ix_N": np.array(maps.force_ix_N),
        "F_simscape_ix_N": -np.array(maps.force_ix_N),
        "F_stress_ix_N": np.array(maps.force_stress_ix_N),
        "dPhi_di_ix_H": dpsi_di,
        "dPhi_dx_ix_Wb_per_m": dpsi_dx,
        "psi_Wb": maps.psi_Wb[None, :],
        "i_f_psix_A": np.array(maps.i_f_A),
        "F_psix_N": np.array(maps.force_N),
        "extrapolated_psix": np.array(maps.extrapolated),
        "info": info,
    }
    buf = io.BytesIO()
    savemat(buf, variables, format="5", do_compression=True, oned_as="row")
    _atomic_write(path, buf.getvalue())
    return path


# --------------------------------------------------------------------------------------------
# Plots
# --------------------------------------------------------------------------------------------


def plot_maps(maps: CharacteristicMaps, directory) -> list[Path]:
    """PNG plots like the paper's figures 12 and 13, plus Psi(i) and F(x) per operating point.

    Files: ``force_psi_x.png`` (F over Psi and x, fig. 12), ``i_f_psi_x.png`` (i_f over Psi and x,
    fig. 13), ``psi_i_per_x.png`` (Psi(i) per position, FEM points and interpolant),
    ``force_x_per_i.png`` (F over x per current). Extrapolated parts are drawn grey/dashed.

    Returns
    -------
    list of Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import cm

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    out = []
    X, P = np.meshgrid(maps.x_m * 1e3, maps.psi_Wb * 1e3)
    ext = maps.extrapolated > 0
    colors = cm.viridis(np.linspace(0, 1, len(maps.x_m)))
    for fname, table, zlabel, title in (
        ("force_psi_x.png", maps.force_N, "force F [N]", "F(Psi, x) (cf. paper fig. 12)"),
        ("i_f_psi_x.png", maps.i_f_A, "field current i_f [A]", "i_f(Psi, x) (cf. paper fig. 13)"),
    ):
        fig = plt.figure(figsize=(12, 5))
        ax = fig.add_subplot(1, 2, 1, projection="3d")
        face = cm.viridis((table - table.min()) / max(np.ptp(table), 1e-300))
        face[ext] = (0.75, 0.75, 0.75, 0.6)
        stride = max(1, len(maps.psi_Wb) // 60)
        ax.plot_surface(X[::stride], P[::stride], table[::stride], facecolors=face[::stride],
                        rstride=1, cstride=1, linewidth=0, antialiased=False, shade=False)
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("Psi [mWb]")
        ax.set_zlabel(zlabel)
        ax.set_title(title + "; grey = extrapolated")
        ax2 = fig.add_subplot(1, 2, 2)
        for j, x in enumerate(maps.x_m):
            inside = ~ext[:, j]
            ax2.plot(maps.psi_Wb[inside] * 1e3, table[inside, j], color=colors[j], label=f"{x * 1e3:.2f} mm")
            ax2.plot(maps.psi_Wb[~inside] * 1e3, table[~inside, j], color=colors[j], ls="--", lw=0.8)
        ax2.set_xlabel("flux linkage Psi [mWb]")
        ax2.set_ylabel(zlabel)
        ax2.grid(True, alpha=0.3)
        ax2.legend(fontsize=6, ncol=2, title="x")
        fig.tight_layout()
        path = directory / fname
        fig.savefig(path, dpi=110)
        plt.close(fig)
        out.append(path)

    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    ii = np.linspace(maps.i_A[0], maps.i_A[-1], 200)
    for j, x in enumerate(maps.x_m):
        axes[0].plot(ii, psi_at(maps, ii, x) * 1e3, color=colors[j], label=f"{x * 1e3:.2f} mm")
        axes[0].plot(maps.i_A, maps.psi_ix_Wb[:, j] * 1e3, ".", color=colors[j], ms=3)
        axes[1].plot(ii, force_at(maps, ii, x), color=colors[j])
        axes[1].plot(maps.i_A, maps.force_ix_N[:, j], ".", color=colors[j], ms=3)
    axes[0].set_xlabel("current i [A]")
    axes[0].set_ylabel("flux linkage Psi [mWb]")
    axes[0].set_title("Psi(i) per position: FEM points, interpolant")
    axes[0].legend(fontsize=6, ncol=2, title="x")
    axes[1].set_xlabel("current i [A]")
    axes[1].set_ylabel("force F [N]")
    axes[1].set_title("F(i) per position (co-energy)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    path = directory / "psi_i_per_x.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    out.append(path)

    fig, ax = plt.subplots(figsize=(7, 5))
    xx = np.linspace(maps.x_m[0], maps.x_m[-1], 200)
    currents = np.linspace(maps.i_A[0], maps.i_A[-1], 6)[1:]
    for c, i in zip(cm.plasma(np.linspace(0, 0.85, len(currents))), currents, strict=True):
        ax.plot(xx * 1e3, force_at(maps, i, xx), color=c, label=f"{i:.2f} A")
        ax.plot(xx * 1e3, force_at(maps, i, xx, stress=True), color=c, ls=":", lw=0.8)
    stroke = maps.metadata.get("stroke", {})
    if "working_min_m" in stroke:
        ax.axvspan(stroke["working_min_m"] * 1e3, stroke["working_max_m"] * 1e3, color="0.9", zorder=0,
                   label="working range")
    ax.set_xlabel("working gap x [mm]")
    ax.set_ylabel("force F [N]")
    ax.set_title("force over stroke (solid: co-energy, dotted: Maxwell stress)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = directory / "force_x_per_i.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    out.append(path)
    return out


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------


def parse_range(text: str, what: str = "range") -> tuple[float, float, int]:
    """Parse ``START:STOP:N`` strictly: two finite numbers with START < STOP and an integer N >= 2.

    Raises
    ------
    argparse.ArgumentTypeError
        With a message naming the text and what is wrong.
    """
    parts = text.split(":")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"{what} {text!r}: expected START:STOP:N, e.g. 0.2:3.5:15")
    try:
        start, stop = float(parts[0]), float(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"{what} {text!r}: START and STOP must be numbers") from None
    if not (math.isfinite(start) and math.isfinite(stop)):
        raise argparse.ArgumentTypeError(f"{what} {text!r}: START and STOP must be finite")
    try:
        n = int(parts[2].strip())
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{what} {text!r}: N must be a whole number, got {parts[2]!r}"
        ) from None
    if n < 2:
        raise argparse.ArgumentTypeError(f"{what} {text!r}: N must be at least 2, got {n}")
    if n > MAX_GRID_POINTS:
        raise argparse.ArgumentTypeError(f"{what} {text!r}: N = {n} is more than {MAX_GRID_POINTS} points "
                                         "(each is a FEM solve per point of the other grid)")
    if not start < stop:
        raise argparse.ArgumentTypeError(f"{what} {text!r}: START must be smaller than STOP")
    return start, stop, n


def _positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {n}")
    return n


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return v


def add_cli(subparsers) -> None:
    """Register ``solenoid-fmu maps``."""
    p = subparsers.add_parser(
        "maps",
        help="sweep the FEM over (i, x) and build the characteristic maps i_f(Psi, x), F(Psi, x)",
        description=(
            "Sweep the FEM over working-gap positions and currents, invert to the real-time maps "
            "i_f(Psi, x) and F(Psi, x) (paper eqs. 2-3), write maps.npz + maps.json. With --from, "
            "plot or export an existing map without a sweep."
        ),
        epilog=(
            "examples:\n"
            "  solenoid-fmu maps -o maps/ps45-literature --plot build/maps-plots --modelica --mat\n"
            "  solenoid-fmu maps --x-mm 0.5:2.8:12 --i-A 0:2.5:26 --mesh-size 2 -o maps/coarse\n"
            "  solenoid-fmu maps --from maps/ps45-literature --plot build/maps-plots\n"
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--geometry", metavar="G.toml", help="solenoid geometry (default: packaged PS45)")
    p.add_argument("--material", metavar="M.csv", help="B(H) curve (default: literature 9SMnPb28)")
    p.add_argument("--x-mm", metavar="START:STOP:N", type=lambda t: parse_range(t, "--x-mm"),
                   help="evenly spaced positions in mm (default: the whole stroke, 27 positions "
                        "clustered at both stops)")
    p.add_argument("--i-A", metavar="START:STOP:N", type=lambda t: parse_range(t, "--i-A"),
                   help="evenly spaced currents in A, START must be 0 (default: 0 to 1.25 x max "
                        "current, 26 currents, denser at low currents)")
    p.add_argument("--mesh-size", metavar="H", type=_positive_float, default=1.0,
                   help="mesh-size factor (default 1.0; larger is coarser)")
    p.add_argument("--workers", metavar="N", type=_positive_int, default=None,
                   help="parallel processes (default: all cores; 1 runs in this process)")
    p.add_argument("-o", "--output", metavar="maps/NAME", help="map directory to write")
    p.add_argument("--from", dest="source", metavar="maps/NAME", help="use an existing map, no sweep")
    p.add_argument("--plot", metavar="DIR", help="write PNG plots (figs. 12, 13, Psi(i), F(x)) into DIR")
    p.add_argument("--modelica", action="store_true", help="also write CombiTable2D files into the map dir")
    p.add_argument("--mat", action="store_true",
                   help="also write maps.mat (Simulink/Simscape) into the map dir")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cli)


def _output_map_dir(output, inputs) -> Path:
    """The map directory ``output`` of a new sweep, checked before the sweep: not under a file, its
    name a valid maps name, and none of the files a build writes or removes (maps.npz, maps.json,
    exports, plots) one of ``inputs``."""
    from ..fileio import refuse_overwriting_inputs, require_directory

    directory = require_directory(output, "-o")
    if (problem := name_problem(directory.name)) is not None:
        raise MapsError(f"-o {output}: the directory name is the maps name: {problem}")
    written = [directory / n for n in (NPZ_NAME, JSON_NAME, *DERIVED_FILES)] + [directory / "plots"]
    return refuse_overwriting_inputs(directory, inputs, written=written)


def _output_plot_dir(plot_dir, inputs) -> Path:
    """``--plot DIR`` checked before any work: not under a file, no input among the plots written."""
    from ..fileio import refuse_overwriting_inputs, require_directory

    plot_dir = require_directory(plot_dir, "--plot")
    return refuse_overwriting_inputs(plot_dir, inputs, written=[plot_dir / n for n in DERIVED_PLOTS])


def _cli(args) -> int:
    if args.plot:  # checked before any work, not after the sweep
        source = [] if args.source is None else [Path(args.source) / n for n in (NPZ_NAME, JSON_NAME)]
        _output_plot_dir(args.plot, [args.geometry, args.material, *source])
    if args.source is not None:
        if args.output is not None:
            raise MapsError("use either -o (build a new map) or --from (use an existing one), not both")
        sweep_opts = [o for o, v in (("--geometry", args.geometry), ("--material", args.material),
                                     ("--x-mm", args.x_mm), ("--i-A", args.i_A), ("--workers", args.workers))
                      if v is not None]
        if sweep_opts:
            raise MapsError(f"{', '.join(sweep_opts)} only apply to a new sweep, not with --from")
        if not (args.plot or args.modelica or args.mat):
            raise MapsError("--from needs something to do: --plot DIR, --modelica or --mat")
        directory = Path(args.source)
        maps = load_maps(directory)
    else:
        if args.output is None:
            raise MapsError("missing -o maps/NAME (or --from maps/NAME to use an existing map)")
        from ..field import load_geometry, load_material

        directory = _output_map_dir(args.output, [args.geometry, args.material])
        geometry = load_geometry(args.geometry)
        material = load_material(args.material)
        x_m = None if args.x_mm is None else np.linspace(*args.x_mm) * 1e-3
        i_A = None
        if args.i_A is not None:
            if args.i_A[0] != 0.0:
                raise MapsError(f"--i-A must start at 0 A (maps hold i_f from Psi = 0), got {args.i_A[0]:g}")
            i_A = np.linspace(*args.i_A)
        executor = None
        if args.workers == 1:
            executor = InlineExecutor()
        elif args.workers is not None:
            executor = cf.ProcessPoolExecutor(max_workers=args.workers)
        try:
            maps = build_maps(geometry, material, x_m=x_m, i_A=i_A, mesh_size=args.mesh_size,
                              executor=executor, progress=not args.quiet, name=directory.name)
        finally:
            if executor is not None:
                executor.shutdown()
        save_maps(maps, directory)
        removed = remove_stale_exports(directory)
        if removed:
            print(f"removed {len(removed)} export(s) of the earlier build in {directory}: "
                  + ", ".join(p.name for p in removed))
        solver = maps.metadata["provenance"]["solver"]
        ni, nx, npsi = maps.shape
        print(f"wrote {directory}/{NPZ_NAME}, {JSON_NAME}: {nx} positions x {ni} currents, "
              f"{npsi} flux points, {solver['wall_time_s']:.1f} s "
              f"({solver['operating_points'] / max(solver['wall_time_s'], 1e-9):.1f} points/s), "
              f"round trip {maps.metadata['round_trip_max_rel_error'] * 100:.3g} %")
    if args.modelica:
        for path in export_combitable2d(maps, directory):
            print(f"wrote {path}")
    if args.mat:
        print(f"wrote {export_mat(maps, directory / 'maps.mat')}")
    if args.plot:
        for path in plot_maps(maps, args.plot):
            print(f"wrote {path}")
    return 0
