"""identification: see the README's package map."""

from .campaign import identify_from_recordings
from .campaign_data import KAPPA_SIGNIFICANT, hysteresis_half_width
from .fit import DEFAULT_MESH_SIZE, NLOPT_CODES, choose_currents, identify_bh, nlopt_code_name
from .flux_model import FluxModel, fem_flux, fem_force_vs_stroke
from .io import write_curve_files
from .measured import force_stroke_curve, group_flux
from .parametrization import SusceptibilityModel, fit_to_curve, scaled_curve
from .report import write_report
from .result import IdentificationResult, h_range_text

__all__ = [
    "KAPPA_SIGNIFICANT",
    "DEFAULT_MESH_SIZE",
    "NLOPT_CODES",
    "FluxModel",
    "IdentificationResult",
    "h_range_text",
    "SusceptibilityModel",
    "choose_currents",
    "fem_flux",
    "fem_force_vs_stroke",
    "fit_to_curve",
    "force_stroke_curve",
    "group_flux",
    "hysteresis_half_width",
    "identify_bh",
    "identify_from_recordings",
    "nlopt_code_name",
    "scaled_curve",
    "write_curve_files",
    "write_report",
]
