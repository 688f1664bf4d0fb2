"""maps: see the README's package map."""

from .core import (
    DEFAULT_CURRENT_FACTOR,
    DEFAULT_NI,
    InlineExecutor,
    build_maps,
    default_currents,
    default_positions,
    load_maps,
    name_problem,
    save_maps,
)
from .eddy import fit_eddy

__all__ = [
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
