"""Command line of the field: ``solenoid-fmu solve`` (one operating point)."""

from __future__ import annotations

import json
import time
from pathlib import Path

from ..argtypes import number
from ..errors import SolenoidError
from .fem import Solver
from .geometry import load_geometry
from .material import load_material
from .mesh import MIN_MESH_SIZE
from .plots import plot_field

__all__ = ["add_cli"]


def add_cli(sub) -> None:
    """Register ``solenoid-fmu solve``."""
    p = sub.add_parser("solve", help="solve one operating point: flux linkage and force")
    p.add_argument("--x-mm", type=number(), required=True, help="working air gap [mm]")
    p.add_argument("--i-A", type=number(), required=True,
                   help=f"coil current [A], |i| up to {MAX_RATED_FACTOR:g} x the coil's rated current")
    p.add_argument("--geometry", help="solenoid TOML (default: packaged PS45)")
    p.add_argument("--material", help="B(H) CSV H_A_per_m,B_T (default: literature 9SMnPb28)")
    p.add_argument("--mesh-size", type=number(MIN_MESH_SIZE), default=1.0,
                   help=f"mesh-size scale (default 1.0; 0.5 = finer; at least {MIN_MESH_SIZE})")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", help="write flux lines and |B| to this PNG")
    p.set_defaults(func=_cli_solve)


#: solve refuses currents beyond this multiple of the coil's rated current (the B(H) curve ends long before).
MAX_RATED_FACTOR = 100.0


def _cli_solve(args) -> int:
    geom = load_geometry(args.geometry)
    mat = load_material(args.material)
    top = MAX_RATED_FACTOR * geom.coil.max_current_A
    if abs(args.i_A) > top:
        raise SolenoidError(f"--i-A {args.i_A:g} A: beyond {MAX_RATED_FACTOR:g} x the coil's rated current "
                            f"({geom.coil.max_current_A:g} A), the steel is saturated far past any B(H) data; "
                            f"give |i| <= {top:g} A")
    t0 = time.perf_counter()
    solver = Solver(geom, mat, args.mesh_size)
    sol = solver.solve(args.i_A, args.x_mm * 1e-3)
    elapsed = time.perf_counter() - t0
    plot_path = None
    if args.plot:
        plot_path = Path(args.plot)
        if plot_path.is_dir():
            raise SolenoidError(f"--plot {args.plot}: is a directory; give a .png file name")
        if plot_path.suffix.lower() != ".png":
            plot_path = plot_path.with_name(plot_path.name + ".png")  # what matplotlib would write anyway
        plot_path.parent.mkdir(parents=True, exist_ok=True)
        plot_field(solver, sol, plot_path)
    if args.json:
        print(json.dumps(sol.as_dict()))
    else:
        print(f"{geom.name}: i = {args.i_A:g} A, x = {args.x_mm:g} mm  ({elapsed:.2f} s incl. mesh)")
        print(f"  Psi                = {sol.psi_Wb * 1e3:.4f} mWb")
        print(f"  F (co-energy)      = {sol.force_coenergy_N:.3f} N")
        print(f"  F (Maxwell stress) = {sol.force_stress_N:.3f} N")
        print(f"  Newton iterations  = {sol.newton_iterations}")
        if plot_path is not None:
            print(f"  field plot: {plot_path}")
    return 0
