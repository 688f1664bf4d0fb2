"""The pythonfmu FMU: validation, agreement with model.py, instances, reset, state, logging, CLI."""

from __future__ import annotations

import hashlib
import json
import math
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import fmpy
import mapsfixture as mf
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave

from solenoid_fmu import cli
from solenoid_fmu import fmu as F
from solenoid_fmu.errors import FmuBuildError, FmuInputError, MapsError
from solenoid_fmu.realtime import model as M

pytestmark = pytest.mark.fmu

X_M = 1.0e-3
OUTS = ("i_out_A", "U_out_V", "F_N", "psi_Wb", "dpsi_dt_V", "i_eddy_A")


@pytest.fixture(scope="module")
def maps_dir(tmp_path_factory):
    return mf.write_maps(tmp_path_factory.mktemp("fmu_maps") / "synthetic", G_eddy_S=0.02)


@pytest.fixture(scope="module")
def fmu_path(maps_dir, tmp_path_factory):
    """The FMU, built once per module (and test worker)."""
    return F.build_fmu(maps_dir, tmp_path_factory.mktemp("fmu") / "synthetic.fmu")


@pytest.fixture(scope="module")
def unzipped(fmu_path):
    return fmpy.extract(str(fmu_path))


@pytest.fixture(scope="module")
def md(fmu_path):
    return fmpy.read_model_description(str(fmu_path))


@pytest.fixture(scope="module")
def tab(maps_dir):
    return M.load_tables(maps_dir)


class Instance:
    """An fmpy FMU2Slave with a logger that records (status, message)."""

    def __init__(self, md, unzipped, name="inst"):
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.messages = []

        # the package's process-wide logger: a per-instance ctypes logger would leave fmpy's one logger
        # slot dangling after the instance is freed (the next FMU message anywhere would crash)
        cb = F.fmi2_callbacks(lambda status, category, message: self.messages.append((status, message)))
        self._cb = cb  # keep the callbacks alive as long as the instance
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate(callbacks=cb, loggingOn=True)
        self.t = 0.0

    def init(self, *, mode="voltage", u=0.0, x=X_M, **params):
        f, vr = self.fmu, self.vr
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        f.setInteger([vr["drive_mode"]], [M.DRIVE_VOLTAGE if mode == "voltage" else M.DRIVE_CURRENT])
        for name, value in params.items():
            f.setReal([vr[name]], [value])
        f.setReal([vr["U_V" if mode == "voltage" else "i_A"], vr["x_m"]], [u, x])
        f.exitInitializationMode()
        self.mode = mode
        self.t = 0.0
        return self

    def step(self, h, u, x=X_M):
        vr = self.vr
        self.fmu.setReal([vr["U_V" if self.mode == "voltage" else "i_A"], vr["x_m"]], [u, x])
        self.fmu.doStep(self.t, h)
        self.t += h
        return self.outputs()

    def outputs(self):
        return self.fmu.getReal([self.vr[k] for k in OUTS])

    def free(self):
        self.fmu.terminate()
        self.fmu.freeInstance()
        F.release_fmi2_callbacks(self._cb)


def model_run(tab, mode, params, u0, x0, inputs, h):
    model = M.SolenoidModel(tab, dict(params, drive_mode=mode))
    model.initialize(u0, x0)
    rows = [[model.i_A, model.U_V, model.F_N, model.psi_Wb, model.dpsi_dt_V, model.i_eddy_A]]
    for u, x in inputs:
        model.step(h, u, x)
        rows.append([model.i_A, model.U_V, model.F_N, model.psi_Wb, model.dpsi_dt_V, model.i_eddy_A])
    return np.array(rows)


def scenario(n=300):
    """Voltage step 24 V then off, gap moving across the map and out of it."""
    k = np.arange(n)
    u = np.where(k < n // 2, 24.0, 0.0)
    x = 0.3e-3 + 4.0e-3 * k / n  # leaves the map at 3.5 mm
    return list(zip(u.tolist(), x.tolist(), strict=True))


# -- modelDescription ------------------------------------------------------------------------------
def test_validate_fmu_reports_no_problems(fmu_path):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmu_path)) == []


def test_model_description_is_complete(md, fmu_path, maps_dir):
    assert md.coSimulation.needsExecutionTool is False
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    assert md.generationTool.startswith("solenoid-fmu")
    assert md.generationDateAndTime.endswith("Z")
    assert md.defaultExperiment is not None and float(md.defaultExperiment.stepSize) == 1e-4
    units = {u.name for u in md.unitDefinitions}
    assert {"V", "A", "m", "N", "Wb", "Ohm", "S", "s"} <= units
    names = [v.name for v in md.modelVariables]
    assert names == [v.name for v in F.VARIABLES]
    for v in md.modelVariables:
        assert v.description
        if v.type == "Real":
            assert v.unit in units, v.name
        if v.causality == "parameter":
            assert v.variability in ("fixed", "tunable") and v.start is not None
    dm = md.modelVariables[names.index("drive_mode")]
    # an Integer 1..2, not an Enumeration: libcosim and Ecos drop Enumeration variables (issue 14)
    assert dm.type == "Integer" and float(dm.min) == 1 and float(dm.max) == 2 and dm.declaredType is None
    assert md.defaultExperiment.tolerance is not None and float(md.defaultExperiment.tolerance) == 1e-6
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    assert {u.variable.name for u in md.outputs} == {v.name for v in outputs}
    assert {u.variable.name for u in md.initialUnknowns} == {v.name for v in outputs}
    assert all(u.dependencies == [] for u in md.outputs)  # no direct feedthrough
    knowns = {v.name for v in md.modelVariables if v.causality in ("input", "parameter")}
    for u in md.initialUnknowns:
        assert {d.name for d in u.dependencies} == knowns
    sha = hashlib.sha256((maps_dir / "maps.npz").read_bytes()).hexdigest()
    assert sha in md.description
    with zipfile.ZipFile(fmu_path) as zf:
        xml = zf.read("modelDescription.xml").decode()
        names_in_zip = zf.namelist()
    assert f'npz_sha256="{sha}"' in xml and "analytic-circuit" in xml
    assert "resources/maps.npz" in names_in_zip and "documentation/index.html" in names_in_zip
    assert not any(n.endswith((".pkl", ".pickle")) for n in names_in_zip)


def test_the_slave_is_a_module_of_the_package(maps_dir, tab):
    """fmu/slave.py, copied into every pythonfmu FMU, also runs in process with the package's model and
    interface table: the interface's variables in order, and model.py's step."""
    from solenoid_fmu.fmu.python_backend import slave_source
    from solenoid_fmu.fmu.slave import SolenoidFmu

    slave = SolenoidFmu(instance_name="in-process", resources=str(maps_dir))
    names = [v.name for v in F.VARIABLES]
    assert [v.name for v in slave.vars.values()] == names
    slave.setup_experiment(0.0)
    slave.U_V, slave.x_m = 24.0, X_M
    slave.exit_initialization_mode()
    assert slave.do_step(0.0, 1e-3) is True
    model = M.SolenoidModel(tab)
    model.initialize(24.0, X_M, 0.0)
    model.step(1e-3, 24.0, X_M, 0.0)
    assert slave.get_real([names.index("psi_Wb"), names.index("F_N")]) == [model.psi_Wb, model.F_N]
    packed = slave_source("solenoid_model_0")  # the FMU's copy: the model beside it, the table as literals
    assert "from solenoid_model_0 import " in packed and "from .interface" not in packed
    assert "from ..realtime" not in packed and "class SolenoidFmu(Fmi2Slave):" in packed


# -- agreement with model.py -----------------------------------------------------------------------
def test_fmu_in_a_fresh_process_matches_model(fmu_path, tab):
    """A new interpreter loads the FMU with fmpy; its outputs equal model.py's to 1e-9."""
    inputs = scenario()
    script = textwrap.dedent(f"""
        import json, sys
        import fmpy
        from fmpy.fmi2 import FMU2Slave
        path = {str(fmu_path)!r}
        md = fmpy.read_model_description(path)
        vr = {{v.name: v.valueReference for v in md.modelVariables}}
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(path),
                        modelIdentifier=md.coSimulation.modelIdentifier, instanceName="fresh")
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setReal([vr["U_V"], vr["x_m"]], [0.0, 0.3e-3])
        fmu.exitInitializationMode()
        outs = [vr[k] for k in {OUTS!r}]
        rows = [fmu.getReal(outs)]
        t = 0.0
        for u, x in json.load(sys.stdin):
            fmu.setReal([vr["U_V"], vr["x_m"]], [u, x])
            fmu.doStep(t, 1e-4)
            t += 1e-4
            rows.append(fmu.getReal(outs))
        fmu.terminate()
        fmu.freeInstance()
        print(json.dumps(rows), flush=True)
        # pythonfmu 0.7.0's wrapper can abort in the interpreter's teardown after all of the above (README,
        # "The pythonfmu FMU in a Python host"): leave without it, the results are out
        import os
        os._exit(0)
    """)
    proc = subprocess.run([sys.executable, "-c", script], input=json.dumps(inputs), capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    got = np.array(json.loads(proc.stdout.strip().splitlines()[-1]))
    ref = model_run(tab, "voltage", {}, 0.0, 0.3e-3, inputs, 1e-4)
    assert got.shape == ref.shape
    scale = np.max(np.abs(ref), axis=0)
    assert np.max(np.abs(got - ref) / scale) <= 1e-9
    assert ref[-1, 3] != ref[0, 3]  # the scenario did something


def test_current_mode_matches_model(md, unzipped, tab):
    inst = Instance(md, unzipped).init(mode="current", u=0.0, G_eddy_S=0.005)
    inputs = [(10.0 * 1e-3 * k, X_M) for k in range(1, 150)]
    got = np.array([inst.outputs()] + [inst.step(1e-3, u, x) for u, x in inputs])
    inst.free()
    ref = model_run(tab, "current", {"G_eddy_S": 0.005}, 0.0, X_M, inputs, 1e-3)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-12)


# -- instances, reset, state -----------------------------------------------------------------------
def test_two_instances_are_independent(md, unzipped, tab):
    a = Instance(md, unzipped, "a").init(mode="voltage", u=24.0)
    b = Instance(md, unzipped, "b").init(mode="current", u=0.5, G_eddy_S=0.0)
    ga, gb = [], []
    for k in range(60):
        ga.append(a.step(1e-3, 24.0))
        gb.append(b.step(1e-3, 0.5 + 0.01 * k))
    a.free()
    b.free()
    ra = model_run(tab, "voltage", {}, 24.0, X_M, [(24.0, X_M)] * 60, 1e-3)[1:]
    rb = model_run(tab, "current", {"G_eddy_S": 0.0}, 0.5, X_M,
                   [(0.5 + 0.01 * k, X_M) for k in range(60)], 1e-3)[1:]
    np.testing.assert_allclose(ga, ra, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(gb, rb, rtol=1e-12, atol=1e-14)


def test_reset_returns_to_the_start_state(md, unzipped):
    inst = Instance(md, unzipped)
    inst.init(mode="voltage", u=24.0, R_ohm=10.0)
    start = inst.outputs()
    first = [inst.step(1e-3, 24.0) for _ in range(30)]
    inst.fmu.reset()
    vr = inst.vr
    # parameters are back at their start values after fmi2Reset
    assert inst.fmu.getReal([vr["R_ohm"]]) == [mf.R_OHM]
    inst.init(mode="voltage", u=24.0, R_ohm=10.0)
    assert inst.outputs() == start
    second = [inst.step(1e-3, 24.0) for _ in range(30)]
    inst.free()
    assert first == second
    assert first[-1][3] > 0.1  # flux built up


def test_fmu_state_round_trip_restores_the_internal_state(md, unzipped):
    inst = Instance(md, unzipped).init(mode="voltage", u=24.0)
    for _ in range(20):
        inst.step(1e-3, 24.0)
    t_saved = inst.t
    state = inst.fmu.getFMUstate()
    ahead = [inst.step(1e-3, 24.0 if k < 5 else 0.0) for k in range(10)]
    assert ahead[-1][3] != ahead[0][3]
    inst.fmu.setFMUstate(state)
    inst.t = t_saved
    again = [inst.step(1e-3, 24.0 if k < 5 else 0.0) for k in range(10)]
    assert again == ahead
    blob = inst.fmu.serializeFMUstate(state)
    assert json.loads(blob.decode())["model_state"][2] > 0.0  # the flux travels in the state
    inst.fmu.freeFMUstate(state)
    # a different instance continues exactly from the deserialized state
    other = Instance(md, unzipped, "other").init(mode="voltage", u=0.0)
    restored = other.fmu.deSerializeFMUstate(blob)
    other.fmu.setFMUstate(restored)
    other.mode, other.t = "voltage", t_saved
    third = [other.step(1e-3, 24.0 if k < 5 else 0.0) for k in range(10)]
    other.fmu.freeFMUstate(restored)
    other.free()
    inst.free()
    assert third == ahead


# -- logging and errors ----------------------------------------------------------------------------
def test_gap_excursion_logged_once_per_excursion(md, unzipped, tab):
    inst = Instance(md, unzipped).init(mode="current", u=1.0, G_eddy_S=0.0)
    for x in (2e-3, 4e-3, 5e-3, 6e-3, 2e-3, 2e-3, 0.1e-3, 0.05e-3, 1e-3):
        inst.step(1e-3, 1.0, x)
    inst.free()
    warnings = [m for s, m in inst.messages if s == 1]
    assert len(warnings) == 2
    assert "x_m = 0.004 m is outside" in warnings[0] and "x_m = 0.0001 m is outside" in warnings[1]


def test_out_of_map_flag(md, unzipped):
    inst = Instance(md, unzipped).init(mode="voltage", u=0.0)
    vr = inst.vr["out_of_map"]
    inst.step(1e-3, 0.0, 9e-3)
    assert inst.fmu.getBoolean([vr]) == [True]
    inst.step(1e-3, 0.0, 1e-3)
    assert inst.fmu.getBoolean([vr]) == [False]
    inst.free()


def test_nan_input_is_refused_with_a_message(md, unzipped):
    inst = Instance(md, unzipped).init(mode="voltage", u=24.0)
    for _ in range(5):
        inst.step(1e-3, 24.0)
    before = inst.outputs()
    with pytest.raises(FMICallException) as info:
        inst.step(1e-3, math.nan)
    assert info.value.status == 2  # fmi2Discard: pythonfmu 0.7 has no route to fmi2Error
    errors = [m for s, m in inst.messages if s == 3]
    assert len(errors) == 1 and "U_V = nan is not finite" in errors[0]
    assert inst.outputs() == before  # state untouched
    inst.t -= 1e-3
    after = inst.step(1e-3, 24.0)  # the instance stays usable
    inst.free()
    assert after[3] > before[3]


def test_non_positive_resistance_is_refused(md, unzipped):
    inst = Instance(md, unzipped).init(mode="voltage", u=24.0, R_ohm=0.0)
    assert any(s == 3 and "R_ohm must be > 0" in m for s, m in inst.messages)
    with pytest.raises(FMICallException):
        inst.step(1e-3, 24.0)
    # tunable: fixing R lets the simulation start
    inst.fmu.setReal([inst.vr["R_ohm"]], [12.0])
    inst.t = 0.0
    out = inst.step(1e-3, 24.0)
    inst.free()
    assert out[0] > 0.0


# -- build errors ----------------------------------------------------------------------------------
def test_build_errors(maps_dir, tmp_path):
    with pytest.raises(FmuBuildError, match="unknown FMU backend 'nope'"):
        F.build_fmu(maps_dir, tmp_path / "a.fmu", backend="nope")
    with pytest.raises(MapsError, match="not found"):
        F.build_fmu(tmp_path / "missing", tmp_path / "a.fmu")
    with pytest.raises(FmuBuildError, match=r"\.fmu"):
        F.build_fmu(maps_dir, tmp_path / "a.zip")
    assert not list(tmp_path.glob("*.fmu")) and not list(tmp_path.glob(".*"))


# -- command line ----------------------------------------------------------------------------------
def test_cli_export(maps_dir, tmp_path, capsys):
    out = tmp_path / "build" / "x.fmu"
    assert cli.main(["export", str(maps_dir), "-o", str(out), "--backend", "python"]) == 0
    assert out.is_file() and "no problems" in capsys.readouterr().out
    assert cli.main(["export", str(tmp_path / "nope"), "-o", str(out)]) == 1


def _measured(tab, kind, drive, n=400, h=2e-4):
    """A 'measured' recording made with model.py itself (same semantics as the playback)."""
    from solenoid_fmu.measure import make_recording

    t = h * np.arange(n)
    if drive == "voltage":
        u = np.where(t < 0.04, 24.0, 0.0)
        u[0] = 0.0
    else:
        u = np.minimum(10.0 * t, 1.5)
    model = M.SolenoidModel(tab, {"drive_mode": drive, "R_ohm": 12.5})
    model.initialize(u[0], X_M)
    i, U, f = [model.i_A], [model.U_V], [model.F_N]
    for k in range(n - 1):
        # the playback's hold rule: mean of the two voltage samples, or the current at the step's end
        model.step(h, 0.5 * (u[k] + u[k + 1]) if drive == "voltage" else u[k + 1], X_M)
        i.append(model.i_A)
        U.append(model.U_V)
        f.append(model.F_N)
    # the drive column holds the input samples themselves
    if drive == "voltage":
        U = u
    else:
        i = u
    return make_recording(kind, "synthetic", t, np.array(i), voltage_V=np.array(U), force_N=np.array(f),
                          position_m=X_M, coil_resistance_ohm=12.5, notes="made by model.py")


@pytest.mark.parametrize(("kind", "drive"), [("voltage_step", "voltage"), ("ramp", "current")])
def test_cli_simulate_reproduces_a_model_made_recording(fmu_path, tab, tmp_path, kind, drive):
    from solenoid_fmu.measure import read_recording, write_recording

    rec = _measured(tab, kind, drive)
    src = write_recording(tmp_path / "measured.csv", rec)
    out = tmp_path / "sim.csv"
    assert cli.main(["simulate", str(fmu_path), str(src), "-o", str(out)]) == 0
    sim = read_recording(out)
    assert sim.kind == kind and sim.header["drive_mode"] == drive
    assert sim.header["position_mm"] == rec.header["position_mm"]
    np.testing.assert_array_equal(sim.time_s, rec.time_s)
    for name in ("current_A", "voltage_V", "force_N"):
        np.testing.assert_allclose(getattr(sim, name), getattr(rec, name), rtol=1e-9, atol=1e-9)
    assert set(sim.extra) == {"psi_Wb", "i_eddy_A"}


def test_simulate_needs_a_voltage_column_for_voltage_drive(fmu_path, tab):
    from solenoid_fmu.measure import make_recording

    rec = _measured(tab, "ramp", "current")
    rec = make_recording("force_stroke", "synthetic", rec.time_s, rec.current_A, force_N=rec.force_N,
                         position_m=np.full(len(rec), X_M))
    with pytest.raises(FmuInputError, match="no voltage_V column"):
        F.simulate_recording(fmu_path, rec, drive="voltage")
    res = F.simulate_recording(fmu_path, rec)  # auto: current-driven
    assert res.drive_mode == "current" and res.recording.voltage_V is not None


# -- example ---------------------------------------------------------------------------------------
def test_example_ramp(maps_dir, tmp_path, tab):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
    try:
        import ex_fmu_ramp
    finally:
        sys.path.pop(0)
    res = ex_fmu_ramp.run(maps_dir, tmp_path, show_plot=False)
    assert res["fmu"].is_file()
    # the FMU's force is the map's force at its own flux and gap (paper eq. 3)
    assert res["F_peak_N"] == pytest.approx(tab.force_N(res["psi_peak_Wb"], res["x_m"]), rel=1e-9)
    # after the hold the eddy current has died out: the static map value at the held current
    assert res["F_hold_end_N"] == pytest.approx(tab.force_N(tab.psi_of_current(res["i_peak_A"], res["x_m"]),
                                                            res["x_m"]), rel=1e-6)
    # rising current induces a positive voltage on top of R i
    assert res["U_minus_Ri_rise_V"] > 0.0
    assert (tmp_path / "ex_fmu_ramp.png").is_file()
