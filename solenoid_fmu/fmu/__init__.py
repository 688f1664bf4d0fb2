"""fmu: see the README's package map."""

from .export import build_fmu, simulate_model, simulate_recording

__all__ = ["build_fmu", "simulate_model", "simulate_recording"]
