"""realtime: see the README's package map."""

from pathlib import Path

from .hysteresis import HysteresisError, PlayHysteresis, PreisachHysteresis, fit_play_to_series
from .model import (
    COPPER_ALPHA_PER_K,
    DEFAULT_PARAMS,
    DRIVE_CURRENT,
    DRIVE_VOLTAGE,
    EFFECT_NAMES,
    EFFECT_STATE_NAMES,
    MAX_SUBSTEPS,
    NEWTON_MAX_ITER,
    NEWTON_TOL_REL,
    ROS2_GAMMA,
    STATE_LAYOUT,
    STATE_NAMES,
    MapTables,
    ModelError,
    ModelInputError,
    ModelMapsError,
    SolenoidModel,
    effects_data,
    load_tables,
)

#: The real-time model's source file: copied whole into every pythonfmu FMU (it imports only numpy).
MODEL_SOURCE = Path(__file__).with_name("model.py")

__all__ = [
    "COPPER_ALPHA_PER_K",
    "DEFAULT_PARAMS",
    "DRIVE_CURRENT",
    "DRIVE_VOLTAGE",
    "EFFECT_NAMES",
    "EFFECT_STATE_NAMES",
    "HysteresisError",
    "MAX_SUBSTEPS",
    "MODEL_SOURCE",
    "MapTables",
    "ModelError",
    "ModelInputError",
    "ModelMapsError",
    "NEWTON_MAX_ITER",
    "NEWTON_TOL_REL",
    "PlayHysteresis",
    "PreisachHysteresis",
    "ROS2_GAMMA",
    "STATE_LAYOUT",
    "STATE_NAMES",
    "SolenoidModel",
    "effects_data",
    "fit_play_to_series",
    "load_tables",
]
