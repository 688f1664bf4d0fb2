"""The characteristic maps as one immutable object (:class:`CharacteristicMaps`) and the checks of its arrays.

The arrays and their units are the maps file format's (:mod:`solenoid_fmu.maps.io`); the checks here are
shared by the constructor and the reader, so a map that loads is a map that could have been built.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np

from ..errors import MapsError
from ..realtime import EddyRecord, replace_meta

__all__ = [
    "ARRAY_UNITS",
    "FORCE_METHODS",
    "INTERPOLATION",
    "CharacteristicMaps",
    "array_problems",
    "first_non_increasing",
    "problem_message",
]

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
#: How each table is interpolated (written into ``maps.json`` under ``"interpolation"``;
#: :mod:`solenoid_fmu.maps.interpolate`).
INTERPOLATION = {
    "psi_ix_Wb": "monotone cubic Hermite in i (slopes from a spline of Psi / i, Hyman filter); "
                 "not-a-knot cubic spline in x",
    "force_ix_N": "per x column F = i^2 g(i), g a not-a-knot cubic spline of F / i^2 (g(0) = g(i_1)); "
                  "not-a-knot cubic spline in x",
    "i_f_A": "bilinear in (psi, x); nodes are the exact inverse of the psi_ix_Wb interpolant",
    "force_N": "bilinear in (psi, x); nodes = the force_ix_N interpolant at i_f along the column",
    "extrapolation": "linear from the last two sweep points of each x column (flagged in 'extrapolated')",
}


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
        problems = array_problems(arrays)
        if problems:
            raise MapsError(problem_message("CharacteristicMaps", problems))
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

    def with_eddy(self, G_eddy_S: float | None, source: str, measured: bool | None = None) -> CharacteristicMaps:
        """A copy with the eddy-current conductance of paper eq. (2) set.

        Parameters
        ----------
        G_eddy_S : float or None
            Eddy-current parameter [S] (A per V of induced voltage dPsi/dt); None = not identified.
        source : str
            Where the value comes from (recordings, fit), stored in the metadata.
        measured : bool, optional
            The fit measured an eddy current (:attr:`~solenoid_fmu.maps.EddyFit.measurable`; maps.json
            ``eddy.measured``, the loop's evidence for its eddy ladder). None: not said.
        """
        if G_eddy_S is not None and not (math.isfinite(G_eddy_S) and G_eddy_S >= 0):
            raise MapsError(f"G_eddy_S must be a finite value >= 0 S, got {G_eddy_S!r}")
        if measured is not None and not isinstance(measured, bool):
            raise MapsError(f"measured must be None, True or False, got {measured!r}")
        eddy = EddyRecord(G_eddy_S=None if G_eddy_S is None else float(G_eddy_S), source=str(source), measured=measured)
        return dataclasses.replace(self, metadata=replace_meta(self.metadata, eddy=eddy))


def problem_message(what: str, problems: list[str]) -> str:
    """One error text: ``what`` with the number of problems, then one indented line per problem."""
    lines = [f"{what}: {len(problems)} problem(s)"] + [f"  - {p}" for p in problems]
    return "\n".join(lines)


def array_problems(arrays: dict[str, np.ndarray]) -> list[str]:
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
    if npsi < 3:  # the rule of every reader (realtime.MapTables, export): one rule
        problems.append(f"psi_Wb needs at least 3 points, has {npsi}")
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
        k = first_non_increasing(a["psi_ix_Wb"][:, j])
        if k is not None:
            problems.append(
                f"psi_ix_Wb does not rise strictly with current at x = {x * 1e3:.4g} mm between "
                f"i = {a['i_A'][k]:.4g} A and {a['i_A'][k + 1]:.4g} A"
            )
        k = first_non_increasing(a["i_f_A"][:, j])
        if k is not None:
            problems.append(
                f"i_f_A does not rise strictly with flux linkage at x = {x * 1e3:.4g} mm between "
                f"psi = {a['psi_Wb'][k]:.6g} Wb and {a['psi_Wb'][k + 1]:.6g} Wb"
            )
    flags = a["extrapolated"]
    if not np.isin(flags, (0.0, 1.0)).all():
        problems.append("extrapolated must hold only 0.0 and 1.0")
    return problems


def first_non_increasing(values: np.ndarray) -> int | None:
    """Index k of the first step ``values[k] -> values[k + 1]`` that does not rise, or None."""
    d = np.diff(values)
    bad = np.flatnonzero(~(d > 0))
    return int(bad[0]) if bad.size else None

