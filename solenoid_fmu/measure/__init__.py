"""measure: see the README's package map."""

from .branches import FluxBranch, peak_curves
from .conditioning import armature_moves, hold_segments
from .flux import CommutationCurve, FluxResult, commutation_curve, flux_linkage
from .format import KINDS, Recording, make_recording, misspelt_in
from .headers import ESTIMATED_KEYS, HeaderFix, headers_from_data
from .polarity import read_unipolar, unipolar
from .reader import read_recording, validate_recording
from .resistance import HEADER_OFF_SIGMAS, ResistanceTrack, closure_problems, resistance_track
from .resistance_campaign import CampaignResistance, campaign_resistance
from .writer import write_recording

__all__ = [
    "HEADER_OFF_SIGMAS",
    "KINDS",
    "ESTIMATED_KEYS",
    "CampaignResistance",
    "CommutationCurve",
    "FluxBranch",
    "FluxResult",
    "HeaderFix",
    "Recording",
    "ResistanceTrack",
    "armature_moves",
    "campaign_resistance",
    "closure_problems",
    "commutation_curve",
    "flux_linkage",
    "headers_from_data",
    "hold_segments",
    "make_recording",
    "misspelt_in",
    "peak_curves",
    "read_recording",
    "read_unipolar",
    "resistance_track",
    "unipolar",
    "validate_recording",
    "write_recording",
]
