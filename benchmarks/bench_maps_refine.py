"""Benchmark: map columns put between FEM positions (``build_maps(..., refine_x=r)``) against more FEM positions.

For one steel (the literature steel, or ``--material CSV``) on the maps presets' mesh (2.0) and an 18-current
sweep to 2.5 A: a reference FEM at 47 positions, then maps from 24 FEM positions, from 12, and from 12 refined
2x and 3x (the ``medium`` preset). Each candidate is read as the real-time model reads it (linearly in x,
:class:`solenoid_fmu.realtime.MapTables`) at the reference's fluxes Psi(i, x), 0.2-2 A, at every reference
position; prints the largest and RMS error of i_f [mA] and F [N], and the wall time of each build with its
ratio to the 24-position build measured in the same run.

Usage::

    python benchmarks/bench_maps_refine.py [--material path/to/material.csv]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from solenoid_fmu.field import load_geometry, load_material
from solenoid_fmu.maps import InlineExecutor, build_maps, default_positions, maps_current_grid
from solenoid_fmu.maps.io import maps_tables

MESH = 2.0
N_CURRENTS = 18
CANDIDATES = ((24, 1), (12, 1), (12, 2), (12, 3))


def reading_errors(maps, ref) -> tuple[np.ndarray, np.ndarray]:
    """|i_f - i| [A] and |F - F_ref| [N] of the model's reading of ``maps`` at the reference's (Psi, x), 0.2-2 A."""
    tab = maps_tables(maps)
    ei, ef = [], []
    for j, x in enumerate(ref.x_m):
        for k, i in enumerate(ref.i_A):
            if 0.2 <= i <= 2.0:
                p = float(ref.psi_ix_Wb[k, j])
                ei.append(tab.i_f_A(p, float(x)) - i)
                ef.append(tab.force_N(p, float(x)) - ref.force_ix_N[k, j])
    return np.abs(ei), np.abs(ef)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--material", help="B(H) curve CSV (default: the literature steel)")
    args = ap.parse_args(argv)
    g = load_geometry()
    steel = load_material(args.material) if args.material else load_material()
    i_A = maps_current_grid(g.coil.max_current_A, [], N_CURRENTS)

    def build(n, r):
        t0 = time.perf_counter()
        m = build_maps(g, steel, x_m=default_positions(g.stroke.min_m, g.stroke.max_m, n), i_A=i_A, mesh_size=MESH,
                       executor=InlineExecutor(), progress=False, refine_x=r)
        return m, time.perf_counter() - t0

    ref, wall_ref = build(47, 1)
    print(f"steel {steel.name}; reference FEM at 47 positions x {i_A.size} currents, mesh {MESH}: {wall_ref:.1f} s")
    print(f"{'FEM positions':>13} {'refine':>6} {'columns':>7} {'i_f max':>9} {'i_f RMS':>9} {'F max':>8} "
          f"{'F RMS':>8} {'wall':>7} {'/ 24 FEM':>8}")
    base = None
    for n, r in CANDIDATES:
        m, wall = build(n, r)
        base = wall if base is None else base
        ei, ef = reading_errors(m, ref)
        print(f"{n:>13} {r:>6} {m.x_m.size:>7} {1e3 * ei.max():>6.2f} mA {1e3 * np.sqrt(np.mean(ei**2)):>6.2f} mA "
              f"{ef.max():>6.3f} N {np.sqrt(np.mean(ef**2)):>6.3f} N {wall:>5.1f} s {wall / base:>8.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
