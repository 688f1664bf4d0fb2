"""Checks of the model's parameters (:data:`DEFAULT_PARAMS`), defaults taken from the maps.

Part of the FMU payload (:mod:`solenoid_fmu.realtime.model`): the standard library only.
"""

from __future__ import annotations

from .definitions import (
    DEFAULT_PARAMS,
    EFFECT_DEFAULTS,
    EFFECT_SCALARS,
    EFFECT_SWITCHES,
    T_START_EXCESS_RANGE_K,
    ModelInputError,
    drive_code,
    finite_float,
)
from .tables import MapTables


def checked_param(key: str, value, tables: MapTables, fx_data: dict):
    """The value parameter ``key`` takes for ``value`` (``None``: the default from the maps); raises
    :class:`ModelInputError` for an unknown key or a value out of range."""
    if key not in DEFAULT_PARAMS:
        raise ModelInputError(f"unknown parameter {key!r}; known: {', '.join(DEFAULT_PARAMS)}")
    if key == "R_ohm":
        if value is None:
            value = tables.resistance_ohm_20C
            if value is None:
                raise ModelInputError("R_ohm not given and maps.json has no coil.resistance_ohm_20C")
        v = finite_float("R_ohm", value)
        if v <= 0.0:
            raise ModelInputError(f"R_ohm must be > 0 ohm, got {v!r}")
        return v
    elif key == "G_eddy_S":
        if value is None:
            value = tables.G_eddy_S or 0.0
        v = finite_float("G_eddy_S", value)
        if v < 0.0:
            raise ModelInputError(f"G_eddy_S must be >= 0 S, got {v!r}")
        return v
    elif key == "drive_mode":
        return drive_code(value)
    elif key == "Psi0_Wb":
        return finite_float("Psi0_Wb", value)
    elif key == "h_sub_max_s":
        v = finite_float("h_sub_max_s", value)
        if v <= 0.0:
            raise ModelInputError(f"h_sub_max_s must be > 0 s, got {v!r}")
        return v
    elif key in EFFECT_SWITCHES:
        name = EFFECT_SWITCHES[key]
        on = (name in fx_data) if value is None else bool(value)
        if on and name not in fx_data:
            raise ModelInputError(f"{key}: the maps carry no {name!r} effect (maps.json 'effects')")
        return on
    elif key == "hyst_gain":
        v = finite_float(key, value)
        if v < 0.0:
            raise ModelInputError(f"hyst_gain must be >= 0, got {v!r}")
        return v
    elif key == "T_start_excess_K":
        v = finite_float(key, value)
        if not T_START_EXCESS_RANGE_K[0] <= v <= T_START_EXCESS_RANGE_K[1]:
            raise ModelInputError(f"T_start_excess_K must lie in [{T_START_EXCESS_RANGE_K[0]:g}, "
                                  f"{T_START_EXCESS_RANGE_K[1]:g}] K, got {v!r}")
        return v
    elif key in EFFECT_SCALARS:
        if value is None:
            sect, field = EFFECT_SCALARS[key]
            value = (fx_data.get(sect) or {}).get(field, EFFECT_DEFAULTS[key])
        v = finite_float(key, value)
        if v < 0.0 or (v == 0.0 and key in ("C_th_J_per_K", "R_th_K_per_W", "presliding_m")):
            raise ModelInputError(f"{key} must be > 0 (>= 0 for alpha and friction), got {v!r}")
        return v
    raise ModelInputError(f"parameter {key!r} has no check")  # a DEFAULT_PARAMS key added without one
