"""Effect sub-models of the real-time model (issue 7) against the virtual rig's own implementation.

The rig (``solenoid_fmu.rig.TruthModel``) integrates the same physics with a different scheme
(full dense ROS2 over all states, sub-sampled, its own code), so agreement is a real check.
"""

import json

import numpy as np
import pytest
from mapsfixture import write_maps

from solenoid_fmu.realtime import model as m
from solenoid_fmu.realtime.hysteresis import PlayHysteresis
from solenoid_fmu.rig import CampaignConfig, EddyLadder, Effects, Excitation, Friction, Heating, TruthModel


def _maps_with_effects(tmp_path, effects, G_eddy_S=0.0):
    d = write_maps(tmp_path / "maps", G_eddy_S=G_eddy_S)
    meta = json.loads((d / "maps.json").read_text())
    meta["effects"] = effects
    (d / "maps.json").write_text(json.dumps(meta))
    return m.load_tables(d)


def _run(model, t, u, x):
    model.initialize(u[0], x[0], t[0])
    out = [model.outputs()]
    for k in range(len(t) - 1):
        model.step(t[k + 1] - t[k], u[k + 1], x[k + 1], t[k])
        out.append(model.outputs())
    return {key: np.array([o[key] for o in out]) for key in out[0]}


def _voltage_step(duration=0.3, U=12.0, rate=10e3):
    return Excitation("step", "voltage_step", "voltage", rate, (0.0, 0.01, 0.0100001, duration),
                      (0.0, 0.0, U, U), (0.0,), (1.5e-3,))


def test_eddy_ladder_matches_rig_truth_on_voltage_step(tmp_path):
    ladder = {"G_S": [3e-3, 2e-3], "tau_s": [3e-4, 3e-3]}
    tab = _maps_with_effects(tmp_path, {"eddy_ladder": ladder})
    exc = _voltage_step()
    truth = TruthModel(tab, Effects(eddy=EddyLadder(G_S=(3e-3, 2e-3), tau_s=(3e-4, 3e-3))),
                       h_sub_max_s=2.5e-5).simulate(exc, CampaignConfig())
    t = truth.time_s
    u = exc.reference(t)
    model = m.SolenoidModel(tab, {"drive_mode": "voltage", "G_eddy_S": 0.0, "h_sub_max_s": 2.5e-5,
                                  "R_ohm": truth.resistance_start_ohm})
    out = _run(model, t, u, np.full_like(t, 1.5e-3))
    # the truth's current is a sample-interval mean; compare the flux (a state) instead
    err = np.max(np.abs(out["psi_Wb"] - truth.psi_Wb)) / np.max(truth.psi_Wb)
    assert err < 2e-3
    # and the ladder matters: without it the flux rises visibly faster
    model_off = m.SolenoidModel(tab, {"drive_mode": "voltage", "G_eddy_S": 0.0, "eddy_ladder_on": False,
                                      "R_ohm": truth.resistance_start_ohm})
    off = _run(model_off, t, u, np.full_like(t, 1.5e-3))
    assert np.max(np.abs(off["psi_Wb"] - truth.psi_Wb)) / np.max(truth.psi_Wb) > 10 * err


def test_heating_matches_rig_truth(tmp_path):
    heat = {"C_th_J_per_K": 2.0, "R_th_K_per_W": 50.0, "alpha_per_K": 0.00393}
    tab = _maps_with_effects(tmp_path, {"heating": heat})
    exc = _voltage_step(duration=1.5, U=24.0, rate=2e3)
    cfg = CampaignConfig()
    truth_model = TruthModel(tab, Effects(heating=Heating(C_th_J_per_K=2.0, R_th_K_per_W=50.0)),
                             alpha_per_K=0.00393)
    truth = truth_model.simulate(exc, cfg)
    t = truth.time_s
    # the model's R is the resistance at the start temperature (what the rig measures before a run)
    model = m.SolenoidModel(tab, {"drive_mode": "voltage", "G_eddy_S": 0.0, "R_ohm": truth.resistance_start_ohm})
    out = _run(model, t, exc.reference(t), np.full_like(t, 1.5e-3))
    rise = truth.temperature_C[-1] - truth.temperature_C[0]
    assert rise > 2.0  # the case heats the coil noticeably
    assert abs(out["T_rise_K"][-1] - rise) < 0.02 * rise
    # settled current falls with R(T): the model follows the truth within 0.2 %
    assert abs(out["i_A"][-1] / truth.current_A[-1] - 1.0) < 2e-3
    off = m.SolenoidModel(tab, {"drive_mode": "voltage", "G_eddy_S": 0.0, "heating_on": False,
                                "R_ohm": truth.resistance_start_ohm})
    out_off = _run(off, t, exc.reference(t), np.full_like(t, 1.5e-3))
    assert abs(out_off["i_A"][-1] / truth.current_A[-1] - 1.0) > 5e-3


def test_a_coil_that_starts_warm_cools_as_the_rig_truth(tmp_path):
    """T_start_excess_K: the coil starts above ambient and cools through R_th while it heats; against the rig's
    truth started at that temperature (its own integration), and without the start excess the model misses."""
    heat = {"C_th_J_per_K": 2.0, "R_th_K_per_W": 5.0, "alpha_per_K": 0.00393}
    tab = _maps_with_effects(tmp_path, {"heating": heat})
    exc = _voltage_step(duration=20.0, U=6.0, rate=200.0)
    cfg = CampaignConfig()
    excess = 30.0
    truth = TruthModel(tab, Effects(heating=Heating(C_th_J_per_K=2.0, R_th_K_per_W=5.0)), alpha_per_K=0.00393,
                       ).simulate(exc, cfg, T_start_C=cfg.ambient_C + excess)
    t = truth.time_s
    fall = truth.temperature_C[0] - truth.temperature_C[-1]
    assert fall > 10.0  # the case cools the coil noticeably although it is driven
    runs = {}
    for T0 in (excess, 0.0):
        model = m.SolenoidModel(tab, {"drive_mode": "voltage", "G_eddy_S": 0.0, "R_ohm": truth.resistance_start_ohm,
                                      "T_start_excess_K": T0, "h_sub_max_s": 1e-3})
        runs[T0] = _run(model, t, exc.reference(t), np.full_like(t, 1.5e-3))
    assert abs(runs[excess]["T_rise_K"][-1] + fall) < 0.01 * fall
    assert abs(runs[excess]["i_A"][-1] / truth.current_A[-1] - 1.0) < 1e-3
    assert runs[0.0]["T_rise_K"][-1] > 0.0  # from ambient it would have warmed
    assert abs(runs[0.0]["i_A"][-1] / truth.current_A[-1] - 1.0) > 0.02


@pytest.mark.parametrize("bad", [-60.0, 161.0, float("nan"), float("inf")])
def test_a_start_excess_out_of_range_is_refused_by_name(tmp_path, bad):
    tab = _maps_with_effects(tmp_path, {"heating": {"C_th_J_per_K": 2.0}})
    with pytest.raises(m.ModelInputError, match="T_start_excess_K"):
        m.SolenoidModel(tab, {"T_start_excess_K": bad})


def test_a_start_excess_with_no_resistance_at_ambient_is_refused(tmp_path):
    tab = _maps_with_effects(tmp_path, {"heating": {"C_th_J_per_K": 2.0}})
    with pytest.raises(m.ModelInputError, match="no positive resistance at ambient"):
        m.SolenoidModel(tab, {"alpha_per_K": 0.03, "T_start_excess_K": -40.0})
    model = m.SolenoidModel(tab, {"T_start_excess_K": 10.0})
    with pytest.raises(m.ModelInputError, match="no positive resistance at ambient"):
        model.set_params(alpha_per_K=0.03, T_start_excess_K=-40.0)
    assert model.params["T_start_excess_K"] == 10.0  # unchanged after the refusal


def test_friction_matches_rig_truth_on_stroke(tmp_path):
    tab = _maps_with_effects(tmp_path, {"friction": {"force_N": 2.5, "presliding_m": 2e-5}})
    exc = Excitation("stroke", "force_stroke", "current", 200.0, (0.0, 10.0), (1.0, 1.0),
                     (0.0, 0.5, 5.0, 9.5, 10.0), (2.8e-3, 2.8e-3, 0.5e-3, 2.8e-3, 2.8e-3), with_force=True)
    truth = TruthModel(tab, Effects(friction=Friction(2.5, 2e-5))).simulate(exc, CampaignConfig())
    t = truth.time_s
    model = m.SolenoidModel(tab, {"drive_mode": "current", "G_eddy_S": 0.0})
    out = _run(model, t, truth.current_A, truth.position_m)
    fr_model = out["F_N"] - np.array([tab.force_N(p, x) for p, x in zip(out["psi_Wb"], truth.position_m,
                                                                         strict=True)])
    fr_truth = truth.force_N - truth.force_magnetic_N
    assert np.max(np.abs(fr_model - fr_truth)) < 0.05
    assert np.ptp(fr_truth) == pytest.approx(5.0, rel=0.01)


def test_play_operator_matches_hysteresis_module(tmp_path):
    play = PlayHysteresis([0.01, 0.03, 0.06], [2.0, 1.0, 0.5], shape=([0.0, 0.2, 0.4], [1.0, 1.5, 0.5]))
    d = play.to_dict()
    tab = _maps_with_effects(tmp_path, {"hysteresis": {k: d[k] for k in ("thresholds", "weights", "shape")}})
    rng = np.random.default_rng(3)
    b = np.cumsum(rng.normal(0, 0.01, 400))
    ref = play.run(b)
    plays = [0.0, 0.0, 0.0]
    hy = m.effects_data(tab)["hysteresis"]
    got = [m.play_step(plays, hy["r"], hy["w"], hy["gb"], hy["gg"], v) for v in b]
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)


def test_effects_off_reproduce_the_base_model_bit_for_bit(tmp_path):
    tab_fx = _maps_with_effects(tmp_path, {"friction": {"force_N": 2.0, "presliding_m": 1e-5},
                                           "eddy_ladder": {"G_S": [1e-3], "tau_s": [1e-3]}}, G_eddy_S=0.01)
    tab = m.load_tables(write_maps(tmp_path / "base", G_eddy_S=0.01))
    t = np.linspace(0, 0.2, 401)
    u = 10.0 * t
    x = np.full_like(t, 1e-3)
    off = {"friction_on": False, "eddy_ladder_on": False, "drive_mode": "current"}
    a = _run(m.SolenoidModel(tab_fx, off), t, u, x)
    b = _run(m.SolenoidModel(tab, {"drive_mode": "current"}), t, u, x)
    for key in ("psi_Wb", "U_V", "F_N"):
        np.testing.assert_array_equal(a[key], b[key])


def test_effect_state_round_trip_and_bad_effects(tmp_path):
    tab = _maps_with_effects(tmp_path, {"heating": {"C_th_J_per_K": 1.0}, "eddy_ladder":
                                        {"G_S": [1e-3], "tau_s": [1e-3]}})
    model = m.SolenoidModel(tab, {"drive_mode": "voltage"})
    model.initialize(12.0, 1e-3)
    for _ in range(50):
        model.step(1e-3, 12.0, 1e-3)
    st = model.get_state()
    assert len(st) == len(model.state_names())
    ref = [model.outputs()]
    for _ in range(20):
        model.step(1e-3, 12.0, 1e-3)
    ref = model.outputs()
    model.set_state(st)
    for _ in range(20):
        model.step(1e-3, 12.0, 1e-3)
    assert model.outputs() == ref
    with pytest.raises(m.ModelInputError, match="friction"):
        m.SolenoidModel(tab, {"friction_on": True})
    with pytest.raises(m.ModelMapsError, match="tau_s"):
        _maps_with_effects(tmp_path / "bad", {"eddy_ladder": {"G_S": [1e-3], "tau_s": [-1.0]}}).meta  # noqa: B018
        m.SolenoidModel(_maps_with_effects(tmp_path / "bad2", {"eddy_ladder": {"G_S": [1e-3], "tau_s": [-1.0]}}))


def test_an_effects_section_of_nulls_is_no_effect(tmp_path):
    from solenoid_fmu.fmu import VARIABLES, interface_for

    tab = _maps_with_effects(tmp_path, {"friction": None, "heating": None})
    model = m.SolenoidModel(tab)
    assert model.state_names() == m.STATE_NAMES
    assert interface_for(tab) == VARIABLES
