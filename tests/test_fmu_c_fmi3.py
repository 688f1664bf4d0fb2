"""FMI 3.0 from the same generated C (``export --backend c --fmi 3``): validation, the FMI 2.0 variables,
results equal to the FMI 2.0 FMU in co-simulation and model exchange, both drive modes, every effect on;
FMU state; only fmi3 functions exported; sources/ build alone with CMake."""

from __future__ import annotations

import json
import shutil
import subprocess
import zipfile

import fmpy
import mapsfixture as mf
import numpy as np
import pytest
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu
from test_fmu_c import HOST_C
from test_fmu_c_effects import EFFECTS

from solenoid_fmu import cli
from solenoid_fmu import fmu as F
from solenoid_fmu.errors import FmuBuildError
from solenoid_fmu.fmu import native

pytestmark = pytest.mark.fmu

OUTS = ["i_out_A", "U_out_V", "F_N", "psi_Wb", "dpsi_dt_V", "i_eddy_A", "out_of_map"]
SWITCHES_ON = {"hysteresis_on": True, "eddy_ladder_on": True, "heating_on": True, "friction_on": True}
TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}


@pytest.fixture(scope="module")
def maps_dir(tmp_path_factory):
    return mf.write_maps(tmp_path_factory.mktemp("fmi3_maps") / "synthetic", G_eddy_S=0.02)


@pytest.fixture(scope="module")
def pair(maps_dir, tmp_path_factory):
    """(FMI 2.0 FMU, FMI 3.0 FMU) of the same maps."""
    d = tmp_path_factory.mktemp("fmi3")
    return (F.build_fmu(maps_dir, d / "s2.fmu", backend="c"),
            F.build_fmu(maps_dir, d / "s3.fmu", backend="c", fmi_version=3))


@pytest.fixture(scope="module")
def fx_pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("fmi3_fx")
    maps = mf.write_maps(d / "fx", G_eddy_S=0.01)
    meta = json.loads((maps / "maps.json").read_text())
    meta["effects"] = EFFECTS
    (maps / "maps.json").write_text(json.dumps(meta))
    return (F.build_fmu(maps, d / "fx2.fmu", backend="c"), F.build_fmu(maps, d / "fx3.fmu", backend="c", fmi_version=3))


def test_fmi3_fmu_validates_and_carries_the_fmi2_variables(pair):
    fmu2, fmu3 = pair
    assert validate_fmu(str(fmu3)) == [] and validate_fmu(str(fmu2)) == []
    md2, md3 = fmpy.read_model_description(str(fmu2)), fmpy.read_model_description(str(fmu3))
    assert md3.fmiVersion == "3.0" and md3.modelExchange is not None and md3.coSimulation is not None
    by_name = {v.name: v for v in md3.modelVariables}
    assert by_name.pop("time").causality == "independent"
    assert len(by_name) == len(md2.modelVariables) == 17
    for v2 in md2.modelVariables:
        v3 = by_name[v2.name]
        assert v3.type == TYPES[v2.type], v2.name
        for attr in ("valueReference", "description", "causality", "variability", "initial", "unit", "min",
                     "max", "start"):
            assert getattr(v3, attr) == getattr(v2, attr), (v2.name, attr)
    drive = by_name["drive_mode"]
    assert drive.type == "Int32" and (drive.min, drive.max) == ("1", "2")
    assert by_name["der(psi_state_Wb)"].derivative is by_name["psi_state_Wb"]
    assert [u.variable.name for u in md3.outputs] == [u.variable.name for u in md2.outputs]
    assert [[d.name for d in u.dependencies] for u in md3.outputs] == [[d.name for d in u.dependencies]
                                                                        for u in md2.outputs]
    assert "binaries x86_64-linux: " in md3.generationTool


def test_fmi3_binaries_export_only_fmi3_functions(pair, tmp_path):
    _, fmu3 = pair
    with zipfile.ZipFile(fmu3) as zf:
        names = set(zf.namelist())
        so = zf.extract(f"binaries/x86_64-linux/{F.MODEL_IDENTIFIER}.so", tmp_path)
    assert {"sources/solenoid_fmi3.c", "sources/solenoid_fmu.c", "sources/fmi3Functions.h",
            "sources/buildDescription.xml", "sources/CMakeLists.txt"} <= names
    if native.cross_compiler(native.WIN64) is not None:
        assert f"binaries/x86_64-windows/{F.MODEL_IDENTIFIER}.dll" in names
    nm = subprocess.run(["nm", "-D", "--defined-only", so], capture_output=True, text=True, timeout=60)
    symbols = {line.split()[-1] for line in nm.stdout.splitlines() if line.strip()}
    assert {"fmi3InstantiateCoSimulation", "fmi3InstantiateModelExchange", "fmi3DoStep",
            "fmi3GetContinuousStateDerivatives"} <= symbols
    assert [s for s in symbols if "fmi2" in s] == [] and len([s for s in symbols if s.startswith("fmi3")]) == 75


def _runs(fmu2, fmu3, fmi_type, start):
    kw = dict(fmi_type=fmi_type, stop_time=0.03, output_interval=1e-4, start_values=start, output=OUTS)
    return fmpy.simulate_fmu(str(fmu2), **kw), fmpy.simulate_fmu(str(fmu3), **kw)


@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
@pytest.mark.parametrize("start", [{"U_V": 24.0}, {"drive_mode": 2, "i_A": 1.5}], ids=["voltage", "current"])
def test_fmi3_results_equal_fmi2(pair, fmi_type, start):
    r2, r3 = _runs(*pair, fmi_type, start)
    assert len(r3) == len(r2) == 301 and r2["psi_Wb"][-1] > 0.05
    for name in OUTS:
        assert np.max(np.abs(r3[name].astype(float) - r2[name].astype(float))) <= 1e-12, name


@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
@pytest.mark.parametrize("start", [{"U_V": 24.0}, {"drive_mode": 2, "i_A": 1.5}], ids=["voltage", "current"])
def test_fmi3_results_equal_fmi2_with_every_effect_on(fx_pair, fmi_type, start):
    r2, r3 = _runs(*fx_pair, fmi_type, {**start, **SWITCHES_ON})
    assert r2["psi_Wb"][-1] > 0.05
    for name in OUTS:
        assert np.max(np.abs(r3[name].astype(float) - r2[name].astype(float))) <= 1e-12, name
    kw = dict(fmi_type=fmi_type, stop_time=0.03, output_interval=1e-4, start_values={**start, **SWITCHES_ON},
              output=["i_hyst_A", "T_rise_K"])
    e2, e3 = fmpy.simulate_fmu(str(fx_pair[0]), **kw), fmpy.simulate_fmu(str(fx_pair[1]), **kw)
    assert e3["T_rise_K"][-1] > 0.0 and np.max(np.abs(e3["i_hyst_A"])) > 0.0
    for name in ("i_hyst_A", "T_rise_K"):
        assert np.max(np.abs(e3[name] - e2[name])) <= 1e-12, name


def test_fmi3_state_round_trip_serialization_and_errors(pair):
    _, fmu3 = pair
    md = fmpy.read_model_description(str(fmu3))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unz = fmpy.extract(str(fmu3))
    messages = []
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=unz, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="s3")
    fmu.instantiate(loggingOn=True, logMessage=lambda env, status, cat, msg: messages.append((status, msg)))
    try:
        fmu.enterInitializationMode(startTime=0.0)
        fmu.setFloat64([vr["U_V"], vr["x_m"]], [24.0, 1e-3])
        fmu.exitInitializationMode()
        h, t = 1e-4, 0.0
        for _ in range(100):
            fmu.doStep(t, h)
            t += h
        state = fmu.getFMUState()
        blob = fmu.serializeFMUState(state)
        runs = []
        for _ in range(2):
            fmu.setFMUState(state)
            tt, out = t, []
            for _ in range(50):
                fmu.doStep(tt, h)
                tt += h
                out.append(fmu.getFloat64([vr["psi_Wb"], vr["F_N"], vr["time"]]))
            runs.append(out)
        assert runs[0] == runs[1] and runs[0][-1][0] != runs[0][0][0]
        assert runs[0][-1][2] == pytest.approx(t + 50 * h, abs=1e-12)   # the independent variable
        again = fmu.deserializeFMUState(blob)
        fmu.setFMUState(again)
        assert fmu.getFloat64([vr["psi_Wb"]]) != [runs[0][-1][0]]
        fmu.setFloat64([vr["U_V"]], [float("nan")])
        with pytest.raises(Exception, match="3|Error"):
            fmu.doStep(t, h)
        assert any("not finite" in str(m) for _, m in messages)
        fmu.freeFMUState(state)
        fmu.freeFMUState(again)
    finally:
        fmu.terminate()
        fmu.freeInstance()


def test_fmi3_sources_build_alone_with_cmake_and_give_the_same_run(pair, tmp_path):
    cmake = shutil.which("cmake")
    assert cmake, "cmake is needed to check the source FMU (Debian package cmake; make setup-system installs it)"
    _, fmu3 = pair
    unz = tmp_path / "fmu"
    with zipfile.ZipFile(fmu3) as zf:
        zf.extractall(unz)
    for cmd in ([cmake, "-S", str(unz / "sources"), "-B", str(tmp_path / "build"), "-DCMAKE_BUILD_TYPE=Release"],
                [cmake, "--build", str(tmp_path / "build")]):
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stdout + proc.stderr
    shipped = fmpy.simulate_fmu(str(fmu3), stop_time=0.02, output_interval=1e-4, start_values={"U_V": 24.0},
                                output=["psi_Wb", "F_N"])
    shutil.copyfile(tmp_path / "build" / f"{F.MODEL_IDENTIFIER}.so",
                    unz / "binaries" / "x86_64-linux" / f"{F.MODEL_IDENTIFIER}.so")
    rebuilt = fmpy.simulate_fmu(str(unz), stop_time=0.02, output_interval=1e-4, start_values={"U_V": 24.0},
                                output=["psi_Wb", "F_N"])
    assert rebuilt["psi_Wb"][-1] > 0.1
    np.testing.assert_array_equal(rebuilt["psi_Wb"], shipped["psi_Wb"])
    np.testing.assert_array_equal(rebuilt["F_N"], shipped["F_N"])


def test_cli_export_fmi3_and_refusals(maps_dir, tmp_path, capsys):
    out = tmp_path / "cli3.fmu"
    assert cli.main(["export", str(maps_dir), "-o", str(out), "--backend", "c", "--fmi", "3"]) == 0
    text = capsys.readouterr().out
    assert "FMI 3.0; fmpy validation: no problems" in text and "binaries: x86_64-linux" in text
    assert fmpy.read_model_description(str(out)).fmiVersion == "3.0"
    assert cli.main(["export", str(maps_dir), "-o", str(tmp_path / "p3.fmu"), "--fmi", "3"]) == 1
    assert "the python backend writes FMI 2, not 3; export --backend c for FMI 3" in capsys.readouterr().err
    with pytest.raises(FmuBuildError, match="writes FMI 2 or 3"):
        F.build_fmu(maps_dir, tmp_path / "x.fmu", backend="c", fmi_version=4)


def test_fmi3_c_host_long_runs_equal_the_fmi2_host_bit_for_bit(pair, tmp_path):
    """tests/c/host_fmi3.c (the long runs of host.c through the fmi3 functions) gives the digests of
    host.c on the FMI 2.0 binary: 2 x 20 000 cycles, every output bit equal, both drive modes."""
    fmu2, fmu3 = pair
    runs = {}
    so = f"{F.MODEL_IDENTIFIER}.so"
    for name, fmu, host_c, lib in (("fmi2", fmu2, HOST_C, f"linux64/{so}"),
                                   ("fmi3", fmu3, HOST_C.with_name("host_fmi3.c"), f"x86_64-linux/{so}")):
        unz = tmp_path / name
        with zipfile.ZipFile(fmu) as zf:
            zf.extractall(unz)
        exe = tmp_path / f"host_{name}"
        proc = subprocess.run([native.find_compiler(), "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror",
                               f"-I{unz}/sources", "-o", str(exe), str(host_c), "-ldl", "-lm"],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stderr
        token = fmpy.read_model_description(str(fmu)).guid
        args = [str(tmp_path / "ramp.csv"), "20000"] if name == "fmi2" else ["20000"]
        proc = subprocess.run([str(exe), str(unz / "binaries" / lib), token, *args], capture_output=True, text=True,
                              timeout=300)
        assert proc.returncode == 0 and proc.stdout.strip().endswith("ok all"), proc.stdout + proc.stderr
        runs[name] = sorted(line for line in proc.stdout.splitlines() if line.startswith("digest_"))
    assert len(runs["fmi3"]) == 2 and runs["fmi3"] == runs["fmi2"]
