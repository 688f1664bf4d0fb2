"""Branches of excitations that hold the current at the top (:func:`solenoid_fmu.measure.branches.split_branches`).

A rig's trapezoid holds its current at the top for a while; the current is quantized by the DAQ (a 16-bit
channel: 153 uA per step on +-5 A), so two samples on the hold can be exactly the highest. ``find_peaks``
gave each of them the full prominence: two peaks a few samples apart, a branch pair of two samples between
them, and a commutation curve of one point from that recording (found on a fresh draw of the campaign
benchmark, ``benchmarks/bench_identify_campaigns.py --fresh``: the identification stopped with an
IndexError deep inside numpy).
"""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from solenoid_fmu.errors import RecordingError
from solenoid_fmu.identification import campaign_data as CD
from solenoid_fmu.identification import identify_from_recordings
from solenoid_fmu.measure import read_recording
from solenoid_fmu.measure.branches import PEAK_PROMINENCE, split_branches

#: The DAQ's current step [A] (16 bit over +-5 A).
LSB_A = 10.0 / 2**16
TOP_A = 0.76


def trapezoids(n_tops: int, hold_s: float, dip_A: float = TOP_A, rate_hz: float = 1000.0, seed: int = 0):
    """Time [s], quantized current [A] with 0.1 mA noise (two thirds of a step: ties at the top are common) and
    Psi [Wb] of ``n_tops`` trapezoids (1 s up, hold, 1 s down to ``TOP_A - dip_A``)."""
    rng = np.random.default_rng(seed)
    seg = []
    for _ in range(n_tops):
        seg += [np.linspace(TOP_A - dip_A, TOP_A, int(rate_hz)), np.full(int(hold_s * rate_hz), TOP_A),
                np.linspace(TOP_A, TOP_A - dip_A, int(rate_hz))]
    i = np.concatenate([np.zeros(200), *seg, np.zeros(200)])
    i = np.round((i + 1e-4 * rng.standard_normal(i.size)) / LSB_A) * LSB_A
    t = np.arange(i.size) / rate_hz
    return t, i, 0.3 * np.tanh(i / 0.4)


@pytest.mark.parametrize("hold_s", [0.0, 0.05, 0.4])
def test_a_quantized_hold_at_the_top_is_one_peak_and_its_branches_span_the_loop(hold_s):
    t, i, psi = trapezoids(3, hold_s)
    branches = split_branches(i, i, psi, thr=3 * LSB_A, k=1)
    assert len(branches) == 6, [(b.direction, b.start, b.stop) for b in branches]
    for b in branches:  # each branch runs from the valley to the top
        assert np.ptp(b.i_A) > 0.95 * TOP_A, (b.direction, b.start, b.stop)


def test_two_tops_apart_by_more_than_the_prominence_stay_two_and_a_shallow_dip_does_not_split():
    deep = PEAK_PROMINENCE * TOP_A * 1.5
    t, i, psi = trapezoids(2, 0.2, dip_A=deep)
    assert len(split_branches(i, i, psi, thr=3 * LSB_A, k=1)) == 4
    t, i, psi = trapezoids(2, 0.2, dip_A=0.5 * PEAK_PROMINENCE * TOP_A)
    branches = split_branches(i, i, psi, thr=3 * LSB_A, k=1)
    # the shallow dip between the tops is inside one top: one peak (the first ascent and the last descent)
    assert len(branches) == 2 and branches[0].stop < branches[1].stop


def test_the_commutation_curve_of_held_trapezoids_covers_the_loop():
    t, i, psi = trapezoids(3, 0.4)
    res = SimpleNamespace(psi_Wb=psi, time_s=t, branches=split_branches(i, i, psi, thr=3 * LSB_A, k=1))
    com_i, com_psi, _ = CD.corrected_curve_of([res], 0.0)
    assert com_i.size >= 95  # of 101 grid points
    assert np.max(np.abs(com_psi - 0.3 * np.tanh(com_i / 0.4))) < 0.01 * 0.3 * np.tanh(TOP_A / 0.4)


def test_a_campaign_whose_flux_recordings_give_no_curve_is_refused_naming_them(monkeypatch):
    """The guard behind the fix: a stroke whose branches give fewer than ``MIN_CURVE_POINTS`` points is left out
    with a note; when none is left the identification stops with a RecordingError naming the recordings."""
    demo = Path(__file__).resolve().parents[1] / "fitting" / "ps45-demo" / "recordings"
    recs = [read_recording(p) for p in sorted(demo.glob("*.csv"))]
    monkeypatch.setattr(CD, "corrected_curve", lambda cc, G, n=101: (np.zeros(1), np.zeros(1), np.zeros(1)))
    with pytest.raises(RecordingError) as err:
        identify_from_recordings(recs, progress=False)
    text = str(err.value)
    assert "01_flux_0p50A.csv" in text and "fewer than" in text
