r"""Identify the steel's B(H) from flux recordings (``sf.identify``, paper section 4).

The FEM at the recordings' stroke is coupled to an optimizer under the physical constraints
(B rising; permeability rising to one inflection point, then falling towards mu0) and fitted to
the measured Psi(i). Writes the curve (CSV, plus ``.bh`` and ``.tab``). Run::

    python examples/ex_identify.py OUT.csv RECORDING.csv ...
"""

from __future__ import annotations

import sys

import solenoid_fmu as sf


def run(recordings, out_csv="build/ex_identify/material.csv", mesh_size: float | None = None,
        n_currents: int = 6) -> dict:
    """The identified curve (``curve``, a BHCurve), its identified H range [A/m] and the flux error."""
    res = sf.identify(recordings, out_csv=out_csv, mesh_size=mesh_size, n_currents=n_currents, progress=False)
    return {"curve": res.curve, "result": res, "out_csv": out_csv}


if __name__ == "__main__":
    r = run(sys.argv[2:], sys.argv[1])
    print(f"B(H) written to {r['out_csv']}")
