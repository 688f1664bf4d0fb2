"""Which resistance the identification's eq.-4 flux uses (:func:`~solenoid_fmu.identification.campaign_data.
resistance_choice`): the header's, unless the coil heats or a recording's own data pin its R away from it.

A three-cycle flux triangle through a coil with a known flux linkage (eq. 4 exact, no hysteresis): its
cycle closures pin R to about 1e-4 relative. A header 0.1 % off (inside the header's own 0.5 % prior, so
not "disagreeing" with it) drifts the eq.-4 flux by ~1 % of the peak per cycle; the data must win.
"""

import numpy as np
import pytest

from solenoid_fmu.identification.campaign_data import HEADER_OFF_SIGMAS, flux_points, resistance_choice
from solenoid_fmu.identification.fit import choose_currents
from solenoid_fmu.measure import make_recording

R_TRUE = 12.0
X_M = 1.5e-3


def _psi(i):
    """A saturating flux linkage [Wb] of the current [A]."""
    return 0.3 * np.tanh(i / 1.2) * 1.2


def _triangles(R_header, cycles=3, peak_A=1.5, period_s=1.6, fs=4000.0, seed=1):
    rest = 0.1
    t = np.arange(0.0, 2 * rest + cycles * period_s, 1.0 / fs)
    tc = np.clip(t - rest, 0.0, cycles * period_s)
    phase = (tc / period_s) % 1.0
    i = np.where(t < rest + cycles * period_s, peak_A * (1.0 - np.abs(2.0 * phase - 1.0)), 0.0)
    i[t < rest] = 0.0
    u = R_TRUE * i + np.gradient(_psi(i), t)
    u = u + 1e-4 * np.random.default_rng(seed).standard_normal(t.size)
    return make_recording("flux", "PS45", t, i, voltage_V=u, position_m=X_M, coil_resistance_ohm=R_header)


@pytest.mark.parametrize("header_off", [0.0, 1e-3])
def test_a_recordings_own_closures_overrule_a_header_a_little_off(header_off):
    rec = _triangles(R_TRUE * (1.0 + header_off))
    camp, use_tracks, notes = resistance_choice([rec])
    tr = camp.track_for(rec)
    assert tr.pinned and abs(tr.R0_ohm / R_TRUE - 1.0) < 2e-4  # the closures find the true R
    off_sigmas = abs(R_TRUE * (1 + header_off) - tr.R0_ohm) / tr.R0_sigma_ohm
    assert use_tracks == (off_sigmas > HEADER_OFF_SIGMAS) == (header_off > 0), (off_sigmas, notes)
    if use_tracks:
        assert "its own data pin R" in notes[0] and not tr.header_disagrees  # within the header's prior
    pts, _, _ = flux_points([rec], 6, choose_currents)
    err = max(abs(p.value / _psi(p.i_A) - 1.0) for p in pts if p.i_A > 0.3)
    assert err < 2e-3, err  # with the header R uncorrected: ~1 % of the peak per cycle


@pytest.mark.parametrize("header_off", [0.0, 1e-3])
def test_the_track_says_when_its_own_data_overrule_the_header(header_off, tmp_path, capsys):
    """The rule lives in measure (``ResistanceTrack.header_overruled``, ``HEADER_OFF_SIGMAS``): the same
    verdict as the identification's choice, and ``solenoid-fmu flux --json`` reports it."""
    import json

    from solenoid_fmu import measure
    from solenoid_fmu.cli import main
    from solenoid_fmu.measure import write_recording

    rec = _triangles(R_TRUE * (1.0 + header_off))
    camp, use_tracks, _ = resistance_choice([rec])
    tr = camp.track_for(rec)
    assert measure.HEADER_OFF_SIGMAS == HEADER_OFF_SIGMAS
    assert tr.header_overruled == use_tracks == (header_off > 0)
    assert tr.summary()["header_overruled"] == tr.header_overruled
    assert tr.header_off_sigmas == pytest.approx(abs(tr.header_R_ohm - tr.R0_ohm) / tr.R0_sigma_ohm)
    path = write_recording(tmp_path / "flux.csv", rec)
    assert main(["flux", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["header_resistance_overruled"] is (header_off > 0)
    assert not out["header_resistance_disagrees"]


@pytest.mark.parametrize("in_memory", [False, True])
def test_a_header_overruled_in_one_recording_leaves_the_others_on_their_headers(tmp_path, in_memory):
    """No heating, one recording's header 0.1 % off: its own track replaces its header, the other recordings
    keep theirs (their flux carries no track uncertainty that is not theirs); heating would need tracks for all.
    In memory (no file names, one label for both) each recording still gets its own track."""
    from solenoid_fmu.measure import read_recording, write_recording

    off, good = (_triangles(R_TRUE * (1 + d), seed=k) if in_memory else
                 read_recording(write_recording(tmp_path / f"{name}.csv", _triangles(R_TRUE * (1 + d), seed=k)))
                 for k, (name, d) in enumerate([("off", 1e-3), ("good", 0.0)]))
    assert (off.label() == good.label()) == in_memory
    camp, use_tracks, notes = resistance_choice([off, good])
    assert use_tracks and camp.header_elsewhere
    assert camp.track_for(off) is not None and camp.track_for(good) is None
    assert "1 recording(s)" in notes[0] and "the others keep their header's resistance" in notes[0]
    pts, _, details = flux_points([off, good], 6, choose_currents)
    err = max(abs(p.value / _psi(p.i_A) - 1.0) for p in pts if p.i_A > 0.3)
    assert err < 2e-3, err
    # the point sigma counts the one track among the two recordings (halved by the average), no more
    rel = max(p.sigma / abs(p.value) for p in pts if p.i_A > 0.3)
    assert rel < 3e-3, rel
