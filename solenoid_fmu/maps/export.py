"""Exports of the maps for other tools: Modelica ``CombiTable2D`` text files and a MATLAB ``.mat`` file.

Also the list of files derived from a map directory's arrays (exports and plots), removed when the
directory is rebuilt (:func:`remove_stale_exports`).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.io import savemat

from ..errors import MapsError
from ..fileio import atomic_write_bytes
from .interpolate import psi_columns
from .tables import CharacteristicMaps

__all__ = [
    "DERIVED_FILES",
    "DERIVED_PLOTS",
    "export_combitable2d",
    "export_mat",
    "read_combitable2d",
    "remove_stale_exports",
]


def _fmt(v: float) -> str:
    return repr(float(v))


def export_combitable2d(maps: CharacteristicMaps, directory) -> list[Path]:
    """Write i_f(Psi, x) and F(Psi, x) as Modelica ``CombiTable2D`` text files (``#1`` format).

    Files ``i_f_A.txt`` (table name ``i_f_A``) and ``force_N.txt`` (table name ``force_N``), each one
    ``double NAME(npsi + 1, nx + 1)`` matrix: row 0 = position grid x [m] (u2), column 0 = flux grid
    Psi [Wb] (u1), element [0, 0] unused (0). Use ``CombiTable2D(tableOnFile=true,
    tableName="i_f_A", fileName=..., u1 = Psi, u2 = x)``; ``smoothness=LinearSegments`` reproduces the
    bilinear interpolation of :func:`solenoid_fmu.maps.interpolate.i_f_at`. Values in SI, written with full
    double precision.

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
        atomic_write_bytes(path, ("\n".join(lines) + "\n").encode("ascii"))
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
      interpolants of :func:`solenoid_fmu.maps.interpolate.psi_at`, for the block's "dPhi/dx and dPhi/di" option.
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
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    spline = psi_columns(maps)
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
    atomic_write_bytes(path, buf.getvalue())
    return path


