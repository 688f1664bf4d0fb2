r"""Sweep the FEM over (i, x) and build the characteristic maps (``sf.build_maps``, paper section 5).

The packaged PS45 geometry with the literature steel on a small grid (a coarse mesh, a few
positions and currents: about a dozen FEM solves), written to a maps directory that ``export``
and the FMU read. Run::

    python examples/ex_build_maps.py [OUT_DIR]
"""

from __future__ import annotations

import sys

import numpy as np

import solenoid_fmu as sf


def run(out_dir="build/ex_build_maps", n_x: int = 3, n_i: int = 4, mesh_size: float = 2.0) -> dict:
    """Build, save and reload the maps; returns both (``maps``, ``loaded``) and the directory."""
    geometry, material = sf.load_geometry(), sf.load_material()
    x = np.linspace(geometry.stroke.min_m, geometry.stroke.max_m, n_x)
    i = np.linspace(0.0, geometry.coil.max_current_A, n_i)
    maps = sf.build_maps(geometry, material, x_m=x, i_A=i, mesh_size=mesh_size, progress=False,
                         name="ex-build-maps")
    directory = sf.save_maps(maps, out_dir)
    return {"maps": maps, "loaded": sf.load_maps(directory), "dir": directory, "mesh_size": mesh_size}


if __name__ == "__main__":
    r = run(*sys.argv[1:2])
    print(f"maps written to {r['dir']}: {len(r['maps'].x_m)} positions x {len(r['maps'].i_A)} currents")
