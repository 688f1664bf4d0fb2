"""fmu: see the README's package map.

``interface`` (the one variable table) -> ``python_backend`` (+ ``slave``, packed into the FMU) and
``native`` (+ ``c_sources``, ``c/solenoid_fmu.c``) -> ``model_description`` -> ``export``
(``build_fmu``); ``simulate`` runs an FMU (fmpy, ``callbacks``) or the model on a recording; ``cli``.
"""

from .callbacks import fmi2_callbacks, release_fmi2_callbacks
from .export import BACKENDS, build_fmu
from .interface import EFFECT_VARIABLES, MODEL_IDENTIFIER, VARIABLES, FmuVariable, interface_for
from .simulate import (
    DRIVE_BY_KIND,
    SimulationResult,
    heating_start,
    simulate_model,
    simulate_recording,
    start_excess_K,
)

__all__ = [
    "BACKENDS",
    "DRIVE_BY_KIND",
    "EFFECT_VARIABLES",
    "MODEL_IDENTIFIER",
    "VARIABLES",
    "FmuVariable",
    "SimulationResult",
    "build_fmu",
    "fmi2_callbacks",
    "heating_start",
    "interface_for",
    "release_fmi2_callbacks",
    "simulate_model",
    "simulate_recording",
    "start_excess_K",
]
