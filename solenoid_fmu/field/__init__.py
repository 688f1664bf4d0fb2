"""field: see the README's package map."""

from .fem import Solver, sweep_currents
from .geometry import load_geometry
from .material import MU_0, MU_R_MAX, BHCurve, load_material, write_bh_csv

__all__ = ["BHCurve", "MU_0", "MU_R_MAX", "Solver", "load_geometry", "load_material", "sweep_currents", "write_bh_csv"]
