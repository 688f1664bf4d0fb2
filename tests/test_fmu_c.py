"""The native (generated C) FMU: description, CS and ME against model.py, a plain C host, valgrind."""

from __future__ import annotations

import ctypes
import math
import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy
import mapsfixture as mf
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Model
from lxml import etree
from test_fmu import OUTS, X_M, Instance, _measured, model_run, scenario

from solenoid_fmu import cli
from solenoid_fmu import fmu as F
from solenoid_fmu.fmu import c_sources
from solenoid_fmu.fmu import native as fmu_c
from solenoid_fmu.realtime import model as M

pytestmark = pytest.mark.fmu

HOST_C = Path(__file__).with_name("c") / "host.c"


@pytest.fixture(scope="module")
def maps_dir(tmp_path_factory):
    return mf.write_maps(tmp_path_factory.mktemp("fmu_c_maps") / "synthetic", G_eddy_S=0.02)


@pytest.fixture(scope="module")
def fmu_path(maps_dir, tmp_path_factory):
    """The native FMU, built once per module (and test worker)."""
    return F.build_fmu(maps_dir, tmp_path_factory.mktemp("fmu_c") / "synthetic.fmu", backend="c")


@pytest.fixture(scope="module")
def unzipped(fmu_path):
    return fmpy.extract(str(fmu_path))


@pytest.fixture(scope="module")
def md(fmu_path):
    return fmpy.read_model_description(str(fmu_path))


@pytest.fixture(scope="module")
def tab(maps_dir):
    return M.load_tables(maps_dir)


@pytest.fixture(scope="module")
def host(unzipped, tmp_path_factory):
    """tests/c/host.c compiled against the FMU's own headers (plain C, dlopen)."""
    exe = tmp_path_factory.mktemp("host") / "host"
    cmd = [fmu_c.find_compiler(), "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", f"-I{unzipped}/sources",
           "-o", str(exe), str(HOST_C), "-ldl", "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return exe


def _rel_err(got, ref):
    got, ref = np.asarray(got), np.asarray(ref)
    scale = np.maximum(np.max(np.abs(ref), axis=0), 1e-300)
    return float(np.max(np.abs(got - ref) / scale))


# -- the FMU file ----------------------------------------------------------------------------------
def test_validate_fmu_reports_no_problems(fmu_path):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmu_path)) == []


def test_model_description_has_both_interfaces_and_the_same_variables(md, fmu_path):
    assert md.coSimulation is not None and md.modelExchange is not None
    for iface in (md.coSimulation, md.modelExchange):
        assert iface.modelIdentifier == F.MODEL_IDENTIFIER
        assert iface.needsExecutionTool is False and iface.canGetAndSetFMUstate is True
        assert iface.canSerializeFMUstate is True
    assert md.coSimulation.canHandleVariableCommunicationStepSize is True
    names = [v.name for v in md.modelVariables]
    assert names[:len(F.VARIABLES)] == [v.name for v in F.VARIABLES]
    assert names[len(F.VARIABLES):] == ["psi_state_Wb", "der(psi_state_Wb)"]
    for k, (v, spec) in enumerate(zip(md.modelVariables, F.VARIABLES, strict=False)):
        assert v.valueReference == k and v.causality == spec.causality and v.unit == spec.unit
    # one continuous state with its derivative
    assert [d.variable.name for d in md.derivatives] == ["der(psi_state_Wb)"]
    assert md.derivatives[0].variable.derivative.name == "psi_state_Wb"
    with zipfile.ZipFile(fmu_path) as zf:
        files = set(zf.namelist())
        root = etree.fromstring(zf.read("modelDescription.xml"))
        doc = zf.read("documentation/index.html").decode()
    assert {"binaries/linux64/SolenoidFmu.so", "sources/solenoid_fmu.c", "sources/solenoid_maps.h",
            "sources/fmi2Functions.h", "sources/CMakeLists.txt", "resources/maps.npz"} <= files
    for tag in ("ModelExchange", "CoSimulation"):
        assert [f.get("name") for f in root.find(tag).find("SourceFiles")] == ["solenoid_fmu.c"]
    assert "c backend" in root.get("generationTool")
    assert "Native FMU" in doc and "Python 3 interpreter" not in doc


def test_c_definitions_are_generated_from_model_py(unzipped):
    """solenoid_model.h carries model.py's constants and state lists and the interface's value references, and
    solenoid_maps.h a default for every model parameter: C and Python are equal by construction."""
    import re

    header = (Path(unzipped) / "sources" / "solenoid_model.h").read_text()
    enums = [[item.split("=")[0].strip() for item in body.split(",") if item.strip()]
             for body in re.findall(r"enum \{(.*?)\};", header, re.S)]
    assert enums[0] == [f"ST_{n.upper()}" for n in M.STATE_NAMES] + ["N_STATE"]
    assert enums[1] == [f"FX_{n.upper()}" for n in M.EFFECT_STATE_NAMES] + ["FX_LAD"]
    assert enums[2] == [f"VR_{v.name.upper()}" for v in F.VARIABLES + F.EFFECT_VARIABLES]
    for line in (f"#define ROS2_GAMMA {M.ROS2_GAMMA!r}", f"#define NEWTON_MAX_ITER {M.NEWTON_MAX_ITER}",
                 f"#define STATE_LAYOUT {M.STATE_LAYOUT}", f"#define SOL_N_PARAMS {len(M.DEFAULT_PARAMS)}",
                 f"#define DRIVE_CURRENT {M.DRIVE_CURRENT}", f"#define MAX_SUBSTEPS {M.MAX_SUBSTEPS!r}"):
        assert line in header, line
    maps_h = (Path(unzipped) / "sources" / "solenoid_maps.h").read_text()
    assert all(f"SOL_{name.upper()}_DEFAULT" in maps_h for name in M.DEFAULT_PARAMS)


def test_cs_only_interface_has_no_direct_feedthrough(maps_dir, fmu_path, md, tmp_path, capsys):
    """export --backend c --interface cs (issue 14): co-simulation only, no output depends on an input (FMI 2.0
    has one ModelStructure; the ME dependencies made OMSimulator report algebraic loops in co-simulation);
    fmpy validation is clean and the binary runs the same co-simulation as the cs+me FMU."""
    from fmpy.validation import validate_fmu

    from solenoid_fmu.errors import FmuBuildError

    cs_path = tmp_path / "cs.fmu"
    assert cli.main(["export", str(maps_dir), "-o", str(cs_path), "--backend", "c", "--interface", "cs"]) == 0
    assert "interface cs" in capsys.readouterr().out
    assert validate_fmu(str(cs_path)) == []
    cs = fmpy.read_model_description(str(cs_path))
    assert cs.modelExchange is None and cs.coSimulation.modelIdentifier == F.MODEL_IDENTIFIER
    assert [v.name for v in cs.modelVariables] == [v.name for v in F.VARIABLES]
    assert {u.variable.name for u in cs.outputs} == {v.name for v in F.VARIABLES if v.causality == "output"}
    assert all(u.dependencies == [] for u in cs.outputs)
    assert any(u.dependencies for u in md.outputs)  # the default cs+me FMU declares the ME dependencies
    kw = dict(stop_time=0.02, output_interval=1e-3, start_values={"U_V": 24.0}, output=["psi_Wb", "F_N"],
              fmi_type="CoSimulation")
    got, ref = fmpy.simulate_fmu(str(cs_path), **kw), fmpy.simulate_fmu(str(fmu_path), **kw)
    np.testing.assert_array_equal(got["psi_Wb"], ref["psi_Wb"])
    np.testing.assert_array_equal(got["F_N"], ref["F_N"])
    with pytest.raises(FmuBuildError, match="offers interface cs"):
        F.build_fmu(maps_dir, tmp_path / "p.fmu", backend="python", interface="cs+me")


def test_sources_build_with_cmake_and_run_the_c_host_like_the_shipped_binary(fmu_path, host, md, tmp_path):
    """Unpack the FMU, build sources/ alone with CMake into a shared library (what Dymola, OMSimulator or
    a macOS/aarch64 user does with a source FMU) and run the C host on it: every check passes and the
    results equal the shipped binary's bit for bit (ramp, 2 x 20 000 long-run steps)."""
    cmake = shutil.which("cmake")
    assert cmake, "cmake is needed to check the source FMU (Debian package cmake; make setup-system installs it)"
    unz = tmp_path / "fmu"
    with zipfile.ZipFile(fmu_path) as zf:
        zf.extractall(unz)
    build = tmp_path / "build"
    for cmd in ([cmake, "-S", str(unz / "sources"), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release"],
                [cmake, "--build", str(build)]):
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stdout + proc.stderr
    built = build / f"{F.MODEL_IDENTIFIER}.so"
    lib = ctypes.CDLL(str(built))
    lib.fmi2GetVersion.restype = ctypes.c_char_p
    assert lib.fmi2GetVersion() == b"2.0"
    runs = {}
    for name, so in (("cmake", built), ("shipped", unz / "binaries" / "linux64" / built.name)):
        csv = tmp_path / f"{name}.csv"
        proc = subprocess.run([str(host), str(so), md.guid, str(csv), "20000"], capture_output=True, text=True,
                              timeout=300)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        lines = proc.stdout.strip().splitlines()
        assert lines[-1] == "ok all" and "ok long_run 20000 steps" in lines
        runs[name] = (csv.read_bytes(), [line for line in lines if line.startswith("digest_")])
    assert len(runs["cmake"][1]) == 2 and runs["cmake"] == runs["shipped"]


def test_source_fmu_builds_with_fmpy_and_gives_the_same_results(fmu_path, tmp_path):
    """Without binaries/, fmpy.build (fmpy >= 0.3.26) compiles sources/ into an FMU that gives the same run."""
    from fmpy.build import build_platform_binary

    src = tmp_path / "src_only"
    with zipfile.ZipFile(fmu_path) as zf:
        for name in zf.namelist():
            if not name.startswith("binaries/"):
                zf.extract(name, src)
    (tmp_path / "build").mkdir()
    build_platform_binary(src, build_dir=tmp_path / "build")
    assert (src / "binaries" / "linux64" / f"{F.MODEL_IDENTIFIER}.so").is_file()
    kw = dict(stop_time=0.02, output_interval=1e-3, start_values={"U_V": 24.0}, output=["psi_Wb", "F_N"])
    rebuilt = fmpy.simulate_fmu(str(src), **kw)
    shipped = fmpy.simulate_fmu(str(fmu_path), **kw)
    assert rebuilt["psi_Wb"][-1] > 0.1
    np.testing.assert_array_equal(rebuilt["psi_Wb"], shipped["psi_Wb"])
    np.testing.assert_array_equal(rebuilt["F_N"], shipped["F_N"])


# -- co-simulation against model.py ----------------------------------------------------------------
def test_cs_voltage_mode_matches_model_with_excursion(md, unzipped, tab):
    inputs = scenario()
    inst = Instance(md, unzipped).init(mode="voltage", u=0.0, x=0.3e-3)
    got = [inst.outputs()] + [inst.step(1e-4, u, x) for u, x in inputs]
    inst.free()
    ref = model_run(tab, "voltage", {}, 0.0, 0.3e-3, inputs, 1e-4)
    assert _rel_err(got, ref) <= 1e-9
    assert ref[-1, 3] != ref[0, 3]
    warnings = [m for s, m in inst.messages if s == 1]
    assert len(warnings) == 1 and "x_m = 0.00351333 m is outside" in warnings[0]


@pytest.mark.parametrize("G", [0.005, 0.0])
def test_cs_current_mode_matches_model_with_variable_steps(md, unzipped, tab, G):
    """Any step size the importer chooses: random h, the integrator covers exactly [t, t + h]."""
    rng = np.random.default_rng(3)
    hs = rng.uniform(2e-5, 2.5e-3, 120)
    t = np.cumsum(hs)
    i_in = np.minimum(10.0 * t, 1.8)
    inst = Instance(md, unzipped).init(mode="current", u=0.0, G_eddy_S=G)
    got = [inst.outputs()] + [inst.step(h, u) for h, u in zip(hs, i_in, strict=True)]
    inst.free()
    model = M.SolenoidModel(tab, {"drive_mode": "current", "G_eddy_S": G})
    model.initialize(0.0, X_M)
    ref = [[model.i_A, model.U_V, model.F_N, model.psi_Wb, model.dpsi_dt_V, model.i_eddy_A]]
    tk = 0.0
    for h, u in zip(hs, i_in, strict=True):
        model.step(h, u, X_M, tk)
        tk += h
        ref.append([model.i_A, model.U_V, model.F_N, model.psi_Wb, model.dpsi_dt_V, model.i_eddy_A])
    if G == 0.0:  # i_eddy is identically zero
        assert np.all(np.asarray(got)[:, 5] == 0.0)
        got, ref = np.asarray(got)[:, :5], np.asarray(ref)[:, :5]
    assert _rel_err(got, ref) <= 1e-9
    assert np.asarray(ref)[-1, 3] > 0.1


def test_fmu_state_round_trip_and_serialization(md, unzipped):
    inst = Instance(md, unzipped).init(mode="voltage", u=24.0)
    for _ in range(20):
        inst.step(1e-3, 24.0)
    t_saved = inst.t
    state = inst.fmu.getFMUstate()
    ahead = [inst.step(1e-3, 24.0 if k < 5 else 0.0) for k in range(10)]
    inst.fmu.setFMUstate(state)
    inst.t = t_saved
    assert [inst.step(1e-3, 24.0 if k < 5 else 0.0) for k in range(10)] == ahead
    blob = inst.fmu.serializeFMUstate(state)
    inst.fmu.freeFMUstate(state)
    other = Instance(md, unzipped, "other").init(mode="voltage", u=0.0)
    restored = other.fmu.deSerializeFMUstate(blob)
    other.fmu.setFMUstate(restored)
    other.mode, other.t = "voltage", t_saved
    third = [other.step(1e-3, 24.0 if k < 5 else 0.0) for k in range(10)]
    other.fmu.freeFMUstate(restored)
    with pytest.raises(FMICallException):
        other.fmu.deSerializeFMUstate(b"x" * len(blob))
    other.free()
    inst.free()
    assert third == ahead and ahead[-1][3] != ahead[0][3]


def test_nan_input_returns_error_and_keeps_the_state(md, unzipped):
    inst = Instance(md, unzipped).init(mode="voltage", u=24.0)
    for _ in range(5):
        inst.step(1e-3, 24.0)
    before = inst.outputs()
    with pytest.raises(FMICallException) as info:
        inst.step(1e-3, math.nan)
    assert info.value.status == 3  # fmi2Error
    errors = [m for s, m in inst.messages if s == 3]
    assert len(errors) == 1 and "U_V = nan is not finite" in errors[0]
    assert inst.outputs() == before
    inst.t -= 1e-3
    after = inst.step(1e-3, 24.0)
    inst.free()
    assert after[3] > before[3]


def test_non_positive_resistance_is_refused(md, unzipped):
    inst = Instance(md, unzipped)
    f, vr = inst.fmu, inst.vr
    f.setupExperiment(startTime=0.0)
    f.enterInitializationMode()
    f.setReal([vr["R_ohm"]], [0.0])
    with pytest.raises(FMICallException) as info:
        f.exitInitializationMode()
    assert info.value.status == 3
    assert any(s == 3 and "R_ohm must be > 0 ohm" in m for s, m in inst.messages)
    f.setReal([vr["R_ohm"]], [12.0])  # tunable: fixing R lets the simulation start
    inst.mode = "voltage"
    out = inst.step(1e-3, 24.0)
    with pytest.raises(FMICallException):  # fixed parameters cannot change after initialization
        f.setReal([vr["h_sub_max_s"]], [1e-5])
    inst.free()
    assert out[0] > 0.0


def test_simulate_recording_runs_the_native_fmu(fmu_path, tab, tmp_path):
    from solenoid_fmu.measure import read_recording, write_recording

    rec = _measured(tab, "ramp", "current")
    src = write_recording(tmp_path / "measured.csv", rec)
    out = tmp_path / "sim.csv"
    assert cli.main(["simulate", str(fmu_path), str(src), "-o", str(out)]) == 0
    sim = read_recording(out)
    for name in ("current_A", "voltage_V", "force_N"):
        np.testing.assert_allclose(getattr(sim, name), getattr(rec, name), rtol=1e-9, atol=1e-9)


def test_cli_export_backend_c(maps_dir, tmp_path, capsys):
    out = tmp_path / "x.fmu"
    assert cli.main(["export", str(maps_dir), "-o", str(out), "--backend", "c"]) == 0
    assert out.is_file() and "backend c" in capsys.readouterr().out


# -- model exchange --------------------------------------------------------------------------------
class MeInstance:
    """An fmpy FMU2Model in continuous-time mode, driven by hand."""

    def __init__(self, md, unzipped, mode, u, x, **params):
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.messages = []

        # the package's process-wide logger: a per-instance ctypes logger would leave fmpy's one logger
        # slot dangling after the instance is freed (the next FMU message anywhere would crash)
        cb = F.fmi2_callbacks(lambda status, category, message: self.messages.append((status, message)))
        self._cb = cb
        self.mode = mode
        f = self.fmu = FMU2Model(guid=md.guid, unzipDirectory=unzipped,
                                 modelIdentifier=md.modelExchange.modelIdentifier, instanceName="me")
        f.instantiate(callbacks=cb, loggingOn=True)
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        f.setInteger([self.vr["drive_mode"]], [M.DRIVE_VOLTAGE if mode == "voltage" else M.DRIVE_CURRENT])
        for name, value in params.items():
            f.setReal([self.vr[name]], [value])
        self.set_inputs(u, x)
        f.exitInitializationMode()
        f.newDiscreteStates()
        f.enterContinuousTimeMode()

    def set_inputs(self, u, x):
        self.fmu.setReal([self.vr["U_V" if self.mode == "voltage" else "i_A"], self.vr["x_m"]], [u, x])

    def eval(self, psi):
        x = (ctypes.c_double * 1)(psi)
        self.fmu.setContinuousStates(x, 1)
        dx = (ctypes.c_double * 1)()
        self.fmu.getDerivatives(dx, 1)
        return [dx[0]] + self.fmu.getReal([self.vr[k] for k in OUTS])

    def free(self):
        self.fmu.terminate()
        self.fmu.freeInstance()
        F.release_fmi2_callbacks(self._cb)


def _me_reference(tab, mode, R, G, psi, u, x):
    """Paper eqs. (1)-(3) solved for dPsi/dt at (Psi, u, x) with model.py's lookups."""
    j, w, _ = tab.x_cell(x)
    pm = tab.psi_max_Wb
    if mode == "current" and G == 0.0:
        p = tab.psi_of_current(u, x)
        i_f, force = tab.i_f_and_force(p, j, w)
        return [0.0, u, R * u, force, p, 0.0, 0.0]
    p = min(max(psi, -pm), pm)
    i_f, force = tab.i_f_and_force(p, j, w)
    if mode == "voltage":
        dpsi = (u - R * i_f) / (1.0 + R * G)
        i, U = i_f + G * dpsi, u
    else:
        dpsi = (u - i_f) / G
        i, U = u, R * u + dpsi
    der = 0.0 if abs(psi) >= pm and dpsi * psi > 0.0 else dpsi
    return [der, i, U, force, p, dpsi, G * dpsi]


@pytest.mark.parametrize(("mode", "G"), [("voltage", 0.02), ("current", 0.005), ("current", 0.0)])
def test_me_derivatives_and_outputs_match_model(md, unzipped, tab, mode, G):
    """On states and inputs across the map (and beyond it), ME agrees with model.py to 1e-9."""
    rng = np.random.default_rng(7)
    pm = tab.psi_max_Wb
    psis = rng.uniform(-1.05 * pm, 1.05 * pm, 200)
    xs = rng.uniform(0.1e-3, 3.8e-3, 200)
    us = rng.uniform(-30.0, 30.0, 200) if mode == "voltage" else rng.uniform(-2.2, 2.2, 200)
    inst = MeInstance(md, unzipped, mode, 0.0, X_M, G_eddy_S=G)
    got, ref = [], []
    for psi, u, x in zip(psis, us, xs, strict=True):
        inst.set_inputs(u, x)
        got.append(inst.eval(psi))
        ref.append(_me_reference(tab, mode, mf.R_OHM, G, psi, u, x))
    inst.free()
    got, ref = np.array(got), np.array(ref)
    nonzero = np.max(np.abs(ref), axis=0) > 0.0
    assert _rel_err(got[:, nonzero], ref[:, nonzero]) <= 1e-9
    assert np.all(got[:, ~nonzero] == 0.0)


@pytest.mark.parametrize(("mode", "u", "G"), [("voltage", 24.0, 0.02), ("current", 1.2, 0.005)])
def test_me_with_cvode_converges_to_the_model(fmu_path, tab, mode, u, G):
    """fmpy integrates the ME interface (CVode, rtol 1e-10): the same trajectory as model.py with tiny sub-steps."""
    name = "U_V" if mode == "voltage" else "i_A"
    sig = np.array([(0.0, u, X_M), (0.03, u, X_M)], dtype=[("time", float), (name, float), ("x_m", float)])
    res = fmpy.simulate_fmu(str(fmu_path), fmi_type="ModelExchange", stop_time=0.03, output_interval=1e-3,
                            relative_tolerance=1e-10, input=sig,
                            start_values={"drive_mode": 1 if mode == "voltage" else 2, "G_eddy_S": G},
                            output=["psi_Wb", "i_out_A", "F_N"])
    model = M.SolenoidModel(tab, {"drive_mode": mode, "G_eddy_S": G, "h_sub_max_s": 2e-7})
    model.initialize(u, X_M)
    ref = [[model.psi_Wb, model.i_A, model.F_N]]
    for _ in range(30):
        model.step(1e-3, u, X_M)
        ref.append([model.psi_Wb, model.i_A, model.F_N])
    got = np.column_stack([res["psi_Wb"], res["i_out_A"], res["F_N"]])
    assert got.shape == (31, 3)
    err = _rel_err(got, ref)
    print(f"ME (CVode) vs model.py: max relative error {err:.3g}")
    assert err <= 1e-6
    assert ref[-1][0] > 0.1


# -- the plain C host and valgrind -----------------------------------------------------------------
def _run_host(host, unzipped, md, csv, n_long, prefix=(), suffix=()):
    lib = Path(unzipped) / "binaries" / "linux64" / f"{F.MODEL_IDENTIFIER}.so"
    proc = subprocess.run([*prefix, str(host), str(lib), md.guid, str(csv), str(n_long), *suffix],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "ok all"
    return proc


def test_c_host_ramp_instances_reset_state_and_a_million_steps(host, unzipped, md, tab, tmp_path):
    proc = _run_host(host, unzipped, md, tmp_path / "ramp.csv", 1_000_000)
    for check in ("ramp", "two_instances", "reset", "state", "nan", "long_run 1000000 steps"):
        assert f"ok {check}" in proc.stdout
    got = np.loadtxt(tmp_path / "ramp.csv", delimiter=",", skiprows=1)
    inputs = [(10.0 * 1e-4 * (k + 1), X_M) for k in range(2000)]
    ref = model_run(tab, "current", {}, 0.0, X_M, inputs, 1e-4)
    np.testing.assert_allclose(got[:, 0], 1e-4 * np.arange(2001), rtol=1e-12)
    assert _rel_err(got[:, 1:], ref) <= 1e-9
    assert ref[-1, 0] == pytest.approx(2.0) and ref[-1, 2] > 1.0  # the ramp reached 2 A, the force rose


def test_c_host_runs_clean_under_valgrind(host, unzipped, md, tmp_path):
    valgrind = shutil.which("valgrind")
    assert valgrind, "valgrind is on PATH here and in CI"
    proc = _run_host(host, unzipped, md, tmp_path / "ramp.csv", 20_000,
                     prefix=(valgrind, "-q", "--error-exitcode=1", "--leak-check=full",
                             "--errors-for-leak-kinds=definite,indirect,possible"))
    assert "Invalid read" not in proc.stderr and "definitely lost" not in proc.stderr


def test_build_refuses_a_model_with_states_the_c_code_lacks(maps_dir, tmp_path, monkeypatch):
    """When model.py gains effects (new states), the native export stops instead of exporting the old model."""
    from solenoid_fmu.errors import FmuBuildError

    monkeypatch.setattr(c_sources, "STATE_NAMES", (*M.STATE_NAMES, "hysteresis_state"))
    monkeypatch.setattr(c_sources, "STATE_LAYOUT", M.STATE_LAYOUT + 1)
    with pytest.raises(FmuBuildError, match="Port the new effects"):
        F.build_fmu(maps_dir, tmp_path / "x.fmu", backend="c")
    assert not list(tmp_path.glob("*.fmu"))


def test_gap_excursion_logged_once_per_excursion_and_flagged(md, unzipped):
    inst = Instance(md, unzipped).init(mode="current", u=1.0, G_eddy_S=0.0)
    flags = []
    for x in (2e-3, 4e-3, 5e-3, 6e-3, 2e-3, 2e-3, 0.1e-3, 0.05e-3, 1e-3):
        inst.step(1e-3, 1.0, x)
        flags.append(inst.fmu.getBoolean([inst.vr["out_of_map"]])[0])
    inst.free()
    warnings = [m for s, m in inst.messages if s == 1]
    assert len(warnings) == 2
    assert "x_m = 0.004 m is outside" in warnings[0] and "x_m = 0.0001 m is outside" in warnings[1]
    assert flags == [False, True, True, True, False, False, True, True, False]


def test_work_per_step_is_bounded(md, unzipped):
    """A step that would need more than 1e7 sub-steps is refused (real time: bounded work per doStep)."""
    inst = Instance(md, unzipped).init(mode="voltage", u=24.0)
    before = inst.outputs()
    with pytest.raises(FMICallException) as info:
        inst.step(1e4, 24.0)
    assert info.value.status == 3 and inst.outputs() == before
    assert any(s == 3 and "sub-steps" in m for s, m in inst.messages)
    inst.t = 0.0
    out = inst.step(0.5, 24.0)  # 5000 sub-steps: fine
    inst.free()
    assert out[3] > before[3]


def test_me_refuses_nan_and_logs_excursions_at_accepted_steps(md, unzipped):
    inst = MeInstance(md, unzipped, "voltage", 0.0, X_M)
    inst.set_inputs(24.0, 5e-3)  # beyond the map's 3.5 mm
    inst.eval(0.1)
    assert not [m for s, m in inst.messages if s == 1]  # trial evaluations log nothing
    inst.fmu.completedIntegratorStep()
    inst.fmu.completedIntegratorStep()
    assert inst.fmu.getBoolean([inst.vr["out_of_map"]]) == [True]
    warnings = [m for s, m in inst.messages if s == 1]
    assert len(warnings) == 1 and "x_m = 0.005 m is outside" in warnings[0]
    inst.set_inputs(math.nan, X_M)
    with pytest.raises(FMICallException) as info:
        inst.eval(0.1)
    assert info.value.status == 3
    assert any(s == 3 and "U_V = nan is not finite" in m for s, m in inst.messages)
    inst.set_inputs(24.0, X_M)
    assert inst.eval(0.1)[0] > 0.0  # usable again once the input is fixed
    inst.free()
