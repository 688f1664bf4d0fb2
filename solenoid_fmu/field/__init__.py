"""field: see the README's package map."""

from .fem import Solution, Solver, solve_point, sweep_currents
from .geometry import Geometry, load_geometry
from .material import MU_0, MU_R_MAX, BHCurve, load_material, unimodal_fit, write_bh_csv

__all__ = ["BHCurve", "Geometry", "MU_0", "MU_R_MAX", "Solution", "Solver", "load_geometry", "load_material",
           "solve_point", "sweep_currents", "unimodal_fit", "write_bh_csv"]
