"""realtime: see the README's package map."""

from .hysteresis import HysteresisError, PlayHysteresis
from .hysteresis_fit import fit_play_to_series
from .model import COPPER_ALPHA_PER_K, ROS2_GAMMA, MapTables, ModelError, load_tables
from .preisach import PreisachHysteresis

__all__ = [
    "COPPER_ALPHA_PER_K",
    "HysteresisError",
    "MapTables",
    "ModelError",
    "PlayHysteresis",
    "PreisachHysteresis",
    "ROS2_GAMMA",
    "fit_play_to_series",
    "load_tables",
]
