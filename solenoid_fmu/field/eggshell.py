"""The weight of the FEM's Maxwell-stress force (its volume, "eggshell", form; see :mod:`solenoid_fmu.field.fem`).

The velocity field of that force is 1 on the armature, falls to 0 across the air around it within
:data:`EGGSHELL_M` and is 0 on every other body, so only air elements contribute.
"""

from __future__ import annotations

import numpy as np

__all__ = ["EGGSHELL_M", "eggshell_weight"]

EGGSHELL_M = 0.4e-3  # thickness of the air layer over which the Maxwell-stress weight falls to 0


def eggshell_weight(solver, cfg) -> np.ndarray:
    """Vertex weight g at the gap of ``cfg`` (a :class:`~solenoid_fmu.field.quadrature.GapConfig`) of the
    ``solver``'s mesh: 1 on the armature, 0 on all other bodies, falling across the air."""
    mm = solver.mesh
    nv = mm.n_vertices
    g = np.full(nv, np.nan)
    body = ~solver.moving_elements & (mm.region >= 0)
    # air regions listed as polygons (material air, e.g. the ring) count as air
    air_regions = [k for k, r in enumerate(solver.geometry.regions) if r.material == "air" and not r.moves]
    body &= ~np.isin(mm.region, air_regions)
    g[mm.t[:, body].ravel()] = 0.0
    g[mm.t[:, solver.moving_elements].ravel()] = 1.0
    free = np.isnan(g)
    # distance of free (air) vertices to the armature's vertices, capped by the layer thickness
    arm_v = np.unique(mm.t[:, solver.moving_elements])
    from scipy.spatial import cKDTree  # loaded on first use (about 0.2 s)

    d, _ = cKDTree(cfg.p[:, arm_v].T).query(cfg.p[:, free].T)
    g[free] = np.clip(1.0 - d / EGGSHELL_M, 0.0, 1.0)
    return g
