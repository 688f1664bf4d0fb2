"""realtime: see the README's package map."""

from .hysteresis import HysteresisError, PlayHysteresis
from .hysteresis_fit import fit_play_to_series
from .model import (
    COPPER_ALPHA_PER_K,
    MAPS_JSON,
    MAPS_NPZ,
    MAPS_SCHEMA,
    MAPS_SCHEMA_VERSION,
    ROS2_GAMMA,
    MapTables,
    ModelError,
    ModelMapsError,
    load_tables,
    read_maps_dir,
)
from .preisach import PreisachHysteresis

__all__ = [
    "COPPER_ALPHA_PER_K",
    "HysteresisError",
    "MAPS_JSON",
    "MAPS_NPZ",
    "MAPS_SCHEMA",
    "MAPS_SCHEMA_VERSION",
    "MapTables",
    "ModelError",
    "ModelMapsError",
    "PlayHysteresis",
    "PreisachHysteresis",
    "ROS2_GAMMA",
    "fit_play_to_series",
    "load_tables",
    "read_maps_dir",
]
