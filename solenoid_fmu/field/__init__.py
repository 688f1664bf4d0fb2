"""field: see the README's package map."""

from .fem import Solution, Solver, solve_point, sweep_currents
from .geometry import Geometry, load_geometry
from .material import MU_0, MU_R_MAX, BHCurve, load_material, write_bh_csv
from .mesh import MIN_MESH_SIZE

__all__ = ["BHCurve", "Geometry", "MIN_MESH_SIZE", "MU_0", "MU_R_MAX", "Solution", "Solver", "load_geometry",
           "load_material", "solve_point", "sweep_currents", "write_bh_csv"]
