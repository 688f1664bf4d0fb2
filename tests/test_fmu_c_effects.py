"""The native (generated C) FMU with the effect sub-models (issue 7) against model.py.

Co-simulation must agree with :class:`solenoid_fmu.model.SolenoidModel` to 1e-9 relative for each
effect alone and all four together, in both drive modes (current mode with and without G_eddy);
model exchange is checked pointwise (derivatives and outputs, 1e-9) and as a CVode run against
model.py with fine sub-steps (the hysteresis and friction states are updated at step events there,
so the tolerance reflects that discretisation).
"""

from __future__ import annotations

import ctypes
import json
import math
import subprocess
import zipfile

import fmpy
import mapsfixture as mf
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from test_fmu import Instance
from test_fmu_c import HOST_C, MeInstance, _rel_err, _run_host

from solenoid_fmu import fmu as F
from solenoid_fmu import fmu_c
from solenoid_fmu import model as M

pytestmark = pytest.mark.fmu

EFFECTS = {
    "hysteresis": {"thresholds": [0.01, 0.03, 0.06], "weights": [2.0, 1.0, 0.5],
                   "shape": {"b_nodes": [0.0, 0.2, 0.4], "g_nodes": [1.0, 1.5, 0.5]}},
    "eddy_ladder": {"G_S": [3e-3, 2e-3], "tau_s": [3e-4, 3e-3]},
    "heating": {"C_th_J_per_K": 0.5, "R_th_K_per_W": 50.0, "alpha_per_K": 0.00393},
    "friction": {"force_N": 2.5, "presliding_m": 2e-5},
}
SWITCHES = {"hysteresis": "hysteresis_on", "eddy_ladder": "eddy_ladder_on", "heating": "heating_on",
            "friction": "friction_on"}
OUTS_FX = ("i_out_A", "U_out_V", "F_N", "psi_Wb", "dpsi_dt_V", "i_eddy_A", "i_hyst_A", "T_rise_K")


@pytest.fixture(scope="module")
def fx_maps(tmp_path_factory):
    d = mf.write_maps(tmp_path_factory.mktemp("fmu_c_fx_maps") / "fx", G_eddy_S=0.01)
    meta = json.loads((d / "maps.json").read_text())
    meta["effects"] = EFFECTS
    (d / "maps.json").write_text(json.dumps(meta))
    return d


@pytest.fixture(scope="module")
def fx_tab(fx_maps):
    return M.load_tables(fx_maps)


@pytest.fixture(scope="module")
def fx_fmu(fx_maps, tmp_path_factory):
    return F.build_fmu(fx_maps, tmp_path_factory.mktemp("fmu_c_fx") / "fx.fmu", backend="c")


@pytest.fixture(scope="module")
def fx_md(fx_fmu):
    return fmpy.read_model_description(str(fx_fmu))


@pytest.fixture(scope="module")
def fx_unzipped(fx_fmu):
    return fmpy.extract(str(fx_fmu))


def _switches(on):
    return {SWITCHES[name]: name in on for name in SWITCHES}


def _cs_init(md, unzipped, mode, u0, x0, params, name="fx"):
    inst = Instance(md, unzipped, name)
    f, vr = inst.fmu, inst.vr
    f.setupExperiment(startTime=0.0)
    f.enterInitializationMode()
    f.setInteger([vr["drive_mode"]], [M.DRIVE_VOLTAGE if mode == "voltage" else M.DRIVE_CURRENT])
    for key, value in params.items():
        if isinstance(value, bool):
            f.setBoolean([vr[key]], [value])
        else:
            f.setReal([vr[key]], [value])
    f.setReal([vr["U_V" if mode == "voltage" else "i_A"], vr["x_m"]], [u0, x0])
    f.exitInitializationMode()
    inst.mode = mode
    return inst


def _inputs(mode, n=160, seed=5):
    """Variable steps, a drive that rises, reverses and falls, and a gap moving back and forth."""
    rng = np.random.default_rng(seed)
    hs = rng.uniform(3e-5, 1.2e-3, n)
    t = np.cumsum(hs)
    phase = np.sin(2 * np.pi * t / t[-1] * 1.5)
    u = (24.0 if mode == "voltage" else 1.6) * np.where(np.abs(phase) > 0.2, np.sign(phase), 0.0)
    if mode == "current":
        u = 1.6 * phase
    x = 1.2e-3 + 0.5e-3 * np.sin(2 * np.pi * t / t[-1] * 3.0)
    return hs, u, x


def _cs_pair(md, unzipped, tab, mode, params, seed=5):
    hs, u, x = _inputs(mode, seed=seed)
    inst = _cs_init(md, unzipped, mode, 0.0, x[0], params)
    got = [inst.fmu.getReal([inst.vr[k] for k in OUTS_FX])]
    t = 0.0
    for h, uk, xk in zip(hs, u, x, strict=True):
        inst.fmu.setReal([inst.vr["U_V" if mode == "voltage" else "i_A"], inst.vr["x_m"]], [uk, xk])
        inst.fmu.doStep(t, h)
        t += h
        got.append(inst.fmu.getReal([inst.vr[k] for k in OUTS_FX]))
    inst.free()
    model = M.SolenoidModel(tab, dict(params, drive_mode=mode))
    model.initialize(0.0, x[0])
    names = ("i_A", "U_V", "F_N", "psi_Wb", "dpsi_dt_V", "i_eddy_A", "i_hyst_A", "T_rise_K")
    ref = [[model.outputs()[k] for k in names]]
    t = 0.0
    for h, uk, xk in zip(hs, u, x, strict=True):
        model.step(h, uk, xk, t)
        t += h
        ref.append([model.outputs()[k] for k in names])
    return np.array(got), np.array(ref)


CASES = [(mode, G, fx) for mode, G in (("voltage", 0.01), ("current", 0.005), ("current", 0.0))
         for fx in (("hysteresis",), ("eddy_ladder",), ("heating",), ("friction",), tuple(EFFECTS), ())]


@pytest.mark.parametrize(("mode", "G", "on"), CASES)
def test_cs_with_effects_matches_model(fx_md, fx_unzipped, fx_tab, mode, G, on):
    got, ref = _cs_pair(fx_md, fx_unzipped, fx_tab, mode, dict(_switches(on), G_eddy_S=G))
    nonzero = np.max(np.abs(ref), axis=0) > 0.0
    assert _rel_err(got[:, nonzero], ref[:, nonzero]) <= 1e-9
    assert np.all(got[:, ~nonzero] == 0.0)
    # the effect is active: its signature output moves
    if "hysteresis" in on:
        assert np.max(np.abs(ref[:, 6])) > 0.01
    if "heating" in on:
        assert ref[-1, 7] > 0.1
    if "friction" in on:
        assert np.ptp(ref[:, 2] - np.array([fx_tab.force_N(p, 0.0) for p in ref[:, 3]])) > 0.0
