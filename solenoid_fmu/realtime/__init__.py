"""realtime: the real-time model (paper eqs. 1-3 and the effect sub-models) and the hysteresis operators.

The subpackage ``model/`` is the FMU payload: numpy only, its modules import nothing from the package
but each other (relative imports) and it is copied into every pythonfmu FMU whole (:data:`MODEL_SOURCE`,
:func:`model_source_files`); its definitions generate the native FMU's C header.
"""

# ruff: noqa: F403, F405  (the model's public names, model.__all__, are re-exported whole by the star import)
from pathlib import Path

from . import model
from .hysteresis import HysteresisError, PlayHysteresis
from .hysteresis_fit import fit_play_to_series
from .model import *
from .preisach import PreisachHysteresis

#: The real-time model's source package (a directory): copied whole into every pythonfmu FMU (it imports
#: only numpy and the standard library).
MODEL_SOURCE = Path(__file__).with_name("model")


def model_source_files() -> list[Path]:
    """The source files of the model package :data:`MODEL_SOURCE`, sorted (what an FMU ships)."""
    return sorted(MODEL_SOURCE.glob("*.py"))


#: The unit's public names: the model's (``model.__all__``, written out here because the layering test reads
#: this list as a literal; tests/test_layering.py checks the two agree) and the hysteresis operators'.
__all__ = [
    "COPPER_ALPHA_PER_K", "DEFAULT_PARAMS", "DRIVE_CURRENT", "DRIVE_VOLTAGE", "EFFECT_NAMES", "EFFECT_STATE_NAMES",
    "MAPS_JSON", "MAPS_MAX_ARRAY_ELEMENTS", "MAPS_NPZ", "MAPS_PREVIOUS", "MAPS_SCHEMA", "MAPS_SCHEMA_VERSION",
    "MAX_SUBSTEPS", "CoilRecord", "EddyRecord", "EffectsRecord", "MapTables", "ModelError", "ModelInputError",
    "ModelMapsError", "NEWTON_MAX_ITER", "NEWTON_TOL_REL", "ROS2_GAMMA", "SolenoidModel", "STATE_LAYOUT",
    "STATE_NAMES", "cell_coefficients", "coil_problems", "eddy_problems", "effects_data", "load_tables",
    "maps_pair_consistent", "pchip_scaled_slopes", "play_step", "read_maps_dir", "replace_meta",
    "T_START_EXCESS_RANGE_K", "heating_alpha",
    # the model package itself and its sources (the FMU payload), the hysteresis operators
    "model", "MODEL_SOURCE", "model_source_files", "HysteresisError", "PlayHysteresis", "PreisachHysteresis",
    "fit_play_to_series",
]
