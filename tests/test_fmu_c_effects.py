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


# -- model exchange --------------------------------------------------------------------------------
class MeFx(MeInstance):
    """Model exchange of the effects FMU: all continuous states set at once."""

    def __init__(self, md, unzipped, mode, u, x, switches, **params):
        self._switches = switches
        self.nx = len(md.derivatives)
        super().__init__(md, unzipped, mode, u, x, **params)

    def set_inputs(self, u, x):
        if self._switches is not None:  # before the first initialization: the switches too
            self.fmu.setBoolean([self.vr[k] for k in self._switches], list(self._switches.values()))
            self._switches = None
        super().set_inputs(u, x)

    def eval(self, states):
        xs = (ctypes.c_double * self.nx)(*states)
        self.fmu.setContinuousStates(xs, self.nx)
        dx = (ctypes.c_double * self.nx)()
        self.fmu.getDerivatives(dx, self.nx)
        return list(dx) + self.fmu.getReal([self.vr[k] for k in OUTS_FX])


def _me_fx_reference(tab, mode, G, on, states, u, x, x0):
    """Paper eqs. (1)-(3) with the effects at the states, with model.py's lookups and play operator;
    the hysteresis and friction memories are those committed at the start (Psi = 0, x = x0)."""
    lad, heat = EFFECTS["eddy_ladder"], EFFECTS["heating"]
    psi, ik, T = states[0], list(states[1:3]), states[3]
    nl = 2 if "eddy_ladder" in on else 0
    T = T if "heating" in on else 0.0
    R = mf.R_OHM * (1.0 + heat["alpha_per_K"] * T) if "heating" in on else mf.R_OHM
    j, w, _ = tab.x_cell(x)
    pm = tab.psi_max_Wb
    p = min(max(psi, -pm), pm)
    i_f, force = tab.i_f_and_force(p, j, w)
    sik = sum(ik[:nl])
    ih = 0.0
    if "hysteresis" in on:
        hy = M._effects_data(tab)["hysteresis"]
        ih = M._play_step([0.0] * len(hy["r"]), hy["r"], hy["w"], hy["gb"], hy["gg"], p)
    if "friction" in on and x != x0:
        target = math.copysign(EFFECTS["friction"]["force_N"], x - x0)
        force += target + (0.0 - target) * math.exp(-abs(x - x0) / EFFECTS["friction"]["presliding_m"])
    if mode == "voltage":
        e = (u - R * (i_f + ih + sik)) / (1.0 + R * G)
        i, U = i_f + ih + G * e + sik, u
    else:
        e = (u - i_f - ih - sik) / G
        i, U = u, R * u + e
    der = [0.0 if abs(psi) >= pm and e * psi > 0.0 else e]
    der += [(lad["G_S"][k] * e - ik[k]) / lad["tau_s"][k] if k < nl else 0.0 for k in range(2)]
    der += [(R * i * i - T / heat["R_th_K_per_W"]) / heat["C_th_J_per_K"] if "heating" in on else 0.0]
    return der + [i, U, force, p, e, G * e + sik, ih, T]


@pytest.mark.parametrize(("mode", "G", "on"), [("voltage", 0.01, tuple(EFFECTS)),
                                               ("current", 0.005, tuple(EFFECTS)),
                                               ("voltage", 0.0, ("heating", "friction"))])
def test_me_with_effects_derivatives_and_outputs_match(fx_md, fx_unzipped, fx_tab, mode, G, on):
    """Pointwise: derivatives of Psi, ladder currents and temperature, and the outputs, to 1e-9."""
    assert [v.name for v in fx_md.modelVariables][len(F.VARIABLES) + len(F.EFFECT_VARIABLES):][:4] == [
        "psi_state_Wb", "ladder_state_0_A", "ladder_state_1_A", "T_state_K"]
    rng = np.random.default_rng(11)
    pm = fx_tab.psi_max_Wb
    n = 150
    states = np.column_stack([rng.uniform(-1.05 * pm, 1.05 * pm, n), rng.uniform(-0.3, 0.3, (n, 2)),
                              rng.uniform(0.0, 60.0, n)])
    xs = rng.uniform(0.2e-3, 3.4e-3, n)
    us = rng.uniform(-30.0, 30.0, n) if mode == "voltage" else rng.uniform(-2.0, 2.0, n)
    inst = MeFx(fx_md, fx_unzipped, mode, 0.0, 1e-3, _switches(on), G_eddy_S=G)
    got, ref = [], []
    for st, u, x in zip(states, us, xs, strict=True):
        inst.set_inputs(u, x)
        got.append(inst.eval(st))
        ref.append(_me_fx_reference(fx_tab, mode, G, on, st, u, x, 1e-3))
    inst.free()
    got, ref = np.array(got), np.array(ref)
    nonzero = np.max(np.abs(ref), axis=0) > 0.0
    assert _rel_err(got[:, nonzero], ref[:, nonzero]) <= 1e-9
    assert np.all(got[:, ~nonzero] == 0.0)
    assert nonzero[1] == ("eddy_ladder" in on) and nonzero[3] == ("heating" in on)
    assert nonzero[4 + OUTS_FX.index("i_hyst_A")] == ("hysteresis" in on)


ME_TOL = 5e-3


@pytest.mark.parametrize(("mode", "u", "G"), [("voltage", 24.0, 0.01), ("current", 1.5, 0.005)])
def test_me_with_all_effects_and_cvode_follows_the_model(fx_fmu, fx_tab, mode, u, G):
    """CVode (rtol 1e-9) through the ME interface, all effects on, against model.py with 1 us sub-steps.

    The ME FMU moves the play operators (and the friction memory) from their state committed at the last
    accepted step, model.py after every sub-step; the heating uses the instantaneous current, model.py
    the sub-step mean; ME inputs (x) are interpolated, model.py holds them. Tolerance ME_TOL relative to
    the largest value of each signal. In current mode U_out_V is a step mean in model.py and
    instantaneous in ME, so it is not compared.
    """
    name = "U_V" if mode == "voltage" else "i_A"
    t_end, dt, k_jump = 0.03, 1e-4, 200
    tt = np.arange(0.0, t_end + dt / 2, dt)
    xx = 1.2e-3 + 0.4e-3 * np.sin(2 * np.pi * tt / t_end)
    # drive: u until t = 0.02 s, then -u/2 (a step at an output point); x moves smoothly (friction)
    rows = [(t, u if k <= k_jump else -0.5 * u, x) for k, (t, x) in enumerate(zip(tt, xx, strict=True))]
    rows.insert(k_jump + 1, (tt[k_jump], -0.5 * u, xx[k_jump]))
    sig = np.array(rows, dtype=[("time", float), (name, float), ("x_m", float)])
    start = {"drive_mode": 1 if mode == "voltage" else 2, "G_eddy_S": G, **_switches(tuple(EFFECTS))}
    res = fmpy.simulate_fmu(str(fx_fmu), fmi_type="ModelExchange", stop_time=t_end, output_interval=dt,
                            relative_tolerance=1e-9, input=sig, start_values=start,
                            output=["psi_Wb", "i_out_A", "U_out_V", "F_N", "i_hyst_A", "T_rise_K"])
    model = M.SolenoidModel(fx_tab, {"drive_mode": mode, "G_eddy_S": G, "h_sub_max_s": 1e-6,
                                     **_switches(tuple(EFFECTS))})
    model.initialize(u, xx[0])
    keys = ("psi_Wb", "i_A", "U_V", "F_N", "i_hyst_A", "T_rise_K")
    ref = [[model.outputs()[k] for k in keys]]
    for k in range(1, len(tt)):
        model.step(dt, u if k <= k_jump else -0.5 * u, xx[k])  # the input over (t_k-1, t_k], x at t_k
        ref.append([model.outputs()[k] for k in keys])
    ref = np.array(ref)
    # fmpy records the values before and after each step event: keep the last row of each output time
    last = len(res) - 1 - np.unique(res["time"][::-1], return_index=True)[1]
    got = np.column_stack([res[k][last] for k in ("psi_Wb", "i_out_A", "U_out_V", "F_N", "i_hyst_A", "T_rise_K")])
    assert len(last) == len(tt)
    keep = np.arange(len(tt)) != k_jump  # at the step itself ME reports the new input's outputs
    cols = [0, 1, 3, 4, 5] if mode == "voltage" else [0, 3, 4, 5]
    err = [_rel_err(got[keep, c], ref[keep, c]) for c in cols]
    print("ME (CVode) with effects vs model.py, max relative error per signal:", np.round(err, 6))
    assert max(err) <= ME_TOL
    assert np.max(np.abs(ref[:, 4])) > 0.01 and ref[-1, 5] > 0.01  # hysteresis and heating are active
