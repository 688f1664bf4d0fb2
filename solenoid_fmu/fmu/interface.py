"""The FMU interface: the one table of variables both backends (pythonfmu, native C) build from.

Names are API; value references are the positions in :func:`interface_for` (then, in a native FMU
with model exchange, the locals of :func:`me_variables`):

======================  =========  ===========  ======================================================
name                    causality  variability  meaning
======================  =========  ===========  ======================================================
``U_V``                 input      continuous   coil voltage [V], the drive in voltage mode
``i_A``                 input      continuous   coil current [A], the drive in current mode
``x_m``                 input      continuous   armature working gap x [m]
``i_out_A``             output     continuous   coil current [A]
``U_out_V``             output     continuous   coil voltage [V]
``F_N``                 output     continuous   magnetic force [N], positive closing the gap (eq. 3)
``psi_Wb``              output     continuous   flux linkage [Wb], the model state
``dpsi_dt_V``           output     continuous   induced voltage dPsi/dt [V]
``i_eddy_A``            output     continuous   eddy current G dPsi/dt [A] (eq. 2)
``out_of_map``          output     discrete     true while x or Psi is clamped to the map
``R_ohm``               parameter  tunable      coil resistance at the start, before self-heating [ohm]
``G_eddy_S``            parameter  tunable      eddy-current conductance [S]
``drive_mode``          parameter  fixed        Integer 1..2: 1 voltage-driven, 2 current-driven
``Psi0_Wb``             parameter  fixed        initial flux linkage [Wb]
``h_sub_max_s``         parameter  fixed        largest internal sub-step [s]
======================  =========  ===========  ======================================================

Maps with an ``effects`` section (effect sub-models) add :data:`EFFECT_VARIABLES` after these. The native C
source gets the value references of this table as a generated enum (``solenoid_model.h``).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..realtime import DRIVE_CURRENT, DRIVE_VOLTAGE, MapTables, effects_data

__all__ = [
    "DEFAULT_EXPERIMENT",
    "DISPLAY_UNITS",
    "DRIVE_MODE_RANGE",
    "EFFECT_VARIABLES",
    "INTERFACES",
    "LOG_CATEGORIES",
    "ME_UNIT_DEFINITIONS",
    "ME_VARIABLES",
    "MODEL_IDENTIFIER",
    "UNIT_DEFINITIONS",
    "VARIABLES",
    "FmuVariable",
    "interface_for",
    "me_dependencies",
    "me_variables",
    "start_values",
]

#: modelIdentifier of the exported FMU (the binary is ``binaries/<platform>/SolenoidFmu.so``).
MODEL_IDENTIFIER = "SolenoidFmu"

#: FMI interfaces an export can declare: co-simulation only, or co-simulation and model exchange.
INTERFACES = ("cs", "cs+me")


@dataclass(frozen=True)
class FmuVariable:
    """One FMU variable: name (API), FMI type, causality, variability, unit, description."""

    name: str
    type: str
    causality: str
    variability: str
    unit: str | None
    description: str


#: The FMU interface, in value-reference order (value reference = index).
VARIABLES = (
    FmuVariable("U_V", "Real", "input", "continuous", "V",
                "coil voltage U [V]; the drive input in voltage mode (held over each step)"),
    FmuVariable("i_A", "Real", "input", "continuous", "A",
                "coil current i [A]; the drive input in current mode (held over each step)"),
    FmuVariable("x_m", "Real", "input", "continuous", "m",
                "armature working gap x [m]; clamped to the map's range (logged once per excursion)"),
    FmuVariable("i_out_A", "Real", "output", "continuous", "A",
                "coil current i = i_f(Psi, x) + i_eddy [A] (paper eq. 2); the input in current mode"),
    FmuVariable("U_out_V", "Real", "output", "continuous", "V",
                "coil voltage U = R i + dPsi/dt [V] (paper eq. 1); the input in voltage mode, "
                "the mean over the last step in current mode"),
    FmuVariable("F_N", "Real", "output", "continuous", "N",
                "magnetic force F(Psi, x) [N] (paper eq. 3), positive when it closes the gap"),
    FmuVariable("psi_Wb", "Real", "output", "continuous", "Wb",
                "coil flux linkage Psi [Wb], the model state"),
    FmuVariable("dpsi_dt_V", "Real", "output", "continuous", "V",
                "induced voltage dPsi/dt [V]; the mean over the last step in current mode"),
    FmuVariable("i_eddy_A", "Real", "output", "continuous", "A",
                "eddy current i_eddy = G_eddy dPsi/dt [A] (paper eq. 2)"),
    FmuVariable("out_of_map", "Boolean", "output", "discrete", None,
                "true while x or Psi lies outside the characteristic maps and is clamped"),
    FmuVariable("R_ohm", "Real", "parameter", "tunable", "Ohm",
                "coil resistance at the start, before self-heating [ohm], > 0 (default: at 20 degC)"),
    FmuVariable("G_eddy_S", "Real", "parameter", "tunable", "S",
                "eddy-current conductance G_eddy [S] (the paper's L_eddy), >= 0"),
    FmuVariable("drive_mode", "Integer", "parameter", "fixed", None,
                "drive mode: 1 = voltage-driven (input U_V), 2 = current-driven (input i_A)"),
    FmuVariable("Psi0_Wb", "Real", "parameter", "fixed", "Wb",
                "initial flux linkage Psi(t0) [Wb] (ignored in current mode with G_eddy = 0)"),
    FmuVariable("h_sub_max_s", "Real", "parameter", "fixed", "s",
                "largest internal integration sub-step [s] (ROS2, L-stable)"),
)

#: Variables an FMU gains when its maps carry effect sub-models (maps.json ``effects``),
#: appended after :data:`VARIABLES` (the base value references do not move).
EFFECT_VARIABLES = (
    FmuVariable("i_hyst_A", "Real", "output", "continuous", "A",
                "hysteresis current of the play operator [A] (part of i_out_A)"),
    FmuVariable("T_rise_K", "Real", "output", "continuous", "K",
                "coil temperature rise since initialization [K] (heating sub-model)"),
    FmuVariable("hysteresis_on", "Boolean", "parameter", "fixed", None,
                "switch: magnetic hysteresis (play operator on Psi adding a current)"),
    FmuVariable("hyst_gain", "Real", "parameter", "tunable", "1", "factor on the hysteresis current [-]"),
    FmuVariable("eddy_ladder_on", "Boolean", "parameter", "fixed", None,
                "switch: frequency-dependent eddy currents (R-L sections beside G_eddy)"),
    FmuVariable("heating_on", "Boolean", "parameter", "fixed", None,
                "switch: coil heating, R(T) = R (1 + alpha T) with a first-order thermal model"),
    FmuVariable("C_th_J_per_K", "Real", "parameter", "fixed", "J/K", "heat capacity of the coil [J/K], > 0"),
    FmuVariable("R_th_K_per_W", "Real", "parameter", "fixed", "K/W",
                "thermal resistance coil to ambient [K/W], > 0"),
    FmuVariable("alpha_per_K", "Real", "parameter", "fixed", "1/K",
                "temperature coefficient of the coil resistance [1/K]"),
    FmuVariable("friction_on", "Boolean", "parameter", "fixed", None,
                "switch: friction in the force output (Dahl model in x)"),
    FmuVariable("friction_N", "Real", "parameter", "tunable", "N", "sliding friction force [N], >= 0"),
    FmuVariable("presliding_m", "Real", "parameter", "fixed", "m",
                "presliding displacement of the friction model [m], > 0"),
    # last: the value references of the variables above stay those of FMUs exported before it
    FmuVariable("T_start_excess_K", "Real", "parameter", "fixed", "K",
                "coil temperature above ambient at initialization [K] (heating: the coil cools from it through "
                "R_th; R_ohm is the resistance at that temperature), -50 .. 160"),
)

#: (min, max) of the Integer ``drive_mode``: an Integer, not an Enumeration, because libcosim (OSP)
#: and Ecos drop FMI 2.0 Enumeration variables (seen with simulators' importers).
DRIVE_MODE_RANGE = (DRIVE_VOLTAGE, DRIVE_CURRENT)

#: SI unit definitions (exponents of the SI base units) used in modelDescription.xml.
UNIT_DEFINITIONS = {
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
    "A": {"A": 1},
    "m": {"m": 1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "Wb": {"kg": 1, "m": 2, "s": -2, "A": -1},
    "Ohm": {"kg": 1, "m": 2, "s": -3, "A": -2},
    "S": {"kg": -1, "m": -2, "s": 3, "A": 2},
    "s": {"s": 1},
    "K": {"K": 1},
    "1/K": {"K": -1},
    "J/K": {"kg": 1, "m": 2, "s": -2, "K": -1},
    "K/W": {"kg": -1, "m": -2, "s": 3, "K": 1},
    "1": {},
}
#: Units only the model-exchange locals use (added when such a local exists).
ME_UNIT_DEFINITIONS = {"A/s": {"A": 1, "s": -1}, "K/s": {"K": 1, "s": -1}}
#: Display units offered to importers: (name, factor) with display = factor * value.
DISPLAY_UNITS = {"m": (("mm", 1000.0),), "Wb": (("mWb", 1000.0),)}

#: Default experiment written into the FMU.
#: The tolerance is for importers that run the model exchange interface with their own solver (the
#: co-simulation steps do not use it): 1e-6 relative keeps their flux error far below the maps' own.
DEFAULT_EXPERIMENT = {"startTime": "0.0", "stopTime": "0.5", "tolerance": "1e-06", "stepSize": "0.0001"}

#: Log categories of the native FMU (name, description); pythonfmu declares its own.
LOG_CATEGORIES = (
    ("logStatusWarning", "Log messages with fmi2Warning status (map excursions)."),
    ("logStatusDiscard", "Log messages with fmi2Discard status."),
    ("logStatusError", "Log messages with fmi2Error status (invalid inputs or parameters)."),
    ("logStatusFatal", "Log messages with fmi2Fatal status."),
    ("logAll", "Log all messages."),
)

#: Model-exchange locals after the 15 variables of :data:`VARIABLES`: (name, unit, description);
#: value references 15 and 16.
ME_VARIABLES = (
    ("psi_state_Wb", "Wb", "continuous state of model exchange: flux linkage Psi [Wb] (frozen in current mode "
                           "with G_eddy_S = 0, where Psi follows the input algebraically)"),
    ("der(psi_state_Wb)", "V", "dPsi/dt [V] of the model-exchange state (paper eqs. 1-2 solved for dPsi/dt)"),
)


def interface_for(tables: MapTables) -> tuple:
    """The FMU variables for these maps: :data:`VARIABLES`, plus :data:`EFFECT_VARIABLES` when
    maps.json's ``effects`` section has an effect that is not null (:attr:`EffectsRecord.active`)."""
    return VARIABLES + (EFFECT_VARIABLES if tables.effects.active else ())


def start_values(tables: MapTables, params: dict) -> dict:
    """Start value of every input and parameter of :func:`interface_for` (``params``: the model's
    parameters for these maps, ``SolenoidModel(tables).params``)."""
    starts = {"U_V": 0.0, "i_A": 0.0, "x_m": 0.5 * (tables.x_min_m + tables.x_max_m)}
    starts.update({v.name: params[v.name] for v in interface_for(tables) if v.causality == "parameter"})
    return starts


def me_variables(tables: MapTables) -> tuple:
    """Model-exchange locals of the native FMU for these maps: (name, unit, description) of the
    continuous states, then of their derivatives (value references from ``len(interface_for(tables))``).

    Without effects: :data:`ME_VARIABLES`. With effects, after ``psi_state_Wb``: one
    ``ladder_state_<k>_A`` per eddy-ladder section and ``T_state_K`` when the maps carry heating.
    """
    fx = effects_data(tables)
    states = [ME_VARIABLES[0]]
    for k in range(len((fx.get("eddy_ladder") or {}).get("G_S", ()))):
        states.append((f"ladder_state_{k}_A", "A", f"continuous state of model exchange: current of eddy-ladder "
                                                   f"section {k} [A] (tau_k di_k/dt = G_k dPsi/dt - i_k)"))
    if "heating" in fx:
        states.append(("T_state_K", "K", "continuous state of model exchange: coil temperature rise [K] "
                                         "(C_th dT/dt = R(T) i^2 - T / R_th)"))
    ders = [ME_VARIABLES[1]] + [(f"der({n})", u + "/s", f"time derivative of {n}") for n, u, _ in states[1:]]
    return tuple(states) + tuple(ders)


def me_dependencies(tables: MapTables) -> tuple[dict, tuple]:
    """Model-exchange dependencies (1-based variable indices, as in ModelStructure).

    Returns ``(outputs, derivatives)``: output name -> indices of the inputs and continuous states it
    depends on (the union over both drive modes; with effects every output may depend on every
    state, conservatively), and the indices every derivative depends on.
    """
    variables = interface_for(tables)
    index = {v.name: k + 1 for k, v in enumerate(variables)}
    n0, nx = len(variables), len(me_variables(tables)) // 2
    i_states = tuple(range(n0 + 1, n0 + 1 + nx))
    u, i, x = index["U_V"], index["i_A"], index["x_m"]
    st = i_states[:1] if nx == 1 else i_states
    outputs = {"i_out_A": (u, i, x, *st), "U_out_V": (u, i, x, *st), "F_N": (i, x, *st),
               "psi_Wb": (i, x, *st), "dpsi_dt_V": (u, i, x, *st), "i_eddy_A": (u, i, x, *st),
               "out_of_map": (i, x, *st), "i_hyst_A": (i, x, *st), "T_rise_K": (u, i, x, *st)}
    return outputs, (u, i, x, *st)
