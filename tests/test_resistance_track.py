"""The coil-resistance track R(t) = R0 (1 + kappa E(t)) estimated from a recording's own data.

Recordings come from the virtual rig with a heating coil (heat capacity 40 J/K, several kelvin per
recording at 2 A; thermal time constant 2 minutes), hysteresis, an eddy ladder and the DAQ's noise
and offsets. The truth's temperatures and flux (TruthResult) are what the track is checked against;
the code under test never sees them.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from solenoid_fmu.measure import (
    campaign_resistance,
    closure_problems,
    commutation_curve,
    flux_linkage,
    make_recording,
    read_recording,
    resistance_track,
    write_recording,
)
from solenoid_fmu.realtime.model import load_tables
from solenoid_fmu.rig import DataAcquisition, EddyLadder, Effects, Excitation, Heating, HysteresisEffect, TruthModel
from solenoid_fmu.rig.daq import measure

MAPS = Path(__file__).resolve().parents[1] / "fitting" / "ps45-demo" / "truth" / "maps"
HOT = Heating(C_th_J_per_K=40.0, R_th_K_per_W=3.0)


@pytest.fixture(scope="module")
def tables():
    return load_tables(MAPS)


def _knots(shape: str, peak: float, rate: float, cycles: int, rest: float, hold: float = 0.0):
    """Reference knots: rest, ``cycles`` unipolar cycles 0 -> peak (-> hold) -> 0, rest."""
    t, v, now = [0.0, rest], [0.0, 0.0], rest
    ramp = peak / rate
    for _ in range(cycles):
        if shape == "sine":
            ph = np.linspace(0.0, 2.0 * math.pi, 25)[1:]
            t += list(now + ph / (2 * math.pi) * 2 * ramp)
            v += list(0.5 * peak * (1 - np.cos(ph)))
        else:
            t += [now + ramp] + ([now + ramp + hold] if hold else []) + [now + 2 * ramp + hold]
            v += [peak] + ([peak] if hold else []) + [0.0]
        now = t[-1]
    return tuple(t + [now + rest]), tuple(v + [0.0])


def _record(tables, shape="triangle", cycles=3, peak=2.0, rate=1.0, hold=0.0, heating=HOT, seed=0, fs=1000.0,
            T_start_C=22.0):
    """(Recording, TruthResult, TruthModel) of one flux excitation at mid stroke."""
    t, v = _knots(shape, peak, rate, cycles, 0.3, hold)
    exc = Excitation(f"flux_{shape}", "flux", "current", fs, t, v, (0.0,), (1.5e-3,),
                     notes=f"{shape}, {cycles} cycle(s)", voltage_offset_V=0.011)
    model = TruthModel(tables, Effects(hysteresis=HysteresisEffect(), eddy=EddyLadder(), heating=heating,
                                       daq=DataAcquisition()))
    truth = model.simulate(exc, T_start_C=T_start_C)
    rec = measure(truth, exc, DataAcquisition(), np.random.default_rng(seed))
    return rec, truth, model


def _psi_error_at_peak(res, truth) -> float:
    p = int(np.argmax(truth.current_A))
    return abs(float(res.psi_Wb[p] - (truth.psi_Wb[p] - truth.psi_Wb[0]))) / abs(float(truth.psi_Wb[p]))


@pytest.mark.parametrize("shape,cycles,hold,seed", [("triangle", 3, 0.0, 1), ("triangle", 4, 0.0, 2),
                                                    ("sine", 3, 0.0, 3), ("trapezoid", 2, 0.5, 4),
                                                    ("trapezoid", 1, 1.0, 5)])
def test_track_follows_the_heating_coil_and_fixes_the_flux(tables, shape, cycles, hold, seed):
    rec, truth, model = _record(tables, shape, cycles, hold=hold, seed=seed)
    R0_true = model.R_ohm_at(truth.temperature_start_C)
    Rend_true = model.R_ohm_at(truth.temperature_end_C)
    assert Rend_true / R0_true - 1 > 0.01  # the coil does warm: R up by more than 1 %
    tr = resistance_track(rec)
    z0 = (tr.R0_ohm - R0_true) / tr.R0_sigma_ohm
    zend = (tr.R_end_ohm - Rend_true) / tr.R_end_sigma_ohm
    kappa_true = model.alpha_per_K / HOT.C_th_J_per_K
    header = flux_linkage(rec)
    track = flux_linkage(rec, resistance=tr)
    e_hdr, e_trk = _psi_error_at_peak(header, truth), _psi_error_at_peak(track, truth)
    print(f"{shape} x{cycles}: R0 {z0:+.2f} sigma, R_end {zend:+.2f} sigma ({tr.R_end_sigma_ohm / Rend_true:.1e}), "
          f"kappa {tr.kappa_per_J:.3g} +- {tr.kappa_sigma_per_J:.2g} (true {kappa_true:.3g}); Psi at peak: header R "
          f"{100 * e_hdr:.2f} %, track {100 * e_trk:.3f} %; {tr.constraints}")
    assert abs(z0) < 3 and abs(zend) < 3
    assert track.track is tr and track.summary()["resistance_pinned"] is tr.pinned
    if tr.pinned:
        assert e_trk < 0.005
    assert e_hdr > 3 * e_trk  # the header R alone is much worse


def test_single_cycle_without_plateau_is_not_pinned_and_the_campaign_says_why(tables):
    single, _, _ = _record(tables, "triangle", 1, peak=1.6, seed=6)
    multi, _, model = _record(tables, "triangle", 3, seed=7)
    tr = resistance_track(single)
    assert not tr.pinned and "header" in tr.why_not_pinned
    assert flux_linkage(single, resistance="track").summary()["resistance_pinned"] is False
    camp = campaign_resistance([single, multi])
    kappa_true = model.alpha_per_K / HOT.C_th_J_per_K
    assert abs(camp.kappa_per_J - kappa_true) < 3 * camp.kappa_sigma_per_J
    assert camp.track_for(multi).kappa_source == "campaign" and camp.track_for(multi) is not camp.track_for(single)
    assert any(line.startswith(single.label()) for line in camp.not_pinned)
    assert camp.summary()["not_pinned"] == camp.not_pinned


def test_stale_header_resistance_is_corrected_by_the_data_and_flagged(tables, tmp_path):
    rec, truth, model = _record(tables, "trapezoid", 2, hold=0.5, seed=8)
    path = write_recording(tmp_path / "flux.csv", rec)
    text = path.read_text()
    R_hdr = rec.coil_resistance_ohm
    stale = tmp_path / "stale.csv"
    stale.write_text(text.replace(f"# coil_resistance_ohm: {R_hdr:g}", f"# coil_resistance_ohm: {1.02 * R_hdr:.4f}"))
    srec = read_recording(stale)
    assert srec.coil_resistance_ohm == pytest.approx(1.02 * R_hdr, rel=1e-4)
    tr = resistance_track(srec)
    R0_true = model.R_ohm_at(truth.temperature_start_C)
    assert abs(tr.R0_ohm - R0_true) < 3 * tr.R0_sigma_ohm
    assert tr.header_disagrees and any("disagrees" in n for n in tr.notes)
    res = flux_linkage(srec, resistance=tr)
    assert any("disagrees" in n for n in res.notes)
    e_trk, e_hdr = _psi_error_at_peak(res, truth), _psi_error_at_peak(flux_linkage(srec), truth)
    print(f"stale header +2 %: Psi at peak with header R {100 * e_hdr:.1f} %, with the track {100 * e_trk:.2f} %")
    assert e_trk < 0.2 * e_hdr and (e_trk < 0.005 or not tr.pinned)
    assert not resistance_track(rec).header_disagrees  # the true header is not flagged


def test_without_heating_kappa_is_zero_and_the_flux_equals_the_header_flux(tables):
    rec, truth, _ = _record(tables, "triangle", 3, heating=None, seed=9)
    tr = resistance_track(rec)
    assert abs(tr.kappa_per_J) < 3 * tr.kappa_sigma_per_J
    assert abs(tr.R0_ohm - rec.coil_resistance_ohm) < 3 * tr.R0_sigma_ohm + 1e-4
    a, b = flux_linkage(rec), flux_linkage(rec, resistance=tr)
    assert abs(a.psi_at_peak_Wb - b.psi_at_peak_Wb) < 3 * tr.psi_peak_sigma_Wb + 1e-5


def test_loops_that_do_not_close_are_named(tables):
    rec, truth, _ = _record(tables, "triangle", 4, seed=10)
    assert closure_problems([resistance_track(rec)]) == []
    u = rec.voltage_V.copy()
    t = rec.time_s
    mid = int(np.searchsorted(t, 0.3 + 2 * 4.0 + 1.0))  # inside the third cycle
    u[mid:mid + 50] += 0.2  # a glitch of the voltage channel: Psi jumps by 0.2 V x 50 ms = 10 mWb
    bad = make_recording("flux", rec.solenoid, t, rec.current_A, voltage_V=u, position_m=1.5e-3,
                         coil_resistance_ohm=rec.coil_resistance_ohm)
    problems = closure_problems([resistance_track(bad)])
    assert len(problems) == 1 and bad.label() in problems[0] and "do not close" in problems[0]


def test_default_flux_is_unchanged_and_commutation_curve_takes_tracks(tables):
    rec, truth, _ = _record(tables, "triangle", 2, seed=11)
    a, b = flux_linkage(rec), flux_linkage(rec, resistance=None)
    assert a.track is None and a.R_ohm == rec.coil_resistance_ohm and a.resistance_method == "header"
    assert np.array_equal(a.psi_Wb, b.psi_Wb)
    with pytest.raises(Exception, match="resistance"):
        flux_linkage(rec, resistance="nonsense")
    cc = commutation_curve([rec], resistance="track")
    assert cc.resistance is not None and cc.results[0].track is cc.resistance.track_for(rec)
    assert cc.results[0].resistance_method == "track"
    assert commutation_curve([rec]).resistance is None


def test_a_noise_free_recording_gets_a_track_not_a_linear_algebra_error(tables):
    """Sensors whose noise is below the ADC's step (or a tool that writes clean signals): the robust noise
    estimate (second differences) is 0, so every equation's sigma would be 0 and the fit divides by it. The
    floor (a 24-bit ADC's step of the largest voltage) keeps it defined; the heating rate comes out near the
    truth's alpha / C_th (adiabatic: within 20 %)."""
    t, v = _knots("trapezoid", 2.0, 10.0, 3, 1.0, hold=1.0)  # mostly holds and rests: flat voltage
    exc = Excitation("flux_trapezoid", "flux", "current", 1000.0, t, v, (0.0,), (1.5e-3,), notes="quiet")
    truth = TruthModel(tables, Effects(heating=HOT)).simulate(exc, T_start_C=22.0)
    quiet = DataAcquisition(voltage_noise_V=0.0, current_noise_A=0.0, force_noise_N=0.0, position_noise_m=0.0)
    rec = measure(truth, exc, quiet, np.random.default_rng(0))
    camp = campaign_resistance([rec])
    assert math.isfinite(camp.kappa_per_J) and camp.kappa_sigma_per_J > 0
    assert camp.kappa_per_J == pytest.approx(0.00393 / HOT.C_th_J_per_K, rel=0.2)


def test_a_coil_warm_from_the_campaign_cools_and_keeps_its_own_heating_rate(tables):
    """One kappa holds for a coil heated from ambient; one that starts 30 K warm also cools, (T - T_amb) / R_th
    (here 10 W against 16 W of Joule heat), and warms within the recording at less than half the rate. The joint
    kappa (a compromise) leaves the loops of both open; their own tracks close them, and the campaign gives each
    its own."""
    cold, _, _ = _record(tables, "triangle", 6, rate=4.0, seed=11)
    warm, truth, model = _record(tables, "triangle", 6, rate=4.0, seed=12, T_start_C=52.0)
    camp = campaign_resistance([cold, warm])
    tr = camp.track_for(warm)
    print(f"warm: kappa {tr.kappa_per_J:.3g} ({tr.kappa_source}), campaign {camp.kappa_per_J:.3g} /J; closure "
          f"{tr.closure_rms_Wb * 1e3:.3g} mWb (noise {tr.closure_noise_Wb * 1e3:.3g}); {tr.notes}")
    assert tr.kappa_source == "recording" and any("also cools" in n for n in tr.notes)
    assert tr.kappa_per_J < 0.7 * camp.track_for(cold).kappa_per_J  # true: 0.4 of the cold coil's rate
    assert camp.problems == []
    assert abs(tr.R0_ohm - model.R_ohm_at(truth.temperature_start_C)) < 3 * tr.R0_sigma_ohm
    forced = resistance_track(warm, kappa_per_J=camp.kappa_per_J, kappa_sigma_per_J=1e-3 * camp.kappa_per_J)
    e_own = _psi_error_at_peak(flux_linkage(warm, resistance=tr), truth)
    e_forced = _psi_error_at_peak(flux_linkage(warm, resistance=forced), truth)
    print(f"Psi at the peak: own track {100 * e_own:.3f} % (+-{100 * tr.psi_peak_sigma_Wb / tr.psi_peak_Wb:.2g} %), "
          f"the campaign's kappa {100 * e_forced:.2f} %")
    assert e_own < 3 * tr.psi_peak_sigma_Wb / tr.psi_peak_Wb and e_own < 0.2 * e_forced
