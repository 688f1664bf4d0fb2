r"""maps: the characteristic maps of the real-time model (paper section 5, figures 12 and 13).

The real-time model does not run the FEM; it runs on two maps, ``i = i_f(Psi, x) + G_eddy dPsi/dt``
(paper eq. 2) and ``F = F(Psi, x)`` (eq. 3). Modules, in the order the data flows:

- :mod:`.tables`: :class:`CharacteristicMaps` (immutable arrays + metadata) and the checks of its arrays;
- :mod:`.interpolate`: lookups Psi(i, x), F(i, x) on the FEM tables, i_f(Psi, x), F(Psi, x) on the maps;
- :mod:`.invert`: Psi(i, x) -> i_f(Psi, x), F(Psi, x) on a regular flux grid, and the round-trip error;
- :mod:`.sweep`: the FEM sweep over (i, x) on any executor (:func:`build_maps`);
- :mod:`.io`: the one writer (:func:`save_maps`) and reader (:func:`load_maps`) of a maps directory
  (``maps.npz`` + ``maps.json``; the files are read by :func:`solenoid_fmu.realtime.read_maps_dir`);
- :mod:`.check`: energy balance around closed cycles; :mod:`.export`: Modelica and MATLAB files;
- :mod:`.eddy`: the eddy-current conductance G_eddy from fast recordings (paper fig. 14);
- :mod:`.plots` (matplotlib) and :mod:`.cli` (``solenoid-fmu maps``, ``solenoid-fmu eddy``).

Units are SI everywhere (m, A, Wb, N); the CLI takes millimetres for positions. The force is
positive when it pulls the armature towards the pole (closes the working gap x).
"""

from .check import CycleEnergy, cycle_energy_balance, rectangle_cycle
from .eddy import EddyFit, fit_eddy, with_fitted_eddy
from .export import export_combitable2d, export_mat, read_combitable2d
from .interpolate import force_at, force_psi_at, i_f_at, psi_at
from .invert import invert_maps, round_trip_error
from .io import encode_maps, load_maps, maps_tables, name_problem, save_maps
from .sweep import (
    CAMPAIGN_CURRENT_MARGIN,
    CAMPAIGN_CURRENT_POWER,
    DEFAULT_CURRENT_FACTOR,
    DEFAULT_CURRENT_POWER,
    DEFAULT_NI,
    InlineExecutor,
    build_maps,
    default_currents,
    default_positions,
    maps_current_grid,
    process_pool,
)
from .tables import CharacteristicMaps

__all__ = [
    "CAMPAIGN_CURRENT_MARGIN",
    "CAMPAIGN_CURRENT_POWER",
    "CharacteristicMaps",
    "CycleEnergy",
    "DEFAULT_CURRENT_FACTOR",
    "DEFAULT_CURRENT_POWER",
    "DEFAULT_NI",
    "EddyFit",
    "InlineExecutor",
    "build_maps",
    "cycle_energy_balance",
    "encode_maps",
    "default_currents",
    "default_positions",
    "export_combitable2d",
    "export_mat",
    "fit_eddy",
    "force_at",
    "force_psi_at",
    "i_f_at",
    "invert_maps",
    "load_maps",
    "maps_current_grid",
    "maps_tables",
    "name_problem",
    "process_pool",
    "psi_at",
    "read_combitable2d",
    "rectangle_cycle",
    "round_trip_error",
    "save_maps",
    "with_fitted_eddy",
]
