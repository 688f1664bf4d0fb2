"""The force channel's lead over the voltage and current (:mod:`solenoid_fmu.loop.force_timing`).

The rig records voltage and current as means over each sample interval and the force at the sample's time
stamp (:mod:`solenoid_fmu.rig.daq`): the force leads by half a sample period. That is the truth the
measurement must find, model-free, on campaigns whose flux carries eddy ladders, hysteresis and coil
heating; a force re-timed on the voltage's time base must give no lead, and a force one sample late must
give -0.5. Compared with the measured lead, an exact model's force on a voltage step falls to the sensor noise.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from steelcampaigns import CAMPAIGNS, campaign_dir, campaign_id
from truthsteels import truth_dir

from solenoid_fmu.loop.force_timing import ForceTiming, measure_force_timing, shifted
from solenoid_fmu.loop.improvement import _cases
from solenoid_fmu.loop.residuals import FluxCache
from solenoid_fmu.measure import read_recording
from solenoid_fmu.realtime import load_tables

#: The rig's lead [sample periods]: force at the stamp, voltage and current interval means.
RIG_LEAD = 0.5


def _campaign(shared, name, effects, seed):
    folder = campaign_dir(shared, name, effects, seed)
    recs = [read_recording(p) for p in sorted((folder / "recordings").glob("*.csv"))]
    return folder, recs, load_tables(truth_dir(name))


def _with_force_moved(recs, lead_samples):
    """The recordings with their force moved by ``lead_samples`` sample periods (interpolated)."""
    return [r if r.force_N is None else dataclasses.replace(r, force_N=shifted(r.time_s, r.force_N,
                                                                                     lead_samples))
            for r in recs]


def test_shifted_moves_a_ramp_by_the_given_samples_on_any_time_base():
    t = np.cumsum(np.r_[0.0, np.full(50, 1e-3), np.full(50, 4e-4)])
    f = 3.0 * t + 1.0
    out = shifted(t, f, 0.5)
    dt = np.gradient(t)
    inside = slice(1, -2)
    assert np.allclose(out[inside], 3.0 * (t + 0.5 * dt)[inside] + 1.0, rtol=0, atol=1e-12)
    assert out[-1] == f[-1]  # held at the end
    assert shifted(t, f, 0.0) is not None and np.array_equal(shifted(t, f, 0.0), f)


@pytest.mark.parametrize(("name", "effects", "seed"), [pytest.param(*c, id=campaign_id(*c)) for c in CAMPAIGNS])
def test_the_rigs_half_sample_lead_is_found_whatever_the_flux_carries(shared_campaigns, name, effects, seed):
    _, recs, tables = _campaign(shared_campaigns, name, effects, seed)
    timing = measure_force_timing(tables, recs, FluxCache())
    msg = json.dumps(timing.as_dict())
    assert timing.applied, msg
    assert abs(timing.lead_samples - RIG_LEAD) <= 0.1, msg
    assert timing.se_samples < 0.05, msg


@pytest.mark.parametrize("moved", [-RIG_LEAD, -1.0])
def test_a_force_moved_in_time_moves_the_lead_with_it(shared_campaigns, moved):
    _, recs, tables = _campaign(shared_campaigns, "VacoferS2", "", 16)
    timing = measure_force_timing(tables, _with_force_moved(recs, moved), FluxCache())
    msg = json.dumps(timing.as_dict())
    assert abs(timing.lead_samples - (RIG_LEAD + moved)) <= 0.1, msg
    if moved == -RIG_LEAD:  # on the voltage's time base: nothing to apply
        assert timing.used_lead_samples == 0.0 or abs(timing.lead_samples) < 0.1, msg
    else:
        assert timing.applied, msg


def test_without_a_force_at_rest_nothing_is_measured(shared_campaigns):
    _, recs, tables = _campaign(shared_campaigns, "VacoferS2", "", 16)
    strokes = [r for r in recs if r.kind in ("force_stroke", "flux", "eddy")]
    timing = measure_force_timing(tables, strokes, FluxCache())
    assert timing == ForceTiming() and timing.used_lead_samples == 0.0


def test_an_exact_models_voltage_step_force_falls_to_the_sensor_noise_with_the_lead(shared_campaigns):
    folder, recs, tables = _campaign(shared_campaigns, "VacoferS2", "", 16)
    noise = json.loads((folder / "truth.json").read_text())["effects"]["noise"]["force_noise_N"]
    step = [r for r in recs if r.kind == "voltage_step"]
    assert step
    plain, timed = FluxCache(), FluxCache()
    timed.force_lead_samples = measure_force_timing(tables, recs, timed).used_lead_samples
    rms = [float(np.sqrt(np.mean(_cases(tables, step, flux_of=fc)[0].residuals["force_N"] ** 2)))
           for fc in (plain, timed)]
    assert rms[0] > 1.5 * noise, rms  # half a sample of a fast rise: well above the noise
    assert rms[1] < 1.25 * noise and rms[1] < 0.65 * rms[0], rms  # the lead removes it: the sensor is left


def test_a_flux_from_rest_is_anchored_on_the_head_rest_not_on_the_first_samples_noise(shared_campaigns):
    """The model follows the current sensor's noise at rest (initial permeability: 1.5 mA, 3 sigma of the noise, is
    about 1 mWb here); an unlucky first sample must not move the whole flux comparison (it did: one sample was the
    anchor)."""
    _, recs, tables = _campaign(shared_campaigns, "random-2", "", 20)
    fc = FluxCache()
    rec = next(r for r in recs if r.kind in ("flux", "eddy") and r.voltage_V is not None
               and fc(r).head_rest_samples >= 20)
    bumped = dataclasses.replace(rec, current_A=np.r_[rec.current_A[0] + 1.5e-3, rec.current_A[1:]])
    psi_step = abs(tables.psi_of_current(1.5e-3, float(rec.positions_m()[0])) - tables.psi_of_current(0.0, float(
        rec.positions_m()[0])))
    res = [_cases(tables, [r], flux_of=FluxCache())[0].residuals["psi_Wb"] for r in (rec, bumped)]
    moved = float(np.median(res[1] - res[0]))
    assert psi_step > 2.0 * float(np.sqrt(np.mean(res[0] ** 2))), psi_step  # the bump would dominate the residual
    assert abs(moved) < 0.1 * psi_step, (moved, psi_step)  # the head rest's mean takes one sample's bump
