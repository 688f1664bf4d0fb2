"""Tests of the virtual test rig (solenoid_fmu.rig) on the synthetic maps of tests/mapsfixture.py.

The truth's Psi(i) is known analytically (mapsfixture.psi_analytic), independent of the rig, so
the flux test compares the recordings with an answer the rig did not produce.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import mapsfixture
import numpy as np
import pytest

from solenoid_fmu.cli import main
from solenoid_fmu.measure import flux_linkage, read_recording
from solenoid_fmu.realtime.model import load_tables
from solenoid_fmu.rig import (
    CampaignConfig,
    DataAcquisition,
    EddyLadder,
    Effects,
    Friction,
    Heating,
    HysteresisEffect,
    RigError,
    RigTruth,
    TruthModel,
    campaign_excitations,
    measure,
    read_truth,
    run_campaign,
)


@pytest.fixture(scope="module")
def maps_dir(tmp_path_factory):
    # no single eddy term in these maps: the effects are tested one at a time against a truth without it
    return mapsfixture.write_maps(tmp_path_factory.mktemp("rigmaps") / "synthetic", G_eddy_S=None)


@pytest.fixture(scope="module")
def tables(maps_dir):
    return load_tables(maps_dir)


def _record(tables, effects, cfg, seed=0, index=None):
    """Simulate the campaign's excitations; return [(excitation, truth result, recording)]."""
    model = TruthModel(tables, effects)
    rng = np.random.default_rng(seed)
    out = []
    for exc in campaign_excitations(cfg):
        res = model.simulate(exc, cfg)
        out.append((exc, res, measure(res, exc, effects.daq, rng)))
    return out if index is None else out[index]


def _last_loop_area(rec) -> float:
    """Area of the last Psi(i) loop, oint i dPsi [J], from flux_linkage's last two branches."""
    fl = flux_linkage(rec)
    asc, desc = fl.branches[-2], fl.branches[-1]
    assert asc.direction == "ascending" and desc.direction == "descending"
    return float(np.trapezoid(asc.i_A, asc.psi_Wb) + np.trapezoid(desc.i_A, desc.psi_Wb))


def test_flux_from_voltage_recovers_truth_psi_with_offset_and_noise(tables):
    daq = DataAcquisition(voltage_offset_V=5e-3, voltage_noise_V=3e-3, current_noise_A=0.5e-3)
    cfg = CampaignConfig(tests=("flux",), flux_peaks_A=(2.0,), flux_cycles=1, flux_rate_A_per_s=2.0,
                         flux_sample_rate_Hz=500.0)
    _, res, rec = _record(tables, Effects(daq=daq), cfg, seed=3, index=0)
    assert rec.voltage_V is not None and not np.array_equal(rec.voltage_V, res.voltage_V)  # noise is there
    fl = flux_linkage(rec)
    assert fl.offset_V == pytest.approx(5e-3, abs=1e-3)
    truth = mapsfixture.psi_analytic(fl.commutation_i_A, cfg.flux_position_m)
    err = np.max(np.abs(fl.commutation_psi_Wb - truth))
    assert err < 0.005 * truth.max()
    assert fl.commutation_i_A[-1] > 1.95


def test_daq_offset_and_quantization_reach_the_file(tables):
    daq = DataAcquisition(voltage_offset_V=5e-3, voltage_noise_V=0.0, current_noise_A=0.0)
    cfg = CampaignConfig(tests=("flux",), flux_peaks_A=(0.5,), flux_cycles=1, flux_rate_A_per_s=5.0,
                         flux_sample_rate_Hz=200.0)
    _, _, rec = _record(tables, Effects(daq=daq), cfg, index=0)
    rest = rec.time_s < 0.9 * cfg.rest_start_s
    lsb = 2 * daq.voltage_range_V / 2**daq.adc_bits
    assert np.mean(rec.voltage_V[rest]) == pytest.approx(5e-3, abs=lsb)
    steps = np.round(rec.voltage_V / lsb)
    assert np.allclose(rec.voltage_V, steps * lsb, rtol=0, atol=1e-6 * lsb + 1e-12)
    with pytest.raises(RigError, match="adc_bits"):
        DataAcquisition(adc_bits=2)


def _force_by_direction(rec, x_q_m: float = 1.5e-3, band_m: float = 0.05e-3) -> tuple[float, float]:
    """Measured force [N] at ``x_q_m`` while the gap opens and while it closes.

    A straight line through the samples within ``band_m`` of ``x_q_m``, per direction; the
    direction comes from the position 10 samples apart (robust to encoder noise).
    """
    x, F = rec.position_m, rec.force_N
    dx = np.zeros_like(x)
    dx[10:-10] = x[20:] - x[:-20]
    near = np.abs(x - x_q_m) < band_m
    opening = near & (dx > 5e-6)
    closing = near & (dx < -5e-6)
    assert opening.sum() >= 3 and closing.sum() >= 3
    return (float(np.polyval(np.polyfit(x[opening] - x_q_m, F[opening], 1), 0.0)),
            float(np.polyval(np.polyfit(x[closing] - x_q_m, F[closing], 1), 0.0)))


def test_hysteresis_loop_area_grows_with_peak_current(tables):
    cfg = CampaignConfig(tests=("flux",), flux_peaks_A=(0.5, 1.0, 2.0), flux_rate_A_per_s=4.0,
                         flux_cycles=2, flux_sample_rate_Hz=200.0)
    with_h = [_last_loop_area(r) for _, _, r in _record(tables, Effects(hysteresis=HysteresisEffect()), cfg)]
    without = [_last_loop_area(r) for _, _, r in _record(tables, Effects(), cfg)]
    assert with_h[0] > 0.0
    assert with_h[0] < with_h[1] < with_h[2]
    assert max(abs(a) for a in without) < 0.05 * with_h[2]


def test_hysteresis_width_default_and_refusal(tables):
    model = TruthModel(tables, Effects(hysteresis=HysteresisEffect()))
    assert model.hysteresis_half_width_A == pytest.approx(0.03 * mapsfixture.I_MAX_A)
    with pytest.raises(RigError, match="fold back"):
        TruthModel(tables, Effects(hysteresis=HysteresisEffect(half_width_A=5.0)))


def test_heating_current_at_fixed_voltage_falls(tables):
    cfg = CampaignConfig(tests=("voltage_step",), step_hold_s=20.0, step_sample_rate_Hz=100.0)
    results = {}
    hot = Effects(heating=Heating(C_th_J_per_K=60.0, R_th_K_per_W=2.0))
    for name, effects in (("hot", hot), ("cold", Effects())):
        _, res, rec = _record(tables, effects, cfg, index=0)
        t, i = rec.time_s, rec.current_A
        results[name] = (i[np.searchsorted(t, 1.5)], i[np.searchsorted(t, cfg.rest_start_s + 20.0) - 1], res)
    i0, i1, res = results["hot"]
    assert i1 < 0.99 * i0
    # steady state at fixed voltage: i = U / R(T); the fall follows the resistance rise
    T_mid = res.temperature_C[np.searchsorted(res.time_s, 1.5)]
    T_end = res.temperature_C[np.searchsorted(res.time_s, cfg.rest_start_s + 20.0) - 1]
    ratio_R = (1.0 + 0.00393 * (T_mid - 20.0)) / (1.0 + 0.00393 * (T_end - 20.0))
    assert i1 / i0 == pytest.approx(ratio_R, rel=2e-3)
    c0, c1, _ = results["cold"]
    assert c1 == pytest.approx(c0, rel=2e-4)


def test_eddy_ladder_lag_grows_with_rate_and_is_frequency_dependent(tables):
    cfg = CampaignConfig(tests=("eddy",), eddy_rates_A_per_s=(12.5, 50.0, 125.0), eddy_cycles=2,
                         eddy_sample_rate_Hz=5000.0)
    ladder = [flux_linkage(r).hysteresis_mean_width_Wb for _, _, r in _record(tables, Effects(eddy=EddyLadder()), cfg)]
    none = [flux_linkage(r).hysteresis_mean_width_Wb for _, _, r in _record(tables, Effects(), cfg)]
    assert ladder[0] < ladder[1] < ladder[2]
    assert max(none) < 0.1 * ladder[0]
    # a single fast section of the same low-rate conductance (the lumped G_eddy of paper eq. 2)
    lumped = EddyLadder(G_S=(sum(EddyLadder().G_S),), tau_s=(1e-6,))
    single = [flux_linkage(r).hysteresis_mean_width_Wb for _, _, r in _record(tables, Effects(eddy=lumped), cfg)]
    assert ladder[2] / ladder[0] < 0.9 * single[2] / single[0]
    assert EddyLadder().effective_G_S(2 * np.pi * 1000.0) < 0.5 * sum(EddyLadder().G_S)


def test_friction_force_differs_by_direction(tables):
    cfg = CampaignConfig(tests=("force_stroke",), stroke_currents_A=(1.0,), stroke_sample_rate_Hz=50.0)
    diffs = {}
    for name, effects in (("friction", Effects(friction=Friction(force_N=2.0))), ("none", Effects())):
        _, _, rec = _record(tables, effects, cfg, index=0)
        f_open, f_close = _force_by_direction(rec)
        diffs[name] = f_open - f_close
    assert diffs["friction"] == pytest.approx(4.0, abs=0.2)
    assert abs(diffs["none"]) < 0.1


def _tiny_campaign() -> CampaignConfig:
    return CampaignConfig(
        flux_peaks_A=(1.0,), flux_cycles=1, flux_rate_A_per_s=5.0, flux_sample_rate_Hz=200.0,
        stroke_currents_A=(1.0,), stroke_from_m=2.0e-3, stroke_to_m=1.0e-3, stroke_speed_m_per_s=2e-3,
        stroke_sample_rate_Hz=50.0, ramp_sample_rate_Hz=1000.0, ramp_hold_s=0.1,
        eddy_rates_A_per_s=(50.0,), eddy_cycles=1, eddy_sample_rate_Hz=2000.0,
        step_hold_s=0.3, step_sample_rate_Hz=1000.0, pause_s=10.0)


def test_campaign_files_name_no_effect_and_truth_round_trips(tables, maps_dir, tmp_path):
    effects = Effects.from_names("hysteresis,heating,eddy-ladder,friction,noise",
                                 friction=Friction(force_N=3.3))
    truth = run_campaign(tables, tmp_path / "camp", effects=effects, campaign=_tiny_campaign(), seed=7,
                         maps_dir=maps_dir)
    files = sorted((tmp_path / "camp" / "recordings").glob("*.csv"))
    kinds = [read_recording(p).kind for p in files]
    assert kinds == ["flux", "force_stroke", "ramp", "eddy", "voltage_step"]
    forbidden = ("hysteres", "eddy-ladder", "ladder", "heating", "friction", "noise", "preisach", "truth",
                 "steel", "material", "offset", "quantiz")
    for p in files:
        text = p.read_text(encoding="utf-8").lower()
        assert not [w for w in forbidden if w in text], p.name
        rec = read_recording(p)
        assert rec.coil_resistance_ohm is not None and rec.coil_temperature_C is not None
    # the coil warms up over the campaign and the header resistance says so
    r_first = read_recording(files[0]).coil_resistance_ohm
    r_last = read_recording(files[-1]).coil_resistance_ohm
    assert r_last > r_first
    back = read_truth(tmp_path / "camp")
    assert back == truth
    assert back.effects.friction.force_N == 3.3
    assert back.effects.names() == ["hysteresis", "eddy-ladder", "heating", "friction", "noise"]
    assert RigTruth.from_dict(json.loads(json.dumps(truth.to_dict()))) == truth
    assert [e["file"] for e in back.recordings] == [f"recordings/{p.name}" for p in files]


def test_truth_file_refuses_wrong_schema(tmp_path):
    (tmp_path / "truth.json").write_text(json.dumps({"schema": "other"}), encoding="utf-8")
    with pytest.raises(RigError, match="not a rig truth file"):
        read_truth(tmp_path)


def test_unknown_effect_is_refused():
    with pytest.raises(RigError, match="'magic'"):
        Effects.from_names("hysteresis,magic")
    with pytest.raises(RigError, match="tau_s"):
        EddyLadder(G_S=(1e-3, 1e-3), tau_s=(1e-3, -1.0))


def test_cli_rig_with_maps(maps_dir, tmp_path, capsys):
    cfg = tmp_path / "campaign.json"
    small = _tiny_campaign().to_dict()
    small["tests"] = ["flux", "voltage_step"]
    cfg.write_text(json.dumps(small), encoding="utf-8")
    out = tmp_path / "cli"
    code = main(["rig", "--maps", str(maps_dir), "--effects", "friction,noise", "--seed", "2",
                 "--campaign", str(cfg), "-o", str(out)])
    assert code == 0
    assert len(list((out / "recordings").glob("*.csv"))) == 2
    assert read_truth(out).effects.names() == ["friction", "noise"]
    assert main(["rig", "--maps", str(maps_dir), "--effects", "bogus", "-o", str(out)]) == 1
    assert "unknown effect 'bogus'" in capsys.readouterr().err


DEMO = Path(__file__).resolve().parents[1] / "fitting" / "ps45-demo"


def test_shipped_demo_campaign_is_consistent():
    files = sorted((DEMO / "recordings").glob("*.csv"))
    total = sum(p.stat().st_size for p in DEMO.rglob("*") if p.is_file())
    assert total < 10e6
    truth = read_truth(DEMO)
    assert {"hysteresis", "friction"} <= set(truth.effects.names())
    assert [e["file"] for e in truth.recordings] == [f"recordings/{p.name}" for p in files]
    material = DEMO / truth.material["path"]
    assert hashlib.sha256(material.read_bytes()).hexdigest() == truth.material["sha256"]
    kinds = {read_recording(p).kind for p in files}
    assert kinds == {"flux", "force_stroke", "ramp", "eddy", "voltage_step"}
    # friction in the force-stroke sweeps: open minus close = 2 F_c at mid-stroke
    rec = read_recording(next(p for p in files if "force_stroke_1p00A" in p.name))
    f_open, f_close = _force_by_direction(rec)
    assert f_open - f_close == pytest.approx(2 * truth.effects.friction.force_N, abs=0.5)


def test_truth_without_effects_agrees_with_the_real_time_model(tables):
    # two independent integrations of paper eqs. 1-3: the rig's ROS2 on its own state vector and
    # solenoid_fmu.realtime.model.SolenoidModel (voltage mode, no eddy term)
    from solenoid_fmu.realtime.model import SolenoidModel

    cfg = CampaignConfig(tests=("voltage_step",), step_hold_s=0.4, step_sample_rate_Hz=2000.0)
    exc, res, _ = _record(tables, Effects(), cfg, index=0)
    R = 12.0 * (1.0 + 0.00393 * (cfg.ambient_C - 20.0))
    model = SolenoidModel(tables, {"R_ohm": R, "G_eddy_S": 0.0, "drive_mode": "voltage"})
    x = cfg.step_position_m
    model.initialize(0.0, x)
    t = res.time_s
    psi = [model.psi_Wb]
    for k in range(1, t.size):
        model.step(t[k] - t[k - 1], float(exc.reference(0.5 * (t[k] + t[k - 1]))), x)
        psi.append(model.psi_Wb)
    psi = np.array(psi)
    assert res.psi_Wb.max() > 0.2
    assert np.max(np.abs(psi - res.psi_Wb)) < 0.005 * res.psi_Wb.max()
