"""The native (generated C) FMU with the effect sub-models (issue 7) against model.py.

Co-simulation must agree with :class:`solenoid_fmu.realtime.model.SolenoidModel` to 1e-9 relative for each
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
from pathlib import Path

import fmpy
import mapsfixture as mf
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from test_fmu import Instance, _measured
from test_fmu_c import HOST_C, MeInstance, _rel_err, _run_host

from solenoid_fmu import fmu as F
from solenoid_fmu.fmu import native as fmu_c
from solenoid_fmu.fmu.interface import me_variables
from solenoid_fmu.measure import Recording
from solenoid_fmu.realtime import model as M

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
    k_fr = model.state_names().index("F_friction_N")
    friction = [model.get_state()[k_fr]]
    t = 0.0
    for h, uk, xk in zip(hs, u, x, strict=True):
        model.step(h, uk, xk, t)
        t += h
        ref.append([model.outputs()[k] for k in names])
        friction.append(model.get_state()[k_fr])
    return np.array(got), np.array(ref), np.array(friction)


CASES = [(mode, G, fx) for mode, G in (("voltage", 0.01), ("current", 0.005), ("current", 0.0))
         for fx in (("hysteresis",), ("eddy_ladder",), ("heating",), ("friction",), tuple(EFFECTS), ())]


@pytest.mark.parametrize(("mode", "G", "on"), CASES)
def test_cs_with_effects_matches_model(fx_md, fx_unzipped, fx_tab, mode, G, on):
    got, ref, friction = _cs_pair(fx_md, fx_unzipped, fx_tab, mode, dict(_switches(on), G_eddy_S=G))
    nonzero = np.max(np.abs(ref), axis=0) > 0.0
    assert _rel_err(got[:, nonzero], ref[:, nonzero]) <= 1e-9
    assert np.all(got[:, ~nonzero] == 0.0)
    # the effect is active: its signature output moves
    if "hysteresis" in on:
        assert np.max(np.abs(ref[:, 6])) > 0.01
    if "heating" in on:
        assert ref[-1, 7] > 0.1
    assert (np.ptp(friction) > 4.0) == ("friction" in on)  # the Dahl force swings between +-2.5 N


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


#: The coil's start above ambient in the pointwise model-exchange test [K] (cools through R_th).
ME_T_START_EXCESS_K = 7.5


def _me_fx_reference(tab, mode, G, on, states, u, x, x0):
    """Paper eqs. (1)-(3) with the effects at the states, with model.py's lookups and play operator;
    the hysteresis and friction memories are those committed at the start (Psi = 0, x = x0)."""
    lad, heat = EFFECTS["eddy_ladder"], EFFECTS["heating"]
    psi, ik, T = states[0], list(states[1:3]), states[3]
    nl = 2 if "eddy_ladder" in on else 0
    T = T if "heating" in on else 0.0
    a = M.heating_alpha(heat["alpha_per_K"], ME_T_START_EXCESS_K)  # the start resistance's coefficient
    R = mf.R_OHM * (1.0 + a * T) if "heating" in on else mf.R_OHM
    j, w, _ = tab.x_cell(x)
    pm = tab.psi_max_Wb
    p = min(max(psi, -pm), pm)
    i_f, force = tab.i_f_and_force(p, j, w)
    sik = sum(ik[:nl])
    ih = 0.0
    if "hysteresis" in on:
        hy = M.effects_data(tab)["hysteresis"]
        ih = M.play_step([0.0] * len(hy["r"]), hy["r"], hy["w"], hy["gb"], hy["gg"], p)
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
    der += [(R * i * i - (T + ME_T_START_EXCESS_K) / heat["R_th_K_per_W"]) / heat["C_th_J_per_K"]
            if "heating" in on else 0.0]
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
    inst = MeFx(fx_md, fx_unzipped, mode, 0.0, 1e-3, _switches(on), G_eddy_S=G, T_start_excess_K=ME_T_START_EXCESS_K)
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


def test_me_refuses_current_mode_without_g_eddy_with_the_ladder(fx_md, fx_unzipped):
    """The one ME case not supported (a differential-algebraic system): refused with a clear error."""
    inst = MeFx(fx_md, fx_unzipped, "current", 0.0, 1e-3, _switches(("heating",)), G_eddy_S=0.0)
    inst.eval([0.1, 0.0, 0.0, 1.0])  # without the ladder: fine (algebraic Psi)
    inst.free()
    with pytest.raises(FMICallException):
        MeFx(fx_md, fx_unzipped, "current", 0.0, 1e-3, _switches(("eddy_ladder",)), G_eddy_S=0.0)


# -- the FMU interface, parameters and state -------------------------------------------------------
def test_interface_and_description_with_effects(fx_md, fx_fmu, fx_tab):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fx_fmu)) == []
    names = [v.name for v in fx_md.modelVariables]
    iface = F.interface_for(fx_tab)
    assert names[:len(iface)] == [v.name for v in iface]
    assert names[len(iface):] == [n for n, _, _ in me_variables(fx_tab)]
    assert [d.variable.name for d in fx_md.derivatives] == ["der(psi_state_Wb)", "der(ladder_state_0_A)",
                                                             "der(ladder_state_1_A)", "der(T_state_K)"]
    by = {v.name: v for v in fx_md.modelVariables}
    defaults = M.SolenoidModel(fx_tab).params
    for v in F.EFFECT_VARIABLES:
        assert by[v.name].causality == v.causality and by[v.name].variability == v.variability
        if v.causality == "parameter":
            start = by[v.name].start
            assert (start == "true") == defaults[v.name] if v.type == "Boolean" else float(start) == defaults[v.name]
    with zipfile.ZipFile(fx_fmu) as zf:
        header = zf.read("sources/solenoid_maps.h").decode()
    assert "#define SOL_N_LAD 2" in header and "#define SOL_N_PLAY 3" in header and "0.003" in header


def test_bad_effect_parameters_and_switches_are_refused(fx_md, fx_unzipped, tmp_path):
    inst = _cs_init(fx_md, fx_unzipped, "voltage", 0.0, 1e-3, {"heating_on": True})
    f, vr = inst.fmu, inst.vr
    with pytest.raises(FMICallException):  # switches and C_th are fixed after initialization
        f.setBoolean([vr["friction_on"]], [False])
    with pytest.raises(FMICallException):
        f.setReal([vr["C_th_J_per_K"]], [1.0])
    f.setReal([vr["hyst_gain"]], [-1.0])  # tunable, but must be >= 0: refused at the next step
    with pytest.raises(FMICallException) as info:
        inst.step(1e-3, 24.0, 1e-3)
    assert info.value.status == 3 and any("hyst_gain must be >= 0" in m for s, m in inst.messages)
    inst.free()
    with pytest.raises(FMICallException):
        _cs_init(fx_md, fx_unzipped, "voltage", 0.0, 1e-3, {"presliding_m": 0.0})
    # a switch for an effect the maps lack
    d = mf.write_maps(tmp_path / "fric_only", G_eddy_S=0.01)
    meta = json.loads((d / "maps.json").read_text())
    meta["effects"] = {"friction": EFFECTS["friction"]}
    (d / "maps.json").write_text(json.dumps(meta))
    fmu = F.build_fmu(d, tmp_path / "fric.fmu", backend="c")
    md = fmpy.read_model_description(str(fmu))
    unz = fmpy.extract(str(fmu))
    inst = Instance(md, unz, "lacks")
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.fmu.setBoolean([inst.vr["hysteresis_on"]], [True])
    with pytest.raises(FMICallException):
        inst.fmu.exitInitializationMode()
    assert any("carry no 'hysteresis' effect" in m for s, m in inst.messages)
    inst.free()


@pytest.mark.parametrize(("params", "words"), [
    ({"T_start_excess_K": 500.0}, "T_start_excess_K must lie in [-50, 160] K"),
    ({"T_start_excess_K": float("nan")}, "T_start_excess_K must lie in"),
    ({"alpha_per_K": 0.03, "T_start_excess_K": -40.0}, "no positive resistance at ambient"),
])
def test_a_bad_start_temperature_is_refused_by_name(fx_md, fx_unzipped, params, words):
    """As model.py refuses it (test_effects_model): at initialization, naming the parameter."""
    inst = Instance(fx_md, fx_unzipped, "warm")
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.fmu.setReal([inst.vr[k] for k in params], list(params.values()))
    with pytest.raises(FMICallException):
        inst.fmu.exitInitializationMode()
    assert any(words in m for s, m in inst.messages), inst.messages
    inst.free()


def test_fmu_state_with_effects_round_trip_and_serialization(fx_md, fx_unzipped):
    on = _switches(tuple(EFFECTS))
    inst = _cs_init(fx_md, fx_unzipped, "voltage", 24.0, 1e-3, on)
    xs = 1e-3 + 2e-4 * np.sin(np.arange(40) / 5.0)
    for k in range(20):
        inst.step(1e-3, 24.0, xs[k])
    t_saved = inst.t
    state = inst.fmu.getFMUstate()

    def run(target):
        out = []
        for k in range(20, 40):
            target.fmu.setReal([target.vr["U_V"], target.vr["x_m"]], [-24.0 if k < 30 else 0.0, xs[k]])
            target.fmu.doStep(target.t, 1e-3)
            target.t += 1e-3
            out.append(target.fmu.getReal([target.vr[n] for n in OUTS_FX]))
        return out

    ahead = run(inst)
    inst.fmu.setFMUstate(state)
    inst.t = t_saved
    assert run(inst) == ahead
    blob = inst.fmu.serializeFMUstate(state)
    inst.fmu.freeFMUstate(state)
    other = _cs_init(fx_md, fx_unzipped, "voltage", 0.0, 1e-3, {}, name="other")
    restored = other.fmu.deSerializeFMUstate(blob)
    other.fmu.setFMUstate(restored)
    other.t = t_saved
    assert run(other) == ahead  # the effect states and switches travel with the state
    other.fmu.freeFMUstate(restored)
    other.free()
    inst.free()
    assert ahead[-1][6] != ahead[0][6] and ahead[-1][7] != ahead[0][7]


def test_simulate_recording_with_effect_parameters_equals_the_pythonfmu_fmu(fx_maps, fx_fmu, fx_tab, tmp_path):
    """simulate_recording(fmu, rec, params={...}) works unchanged: native and pythonfmu FMU agree to 1e-9."""
    py_fmu = F.build_fmu(fx_maps, tmp_path / "py.fmu", backend="python")
    params = {"hysteresis_on": True, "heating_on": True, "friction_on": False, "eddy_ladder_on": True,
              "hyst_gain": 0.5}
    for kind, drive in (("voltage_step", "voltage"), ("ramp", "current")):
        rec = _measured(fx_tab, kind, drive, n=250)
        native = F.simulate_recording(fx_fmu, rec, params=params).recording
        python = F.simulate_recording(py_fmu, rec, params=params).recording
        for name in ("current_A", "voltage_V", "force_N"):
            ref = getattr(python, name)
            assert _rel_err(getattr(native, name), ref) <= 1e-9
        assert np.max(np.abs(native.force_N)) > 0.1


# -- the plain C host and valgrind with all effects on ---------------------------------------------
@pytest.fixture(scope="module")
def fx_host(fx_unzipped, tmp_path_factory):
    exe = tmp_path_factory.mktemp("fx_host") / "host"
    cmd = [fmu_c.find_compiler(), "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", f"-I{fx_unzipped}/sources",
           "-o", str(exe), str(HOST_C), "-ldl", "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return exe


def test_c_host_with_all_effects(fx_host, fx_unzipped, fx_md, fx_tab, tmp_path):
    proc = _run_host(fx_host, fx_unzipped, fx_md, tmp_path / "ramp.csv", 200_000, suffix=("fx",))
    for check in ("ramp", "two_instances", "reset", "state", "nan", "long_run 200000 steps"):
        assert f"ok {check}" in proc.stdout
    got = np.loadtxt(tmp_path / "ramp.csv", delimiter=",", skiprows=1)
    model = M.SolenoidModel(fx_tab, {"drive_mode": "current", **_switches(tuple(EFFECTS))})
    model.initialize(0.0, 1e-3)
    ref = [[model.i_A, model.U_V, model.F_N, model.psi_Wb, model.dpsi_dt_V, model.i_eddy_A]]
    for k in range(2000):
        model.step(1e-4, 10.0 * 1e-4 * (k + 1), 1e-3, 1e-4 * k)
        ref.append([model.i_A, model.U_V, model.F_N, model.psi_Wb, model.dpsi_dt_V, model.i_eddy_A])
    assert _rel_err(got[:, 1:], ref) <= 1e-9
    assert model.i_hyst_A != 0.0 and model.T_rise_K > 0.0


def test_c_host_with_all_effects_runs_clean_under_valgrind(fx_host, fx_unzipped, fx_md, tmp_path):
    import shutil

    valgrind = shutil.which("valgrind")
    assert valgrind, "valgrind is on PATH here and in CI"
    proc = _run_host(fx_host, fx_unzipped, fx_md, tmp_path / "ramp.csv", 20_000, suffix=("fx",),
                     prefix=(valgrind, "-q", "--error-exitcode=1", "--leak-check=full",
                             "--errors-for-leak-kinds=definite,indirect,possible"))
    assert "Invalid read" not in proc.stderr and "uninitialised" not in proc.stderr


def test_partial_effects_sections_build_and_match(tmp_path):
    """Only some effects, a hysteresis without shape table, heating with default scalars: builds
    (-Wall -Wextra -Werror with empty tables) and matches model.py; current mode G = 0 algebraic path."""
    d = mf.write_maps(tmp_path / "partial", G_eddy_S=0.0)
    meta = json.loads((d / "maps.json").read_text())
    meta["effects"] = {"hysteresis": {"thresholds": [0.02, 0.05], "weights": [1.5, 0.7], "shape": None},
                       "heating": {"C_th_J_per_K": 0.3}, "friction": None}
    (d / "maps.json").write_text(json.dumps(meta))
    fmu = F.build_fmu(d, tmp_path / "partial.fmu", backend="c")
    md = fmpy.read_model_description(str(fmu))
    unz = fmpy.extract(str(fmu))
    tab = M.load_tables(d)
    assert [u.variable.name for u in md.derivatives] == ["der(psi_state_Wb)", "der(T_state_K)"]
    for mode in ("voltage", "current"):
        got, ref, _ = _cs_pair(md, unz, tab, mode, {"hysteresis_on": True, "heating_on": True}, seed=9)
        assert _rel_err(got, ref) <= 1e-9
        assert np.max(np.abs(ref[:, 6])) > 0.01 and ref[-1, 7] > 0.0


def test_one_section_ladder_builds_and_steps_as_the_python_model(tmp_path):
    """A ladder of one section (the lumped eddy current with one time constant) compiles under the build's
    -Werror (gcc took the ladder's current array for maybe uninitialized and refused it) and its C step
    gives what the Python step gives."""
    d = mf.write_maps(tmp_path / "one", G_eddy_S=0.01)
    meta = json.loads((d / "maps.json").read_text())
    meta["effects"] = {"eddy_ladder": {"G_S": [4e-3], "tau_s": [1e-3]}}
    (d / "maps.json").write_text(json.dumps(meta))
    fmu = F.build_fmu(d, tmp_path / "one.fmu", backend="c")
    md = fmpy.read_model_description(str(fmu))
    unzipped = fmpy.extract(str(fmu), str(tmp_path / "one_unzipped"))
    got, ref, _ = _cs_pair(md, unzipped, M.load_tables(d), "voltage", {"eddy_ladder_on": True})
    assert np.max(np.abs(got[:, 5])) > 1e-3  # the ladder carries current
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-12)


def test_null_effects_are_no_effects_in_both_fmus(tmp_path):
    """An ``effects`` section naming only null effects is no effect for either FMU: one predicate
    (:attr:`EffectsRecord.active`) decides the effect variables. Both FMUs expose the same interface (the native
    one then has its model-exchange locals, at the value references its description gives: the C code counted
    the effect variables when the file named any effect, so ``psi_state_Wb`` was not where the description said)."""
    from test_fmu_c import MeInstance

    from solenoid_fmu.fmu.interface import interface_for

    d = mf.write_maps(tmp_path / "nulls", G_eddy_S=0.01)
    meta = json.loads((d / "maps.json").read_text())
    meta["effects"] = {"hysteresis": None, "eddy_ladder": None, "heating": None, "friction": None}
    (d / "maps.json").write_text(json.dumps(meta))
    tab = M.load_tables(d)
    assert tab.effects.named and not tab.effects.active and interface_for(tab) == F.VARIABLES
    names = {}
    for backend in ("python", "c"):
        fmu = F.build_fmu(d, tmp_path / f"nulls-{backend}.fmu", backend=backend)
        names[backend] = [v.name for v in fmpy.read_model_description(str(fmu)).modelVariables]
    me_locals = [name for name, _, _ in me_variables(tab)]
    assert names["python"] == [v.name for v in F.VARIABLES]
    assert names["c"] == names["python"] + me_locals
    unzipped = fmpy.extract(str(tmp_path / "nulls-c.fmu"), str(tmp_path / "nulls_unzipped"))
    assert "#define SOL_HAS_FX 0" in (Path(unzipped) / "sources" / "solenoid_maps.h").read_text()
    md = fmpy.read_model_description(str(tmp_path / "nulls-c.fmu"))
    inst = MeInstance(md, unzipped, "voltage", 12.0, 1.2e-3)
    try:
        dpsi = inst.eval(2e-3)[0]
        psi_state, der_psi = inst.fmu.getReal([inst.vr["psi_state_Wb"], inst.vr["der(psi_state_Wb)"]])
    finally:
        inst.free()
    assert psi_state == 2e-3 and der_psi == dpsi != 0.0


def test_an_fmu_run_starts_at_the_coil_temperature_the_header_resistance_gives(fx_fmu, fx_tab):
    """``simulate_recording(..., ambient_R_ohm=)`` sets ``T_start_excess_K`` from the header resistance as
    ``simulate_model`` does (equal to 1e-9), and the warm start shows: the coil cools (T_rise < 0 at the end of
    a run at low current), where it would warm from ambient."""
    t = np.linspace(0.0, 4.0, 801)
    i = 0.1 * np.sin(np.pi * t / 4.0) ** 2
    R_amb = mf.R_OHM
    R_start = R_amb * (1.0 + 0.00393 * 20.0)  # 20 K above ambient
    rec = Recording("flux", "PS45", {"position_mm": "1.0", "coil_resistance_ohm": repr(R_start)}, t, i,
                    R_start * i, None, None, {})
    on = {"heating_on": True, "hysteresis_on": False, "eddy_ladder_on": False, "friction_on": False}
    warm = F.simulate_recording(fx_fmu, rec, params=on, ambient_R_ohm=R_amb)
    ref = F.simulate_model(fx_tab, rec, params=on, ambient_R_ohm=R_amb)
    cold = F.simulate_recording(fx_fmu, rec, params=on)
    T_warm, T_ref, T_cold = (r.recording.extra["T_rise_K"] for r in (warm, ref, cold))
    np.testing.assert_allclose(T_warm, T_ref, rtol=1e-9, atol=1e-12)
    assert T_warm[-1] < -1.0 < 0.0 < T_cold[-1]
