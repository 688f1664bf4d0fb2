"""What a map set must mean, beyond its shapes (checked by :func:`solenoid_fmu.maps.load_maps`, so by
every reader and by ``export``): the tables of one set agree with each other.

- **i_f inverts Psi**: at every position of the grid, Psi(i_f(Psi, x), x) (the FEM table through its
  interpolant) returns Psi at each flux node within :data:`ROUND_TRIP_TOL` of the column's top flux (a
  map built by ``solenoid-fmu maps`` is exact at the nodes to ~1e-15; the analytic test maps 5e-4).
- **the force pulls**: F(i, x) and F(Psi, x) are nowhere below -:data:`FORCE_NEGATIVE_TOL` of the
  largest |F| (positive force closes the gap; a solenoid's reluctance force always does).
- **F(Psi, x) is F(i, x)**: at each flux node inside the swept range, F(Psi, x) equals F(i_f(Psi, x), x)
  within :data:`FORCE_AGREE_TOL` of the largest |F|.
"""

from __future__ import annotations

import numpy as np

from .interpolate import force_at, psi_at
from .tables import CharacteristicMaps

__all__ = ["FORCE_AGREE_TOL", "FORCE_NEGATIVE_TOL", "ROUND_TRIP_TOL", "consistency_problems"]

#: Largest round-trip error Psi -> i_f -> Psi at the flux nodes, relative to the column's top flux.
ROUND_TRIP_TOL = 0.01
#: Most negative force accepted, relative to the largest |F| (FEM noise at zero current is ~1e-40).
FORCE_NEGATIVE_TOL = 0.02
#: Largest difference of F(Psi, x) and F(i_f(Psi, x), x), relative to the largest |F|.
FORCE_AGREE_TOL = 0.02


def consistency_problems(maps: CharacteristicMaps) -> list[str]:
    """Every way the tables of ``maps`` contradict each other (empty when they agree)."""
    problems = []
    scale = float(np.max(np.abs(maps.force_ix_N)))
    recorded = maps.metadata.get("round_trip_max_rel_error")
    note = f" (maps.json records a round-trip error of {recorded:.3g})" if isinstance(recorded, float) else ""
    for name, table, inside in (("force_ix_N", maps.force_ix_N, np.ones(maps.force_ix_N.shape, bool)),
                                ("force_N", maps.force_N, maps.extrapolated == 0)):
        vals = np.where(inside, table, np.inf)
        k, j = np.unravel_index(int(np.argmin(vals)), vals.shape)
        if scale > 0 and vals[k, j] < -FORCE_NEGATIVE_TOL * scale:
            grid = (f"i = {maps.i_A[k]:.4g} A" if name == "force_ix_N" else f"psi = {maps.psi_Wb[k]:.6g} Wb")
            share = float(np.mean(table[inside] < 0))
            problems.append(f"{name} is negative ({vals[k, j]:.4g} N at {grid}, x = {maps.x_m[j] * 1e3:.4g} mm; "
                            f"{share:.0%} of the table): positive force closes the gap, a solenoid pulls")
    worst_rt, worst_f = (0.0, None), (0.0, None)
    for j, x in enumerate(maps.x_m):
        sel = (maps.extrapolated[:, j] == 0) & (maps.psi_Wb > 0)
        if not sel.any():
            continue
        p = maps.psi_Wb[sel]
        i = np.clip(maps.i_f_A[sel, j], maps.i_A[0], maps.i_A[-1])
        xs = np.full(p.shape, x)
        rt = float(np.max(np.abs(psi_at(maps, i, xs) - p))) / max(float(maps.psi_ix_Wb[-1, j]), 1e-300)
        if rt > worst_rt[0]:
            worst_rt = (rt, x)
        if scale > 0:
            df = float(np.max(np.abs(force_at(maps, i, xs) - maps.force_N[sel, j]))) / scale
            if df > worst_f[0]:
                worst_f = (df, x)
    if worst_rt[0] > ROUND_TRIP_TOL:
        problems.append(f"i_f_A does not invert psi_ix_Wb: Psi(i_f(Psi, x), x) misses Psi by {worst_rt[0]:.3g} of the "
                        f"top flux at x = {worst_rt[1] * 1e3:.4g} mm (limit {ROUND_TRIP_TOL:g}){note}")
    if worst_f[0] > FORCE_AGREE_TOL:
        problems.append(f"force_N (F(Psi, x)) disagrees with force_ix_N (F(i, x)) by {worst_f[0]:.3g} of the "
                        f"largest |F| at x = {worst_f[1] * 1e3:.4g} mm (limit {FORCE_AGREE_TOL:g})")
    return problems
