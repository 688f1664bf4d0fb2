"""Benchmark: wall time of the default PS45 characteristic map and operating points per second.

Runs in one process tree:

1. a serial baseline on a subset of the default grid (a few positions, all currents) in this process
   (:class:`solenoid_fmu.maps.InlineExecutor`);
2. the whole default map (15 positions x 26 currents, mesh size 1.0) on the default executor
   (a process pool with one worker per core);

and prints the wall times, operating points per second, the parallel/serial throughput ratio and
whether the goal (default map in under 3 minutes) is met.

Usage::

    python benchmarks/bench_maps.py [--mesh-size 1.0] [--serial-positions 2] [--save maps/NAME]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

from solenoid_fmu.field.geometry import load_geometry
from solenoid_fmu.field.material import load_material
from solenoid_fmu.maps import (
    DEFAULT_CURRENT_FACTOR,
    DEFAULT_NI,
    InlineExecutor,
    build_maps,
    default_currents,
    default_positions,
    round_trip_error,
    save_maps,
)
from solenoid_fmu.maps.sweep import DEFAULT_NX

GOAL_S = 180.0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh-size", type=float, default=1.0, help="mesh-size factor (default 1.0)")
    parser.add_argument("--serial-positions", type=int, default=2,
                        help="positions in the serial baseline (default 2; 0 skips it)")
    parser.add_argument("--save", metavar="DIR", help="also save the map there")
    args = parser.parse_args(argv)

    geometry, material = load_geometry(), load_material()
    x_all = default_positions(geometry.stroke.min_m, geometry.stroke.max_m, DEFAULT_NX)
    i_all = default_currents(DEFAULT_CURRENT_FACTOR * geometry.coil.max_current_A, DEFAULT_NI)
    cores = os.cpu_count() or 1
    print(f"PS45 default map: {len(x_all)} positions x {len(i_all)} currents = {len(x_all) * len(i_all)} "
          f"operating points, mesh size {args.mesh_size}, {cores} cores")

    serial_rate = None
    if args.serial_positions > 0:
        # a spread of positions: the cost of a column depends on the gap (saturation)
        pick = np.unique(np.linspace(0, len(x_all) - 1, args.serial_positions + 2).round().astype(int)[1:-1])
        t0 = time.perf_counter()
        build_maps(geometry, material, x_m=x_all[pick], i_A=i_all, mesh_size=args.mesh_size,
                   executor=InlineExecutor(), progress=False)
        serial_s = time.perf_counter() - t0
        points = len(pick) * len(i_all)
        serial_rate = points / serial_s
        print(f"serial baseline ({len(pick)} positions, {points} points, one process): {serial_s:.1f} s, "
              f"{serial_rate:.2f} points/s")

    t0 = time.perf_counter()
    maps = build_maps(geometry, material, mesh_size=args.mesh_size, progress=sys.stderr.isatty())
    wall_s = time.perf_counter() - t0
    points = len(maps.x_m) * len(maps.i_A)
    rate = points / wall_s
    solver = maps.metadata["provenance"]["solver"]
    print(f"default map ({solver['executor']}, {solver['workers']} workers): {wall_s:.1f} s wall, "
          f"{rate:.2f} points/s, {solver['newton_iterations_total']} Newton iterations")
    if serial_rate is not None:
        print(f"parallel / serial throughput: {rate / serial_rate:.2f} x on {cores} cores")
    print(f"flux grid: {len(maps.psi_Wb)} points; round trip Psi -> i_f -> Psi: "
          f"{round_trip_error(maps, points_per_interval=4) * 100:.4f} % at the map positions, "
          f"{maps.metadata['round_trip_max_rel_error_between_positions'] * 100:.3f} % between them")
    print(f"goal (< {GOAL_S:.0f} s): {'met' if wall_s < GOAL_S else 'NOT met'}")
    if args.save:
        print(f"saved {save_maps(maps, args.save)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
