"""Hostile but fair input to the FMUs (issue 13, FMU items): non-finite maps data, tampered FMU states,
unbounded sub-steps in the pythonfmu FMU, and fmpy's process-wide logger slot.

Every FMU is driven in a fresh process (as a host would): a crash fails the test instead of pytest.
"""

import json
import math
import subprocess
import sys
from pathlib import Path

import mapsfixture
import numpy as np
import pytest

from solenoid_fmu.errors import FmuBuildError, MapsError
from solenoid_fmu.fmu import build_fmu, c_sources
from solenoid_fmu.measure import make_recording, write_recording
from solenoid_fmu.realtime.model import load_tables

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def maps_dir(tmp_path_factory):
    return mapsfixture.write_maps(tmp_path_factory.mktemp("hostile_fmu") / "maps")


@pytest.fixture(scope="module")
def native(maps_dir, tmp_path_factory):
    return build_fmu(maps_dir, tmp_path_factory.mktemp("hostile_fmu_c") / "n.fmu", backend="c")


@pytest.fixture(scope="module")
def pythonfmu(maps_dir, tmp_path_factory):
    return build_fmu(maps_dir, tmp_path_factory.mktemp("hostile_fmu_py") / "p.fmu")


_HEAD = """
import gc, json, math, struct, sys, time
import fmpy

def slave(fmu, **values):
    md = fmpy.read_model_description(fmu)
    s = fmpy.instantiate_fmu(fmpy.extract(fmu), md, fmi_type="CoSimulation",  # fmpy's default callbacks
                             debug_logging=True)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    for name, value in values.items():
        (s.setInteger if name == "drive_mode" else s.setReal)([vr[name]], [value])
    s.exitInitializationMode()
    return s, vr

def call(f, *args):
    try:
        return "ok", f(*args)
    except Exception as exc:
        return str(exc), None

fmu = sys.argv[1]
out = {}
"""


def _run(script: str, *args) -> tuple[dict, str]:
    """Run ``_HEAD + script`` in a fresh Python (the worktree's package); its ``out`` dict and stdout."""
    proc = subprocess.run([sys.executable, "-c", _HEAD + script + '\nprint("RESULT " + json.dumps(out))',
                           *map(str, args)], capture_output=True, text=True, timeout=120, cwd=REPO)
    assert proc.returncode == 0, f"exit {proc.returncode}: {proc.stderr[-1500:]}"  # SIGSEGV is -11
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT "))
    return json.loads(line[len("RESULT "):]), proc.stdout


# -- numbers reaching generated C ------------------------------------------------------------------
def test_non_finite_maps_data_is_refused_naming_the_file_and_key(maps_dir, tmp_path):
    import shutil

    d = tmp_path / "inf"
    shutil.copytree(maps_dir, d)
    meta = json.loads((d / "maps.json").read_text())
    meta["effects"] = {"eddy_ladder": {"G_S": [0.01, float("inf")], "tau_s": [1e-3, 1e-2]}}
    (d / "maps.json").write_text(json.dumps(meta))  # Python writes the non-JSON token Infinity
    for backend in ("c", "python"):
        with pytest.raises(MapsError, match=r"maps\.json: effects\.eddy_ladder\.G_S\[1\] = inf is not a finite"):
            build_fmu(d, tmp_path / f"x_{backend}.fmu", backend=backend)
    assert not list(tmp_path.glob("*.fmu"))


def test_a_non_finite_table_value_never_reaches_generated_c(maps_dir, tmp_path):
    tab = load_tables(maps_dir)
    real = tab.tables()
    coef = np.array(real["i_f_coef"], dtype=float)
    coef.ravel()[13] = np.inf
    tab.tables = lambda: dict(real, i_f_coef=coef)  # as if the maps' cubics had overflowed
    with pytest.raises(FmuBuildError, match=r"i_f cell cubics\[13\] = inf is not finite \(1 such value"):
        c_sources.generate_sources(tab, tmp_path / "src")
    assert not (tmp_path / "src" / "solenoid_maps.h").exists()
    eff = load_tables(maps_dir)
    eff.meta["effects"] = {"hysteresis": {"thresholds": [1e-4], "weights": [2.0],
                                          "shape": {"b_nodes": [0.0, 0.1], "g_nodes": [1.0, float("nan")]}}}
    with pytest.raises(FmuBuildError, match=r"effects\.hysteresis: finite thresholds"):  # model.py's check
        c_sources.generate_sources(eff, tmp_path / "src2")
    with pytest.raises(FmuBuildError, match="not finite"):
        c_sources._c_double(float("-inf"))  # no HUGE_VAL fallback any more
    assert c_sources._c_double(0.1) == "0.1" and float(c_sources._c_double(1 / 3)) == 1 / 3


# -- fmpy's one logger slot --------------------------------------------------------------------------
_LOGGER = """
from solenoid_fmu.fmu import simulate_recording
simulate_recording(fmu, sys.argv[2])  # its logger callback must outlive it
gc.collect()
s, vr = slave(fmu, drive_mode=2, G_eddy_S=1e308, i_A=1.0, x_m=1.5e-3)
out["step"], _ = call(s.doStep, 0.0, 1e-3)  # logs an error through fmpy's logger proxy
out["psi"] = s.getReal([vr["psi_Wb"]])[0]
s.terminate(); s.freeInstance()
"""


def test_simulate_recording_leaves_no_dangling_fmpy_logger(native, tmp_path):
    t = np.arange(50) * 1e-3
    rec = write_recording(tmp_path / "r.csv", make_recording("flux", "X", t, np.full(50, 0.5), voltage_V=np.ones(50),
                                                           position_m=1.5e-3, coil_resistance_ohm=12.0))
    out, stdout = _run(_LOGGER, native, rec)  # before the fix: SIGSEGV (exit -11) inside fmi2DoStep
    assert "status 3" in out["step"] and math.isfinite(out["psi"])
    assert "[ERROR] doStep at t = 0 s: the state became non-finite" in stdout  # fmpy's own printer got it


def test_fmi2_callbacks_route_each_instance_to_its_own_log(native):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    from solenoid_fmu.fmu.callbacks import _LOG_SINKS, fmi2_callbacks, release_fmi2_callbacks

    md = read_model_description(str(native))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    logs, slaves = ([], []), []
    for k in range(2):
        cb = fmi2_callbacks(lambda st, cat, msg, k=k: logs[k].append((st, msg)))
        s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(native)), modelIdentifier="SolenoidFmu",
                      instanceName=f"i{k}")
        s.instantiate(callbacks=cb, loggingOn=True)
        slaves.append((s, cb))
    s0 = slaves[0][0]
    with pytest.raises(Exception, match="status 3"):
        s0.setReal([vr["R_ohm"]], [1.0]) or s0.setupExperiment(startTime=0.0) or s0.doStep(0.0, 1e-3)
    assert logs[0] and logs[0][-1][0] == 3 and "fmi2DoStep outside step mode" in logs[0][-1][1]
    assert logs[1] == []  # the other instance's log got nothing
    for s, cb in slaves:
        s.freeInstance()
        release_fmi2_callbacks(cb)
        assert cb.componentEnvironment not in _LOG_SINKS


# -- tampered native FMU state ------------------------------------------------------------------------
_STATE_C = """
s, vr = slave(fmu, drive_mode=1, U_V=12.0, x_m=1.5e-3)
s.doStep(0.0, 1e-3)
psi = s.getReal([vr["psi_Wb"]])[0]
good = bytes(s.serializeFMUstate(s.getFMUstate()))
inv = struct.pack("<d", 1.0 / 1e-4)   # inv_hsub of h_sub_max_s = 1e-4 (the default)
nan = struct.pack("<d", math.nan)
out["n_inv"] = good.count(inv)
out["n_psi"] = good.count(struct.pack("<d", psi))
cases = {"inv_hsub": good.replace(inv, struct.pack("<d", 1e300)),
         "psi_nan": good.replace(struct.pack("<d", psi), nan),
         "short": good[:-8]}
for name, data in cases.items():
    out[name], _ = call(s.deSerializeFMUstate, data)
out["same"] = s.getReal([vr["psi_Wb"]])[0] == psi
s.doStep(1e-3, 1e-3)
out["next"] = s.getReal([vr["psi_Wb"]])[0]
status, st = call(s.deSerializeFMUstate, good)
out["good"] = status
s.setFMUstate(st)
out["restored"] = s.getReal([vr["psi_Wb"]])[0] == psi
"""


def test_native_fmu_refuses_a_tampered_serialized_state(native):
    out, stdout = _run(_STATE_C, native)
    assert out["n_inv"] == 1 and out["n_psi"] >= 1  # the tampering hits what it means to
    for case in ("inv_hsub", "psi_nan", "short"):
        assert "status 3" in out[case], case  # fmi2Error, never OK, never a crash
    assert "not a valid state of this FMU (h_sub_max_s in use)" in stdout  # 1e300 sub-steps per second
    assert "not a valid state of this FMU (model state not finite)" in stdout
    assert out["same"] and out["next"] > 0.0 and out["good"] == "ok" and out["restored"]


# -- pythonfmu FMU: bounded sub-steps ----------------------------------------------------------------
_SUBSTEPS_PY = """
for case, (hsub, h) in {"tiny_hsub": (1e-300, 1e-3), "huge_h": (1e-4, 1e5)}.items():
    s, vr = slave(fmu, drive_mode=1, h_sub_max_s=hsub, U_V=12.0, x_m=1.5e-3)
    t0 = time.perf_counter()
    out[case], _ = call(s.doStep, 0.0, h)
    out[case + "_s"] = time.perf_counter() - t0
    out[case + "_psi"] = s.getReal([vr["psi_Wb"]])[0]
    if case == "huge_h":
        out["after"], _ = call(s.doStep, 0.0, 1e-3)  # the instance stays usable
        out["after_psi"] = s.getReal([vr["psi_Wb"]])[0]
    s.terminate(); s.freeInstance()
"""


def test_pythonfmu_refuses_unbounded_sub_steps_without_hanging(pythonfmu):
    out, stdout = _run(_SUBSTEPS_PY, pythonfmu)
    for case in ("tiny_hsub", "huge_h"):
        assert "status 2" in out[case] and out[case + "_s"] < 2.0, case  # fmi2Discard, in milliseconds
        assert out[case + "_psi"] == 0.0  # the state is kept (initialized at Psi0 = 0)
    assert "sub-steps" in stdout and out["after"] == "ok" and out["after_psi"] > 0.0
