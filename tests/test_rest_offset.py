"""The voltage offset of eq. 4 from the zero-current rests, when a voltage still decays in them.

After the current returns to "zero" it still has a tail under the rest threshold (a current controller's
undershoot of ~1 mA, decaying over ~15 ms), and R i plus the flux it moves (eddy currents, hysteresis creep
too) put a decaying voltage of some mV into the rest; a short end rest sees it. Taken for the offset it is
a drift of several mV/s, which the eq.-4 integral turns into a flux ramp, and the resistance track into a
heating rate of many sigmas on a coil that does not heat (the loop then adds heating to a clean campaign).
"""

import math

import numpy as np
import pytest

from solenoid_fmu.measure import campaign_resistance, flux_linkage, make_recording
from solenoid_fmu.measure.conditioning import rest_level

R_OHM = 12.05


def psi_Wb(i_A):
    return 0.12 * np.tanh(np.asarray(i_A) / 0.8) + 0.01 * np.asarray(i_A)


def recording(peaks_A, *, rest_s=0.06, decay_V=0.1, tau_s=0.015, offset_V=5e-3, seed=1, noise_V=1e-3):
    """Triangles at 1 A/s with rests of ``rest_s`` at both ends (5 kHz); after the last one the voltage
    carries ``decay_V exp(-(t - t_end) / tau_s)``, a voltage decaying in the rest."""
    knots_t, knots_i, t = [0.0, rest_s], [0.0, 0.0], rest_s
    for k, peak in enumerate(peaks_A):
        knots_t += [t + peak, t + 2 * peak, t + 2 * peak + (0.2 if k < len(peaks_A) - 1 else rest_s)]
        knots_i += [peak, 0.0, 0.0]
        t = knots_t[-1]
    t_s = np.arange(0.0, knots_t[-1], 2e-4)
    i = np.interp(t_s, knots_t, knots_i)
    t_end = knots_t[-2]
    rng = np.random.default_rng(seed)
    u = R_OHM * i + np.gradient(psi_Wb(i), t_s) + offset_V + rng.normal(0.0, noise_V, t_s.size)
    u = u + np.where(t_s > t_end, decay_V * np.exp(-np.clip(t_s - t_end, 0.0, None) / tau_s), 0.0)
    i_meas = i + rng.normal(0.0, 0.5e-3, t_s.size)
    return make_recording("flux", "PS45", t_s, i_meas, voltage_V=u, position_m=1e-3, coil_resistance_ohm=R_OHM,
                          sample_rate_Hz=5000.0)


def test_a_decaying_end_rest_is_not_taken_for_an_offset_drift():
    rec = recording([1.5, 1.5, 1.5])
    res = flux_linkage(rec)
    # the second half of the 60 ms end rest still carries 1.4-5 mV of the decay: taken as the offset at the end
    # it would be a drift of ~0.7 mV/s
    assert abs(res.offset_drift_V_per_s) < 1e-4
    assert res.offset_V == pytest.approx(5e-3, abs=3e-4)
    branch = res.commutation_psi_Wb - psi_Wb(res.commutation_i_A)
    assert float(np.max(np.abs(branch))) < 5e-3 * psi_Wb(1.5)


def test_a_settling_rest_gives_the_level_it_decays_to_with_an_honest_error():
    """Over 60 noise draws: flat rests are "flat", most decays (5.7 mV at the start, 2 mV noise) "settling" (the
    others "trending", which :func:`offset_model` drops against the other rest), and the asymptote's error is within
    its standard error as often as a normal deviate is (no more than 3 of 60 beyond 2.5 sigma)."""
    t = np.arange(0.0, 0.04, 2e-4)
    z, states = [], []
    for seed in range(60):
        rng = np.random.default_rng(seed)
        u = 7e-3 + 0.03 * np.exp(-(t + 0.02) / 0.012) + rng.normal(0.0, 2e-3, t.size)
        level = rest_level(t, u)
        states.append(level.state)
        if level.state == "settling":
            z.append((level.level_V - 7e-3) / level.se_V)
        flat = rest_level(t, 7e-3 + rng.normal(0.0, 2e-3, t.size))
        assert flat.state == "flat" and flat.level_V == pytest.approx(7e-3, abs=5 * flat.se_V)
    assert states.count("settling") >= 40, states
    z = np.array(z)
    assert int(np.sum(np.abs(z) > 2.5)) <= 3, np.round(z, 2)
    assert 0.5 < math.sqrt(float(np.mean(z * z))) < 1.5


def test_a_drift_seen_inside_a_rest_and_between_the_rests_is_a_drift():
    t = np.arange(0.0, 0.5, 2e-4)
    rng = np.random.default_rng(3)
    level = rest_level(t, 5e-3 + 0.02 * t + rng.normal(0.0, 1e-3, t.size))
    assert level.state == "trending"
    assert level.slope_V_per_s == pytest.approx(0.02, abs=3 * level.slope_se_V_per_s)


def test_campaign_kappa_is_not_a_heating_where_the_rests_settle():
    """Six clean recordings (no heating), each with the decay in its 80 ms end rest at another size: the joint
    heating rate stays within 3 of its sigmas of 0 (the identification's "coil heats" threshold). With the end
    rest's mean taken for the offset (stop 42's code) it was -6.2 sigmas."""
    recs = [recording([1.8, 1.8, 1.8, 1.8], decay_V=d, seed=10 + k, rest_s=0.08)
            for k, d in enumerate((0.1, 0.15, 0.2, 0.25, 0.3, 0.35))]
    camp = campaign_resistance(recs)
    assert abs(camp.kappa_per_J) < 3.0 * camp.kappa_sigma_per_J, (camp.kappa_per_J, camp.kappa_sigma_per_J)


def lone_rest_recording(seed, decay_V=0.06, tau_s=0.015, rest_s=0.04, fs_Hz=1250.0):
    """Two triangles from the first sample (no rest before them), then a 40 ms end rest at 1.25 kHz carrying
    ``decay_V exp(-(t - 6 s) / tau_s)``: its second half (27 samples) is the recording's only rest."""
    knots_t, knots_i = [0.0, 1.5, 3.0, 4.5, 6.0, 6.0 + rest_s], [0.0, 1.5, 0.0, 1.5, 0.0, 0.0]
    t = np.arange(0.0, knots_t[-1], 1.0 / fs_Hz)
    i = np.interp(t, knots_t, knots_i)
    rng = np.random.default_rng(seed)
    u = R_OHM * i + np.gradient(psi_Wb(i), t) + 5e-3 + rng.normal(0.0, 1e-3, t.size)
    u = u + np.where(t > 6.0, decay_V * np.exp(-np.clip(t - 6.0, 0.0, None) / tau_s), 0.0)
    return make_recording("flux", "PS45", t, i + rng.normal(0.0, 0.5e-3, t.size), voltage_V=u, position_m=1e-3,
                          coil_resistance_ohm=R_OHM, sample_rate_Hz=fs_Hz)


def test_a_lone_trending_rest_reports_the_offset_as_uncertain_as_it_is():
    """With one short rest whose voltage still falls, nothing tells a drift from a decay: the offset (its mean,
    9-10 mV off here) must come with an uncertainty that covers it (stop 43's first version said 0.2 mV, and
    the loop compared a 2.7 % flux ramp of such an eddy recording as if it were a model error)."""
    for seed in range(5):
        rec = lone_rest_recording(seed)
        res = flux_linkage(rec)
        se_V = res.offset_uncertainty_Wb / float(rec.time_s[-1] - rec.time_s[0])
        assert abs(res.offset_V - 5e-3) <= 2.5 * se_V, (seed, res.offset_V, se_V)
