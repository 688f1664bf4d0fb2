"""maps: see the README's package map."""

from .core import (
    DEFAULT_CURRENT_FACTOR,
    DEFAULT_NI,
    InlineExecutor,
    build_maps,
    default_currents,
    default_positions,
    force_at,
    force_psi_at,
    i_f_at,
    load_maps,
    name_problem,
    psi_at,
    save_maps,
)
from .eddy import fit_eddy

__all__ = [
    "force_at",
    "force_psi_at",
    "i_f_at",
    "psi_at",
    "DEFAULT_CURRENT_FACTOR",
    "DEFAULT_NI",
    "InlineExecutor",
    "build_maps",
    "default_currents",
    "default_positions",
    "fit_eddy",
    "load_maps",
    "name_problem",
    "save_maps",
]
