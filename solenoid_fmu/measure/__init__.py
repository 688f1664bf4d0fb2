"""measure: see the README's package map."""

from .branches import FluxBranch, peak_curves
from .flux import CommutationCurve, FluxResult, commutation_curve, flux_linkage
from .format import KINDS, Recording, make_recording
from .reader import read_recording, validate_recording
from .writer import write_recording

__all__ = [
    "KINDS",
    "CommutationCurve",
    "FluxBranch",
    "FluxResult",
    "Recording",
    "commutation_curve",
    "flux_linkage",
    "make_recording",
    "peak_curves",
    "read_recording",
    "validate_recording",
    "write_recording",
]
