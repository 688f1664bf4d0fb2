r"""Export the real-time model as FMI 2.0 FMUs, both backends (``sf.export_fmu``, paper eqs. 1-3).

``backend="python"``: pythonfmu, co-simulation, needs Python with numpy at run time.
``backend="c"``: generated C compiled here, co-simulation and model exchange, no Python.
Both are checked with fmpy's validation. Run::

    python examples/ex_export_fmu.py [MAPS_DIR] [OUT_DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import solenoid_fmu as sf


def run(maps_dir="maps/ps45-literature", out_dir="build/ex_export_fmu") -> dict:
    """Export both backends; returns per backend the FMU path, fmpy's validation problems and the
    variables (name -> (value reference, causality, unit))."""
    import fmpy  # the FMI importer the tests compare against
    from fmpy.validation import validate_fmu

    out = {}
    for backend in ("python", "c"):
        fmu = sf.export_fmu(maps_dir, Path(out_dir) / f"{Path(maps_dir).name}-{backend}.fmu", backend=backend)
        md = fmpy.read_model_description(fmu)
        out[backend] = {"fmu": fmu, "problems": validate_fmu(str(fmu)),
                        "variables": {v.name: (v.valueReference, v.causality, v.unit) for v in md.modelVariables}}
    return out


if __name__ == "__main__":
    for backend, r in run(*sys.argv[1:3]).items():
        print(f"{backend}: {r['fmu']} ({len(r['variables'])} variables, {len(r['problems'])} validation problems)")
