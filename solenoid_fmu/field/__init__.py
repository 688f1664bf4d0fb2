"""field: see the README's package map."""

from .fem import Solution, Solver, solve_point, sweep_currents
from .geometry import Coil, Domain, Geometry, Region, Stroke, load_geometry
from .material import MU_0, MU_R_MAX, BHCurve, load_material, read_bh_csv, unimodal_fit, write_bh_csv
from .mesh import MIN_MESH_SIZE
from .steels import STEELS, RoschkeParameters, roschke_curve, roschke_mu_r, steel_curve, steel_names
from .threads import single_threaded

__all__ = ["single_threaded", "BHCurve", "Coil", "Domain", "Geometry", "Region", "Stroke",
           "MIN_MESH_SIZE", "MU_0", "MU_R_MAX", "STEELS", "RoschkeParameters", "Solution",
           "Solver", "load_geometry", "load_material", "roschke_curve", "roschke_mu_r", "solve_point", "steel_curve",
           "steel_names", "sweep_currents", "unimodal_fit", "read_bh_csv", "write_bh_csv"]
