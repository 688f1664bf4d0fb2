"""Simulation of a recording: with an FMU through fmpy, or with the real-time model in process.

``simulate_recording(fmu, recording)`` drives an FMU with fmpy from a recording's measured inputs
and returns a recording in the same format (CLI ``solenoid-fmu simulate``); ``simulate_model``
drives :class:`solenoid_fmu.realtime.model.SolenoidModel` the same way (the fast path of the fits).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FmuInputError
from ..measure import Recording, read_recording
from ..realtime import (
    COPPER_ALPHA_PER_K,
    DRIVE_CURRENT,
    DRIVE_VOLTAGE,
    STATE_NAMES,
    T_START_EXCESS_RANGE_K,
    MapTables,
    ModelError,
    SolenoidModel,
    load_tables,
)
from .callbacks import fmi2_callbacks, release_fmi2_callbacks
from .interface import VARIABLES
from .native_sim import native_run

__all__ = ["DRIVE_BY_KIND", "SimulationResult", "simulate_model", "simulate_recording"]


@dataclass
class SimulationResult:
    """A recording simulated by an FMU.

    Attributes
    ----------
    recording : solenoid_fmu.measure.Recording
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



def start_excess_K(R_ohm: float | None, ambient_R_ohm: float | None, alpha_per_K: float) -> float:
    """The coil's temperature above ambient [K] at the start of a run whose coil resistance is ``R_ohm``
    [ohm], the coil at ambient having ``ambient_R_ohm``: ``(R / R_amb - 1) / alpha``, within the model's
    :data:`~solenoid_fmu.realtime.model.T_START_EXCESS_RANGE_K`; 0 when either is unknown or alpha <= 0."""
    if not R_ohm or not ambient_R_ohm or not alpha_per_K > 0.0:
        return 0.0
    lo, hi = T_START_EXCESS_RANGE_K
    return min(max((R_ohm / ambient_R_ohm - 1.0) / alpha_per_K, lo), hi)


def heating_start(tables: MapTables, R_ohm: float | None, ambient_R_ohm: float | None) -> dict:
    """The model parameters of a run that starts at ``R_ohm`` [ohm] on ``tables``: ``T_start_excess_K`` from the
    coil's resistance at ambient ``ambient_R_ohm`` [ohm] (:func:`start_excess_K`) where the tables carry coil
    heating (the coil then cools from it through R_th while it heats); ``{}`` otherwise or without ``ambient_R_ohm``."""
    heat = tables.effects.heating if tables.effects is not None else None
    if not heat or ambient_R_ohm is None:
        return {}
    alpha = float(heat.get("alpha_per_K", COPPER_ALPHA_PER_K))  # the model's default where the section has none
    return {"T_start_excess_K": start_excess_K(R_ohm, ambient_R_ohm, alpha)}


def simulate_recording(fmu_path, recording, *, drive: str = "auto", R_ohm: float | None = None,
                       G_eddy_S: float | None = None, Psi0_Wb: float | None = None,
                       params: dict | None = None, ambient_R_ohm: float | None = None) -> SimulationResult:
    """Drive an FMU with fmpy from a recording's measured inputs; return the simulated recording.

    Parameters
    ----------
    fmu_path : path-like
        FMU built by :func:`build_fmu`.
    recording : path-like or solenoid_fmu.measure.Recording
        The measured recording (format v1).
    drive : {"auto", "voltage", "current"}
        ``auto``: voltage-driven for ``voltage_step``, current-driven for the others (:data:`DRIVE_BY_KIND`).
    R_ohm : float, optional
        Coil resistance [ohm]; default the header's ``coil_resistance_ohm``, else the FMU's (20 degC).
    G_eddy_S : float, optional
        Eddy-current conductance [S]; default the FMU's (from the maps).
    Psi0_Wb : float, optional
        Initial flux linkage [Wb]; default the map's flux at the first measured current and gap.
    params : dict, optional
        Further parameters by name (e.g. ``heating_on``: False), set before initialization.
    ambient_R_ohm : float, optional
        The coil's resistance at ambient [ohm]: with heating, the run starts above it (:func:`heating_start`).

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
    Simulated sample k+1 is the FMU's output after the step t_k -> t_{k+1}, the input held at the current
    of sample k+1 (current drive: the output at t_{k+1} must see i at t_{k+1}) or at the mean voltage of
    samples k and k+1 (voltage drive: the trapezoid eq. 4 integrates), the gap at sample k+1's. Sample 0
    is the output after initialization.
    """
    import fmpy  # third-party FMI host, loaded only when an FMU runs
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave

    rec = recording if isinstance(recording, Recording) else read_recording(recording)
    drive = _drive_of(rec, drive)
    t, x, u, u_step = _drive_inputs(rec, drive)
    R_ohm = rec.coil_resistance_ohm if R_ohm is None else R_ohm
    fmu_path = Path(fmu_path)
    md, vrs = _solenoid_model_description(fmu_path, params or {})
    unzip = fmpy.extract(str(fmu_path))
    messages: list[str] = []

    def log(status, category, message):
        messages.append(f"{_STATUS_NAMES.get(status, status)}: {message}")

    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="simulate")
    out_names = [name for name in _OUTPUTS if name in vrs]
    callbacks = fmi2_callbacks(log)
    try:
        fmu.instantiate(callbacks=callbacks, loggingOn=True)
        try:
            tables = load_tables(Path(unzip) / "resources")
            Psi0_Wb = tables.psi_of_current(float(rec.current_A[0]), float(x[0])) if Psi0_Wb is None else Psi0_Wb
            reals = {"Psi0_Wb": Psi0_Wb, "R_ohm": R_ohm, "G_eddy_S": G_eddy_S}
            params = {**heating_start(tables, R_ohm, ambient_R_ohm), **(params or {})}
            in_vr = _initialize(fmu, md, vrs, drive, float(t[0]), reals, params or {}, (float(u[0]), float(x[0])))
            out = _run(fmu, in_vr, [vrs[k] for k in out_names], t, x, u_step)
        except FMICallException as exc:
            detail = "; ".join(messages[-5:]) or str(exc)
            raise FmuInputError(f"{fmu_path} refused the recording {rec.label()}: {detail}") from None
        finally:
            fmu.freeInstance()
    finally:
        release_fmi2_callbacks(callbacks)
        shutil.rmtree(unzip, ignore_errors=True)
    return _simulated(rec, drive, u, out, out_names, f"{fmu_path.name} ({md.modelName})", messages)


#: The outputs a simulation reads, in this order (the effect outputs when the FMU has them).
_OUTPUTS = ("U_out_V", "i_out_A", "F_N", "psi_Wb", "i_eddy_A", "dpsi_dt_V", "i_hyst_A", "T_rise_K")
#: FMI 2.0 status codes by name, for the log messages.
_STATUS_NAMES = {0: "ok", 1: "warning", 2: "discard", 3: "error", 4: "fatal", 5: "pending"}


def _drive_of(rec, drive: str) -> str:
    """``"voltage"`` or ``"current"``: the drive asked for, ``auto`` by the recording's kind (:data:`DRIVE_BY_KIND`)."""
    if drive == "auto":
        drive = DRIVE_BY_KIND.get(rec.kind, "current")
    if drive not in ("voltage", "current"):
        raise FmuInputError(f"drive must be 'auto', 'voltage' or 'current', got {drive!r}")
    if drive == "voltage" and rec.voltage_V is None:
        raise FmuInputError(f"{rec.label()}: no voltage_V column to drive the model with; "
                            "use --drive current")
    return drive


def _solenoid_model_description(fmu_path: Path, params: dict) -> tuple:
    """(fmpy's model description, value reference by name) of a solenoid-fmu FMU with the parameters
    ``params``; FmuInputError otherwise."""
    import fmpy  # third-party FMI host, loaded only when an FMU runs

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
    for name in params:
        if name not in vrs or name in ("U_V", "i_A", "x_m", "drive_mode"):
            raise FmuInputError(f"{fmu_path}: no settable parameter {name!r} in this FMU")
    return md, vrs


def _initialize(fmu, md, vrs: dict, drive: str, t0: float, reals: dict, params: dict, inputs: tuple):
    """Initialize the instantiated ``fmu`` at ``t0``: drive mode, the given reals (None: the FMU's default),
    ``params`` and the first inputs (drive input, gap); returns the value references of the inputs."""
    fmu.setupExperiment(startTime=t0)
    fmu.enterInitializationMode()
    fmu.setInteger([vrs["drive_mode"]], [DRIVE_VOLTAGE if drive == "voltage" else DRIVE_CURRENT])
    for name, value in reals.items():
        if value is not None:
            fmu.setReal([vrs[name]], [float(value)])
    types = {v.name: v.type for v in md.modelVariables}
    for name, value in params.items():
        if types[name] == "Boolean":
            fmu.setBoolean([vrs[name]], [bool(value)])
        else:
            fmu.setReal([vrs[name]], [float(value)])
    in_vr = [vrs["U_V" if drive == "voltage" else "i_A"], vrs["x_m"]]
    fmu.setReal(in_vr, list(inputs))
    fmu.exitInitializationMode()
    return in_vr


def _run(fmu, in_vr: list, out_vr: list, t, x, u_step) -> np.ndarray:
    """The outputs after initialization and after each step (inputs held as :func:`simulate_recording` says)."""
    n = t.size
    out = np.empty((n, len(out_vr)))
    out[0] = fmu.getReal(out_vr)
    for k in range(n - 1):
        fmu.setReal(in_vr, [float(u_step[k]), float(x[k + 1])])
        fmu.doStep(float(t[k]), float(t[k + 1] - t[k]))
        out[k + 1] = fmu.getReal(out_vr)
    fmu.terminate()
    return out


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


def simulate_model(tables: MapTables, recording, *, drive: str = "auto", R_ohm: float | None = None,
                   params: dict | None = None, ambient_R_ohm: float | None = None) -> SimulationResult:
    """Drive ``model.py`` in this process exactly as :func:`simulate_recording` drives an FMU.

    The FMU ships the same ``model.py`` (its agreement with the FMU to 1e-9 is tested), so this is
    the fast path for fitting effect parameters (``improve``); reports use the FMU itself. Where a C compiler is
    there, the steps run in the native FMU's compiled step (:mod:`.native_sim`: the same numbers bit for bit,
    ~100x sooner; ``SOLENOID_FMU_SIMULATOR=python`` runs the Python model); the result's ``simulated_by`` header
    says which ran.

    Parameters
    ----------
    tables : MapTables
        The maps, with any ``effects`` section in their maps.json meta.
    recording : path-like or Recording
    drive, R_ohm, ambient_R_ohm : see :func:`simulate_recording`
    params : dict, optional
        Further model parameters (:data:`solenoid_fmu.realtime.model.DEFAULT_PARAMS` keys).
    """
    rec = recording if isinstance(recording, Recording) else read_recording(recording)
    if drive == "auto":
        drive = DRIVE_BY_KIND.get(rec.kind, "current")
    t, x, u, u_step = _drive_inputs(rec, drive)
    R_ohm = R_ohm if R_ohm is not None else rec.coil_resistance_ohm
    p = {"drive_mode": drive, "Psi0_Wb": tables.psi_of_current(float(rec.current_A[0]), float(x[0]))}
    if R_ohm is not None:
        p["R_ohm"] = R_ohm
    p.update(heating_start(tables, R_ohm, ambient_R_ohm))
    p.update(params or {})
    try:
        model = SolenoidModel(tables, p)
        model.initialize(float(u[0]), float(x[0]), float(t[0]))
        names = ["U_V", "i_A", "F_N", "psi_Wb", "i_eddy_A", "dpsi_dt_V"]
        fx = ["i_hyst_A", "T_rise_K"] if model.state_names()[len(STATE_NAMES):] else []
        out_names = ["U_out_V", "i_out_A", "F_N", "psi_Wb", "i_eddy_A", "dpsi_dt_V"] + fx
        settings = [("drive_mode", DRIVE_VOLTAGE if drive == "voltage" else DRIVE_CURRENT)]
        settings += [(k, v) for k, v in p.items() if k != "drive_mode"]
        run = native_run(tables, settings, drive == "voltage", t, x, float(u[0]), u_step, out_names)
        if run is not None and run.out is not None:  # the same numbers, compiled (native_sim)
            return _simulated(rec, drive, u, run.out, out_names, "solenoid_fmu.model (in process, native step)", [])
        # else the Python model: where the native one refused an input, it raises the error users see
        out = np.empty((t.size, len(names) + len(fx)))
        o = model.outputs()
        out[0] = [o[k] for k in names + fx]
        step, dt = model.step, np.diff(t)
        for k in range(t.size - 1):
            step(float(dt[k]), float(u_step[k]), float(x[k + 1]), float(t[k]))
            o = model.outputs()
            out[k + 1] = [o[k2] for k2 in names + fx]
    except ModelError as exc:
        raise FmuInputError(f"model refused the recording {rec.label()}: {exc}") from None
    return _simulated(rec, drive, u, out, out_names, "solenoid_fmu.model (in process)", [])

