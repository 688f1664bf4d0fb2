"""The rig's error and its parameter check (shared by every rig module)."""

from __future__ import annotations

import math

from ..errors import SolenoidError

__all__ = ["RigError", "positive"]


class RigError(SolenoidError):
    """Bad rig configuration: unknown effect, unphysical parameter, unusable maps or truth file."""


def positive(name: str, value, allow_zero: bool = False) -> float:
    """``value`` as a finite float > 0 (>= 0 with ``allow_zero``), else :class:`RigError` naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise RigError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        raise RigError(f"{name} must be a finite number {'>=' if allow_zero else '>'} 0, got {value!r}")
    return v
