"""Definitions of the real-time model: constants, state layout, parameters, errors, input checks.

Part of the FMU payload (:mod:`solenoid_fmu.realtime.model`): numpy and the standard library only.
The named state indices (``ST_*``, ``FX_*``) are the names ``solenoid_fmu.fmu.c_sources`` generates for
the C model (``enum ST_*``, ``enum FX_*`` in ``solenoid_model.h``), so both read alike.
"""

from __future__ import annotations

import math

#: Drive modes (also the FMU enumeration values).
DRIVE_VOLTAGE = 1
DRIVE_CURRENT = 2
DRIVE_NAMES = {"voltage": DRIVE_VOLTAGE, "current": DRIVE_CURRENT}

#: ROS2 parameter gamma = 1 + 1/sqrt(2).
ROS2_GAMMA = 1.0 + 1.0 / math.sqrt(2.0)
#: Newton iteration limits for the algebraic case (current mode, G = 0).
NEWTON_MAX_ITER = 60
NEWTON_TOL_REL = 1e-12

#: Layout version of the state vector; bumped whenever states are added.
STATE_LAYOUT = 1
#: Names of the state vector entries, in order (flags are 0.0 or 1.0).
STATE_NAMES = (
    "state_layout",  # STATE_LAYOUT
    "time_s",  # model time [s]
    "psi_Wb",  # flux linkage [Wb], the ODE state
    "initialized",  # 1.0 once initialize() has run
    "excursion_psi",  # |Psi| held at psi_max
    "excursion_x",  # x clamped to the map's gap range
    "excursion_extrapolated",  # (Psi, x) beyond the FEM data of the map
    "out_i_A",  # outputs held since the last communication point
    "out_U_V",
    "out_F_N",
    "out_dpsi_dt_V",
    "out_i_eddy_A",
)
STATE_INDEX = {name: k for k, name in enumerate(STATE_NAMES)}
# Named indices of the state vector (the C model's generated ``ST_*`` names).
ST_STATE_LAYOUT = STATE_INDEX["state_layout"]
ST_TIME_S = STATE_INDEX["time_s"]
ST_PSI_WB = STATE_INDEX["psi_Wb"]
ST_INITIALIZED = STATE_INDEX["initialized"]
ST_EXCURSION_PSI = STATE_INDEX["excursion_psi"]
ST_EXCURSION_X = STATE_INDEX["excursion_x"]
ST_EXCURSION_EXTRAPOLATED = STATE_INDEX["excursion_extrapolated"]
ST_OUT_I_A = STATE_INDEX["out_i_A"]
ST_OUT_U_V = STATE_INDEX["out_U_V"]
ST_OUT_F_N = STATE_INDEX["out_F_N"]
ST_OUT_DPSI_DT_V = STATE_INDEX["out_dpsi_dt_V"]
ST_OUT_I_EDDY_A = STATE_INDEX["out_i_eddy_A"]

#: Parameters and their defaults; ``None`` means "take the value from maps.json".
DEFAULT_PARAMS = {
    # coil resistance at the start, before self-heating [ohm]: the heating sub-model multiplies it by
    # (1 + alpha T_rise); default the maps' value at 20 degC (coil.resistance_ohm_20C), and validation gives it
    # the recording's measured one (the coil at the temperature the run starts from)
    "R_ohm": None,
    "G_eddy_S": None,  # eddy-current conductance [S] (maps.json eddy.G_eddy_S, 0 if null)
    "drive_mode": "voltage",  # "voltage" / "current" (or DRIVE_VOLTAGE / DRIVE_CURRENT)
    "Psi0_Wb": 0.0,  # initial flux linkage [Wb] (ignored in current mode with G = 0)
    "h_sub_max_s": 1e-4,  # largest internal sub-step [s]
    # switchable effect sub-models; None = "as maps.json's effects section says"
    "hysteresis_on": None,  # magnetic hysteresis (play operator on Psi, extra current [A])
    "hyst_gain": 1.0,  # factor on the hysteresis current [-]
    "eddy_ladder_on": None,  # frequency-dependent eddy currents (R-L sections beside G_eddy)
    "heating_on": None,  # coil heating: R(T) with a first-order thermal model
    "C_th_J_per_K": None,  # heat capacity of the coil [J/K]
    "R_th_K_per_W": None,  # thermal resistance to ambient [K/W]
    "alpha_per_K": None,  # temperature coefficient of R [1/K]
    # coil temperature above ambient at initialization [K] (heating: the coil cools from it towards ambient
    # through R_th; R_ohm is its resistance at that temperature). 0: the run starts at ambient
    "T_start_excess_K": 0.0,
    "friction_on": None,  # friction in the force output (Dahl model in x)
    "friction_N": None,  # sliding friction force [N]
    "presliding_m": None,  # presliding displacement of the Dahl model [m]
}

#: Range of ``T_start_excess_K`` [K]: from a coil colder than ambient to one at insulation class H's 180 degC
#: in a 20 degC room (beyond, the linear R(T) and the first-order thermal model are no longer the coil).
T_START_EXCESS_RANGE_K = (-50.0, 160.0)

def heating_alpha(alpha_per_K: float, T_start_excess_K: float) -> float:
    """The coefficient [1/K] of the temperature rise ``T`` in ``R(T) = R (1 + a T)`` for a run whose start
    resistance ``R`` is that of a coil ``T_start_excess_K`` above ambient: ``alpha / (1 + alpha T_0)`` (the coil's
    resistance is linear in its temperature with ``alpha`` at ambient; the native FMU computes the same)."""
    return alpha_per_K / (1.0 + alpha_per_K * T_start_excess_K)


#: Temperature coefficient of copper's resistance at 20 degC [1/K]; the one value every module uses.
COPPER_ALPHA_PER_K = 0.00393

#: Names of the effect sub-models (the ``effects`` section of maps.json).
EFFECT_NAMES = ("hysteresis", "eddy_ladder", "heating", "friction")
#: Defaults of the effect scalars when the effects section leaves them out.
EFFECT_DEFAULTS = {"C_th_J_per_K": 300.0, "R_th_K_per_W": 1.0, "alpha_per_K": COPPER_ALPHA_PER_K, "friction_N": 0.0,
                    "presliding_m": 20e-6}
EFFECT_SWITCHES = {"hysteresis_on": "hysteresis", "eddy_ladder_on": "eddy_ladder", "heating_on": "heating",
             "friction_on": "friction"}
EFFECT_SCALARS = {"C_th_J_per_K": ("heating", "C_th_J_per_K"), "R_th_K_per_W": ("heating", "R_th_K_per_W"),
                   "alpha_per_K": ("heating", "alpha_per_K"), "friction_N": ("friction", "force_N"),
                   "presliding_m": ("friction", "presliding_m")}
#: Names of the effect states appended to the state vector when the maps carry effects
#: (followed by one ``ladder_k`` per eddy section and one ``play_k`` per hysteresis play).
EFFECT_STATE_NAMES = ("T_rise_K", "F_friction_N", "x_prev_m", "i_hyst_A")

#: Severity of the excursion events (FMI log status names).
EVENT_SEVERITY = {
    "psi": "warning",
    "x": "warning",
    "extrapolated": "warning",
}


class ModelError(Exception):
    """Base class of the errors this module raises (it cannot import the package's errors)."""


#: Most sub-steps one communication step may take (as the native FMU's MAX_SUBSTEPS): beyond it the
#: step is refused, never run for hours.
MAX_SUBSTEPS = 1.0e7
_FX_IDX = {name: k for k, name in enumerate(EFFECT_STATE_NAMES)}
# Named indices of the effect states (the C model's generated ``FX_*`` names); the ladder currents
# start at FX_LAD, the plays follow them.
FX_T_RISE_K = _FX_IDX["T_rise_K"]
FX_F_FRICTION_N = _FX_IDX["F_friction_N"]
FX_X_PREV_M = _FX_IDX["x_prev_m"]
FX_I_HYST_A = _FX_IDX["i_hyst_A"]
FX_LAD = len(EFFECT_STATE_NAMES)



class ModelInputError(ModelError, ValueError):
    """An input or parameter is invalid: NaN or infinite, ``R <= 0``, ``G < 0``, bad mode."""


class ModelMapsError(ModelError):
    """The maps directory is missing, malformed, or breaks what the model needs."""




def finite_float(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ModelInputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ModelInputError(f"{name} must be finite, got {v!r}")
    return v



def drive_code(value) -> int:
    if isinstance(value, str):
        code = DRIVE_NAMES.get(value.strip().lower())
        if code is None:
            raise ModelInputError(f"drive_mode must be 'voltage' or 'current', got {value!r}")
        return code
    try:
        code = int(value)
    except (TypeError, ValueError):
        raise ModelInputError(f"drive_mode must be 'voltage'/'current' or 1/2, got {value!r}") from None
    if code not in (DRIVE_VOLTAGE, DRIVE_CURRENT) or code != value:
        raise ModelInputError(f"drive_mode must be {DRIVE_VOLTAGE} (voltage) or {DRIVE_CURRENT} (current), "
                              f"got {value!r}")
    return code
