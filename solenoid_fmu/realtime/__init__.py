"""realtime: the real-time model (paper eqs. 1-3 and the effect sub-models) and the hysteresis operators.

The subpackage ``model/`` is the FMU payload: numpy only, its modules import nothing from the package
but each other (relative imports) and it is copied into every pythonfmu FMU whole (:data:`MODEL_SOURCE`,
:func:`model_source_files`); its definitions generate the native FMU's C header.
"""

from pathlib import Path

from .hysteresis import HysteresisError, PlayHysteresis
from .hysteresis_fit import fit_play_to_series
from .model import (
    COPPER_ALPHA_PER_K,
    DEFAULT_PARAMS,
    DRIVE_CURRENT,
    DRIVE_VOLTAGE,
    EFFECT_NAMES,
    EFFECT_STATE_NAMES,
    MAPS_JSON,
    MAPS_NPZ,
    MAPS_PREVIOUS,
    MAPS_SCHEMA,
    MAPS_SCHEMA_VERSION,
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
    maps_pair_consistent,
    read_maps_dir,
)
from .preisach import PreisachHysteresis

#: The real-time model's source package (a directory): copied whole into every pythonfmu FMU (it imports
#: only numpy and the standard library).
MODEL_SOURCE = Path(__file__).with_name("model")


def model_source_files() -> list[Path]:
    """The source files of the model package :data:`MODEL_SOURCE`, sorted (what an FMU ships)."""
    return sorted(MODEL_SOURCE.glob("*.py"))

__all__ = [
    "COPPER_ALPHA_PER_K", "DEFAULT_PARAMS", "DRIVE_CURRENT", "DRIVE_VOLTAGE", "EFFECT_NAMES", "EFFECT_STATE_NAMES",
    "HysteresisError", "MAPS_JSON", "MAPS_NPZ", "MAPS_PREVIOUS", "MAPS_SCHEMA", "MAPS_SCHEMA_VERSION", "MAX_SUBSTEPS",
    "MODEL_SOURCE",
    "MapTables", "ModelError", "ModelInputError", "ModelMapsError", "NEWTON_MAX_ITER", "NEWTON_TOL_REL",
    "PlayHysteresis", "PreisachHysteresis", "ROS2_GAMMA", "STATE_LAYOUT", "STATE_NAMES", "SolenoidModel",
    "effects_data", "fit_play_to_series", "load_tables", "maps_pair_consistent", "model_source_files",
    "read_maps_dir",
]
