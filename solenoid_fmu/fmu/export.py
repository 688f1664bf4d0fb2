"""FMI 2.0 co-simulation FMU of the real-time solenoid model: export and recording playback.

``build_fmu(maps_dir, dest_fmu)`` packs :mod:`solenoid_fmu.model` (numpy only), a generated
pythonfmu slave and the maps (``maps.npz`` + ``maps.json``, no pickle) into an FMU, then rewrites
its ``modelDescription.xml`` with lxml into what a strict importer expects: SI unit definitions
and a unit on every real variable, descriptions, start values, explicit variabilities, the drive
mode as an enumeration, ``ModelStructure`` with ``Outputs`` and ``InitialUnknowns`` and their
dependencies, a ``DefaultExperiment``, generation tool and date, and the maps' provenance (in the
model description and as a vendor annotation). Every FMU built is checked with
``fmpy.validation.validate_fmu`` and refused if it reports anything.

The FMU interface (names are API; value references are the positions in :data:`VARIABLES`):

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
``R_ohm``               parameter  tunable      coil resistance at 20 degC [ohm]
``G_eddy_S``            parameter  tunable      eddy-current conductance [S]
``drive_mode``          parameter  fixed        Integer 1..2: 1 voltage-driven, 2 current-driven
``Psi0_Wb``             parameter  fixed        initial flux linkage [Wb]
``h_sub_max_s``         parameter  fixed        largest internal sub-step [s]
======================  =========  ===========  ======================================================

Semantics (see :mod:`solenoid_fmu.model`): inputs are held over a communication step; outputs are
computed at the end of each step from the state and the inputs of that step (no direct
feedthrough, ``dependencies=""``). Out-of-map inputs are clamped and logged once per excursion
through the FMI logger (status warning).

Errors: the pythonfmu 0.7 C wrapper turns any Python exception into ``fmi2Fatal`` and drops its
references to the Python instance, after which freeing the instance can crash the importing
process; it offers no route to ``fmi2Error``. The slave therefore never raises: a NaN or
infinite input, ``R_ohm <= 0`` or ``G_eddy_S < 0`` is logged with status ``fmi2Error`` naming the
value, and ``fmi2DoStep`` returns ``fmi2Discard`` with the state unchanged (the instance stays
usable once the input is fixed). A native (C) backend can return ``fmi2Error`` directly.

Backends (:data:`BACKENDS`): ``python`` packs the model for pythonfmu (above; co-simulation,
needs Python with numpy where it runs); ``c`` generates and compiles native C with the same
variables plus model exchange (:mod:`solenoid_fmu.fmu_c`).

``simulate_recording(fmu, recording)`` drives an FMU with fmpy from a recording's measured inputs
and returns a recording in the same format (CLI ``solenoid-fmu simulate``).
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import html
import json
import math
import os
import pprint
import shutil
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import FmuBuildError, FmuInputError, MapsError
from ..realtime import model as _model

__all__ = [
    "BACKENDS",
    "MODEL_IDENTIFIER",
    "VARIABLES",
    "FmuVariable",
    "SimulationResult",
    "add_cli",
    "build_fmu",
    "finalize_model_description",
    "fmi2_callbacks",
    "load_maps_tables",
    "release_fmi2_callbacks",
    "simulate_model",
    "simulate_recording",
]

#: modelIdentifier of the exported FMU (the binary is ``binaries/<platform>/SolenoidFmu.so``).
MODEL_IDENTIFIER = "SolenoidFmu"


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
    FmuVariable("R_ohm", "Real", "parameter", "tunable", "Ohm", "coil resistance R at 20 degC [ohm], > 0"),
    FmuVariable("G_eddy_S", "Real", "parameter", "tunable", "S",
                "eddy-current conductance G_eddy [S] (the paper's L_eddy), >= 0"),
    FmuVariable("drive_mode", "Integer", "parameter", "fixed", None,
                "drive mode: 1 = voltage-driven (input U_V), 2 = current-driven (input i_A)"),
    FmuVariable("Psi0_Wb", "Real", "parameter", "fixed", "Wb",
                "initial flux linkage Psi(t0) [Wb] (ignored in current mode with G_eddy = 0)"),
    FmuVariable("h_sub_max_s", "Real", "parameter", "fixed", "s",
                "largest internal integration sub-step [s] (ROS2, L-stable)"),
)
_VR = {v.name: k for k, v in enumerate(VARIABLES)}

#: Variables an FMU gains when its maps carry effect sub-models (maps.json ``effects``; issue 7),
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
)


def interface_for(tables: _model.MapTables) -> tuple:
    """The FMU variables for these maps: :data:`VARIABLES`, plus :data:`EFFECT_VARIABLES` when
    maps.json carries an ``effects`` section."""
    fx = tables.meta.get("effects") or {}
    return VARIABLES + (EFFECT_VARIABLES if any(v for v in fx.values()) else ())

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
#: Display units offered to importers: (name, factor) with display = factor * value.
DISPLAY_UNITS = {"m": (("mm", 1000.0),), "Wb": (("mWb", 1000.0),)}

#: Default experiment written into the FMU.
#: The tolerance is for importers that run the model exchange interface with their own solver (the
#: co-simulation steps do not use it): 1e-6 relative keeps their flux error far below the maps' own.
DEFAULT_EXPERIMENT = {"startTime": "0.0", "stopTime": "0.5", "tolerance": "1e-06", "stepSize": "0.0001"}


# ----------------------------------------------------------------------------------------------
# The pythonfmu slave (generated into the FMU next to the model module and the maps)
# ----------------------------------------------------------------------------------------------

_SLAVE_TEMPLATE = '''"""pythonfmu slave of solenoid-fmu (generated by solenoid_fmu.fmu; do not edit).

Wraps the numpy-only real-time model @MODEL_MODULE@ (paper eqs. 1-3). It raises into the
pythonfmu C wrapper (which turns any exception into fmi2Fatal) only in setFMUstate, for a state
that is not one of this FMU's (bad bytes or JSON): the wrapper has no other way to refuse, and
OK would hide it; the previous state is kept and the log names the reason. Invalid inputs are
logged with status error and fmi2DoStep returns fmi2Discard.
"""
import json
import os

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

import @MODEL_MODULE@ as _model

_VARIABLES = @VARIABLES@
_FX_VARIABLES = @FX_VARIABLES@
_PARAMS = ("R_ohm", "G_eddy_S", "drive_mode", "Psi0_Wb", "h_sub_max_s")
_TUNABLE = ("R_ohm", "G_eddy_S")
_FX_TUNABLE = ("hyst_gain", "friction_N")
_STATE_LAYOUT = 1
_TABLES = {}


def _tables_for(resources):
    """Maps of this FMU, read once per resources directory and process (read-only, shared)."""
    npz = os.path.join(resources, "maps.npz")
    st = os.stat(npz)
    key = (os.path.abspath(resources), st.st_mtime_ns, st.st_size)
    tab = _TABLES.get(key)
    if tab is None:
        tab = _TABLES[key] = _model.load_tables(resources)
    return tab


class @CLASS@(Fmi2Slave):
    """Valve solenoid, real-time lumped model from characteristic maps."""

    author = "solenoid-fmu"
    description = "Valve solenoid real-time lumped model (paper eqs. 1-3)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        tab = _tables_for(self.resources)
        model = self._model = _model.SolenoidModel(tab)
        p = model.params
        self.U_V = 0.0
        self.i_A = 0.0
        self.x_m = 0.5 * (tab.x_min_m + tab.x_max_m)
        self.R_ohm = p["R_ohm"]
        self.G_eddy_S = p["G_eddy_S"]
        self.drive_mode = p["drive_mode"]
        self.Psi0_Wb = p["Psi0_Wb"]
        self.h_sub_max_s = p["h_sub_max_s"]
        self._fx = bool(model.state_names()[len(_model.STATE_NAMES):])
        variables = _VARIABLES + (_FX_VARIABLES if self._fx else ())
        self._params = _PARAMS + tuple(v[0] for v in variables[len(_VARIABLES):] if v[2] == "parameter")
        self._tunable = _TUNABLE + (_FX_TUNABLE if self._fx else ())
        for name in self._params[len(_PARAMS):]:
            setattr(self, name, p[name])
        self._t0 = 0.0
        self._dirty = True  # parameters to (re)apply before the next step
        self._ready = False  # initialized successfully
        self._voltage = True
        getters = {
            "i_out_A": lambda: model.i_A, "U_out_V": lambda: model.U_V, "F_N": lambda: model.F_N,
            "psi_Wb": lambda: model.psi_Wb, "dpsi_dt_V": lambda: model.dpsi_dt_V,
            "i_eddy_A": lambda: model.i_eddy_A, "out_of_map": lambda: model.out_of_map,
            "i_hyst_A": lambda: model.i_hyst_A, "T_rise_K": lambda: model.T_rise_K,
        }
        kinds = {"Real": Real, "Integer": Integer, "Enumeration": Integer, "Boolean": Boolean}
        for name, typ, causality, variability, description in variables:
            kw = dict(causality=getattr(Fmi2Causality, causality),
                      variability=getattr(Fmi2Variability, variability), description=description)
            if causality == "output":
                kw["getter"] = getters[name]
            elif causality == "parameter":
                kw["setter"] = (lambda v, n=name: self._set_param(n, v))
            self.register_variable(kinds[typ](name, **kw))

    def _set_param(self, name, value):
        setattr(self, name, value)
        self._dirty = True

    def _apply_params(self, all_params):
        self._dirty = True
        names = self._params if all_params else self._tunable
        self._model.set_params(**{n: getattr(self, n) for n in names})
        self._voltage = self._model.params["drive_mode"] == _model.DRIVE_VOLTAGE
        self._dirty = False

    def _flush_events(self, t):
        for _kind, severity, message in self._model.events:
            self.log(f"t = {t:.9g} s: {message}", getattr(Fmi2Status, severity))
        self._model.events.clear()

    def _initialize(self):
        self._ready = False
        self._apply_params(True)
        u = self.U_V if self._voltage else self.i_A
        self._model.initialize(u, self.x_m, self._t0)
        self._ready = True
        self._flush_events(self._t0)

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        try:
            self._t0 = float(start_time)
        except Exception:  # noqa: BLE001 - never raise into the C wrapper
            self._t0 = 0.0

    def exit_initialization_mode(self):
        try:
            self._initialize()
        except Exception as exc:  # noqa: BLE001 - never raise into the C wrapper
            self.log(f"initialization: {exc}", Fmi2Status.error)

    def do_step(self, current_time, step_size):
        model = self._model
        try:
            if self._dirty:
                if self._ready:
                    self._apply_params(False)
                else:
                    self._initialize()
            model.step(step_size, self.U_V if self._voltage else self.i_A, self.x_m, current_time)
        except _model.ModelError as exc:
            self.log(f"doStep at t = {current_time!r} s: {exc}", Fmi2Status.error)
            return False
        except Exception as exc:  # noqa: BLE001 - never raise into the C wrapper
            self.log(f"doStep at t = {current_time!r} s: internal error {type(exc).__name__}: {exc}",
                     Fmi2Status.error)
            return False
        if model.events:
            self._flush_events(current_time + step_size)
        return True

    def _get_fmu_state(self):
        return {
            "layout": _STATE_LAYOUT,
            "state_names": list(self._model.state_names()),
            "model_state": self._model.get_state(),
            "model_params": dict(self._model.params),
            "inputs": [self.U_V, self.i_A, self.x_m],
            "params": [getattr(self, n) for n in self._params],
            "t0": self._t0,
            "dirty": self._dirty,
            "ready": self._ready,
        }

    @staticmethod
    def _fmu_state_from_bytes(state):
        # never raise here: the C wrapper turns that into fmi2Fatal; _set_fmu_state refuses the marker
        try:
            out = json.loads(bytes(state).decode("utf-8"))
        except Exception as exc:  # noqa: BLE001
            return {"__invalid__": f"{type(exc).__name__}: {exc}"}
        return out if isinstance(out, dict) else {"__invalid__": "not a JSON object"}

    def _set_fmu_state(self, state):
        keep = self._get_fmu_state()
        try:
            self._restore(state)
        except Exception as exc:  # noqa: BLE001
            self._restore(keep)
            self.log(f"setFMUstate: state not restored, the previous one kept: {type(exc).__name__}: {exc}",
                     Fmi2Status.error)
            raise RuntimeError("setFMUstate refused") from None

    def _restore(self, state):
        if not isinstance(state, dict) or "__invalid__" in state:
            raise _model.ModelInputError(f"not a serialized state of this FMU "
                                         f"({state.get('__invalid__') if isinstance(state, dict) else state!r})")
        if (state.get("layout") != _STATE_LAYOUT
                or list(state["state_names"]) != list(self._model.state_names())):
            raise _model.ModelInputError("FMU state from an incompatible model version")
        self._model.set_params(**state["model_params"])
        self._model.set_state(state["model_state"])
        self.U_V, self.i_A, self.x_m = (float(v) for v in state["inputs"])
        if len(state["params"]) != len(self._params):
            raise _model.ModelInputError("FMU state with a different parameter set")
        for name, value in zip(self._params, state["params"]):
            setattr(self, name, value)
        self._t0 = float(state["t0"])
        self._dirty = bool(state["dirty"])
        self._ready = bool(state["ready"])
        self._voltage = self._model.params["drive_mode"] == _model.DRIVE_VOLTAGE
'''


def _source_hash() -> str:
    """Short hash of the model and slave sources: names the modules shipped in the FMU."""
    h = hashlib.sha256(Path(_model.__file__).read_bytes())
    h.update(_SLAVE_TEMPLATE.encode())
    return h.hexdigest()[:12]


def _slave_source(model_module: str) -> str:
    def rows(spec):
        return tuple((v.name, v.type, v.causality, v.variability, v.description) for v in spec)

    return (_SLAVE_TEMPLATE.replace("@MODEL_MODULE@", model_module).replace("@CLASS@", MODEL_IDENTIFIER)
            .replace("@VARIABLES@", pprint.pformat(rows(VARIABLES), width=100))
            .replace("@FX_VARIABLES@", pprint.pformat(rows(EFFECT_VARIABLES), width=100)))


# ----------------------------------------------------------------------------------------------
# Building
# ----------------------------------------------------------------------------------------------

def load_maps_tables(maps_dir) -> _model.MapTables:
    """Read a maps directory for export; model-level problems become :class:`MapsError`.

    Parameters
    ----------
    maps_dir : str or path-like
        Directory with ``maps.npz`` and ``maps.json``.

    Returns
    -------
    solenoid_fmu.model.MapTables
    """
    maps_dir = Path(maps_dir)
    if not maps_dir.is_dir():
        raise MapsError(f"{maps_dir}: maps directory not found")
    from ..maps import load_maps

    load_maps(maps_dir)  # one rule for every reader: the checks of `solenoid-fmu maps --from` (schema, units,
    # name, arrays, npz and json written together) before the model's own
    try:
        return _model.load_tables(maps_dir)
    except _model.ModelMapsError as exc:
        raise MapsError(str(exc)) from None


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _build_python(maps_dir: Path, dest: Path, tables: _model.MapTables) -> str:
    """Write the pythonfmu FMU (modelDescription not yet final) to ``dest``; returns generationTool."""
    import pythonfmu
    from pythonfmu import FmuBuilder

    tag = _source_hash()
    model_module = f"solenoid_model_{tag}"
    slave_module = f"solenoid_slave_{tag}"
    with tempfile.TemporaryDirectory(prefix="solenoid_fmu_build_") as tmp:
        tmp = Path(tmp)
        src = tmp / "src"
        src.mkdir()
        script = src / f"{slave_module}.py"
        script.write_text(_slave_source(model_module), encoding="utf-8")
        shutil.copyfile(_model.__file__, src / f"{model_module}.py")
        project = [src / f"{model_module}.py"]
        for name in ("maps.npz", "maps.json"):
            shutil.copyfile(maps_dir / name, src / name)
            project.append(src / name)
        out = tmp / "out"
        out.mkdir()
        path_before = list(sys.path)
        try:
            built = FmuBuilder.build_FMU(script, dest=out / f"{MODEL_IDENTIFIER}.fmu", project_files=project,
                                         needsExecutionTool="false", canGetAndSetFMUstate="true",
                                         canSerializeFMUstate="true",
                                         canHandleVariableCommunicationStepSize="true",
                                         canInterpolateInputs="false",
                                         canBeInstantiatedOnlyOncePerProcess="false")
        except Exception as exc:  # pythonfmu reports build problems with bare exceptions
            raise FmuBuildError(f"pythonfmu could not build the FMU from {maps_dir}: "
                                f"{type(exc).__name__}: {exc}") from exc
        finally:
            sys.path[:] = path_before
            for mod in (slave_module, model_module):
                sys.modules.pop(mod, None)
        shutil.copyfile(built, dest)
    return f"solenoid-fmu {__version__} (python backend: pythonfmu {pythonfmu.__version__})"


def _build_c(maps_dir: Path, dest: Path, tables: _model.MapTables) -> str:
    """Write the native FMU (generated C, compiled here; see :mod:`solenoid_fmu.fmu_c`) to ``dest``."""
    from . import native as fmu_c

    return fmu_c.build_c_fmu(maps_dir, dest, tables)


def _finish_c(fmu_path: Path, tables: _model.MapTables) -> None:
    from . import native as fmu_c

    fmu_c.finish_model_description(fmu_path, tables)


#: Export backends: name -> function(maps_dir, dest_fmu, tables) -> generationTool string.
#: A backend writes an FMU with the interface of :data:`VARIABLES`; :func:`build_fmu` then
#: rewrites its modelDescription.xml with :func:`finalize_model_description`, applies the
#: backend's entry in :data:`_FINISHERS` (if any) and validates it. ``python``: pythonfmu
#: (co-simulation; needs Python with numpy where it runs); ``c``: native C, co-simulation and
#: model exchange (:mod:`solenoid_fmu.fmu_c`).
BACKENDS = {"python": _build_python, "c": _build_c}
#: Backend name -> function(fmu_path, tables) run after :func:`finalize_model_description`.
_FINISHERS = {"c": _finish_c}


def build_fmu(maps_dir, dest_fmu, *, backend: str = "python", model_name: str | None = None,
              validate: bool = True) -> Path:
    """Export the real-time model with the given maps as an FMI 2.0 co-simulation FMU.

    Parameters
    ----------
    maps_dir : str or path-like
        Maps directory (``maps.npz`` + ``maps.json``, shared format).
    dest_fmu : str or path-like
        FMU file to write (parent directories are created; an existing file is replaced).
    backend : str
        Key of :data:`BACKENDS`: ``"python"`` (pythonfmu co-simulation; the FMU needs Python with
        numpy) or ``"c"`` (native binary from generated C, co-simulation and model exchange).
    model_name : str, optional
        ``modelName`` in the model description; default ``"solenoid <maps name>"``.
    validate : bool
        Check the result with ``fmpy.validation.validate_fmu``; any problem is an error.

    Returns
    -------
    pathlib.Path
        The FMU written.

    Raises
    ------
    MapsError
        The maps directory is missing or unusable.
    FmuBuildError
        Unknown backend, exporter failure, or validation problems (all listed).
    """
    maps_dir = Path(maps_dir)
    dest = Path(dest_fmu)
    if backend not in BACKENDS:
        raise FmuBuildError(f"unknown FMU backend {backend!r}; available: {', '.join(BACKENDS)}")
    if dest.suffix.lower() != ".fmu":
        raise FmuBuildError(f"{dest}: the output file must end in .fmu")
    tables = load_maps_tables(maps_dir)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{dest.stem}.", suffix=".fmu", dir=dest.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        tool = BACKENDS[backend](maps_dir, tmp, tables)
        finalize_model_description(tmp, tables=tables, maps_dir=maps_dir, generation_tool=tool,
                                    model_name=model_name)
        if backend in _FINISHERS:
            _FINISHERS[backend](tmp, tables)
        if validate:
            from fmpy.validation import validate_fmu

            problems = validate_fmu(str(tmp))
            if problems:
                raise FmuBuildError(f"{dest}: fmpy validation found {len(problems)} problem(s):\n"
                                    + "\n".join(f"  - {p}" for p in problems))
        from ..fileio import umask

        os.chmod(tmp, 0o666 & ~umask())  # the mode open() would give, not mkstemp's private 0600
        os.replace(tmp, dest)
    finally:
        if tmp.exists():
            tmp.unlink()
    return dest


def _fmt(value: float) -> str:
    return repr(float(value))


def finalize_model_description(fmu_path, *, tables: _model.MapTables, maps_dir, generation_tool: str,
                               model_name: str | None = None) -> None:
    """Rewrite ``modelDescription.xml`` inside ``fmu_path`` (in place) for strict importers.

    Parameters
    ----------
    fmu_path : path-like
        FMU whose variables follow :data:`VARIABLES` (any backend).
    tables : solenoid_fmu.model.MapTables
        The maps packed into the FMU (their ranges and sidecar go into the description).
    maps_dir : path-like
        The maps directory (file hashes for the provenance).
    generation_tool : str
        ``generationTool`` attribute.
    model_name : str, optional
        ``modelName``; default ``"solenoid <maps name>"``.

    Notes
    -----
    Adds or replaces: root attributes (description with provenance, generation tool and UTC
    date, version), CoSimulation capability flags, ``UnitDefinitions`` (SI base-unit exponents),
    ``DefaultExperiment`` (with a tolerance),
    ``VendorAnnotations`` (maps provenance as JSON), a unit, description, variability and start
    value on every variable, and ``ModelStructure`` (Outputs without direct feedthrough;
    InitialUnknowns depending on the inputs and parameters). Also adds ``documentation/index.html``.
    """
    from lxml import etree

    fmu_path = Path(fmu_path)
    maps_dir = Path(maps_dir)
    with zipfile.ZipFile(fmu_path) as zf:
        entries = [(info, zf.read(info.filename)) for info in zf.infolist()]
    md_bytes = next((data for info, data in entries if info.filename == "modelDescription.xml"), None)
    if md_bytes is None:
        raise FmuBuildError(f"{fmu_path}: no modelDescription.xml in the FMU")
    root = etree.fromstring(md_bytes, etree.XMLParser(remove_blank_text=True))
    meta = tables.meta
    maps_name = str(meta.get("name") or maps_dir.name)
    prov = meta.get("provenance") or {}
    geo = prov.get("geometry") or {}
    sha_npz = _sha256(maps_dir / "maps.npz")
    sha_json = _sha256(maps_dir / "maps.json")
    now = datetime.datetime.now(datetime.UTC).replace(microsecond=0)

    # -- root attributes --------------------------------------------------------------------
    root.set("modelName", model_name or f"solenoid {maps_name}")
    root.set("description",
             f"Valve solenoid real-time lumped model (paper eqs. 1-3: U = R i + dPsi/dt, "
             f"i = i_f(Psi, x) + G_eddy dPsi/dt, F = F(Psi, x)) from the characteristic maps "
             f"'{maps_name}' (maps.npz sha256 {sha_npz}; geometry {geo.get('name', '?')} "
             f"sha256 {geo.get('sha256', '?')}; maps created {prov.get('created_utc', '?')}, "
             f"code {prov.get('code_version', '?')}). Gap range {tables.x_min_m:.6g} .. "
             f"{tables.x_max_m:.6g} m, |Psi| <= {tables.psi_max_Wb:.6g} Wb.")
    root.set("generationTool", generation_tool)
    root.set("generationDateAndTime", now.strftime("%Y-%m-%dT%H:%M:%SZ"))
    root.set("version", __version__)
    root.set("author", "solenoid-fmu")
    root.set("variableNamingConvention", "structured")

    children = {child.tag: child for child in root}
    cs = children.get("CoSimulation")
    if cs is None:
        raise FmuBuildError(f"{fmu_path}: modelDescription.xml has no CoSimulation element")
    for key, value in (("needsExecutionTool", "false"), ("canHandleVariableCommunicationStepSize", "true"),
                       ("canInterpolateInputs", "false"), ("canBeInstantiatedOnlyOncePerProcess", "false"),
                       ("canGetAndSetFMUstate", "true"), ("canSerializeFMUstate", "true"),
                       ("providesDirectionalDerivative", "false")):
        cs.set(key, value)

    units = etree.Element("UnitDefinitions")
    for name, exps in UNIT_DEFINITIONS.items():
        u = etree.SubElement(units, "Unit", name=name)
        etree.SubElement(u, "BaseUnit", **{k: str(v) for k, v in exps.items()})
        for dname, factor in DISPLAY_UNITS.get(name, ()):
            etree.SubElement(u, "DisplayUnit", name=dname, factor=_fmt(factor))

    # drive_mode is an Integer with min/max, not an Enumeration: libcosim (OSP) and Ecos drop FMI 2.0
    # Enumeration variables, which made the current-driven mode unreachable there (issue 14)
    types = None

    log_categories = children.get("LogCategories")
    experiment = etree.Element("DefaultExperiment", **DEFAULT_EXPERIMENT)

    vendor = etree.Element("VendorAnnotations")
    tool = etree.SubElement(vendor, "Tool", name="solenoid-fmu")
    maps_el = etree.SubElement(tool, "Maps", name=maps_name, npz_sha256=sha_npz, json_sha256=sha_json,
                               psi_max_Wb=_fmt(tables.psi_max_Wb), x_min_m=_fmt(tables.x_min_m),
                               x_max_m=_fmt(tables.x_max_m), n_psi=str(tables.n_psi), n_x=str(tables.n_x))
    sidecar = {k: meta.get(k) for k in ("name", "force_method", "coil", "eddy", "effects", "provenance")
               if k in meta}
    maps_el.text = json.dumps(sidecar, sort_keys=True)

    # -- variables --------------------------------------------------------------------------
    variables = children.get("ModelVariables")
    scalars = list(variables) if variables is not None else []
    by_name = {sv.get("name"): sv for sv in scalars}
    interface = interface_for(tables)
    if [sv.get("name") for sv in scalars] != [v.name for v in interface]:
        raise FmuBuildError(f"{fmu_path}: model variables {[sv.get('name') for sv in scalars]} do not "
                            f"match the interface {[v.name for v in interface]}")
    for k, spec in enumerate(interface):
        sv = by_name[spec.name]
        sv.set("valueReference", str(k))
        sv.set("description", spec.description)
        sv.set("causality", spec.causality)
        sv.set("variability", spec.variability)
        if spec.causality == "parameter":
            sv.set("initial", "exact")
        elif spec.causality == "output":
            sv.set("initial", "calculated")
        elif "initial" in sv.attrib:
            del sv.attrib["initial"]
        old = sv[0] if len(sv) else None
        start = old.get("start") if old is not None else None
        for child in list(sv):
            sv.remove(child)
        el = etree.SubElement(sv, spec.type)
        if spec.name == "drive_mode":
            el.set("min", str(_model.DRIVE_VOLTAGE))
            el.set("max", str(_model.DRIVE_CURRENT))
        if spec.unit is not None:
            el.set("unit", spec.unit)
            if spec.unit in DISPLAY_UNITS:
                el.set("displayUnit", DISPLAY_UNITS[spec.unit][0][0])
        if spec.causality in ("input", "parameter"):
            if start is None:
                raise FmuBuildError(f"{fmu_path}: variable {spec.name} has no start value")
            if spec.type == "Real":
                start = _fmt(float(start))
            elif spec.type == "Boolean":
                start = "true" if start.lower() in ("true", "1") else "false"
            else:
                start = str(int(start))
            el.set("start", start)

    # -- model structure --------------------------------------------------------------------
    index = {v.name: k + 1 for k, v in enumerate(interface)}
    knowns = " ".join(str(index[v.name]) for v in interface if v.causality in ("input", "parameter"))
    structure = etree.Element("ModelStructure")
    outputs = etree.SubElement(structure, "Outputs")
    initial = etree.SubElement(structure, "InitialUnknowns")
    for v in interface:
        if v.causality == "output":
            etree.SubElement(outputs, "Unknown", index=str(index[v.name]), dependencies="")
            etree.SubElement(initial, "Unknown", index=str(index[v.name]), dependencies=knowns)

    # -- reassemble in schema order ---------------------------------------------------------
    for child in list(root):
        root.remove(child)
    for el in (cs, units, types, log_categories, experiment, vendor, variables, structure):
        if el is not None:
            root.append(el)
    xml = etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)

    doc = _documentation_html(root.get("modelName"), root.get("description"), tables).encode("utf-8")
    fd, tmp_name = tempfile.mkstemp(prefix=".md.", suffix=".fmu", dir=fmu_path.parent)
    os.close(fd)
    try:
        with zipfile.ZipFile(tmp_name, "w", zipfile.ZIP_DEFLATED) as out:
            for info, data in entries:
                if info.filename in ("modelDescription.xml", "documentation/index.html"):
                    continue
                out.writestr(info, data)
            out.writestr("modelDescription.xml", xml)
            out.writestr("documentation/index.html", doc)
        os.replace(tmp_name, fmu_path)
    finally:
        if os.path.exists(tmp_name):
            os.unlink(tmp_name)


#: The documentation page's note on the pythonfmu backend (issue 14: C/C++ hosts need libpython preloaded).
DOC_PYTHON_BACKEND = (
    "<li>The Python backend needs a Python 3 interpreter with numpy on the machine that runs the FMU. "
    "In a C/C++ host (OMSimulator, libcosim, Ecos, Simulink) libpython must be loaded globally before the "
    "FMU, or the host fails with <code>undefined symbol: _Py_NoneStruct</code> (or crashes): on Linux start "
    "the host as <code>LD_PRELOAD=$(python3 -c \"import os, sysconfig as s; print(os.path.join("
    "s.get_config_var('LIBDIR'), s.get_config_var('INSTSONAME')))\") HOST ...</code> with the python3 whose "
    "numpy the FMU should use. Without that, use the native FMU (<code>solenoid-fmu export --backend c</code>): "
    "no Python at run time.</li>")


def _documentation_html(model_name: str, description: str, tables: _model.MapTables) -> str:
    rows = "\n".join(
        f"<tr><td><code>{html.escape(v.name)}</code></td><td>{v.causality}</td><td>{v.variability}</td>"
        f"<td>{html.escape(v.unit or '')}</td><td>{html.escape(v.description)}</td></tr>"
        for v in interface_for(tables))
    return f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>{html.escape(model_name)}</title></head>
<body>
<h1>{html.escape(model_name)}</h1>
<p>{html.escape(description)}</p>
<h2>Interface</h2>
<table border="1" cellspacing="0" cellpadding="3">
<tr><th>name</th><th>causality</th><th>variability</th><th>unit</th><th>meaning</th></tr>
{rows}
</table>
<h2>Semantics</h2>
<ul>
<li>Inputs are held constant over each communication step; the outputs after a step are computed
from the state and the inputs of that step (no direct feedthrough).</li>
<li>Voltage mode: outputs are instantaneous values. Current mode: U_out_V, dpsi_dt_V and i_eddy_A are
exact means over the last step (dPsi/dt = (Psi(t+h) - Psi(t)) / h).</li>
<li>Integrator: ROS2 (2nd order, L-stable, linearly implicit) with sub-steps of at most h_sub_max_s;
current mode with G_eddy_S = 0 solves i_f(Psi, x) = i by a safeguarded Newton iteration.</li>
<li>x outside [{tables.x_min_m:.6g}, {tables.x_max_m:.6g}] m and |Psi| above {tables.psi_max_Wb:.6g} Wb are
clamped and logged once per excursion (turn FMU logging on to see the messages); the output
out_of_map is true meanwhile.</li>
<li>A NaN or infinite input, R_ohm &lt;= 0 or G_eddy_S &lt; 0 is logged with status error and
fmi2DoStep returns fmi2Discard; the state is left unchanged.</li>
{DOC_PYTHON_BACKEND}
</ul>
</body></html>
"""


# ----------------------------------------------------------------------------------------------
# Simulation of a recording with fmpy
# ----------------------------------------------------------------------------------------------

@dataclass
class SimulationResult:
    """A recording simulated by an FMU.

    Attributes
    ----------
    recording : solenoid_fmu.recordings.Recording
        Same kind, header (plus ``simulated_by`` and ``drive_mode``) and time column as the
        measured recording; simulated ``voltage_V``, ``current_A``, ``force_N``; extra columns
        ``psi_Wb`` and ``i_eddy_A``.
    drive_mode : str
        ``"voltage"`` or ``"current"``.
    messages : list of str
        The FMU's log messages (excursions and errors), ``"status: message"``.
    """

    recording: object
    drive_mode: str
    messages: list


#: Default drive mode per recording kind (the measured quantity that drives the simulation).
DRIVE_BY_KIND = {"flux": "current", "force_stroke": "current", "ramp": "current", "eddy": "current",
                 "voltage_step": "voltage"}


#: Log sinks of :func:`fmi2_callbacks` by componentEnvironment key; the one ctypes logger of the process.
_LOG_SINKS: dict = {}
_LOG_STATE = {"next_key": 1, "logger": None}


def _dispatch_fmi2_log(env, instance, status, category, message) -> None:
    """The process-wide FMI logger: hands a message to the sink registered for ``env`` (fmpy's
    printLogMessage for callbacks that are not ours, e.g. fmpy's defaults)."""
    sink = _LOG_SINKS.get(env)
    if sink is None:
        from fmpy.fmi1 import printLogMessage

        printLogMessage(env, instance, status, category, message)
        return
    sink(int(status), (category or b"").decode("utf-8", "replace"), (message or b"").decode("utf-8", "replace"))


def fmi2_callbacks(log):
    """fmpy ``fmi2CallbackFunctions`` whose logger calls ``log(status, category, message)`` (int, str, str).

    fmpy's native logger proxy (``fmpy.logging.addLoggerProxy``, which formats the FMU's printf-style
    messages) keeps ONE logger for the whole process, the last one registered. A ctypes callback made
    per FMU instance is freed with the instance and leaves that slot dangling: the next message of any
    FMU instantiated with fmpy's default callbacks then crashes the process (SIGSEGV). So the proxy
    always points to one callback that lives as long as the process, which passes each message to the
    ``log`` registered under the callbacks' componentEnvironment. Call :func:`release_fmi2_callbacks`
    when the instance is freed (an unreleased sink only keeps ``log`` alive).
    """
    from ctypes import byref

    import fmpy
    from fmpy.fmi2 import (
        fmi2CallbackAllocateMemoryTYPE,
        fmi2CallbackFreeMemoryTYPE,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
    )
    from fmpy.logging import addLoggerProxy

    if _LOG_STATE["logger"] is None:
        _LOG_STATE["logger"] = fmi2CallbackLoggerTYPE(_dispatch_fmi2_log)
    key = _LOG_STATE["next_key"]
    _LOG_STATE["next_key"] = key + 1
    _LOG_SINKS[key] = log
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = _LOG_STATE["logger"]
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
    callbacks.componentEnvironment = key
    addLoggerProxy(byref(callbacks))
    return callbacks


def release_fmi2_callbacks(callbacks) -> None:
    """Forget the log sink of callbacks made by :func:`fmi2_callbacks` (after fmi2FreeInstance)."""
    _LOG_SINKS.pop(callbacks.componentEnvironment, None)


def simulate_recording(fmu_path, recording, *, drive: str = "auto", R_ohm: float | None = None,
                       G_eddy_S: float | None = None, Psi0_Wb: float | None = None,
                       params: dict | None = None) -> SimulationResult:
    """Drive an FMU with fmpy from a recording's measured inputs; return the simulated recording.

    Parameters
    ----------
    fmu_path : path-like
        FMU built by :func:`build_fmu`.
    recording : path-like or solenoid_fmu.recordings.Recording
        The measured recording (format v1).
    drive : {"auto", "voltage", "current"}
        ``auto``: voltage-driven for ``voltage_step``, current-driven for the other kinds
        (:data:`DRIVE_BY_KIND`).
    R_ohm : float, optional
        Coil resistance [ohm]; default the recording's header ``coil_resistance_ohm`` (measured
        before the run), else the FMU's default (20 degC).
    G_eddy_S : float, optional
        Eddy-current conductance [S]; default the FMU's (from the maps).
    Psi0_Wb : float, optional
        Initial flux linkage [Wb]; default the map's flux at the first measured current and gap.
    params : dict, optional
        Further parameters by name (e.g. effect switches ``heating_on``: False), set before
        initialization.

    Returns
    -------
    SimulationResult

    Raises
    ------
    FmuInputError
        Voltage drive without a voltage column, an unknown drive, an FMU that is not a
        solenoid-fmu FMU, or a step the FMU refused (with its log messages).

    Notes
    -----
    The simulated sample k+1 is the FMU's output after the step from t_k to t_{k+1}; over that
    step the input is held at the current of sample k+1 (current drive: the flux follows the
    current, so the output at t_{k+1} must see i at t_{k+1}) or at the mean of the voltages of
    samples k and k+1 (voltage drive: the trapezoid that paper eq. 4 integrates), with the gap of
    sample k+1. Sample 0 is the output after initialization.
    """
    import fmpy
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave

    from ..measure import Recording, read_recording

    rec = recording if isinstance(recording, Recording) else read_recording(recording)
    if drive == "auto":
        drive = DRIVE_BY_KIND.get(rec.kind, "current")
    if drive not in ("voltage", "current"):
        raise FmuInputError(f"drive must be 'auto', 'voltage' or 'current', got {drive!r}")
    if drive == "voltage" and rec.voltage_V is None:
        raise FmuInputError(f"{rec._where()}: no voltage_V column to drive the model with; "
                            "use --drive current")
    t, x, u, u_step = _drive_inputs(rec, drive)
    if R_ohm is None:
        R_ohm = rec.coil_resistance_ohm

    fmu_path = Path(fmu_path)
    if not fmu_path.is_file():
        raise FmuInputError(f"{fmu_path}: FMU file not found")
    try:
        md = fmpy.read_model_description(str(fmu_path))
    except Exception as exc:  # fmpy raises zip, XML and validation errors of its own
        raise FmuInputError(f"{fmu_path}: not a readable FMU ({type(exc).__name__}: {exc})") from None
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    missing = [v.name for v in VARIABLES if v.name not in vrs]
    if missing:
        raise FmuInputError(f"{fmu_path}: not a solenoid-fmu FMU (missing {', '.join(missing)})")
    unzip = fmpy.extract(str(fmu_path))
    messages: list[str] = []
    status_names = {0: "ok", 1: "warning", 2: "discard", 3: "error", 4: "fatal", 5: "pending"}

    def log(status, category, message):
        messages.append(f"{status_names.get(status, status)}: {message}")

    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="simulate")
    n = t.size
    out_names = ["U_out_V", "i_out_A", "F_N", "psi_Wb", "i_eddy_A", "dpsi_dt_V"]
    out_names += [name for name in ("i_hyst_A", "T_rise_K") if name in vrs]
    out = np.empty((n, len(out_names)))
    out_vr = [vrs[k] for k in out_names]
    types = {v.name: v.type for v in md.modelVariables}
    for name in params or {}:
        if name not in vrs or name in ("U_V", "i_A", "x_m", "drive_mode"):
            raise FmuInputError(f"{fmu_path}: no settable parameter {name!r} in this FMU")
    callbacks = fmi2_callbacks(log)
    try:
        fmu.instantiate(callbacks=callbacks, loggingOn=True)
        try:
            if Psi0_Wb is None:
                tab = _model.load_tables(Path(unzip) / "resources")
                Psi0_Wb = tab.psi_of_current(float(rec.current_A[0]), float(x[0]))
            fmu.setupExperiment(startTime=float(t[0]))
            fmu.enterInitializationMode()
            fmu.setInteger([vrs["drive_mode"]],
                           [_model.DRIVE_VOLTAGE if drive == "voltage" else _model.DRIVE_CURRENT])
            reals = {"Psi0_Wb": Psi0_Wb, "R_ohm": R_ohm, "G_eddy_S": G_eddy_S}
            for name, value in reals.items():
                if value is not None:
                    fmu.setReal([vrs[name]], [float(value)])
            for name, value in (params or {}).items():
                if types[name] == "Boolean":
                    fmu.setBoolean([vrs[name]], [bool(value)])
                else:
                    fmu.setReal([vrs[name]], [float(value)])
            in_vr = [vrs["U_V" if drive == "voltage" else "i_A"], vrs["x_m"]]
            fmu.setReal(in_vr, [float(u[0]), float(x[0])])
            fmu.exitInitializationMode()
            out[0] = fmu.getReal(out_vr)
            for k in range(n - 1):
                fmu.setReal(in_vr, [float(u_step[k]), float(x[k + 1])])
                fmu.doStep(float(t[k]), float(t[k + 1] - t[k]))
                out[k + 1] = fmu.getReal(out_vr)
            fmu.terminate()
        except FMICallException as exc:
            detail = "; ".join(messages[-5:]) or str(exc)
            raise FmuInputError(f"{fmu_path} refused the recording {rec._where()}: {detail}") from None
        finally:
            fmu.freeInstance()
    finally:
        release_fmi2_callbacks(callbacks)
        shutil.rmtree(unzip, ignore_errors=True)
    return _simulated(rec, drive, u, out, out_names, f"{fmu_path.name} ({md.modelName})", messages)


def _drive_inputs(rec, drive: str):
    """Sample times, gaps, drive input and the input held over each step (see simulate_recording)."""
    t = np.asarray(rec.time_s, dtype=float)
    x = np.asarray(rec.positions_m(), dtype=float)
    u = np.asarray(rec.voltage_V if drive == "voltage" else rec.current_A, dtype=float)
    # Input held over the step t_k -> t_k+1 (whose output is sample k+1): the current at the end of
    # the step in current drive (the flux follows it algebraically, or nearly); the mean of the two
    # samples in voltage drive (the flux integrates it: the trapezoid of paper eq. 4).
    u_step = 0.5 * (u[:-1] + u[1:]) if drive == "voltage" else u[1:]
    return t, x, u, u_step


def _simulated(rec, drive, u, out, out_names, by: str, messages) -> SimulationResult:
    from ..measure import Recording

    if drive == "voltage":
        voltage, current = u, out[:, 1]
    else:
        voltage, current = out[:, 0], u
    header = dict(rec.header)
    header["simulated_by"] = by
    header["drive_mode"] = drive
    extra = {"psi_Wb": out[:, 3], "i_eddy_A": out[:, 4]}
    extra.update({name: out[:, k] for k, name in enumerate(out_names) if k >= 6})
    sim = Recording(kind=rec.kind, solenoid=rec.solenoid, header=header, time_s=rec.time_s, current_A=current,
                    voltage_V=voltage, force_N=out[:, 2], position_m=rec.position_m, extra=extra)
    return SimulationResult(recording=sim, drive_mode=drive, messages=messages)


def simulate_model(tables: _model.MapTables, recording, *, drive: str = "auto", R_ohm: float | None = None,
                   params: dict | None = None) -> SimulationResult:
    """Drive ``model.py`` in this process exactly as :func:`simulate_recording` drives an FMU.

    The FMU ships the same ``model.py`` (its agreement with the FMU to 1e-9 is tested), so this is
    the fast path for fitting effect parameters (``improve``); reports use the FMU itself.

    Parameters
    ----------
    tables : MapTables
        The maps, with any ``effects`` section in their maps.json meta.
    recording : path-like or Recording
    drive, R_ohm : see :func:`simulate_recording`
    params : dict, optional
        Further model parameters (:data:`solenoid_fmu.model.DEFAULT_PARAMS` keys).
    """
    from ..measure import Recording, read_recording

    rec = recording if isinstance(recording, Recording) else read_recording(recording)
    if drive == "auto":
        drive = DRIVE_BY_KIND.get(rec.kind, "current")
    t, x, u, u_step = _drive_inputs(rec, drive)
    R_ohm = R_ohm if R_ohm is not None else rec.coil_resistance_ohm
    p = {"drive_mode": drive, "Psi0_Wb": tables.psi_of_current(float(rec.current_A[0]), float(x[0]))}
    if R_ohm is not None:
        p["R_ohm"] = R_ohm
    p.update(params or {})
    try:
        model = _model.SolenoidModel(tables, p)
        model.initialize(float(u[0]), float(x[0]), float(t[0]))
        names = ["U_V", "i_A", "F_N", "psi_Wb", "i_eddy_A", "dpsi_dt_V"]
        fx = ["i_hyst_A", "T_rise_K"] if model.state_names()[len(_model.STATE_NAMES):] else []
        out = np.empty((t.size, len(names) + len(fx)))
        o = model.outputs()
        out[0] = [o[k] for k in names + fx]
        step, dt = model.step, np.diff(t)
        for k in range(t.size - 1):
            step(float(dt[k]), float(u_step[k]), float(x[k + 1]), float(t[k]))
            o = model.outputs()
            out[k + 1] = [o[k2] for k2 in names + fx]
    except _model.ModelError as exc:
        raise FmuInputError(f"model refused the recording {rec._where()}: {exc}") from None
    return _simulated(rec, drive, u, out, ["U_out_V", "i_out_A", "F_N", "psi_Wb", "i_eddy_A", "dpsi_dt_V"] + fx,
                      "solenoid_fmu.model (in process)", [])


# ----------------------------------------------------------------------------------------------
# Command line
# ----------------------------------------------------------------------------------------------

def add_cli(subparsers) -> None:
    """Register ``export`` (maps -> FMU) and ``simulate`` (FMU + recording -> simulated recording)."""
    p = subparsers.add_parser(
        "export", help="export the real-time model with a maps directory as an FMI 2.0 co-simulation FMU",
        description="Build an FMI 2.0 co-simulation FMU (paper eqs. 1-3) from maps/NAME; the result is "
                    "checked with fmpy.validation.validate_fmu.")
    p.add_argument("maps_dir", type=Path, help="maps directory with maps.npz and maps.json")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="FMU", help="FMU file to write")
    p.add_argument("--backend", choices=sorted(BACKENDS), default="python",
                   help="python: pythonfmu (the FMU needs Python 3 with numpy where it runs); c: native "
                        "FMU from generated C (co-simulation and model exchange, no Python at run time, "
                        "compiled with the machine's gcc/cc, sources/ inside)")
    p.add_argument("--name", help="modelName written into the FMU (default: 'solenoid <maps name>')")
    p.set_defaults(func=_cmd_export)

    s = subparsers.add_parser(
        "simulate", help="drive an FMU with a recording's measured inputs; write the simulated recording",
        description="Simulate a recording (format v1) with an FMU through fmpy and write the result in the "
                    "same format (same header and time column, simulated voltage/current/force, extra "
                    "columns psi_Wb and i_eddy_A), so measured and simulated files compare column by column.")
    s.add_argument("fmu", type=Path, help="FMU built by 'solenoid-fmu export'")
    s.add_argument("recording", type=Path, help="measured recording CSV (format v1)")
    s.add_argument("-o", "--output", type=Path, required=True, metavar="CSV",
                   help="simulated recording to write")
    s.add_argument("--drive", choices=("auto", "voltage", "current"), default="auto",
                   help="auto: voltage-driven for voltage_step, current-driven for flux, force_stroke, "
                        "ramp, eddy")
    s.add_argument("--R-ohm", dest="R_ohm", type=float,
                   help="coil resistance [ohm] (default: the recording's header, else the FMU's)")
    s.add_argument("--G-eddy-S", dest="G_eddy_S", type=float, help="eddy-current conductance [S]")
    s.set_defaults(func=_cmd_simulate)


def _cmd_export(args: argparse.Namespace) -> int:
    from ..fileio import refuse_overwriting_inputs

    refuse_overwriting_inputs(args.output, [args.maps_dir / "maps.npz", args.maps_dir / "maps.json"])
    path = build_fmu(args.maps_dir, args.output, backend=args.backend, model_name=args.name)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB, backend {args.backend}; "
          "fmpy validation: no problems)")
    print(backend_advice(args.backend))
    return 0


def backend_advice(backend: str) -> str:
    """Which FMU to use in which importer (printed by ``export``; README "Which export to use when")."""
    if backend == "c":
        return ("native FMU: runs in any FMI 2.0 importer (fmpy, Simulink, OpenModelica/OMSimulator, libcosim, "
                "Ecos, real-time targets), co-simulation and model exchange, no Python at run time")
    import sysconfig

    lib = os.path.join(sysconfig.get_config_var("LIBDIR") or "", sysconfig.get_config_var("INSTSONAME") or "")
    return ("pythonfmu FMU: runs in Python hosts (fmpy, PyFMI) as it is; in C/C++ hosts (OMSimulator, libcosim, "
            f"Ecos, Simulink) start the host with LD_PRELOAD={lib} (this Python's libpython, with numpy), "
            "or export --backend c for those hosts")


def _cmd_simulate(args: argparse.Namespace) -> int:
    from ..measure import write_recording

    if args.R_ohm is not None and not (math.isfinite(args.R_ohm) and args.R_ohm > 0):
        raise FmuInputError(f"--R-ohm must be > 0, got {args.R_ohm!r}")
    from ..fileio import refuse_overwriting_inputs

    refuse_overwriting_inputs(args.output, [args.fmu, args.recording])
    res = simulate_recording(args.fmu, args.recording, drive=args.drive, R_ohm=args.R_ohm,
                             G_eddy_S=args.G_eddy_S)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    write_recording(args.output, res.recording)
    for msg in res.messages:
        print(f"FMU: {msg}", file=sys.stderr)
    print(f"wrote {args.output} ({len(res.recording)} samples, {res.drive_mode}-driven)")
    return 0
