"""pythonfmu slave of solenoid-fmu: the Fmi2Slave class packed into every pythonfmu FMU.

Wraps the numpy-only real-time model :mod:`solenoid_fmu.realtime.model` (paper eqs. 1-3) with the
variables of :mod:`solenoid_fmu.fmu.interface`. The python backend
(:func:`solenoid_fmu.fmu.python_backend.slave_source`) copies this file into the FMU as
``solenoid_slave_<hash>.py`` with its two package imports replaced: the model by its copy
package ``solenoid_model_<hash>/`` shipped beside it, the interface table by literals. The class name is
the FMU's modelIdentifier (pythonfmu takes it from the class).

It raises into the pythonfmu C wrapper (which turns any exception into fmi2Fatal) only to refuse a
call: setFMUstate of a state that is not one of this FMU's (bad bytes or JSON), get/set of a value
reference this FMU does not have (or of another type), and a fixed parameter (``drive_mode``,
``Psi0_Wb``, ``h_sub_max_s``) set after initialization. The wrapper has no other way to refuse, and OK
would hide it; nothing is changed and the log names the reason. Invalid inputs are logged with status
error and fmi2DoStep returns fmi2Discard.

pythonfmu 0.7's wrapper releases the slave class, the slave and its log queue once per exception it
handles (``handle_py_exception`` -> ``cleanPyObject``: ``Py_XDECREF`` of references it does not give
up), so after a few refused calls the log queue was freed and the next ``clearLogBuffer`` crashed the
host. :func:`_refuse` keeps one extra reference to each of the three per exception raised into the
wrapper (:data:`_WRAPPER_REFS`), which those releases consume (upstream report:
``docs/upstream-pythonfmu.md``).
"""

import json
import os

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

from ..realtime import DRIVE_VOLTAGE, STATE_NAMES, ModelError, ModelInputError, SolenoidModel, load_tables
from .interface import EFFECT_VARIABLES, VARIABLES

_PARAMS = tuple(v.name for v in VARIABLES if v.causality == "parameter")
_TUNABLE = tuple(v.name for v in VARIABLES if v.variability == "tunable")
_FX_TUNABLE = tuple(v.name for v in EFFECT_VARIABLES if v.variability == "tunable")
#: Layout of the serialized FMU state of this slave (JSON).
_STATE_LAYOUT = 1
_TABLES = {}
#: One reference to the slave class, the slave and its log queue per exception raised into pythonfmu's
#: C wrapper, which releases each of them once per exception (module docstring).
_WRAPPER_REFS = []


def _refuse(slave, message):
    """Log ``message`` as an error and raise into the C wrapper (fmi2Fatal), compensating the references
    the wrapper releases when it handles the exception."""
    slave.log(message, Fmi2Status.error)
    _WRAPPER_REFS.extend((type(slave), slave, slave.log_queue))
    raise RuntimeError(message)


def _tables_for(resources):
    """Maps of this FMU, read once per resources directory and process (read-only, shared)."""
    npz = os.path.join(resources, "maps.npz")
    st = os.stat(npz)
    key = (os.path.abspath(resources), st.st_mtime_ns, st.st_size)
    tab = _TABLES.get(key)
    if tab is None:
        tab = _TABLES[key] = load_tables(resources)
    return tab


class SolenoidFmu(Fmi2Slave):
    """Valve solenoid, real-time lumped model from characteristic maps."""

    author = "solenoid-fmu"
    description = "Valve solenoid real-time lumped model (paper eqs. 1-3)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        tab = _tables_for(self.resources)
        model = self._model = SolenoidModel(tab)
        p = model.params
        self.U_V = 0.0
        self.i_A = 0.0
        self.x_m = 0.5 * (tab.x_min_m + tab.x_max_m)
        self.R_ohm = p["R_ohm"]
        self.G_eddy_S = p["G_eddy_S"]
        self.drive_mode = p["drive_mode"]
        self.Psi0_Wb = p["Psi0_Wb"]
        self.h_sub_max_s = p["h_sub_max_s"]
        self._fx = bool(model.state_names()[len(STATE_NAMES):])
        variables = VARIABLES + (EFFECT_VARIABLES if self._fx else ())
        self._params = _PARAMS + tuple(v.name for v in variables[len(VARIABLES):] if v.causality == "parameter")
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
        for spec in variables:
            kw = dict(causality=getattr(Fmi2Causality, spec.causality),
                      variability=getattr(Fmi2Variability, spec.variability), description=spec.description)
            if spec.causality == "output":
                kw["getter"] = getters[spec.name]
            elif spec.causality == "parameter":
                kw["setter"] = (lambda v, n=spec.name: self._set_param(n, v))
            self.register_variable(kinds[spec.type](spec.name, **kw))

    def _set_param(self, name, value):
        setattr(self, name, value)
        self._dirty = True

    def _vars_of(self, call, vrs, kind, setting=False):
        """The variables of ``vrs`` (all checked before any is read or set), else refused: an unknown value
        reference, one of another type, or (``setting``) a fixed parameter after initialization."""
        out = []
        for vr in vrs:
            var = self.vars.get(vr)
            if var is None:
                _refuse(self, f"{call}: no variable with value reference {vr}; nothing {'set' if setting else 'read'}")
            if not isinstance(var, kind):
                _refuse(self, f"{call}: {var.name} (value reference {vr}) is not of type {kind.__name__}")
            if setting and self._ready and var.name in self._params and var.name not in self._tunable:
                _refuse(self, f"{call}: {var.name} is a fixed parameter, not settable after initialization "
                              "(it keeps its value; instantiate anew or reset to change it)")
            if setting and var.setter is None:
                _refuse(self, f"{call}: {var.name} is an output, not settable")
            out.append(var)
        return out

    def get_real(self, vrs):
        return [float(v.getter()) for v in self._vars_of("fmi2GetReal", vrs, Real)]

    def get_integer(self, vrs):
        return [int(v.getter()) for v in self._vars_of("fmi2GetInteger", vrs, Integer)]

    def get_boolean(self, vrs):
        return [bool(v.getter()) for v in self._vars_of("fmi2GetBoolean", vrs, Boolean)]

    def get_string(self, vrs):
        _refuse(self, "fmi2GetString: this FMU has no String variables") if vrs else None
        return []

    def set_real(self, vrs, values):
        for var, value in zip(self._vars_of("fmi2SetReal", vrs, Real, True), values, strict=True):
            var.setter(value)

    def set_integer(self, vrs, values):
        for var, value in zip(self._vars_of("fmi2SetInteger", vrs, Integer, True), values, strict=True):
            var.setter(value)

    def set_boolean(self, vrs, values):
        for var, value in zip(self._vars_of("fmi2SetBoolean", vrs, Boolean, True), values, strict=True):
            var.setter(value)

    def set_string(self, vrs, values):
        _refuse(self, "fmi2SetString: this FMU has no String variables") if vrs else None

    def _apply_params(self, all_params):
        self._dirty = True
        names = self._params if all_params else self._tunable
        self._model.set_params(**{n: getattr(self, n) for n in names})
        self._voltage = self._model.params["drive_mode"] == DRIVE_VOLTAGE
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
        except ModelError as exc:
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
            _refuse(self, f"setFMUstate: state not restored, the previous one kept: {type(exc).__name__}: {exc}")

    def _restore(self, state):
        if not isinstance(state, dict) or "__invalid__" in state:
            raise ModelInputError(f"not a serialized state of this FMU "
                                         f"({state.get('__invalid__') if isinstance(state, dict) else state!r})")
        if (state.get("layout") != _STATE_LAYOUT
                or list(state["state_names"]) != list(self._model.state_names())):
            raise ModelInputError("FMU state from an incompatible model version")
        self._model.set_params(**state["model_params"])
        self._model.set_state(state["model_state"])
        self.U_V, self.i_A, self.x_m = (float(v) for v in state["inputs"])
        if len(state["params"]) != len(self._params):
            raise ModelInputError("FMU state with a different parameter set")
        for name, value in zip(self._params, state["params"], strict=True):
            setattr(self, name, value)
        self._t0 = float(state["t0"])
        self._dirty = bool(state["dirty"])
        self._ready = bool(state["ready"])
        self._voltage = self._model.params["drive_mode"] == DRIVE_VOLTAGE
