"""loop: see the README's package map."""

from .diagnosis import Diagnosis, diagnose
from .heating_fit import heating_corrected
from .identifiability import not_identifiable
from .improvement import Improvement, ImproveResult, effects_summary_lines, improve, improve_tables
from .metrics import ValidationError, signal_metrics, validate_cases
from .residuals import FluxCache, ResidualCase, ambient_resistance, cases_from_recordings
from .split import split_recordings
from .tables import ImproveError, maps_from_fmu, tables_from_fmu, with_effects
from .validation import timed_cases, validate, validate_model

__all__ = [
    "Diagnosis",
    "FluxCache",
    "ImproveError",
    "ImproveResult",
    "Improvement",
    "ResidualCase",
    "ValidationError",
    "ambient_resistance",
    "cases_from_recordings",
    "diagnose",
    "effects_summary_lines",
    "heating_corrected",
    "improve",
    "improve_tables",
    "maps_from_fmu",
    "not_identifiable",
    "signal_metrics",
    "split_recordings",
    "tables_from_fmu",
    "timed_cases",
    "validate",
    "validate_cases",
    "validate_model",
    "with_effects",
]
