"""measure: see the README's package map."""

from .recordings import (
    Recording,
    commutation_curve,
    flux_linkage,
    make_recording,
    peak_curves,
    read_recording,
    write_recording,
)

__all__ = [
    "Recording",
    "commutation_curve",
    "flux_linkage",
    "make_recording",
    "peak_curves",
    "read_recording",
    "write_recording",
]
