"""A position column on fixed-stroke recordings, read by a sensor with noise (recordings.md allows the column in place
of the ``position_mm`` header).

Found at stop 52: 2 um of noise on every fixed-stroke recording of a randomized X6Cr17 campaign made each one
"moving" (its range above 1 um), and ``identify`` refused the whole campaign ("no recording with voltage at a fixed
stroke": no resistance tracks). :func:`solenoid_fmu.measure.conditioning.armature_moves` now reads a move against
the column's own noise.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from truthsteels import truth_dir

from solenoid_fmu.measure import campaign_resistance, read_recording
from solenoid_fmu.measure.conditioning import armature_moves
from solenoid_fmu.realtime import load_tables
from solenoid_fmu.rig.protocols import random_campaign


def noisy_position(rec, sigma_m, rng):
    """``rec`` with its header stroke replaced by a position column with white noise, quantized to 1 um."""
    x = float(rec.header["position_mm"]) * 1e-3
    col = np.round((x + rng.normal(0.0, sigma_m, rec.time_s.size)) * 1e6) * 1e-6
    return dataclasses.replace(rec, position_m=col, header={k: v for k, v in rec.header.items() if k != "position_mm"})


def test_a_noisy_fixed_stroke_does_not_move_a_carriage_run_does():
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 2.0, 20000)
    for sigma in (0.0, 1e-6, 2e-6, 5e-6):
        assert not armature_moves(np.round((1.5e-3 + rng.normal(0.0, sigma, t.size)) * 1e6) * 1e-6), sigma
    for span in (20e-6, 100e-6, 2e-3):  # a carriage run there and back, with 2 um of noise
        x = 1.0e-3 + span * np.sin(np.pi * t / t[-1]) + rng.normal(0.0, 2e-6, t.size)
        assert armature_moves(x), span
    assert not armature_moves(None)


@pytest.fixture(scope="module")
def recs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("posnoise")
    random_campaign(load_tables(truth_dir("X6Cr17")), folder, "heating", seed=501, max_samples=4000)
    return [r for r in (read_recording(p) for p in sorted((folder / "recordings").glob("*.csv")))
            if r.kind in ("flux", "ramp", "eddy") and r.voltage_V is not None]


def test_the_resistance_tracks_of_noisy_fixed_strokes_are_those_of_the_header_strokes(recs):
    """The tracks do not read the position: with the column they must be the same as with the header."""
    rng = np.random.default_rng(7)
    plain = campaign_resistance(recs)
    noisy = campaign_resistance([noisy_position(r, 2e-6, rng) for r in recs])
    assert not noisy.skipped and len(noisy.tracks) == len(plain.tracks) == len(recs)
    for a, b in zip(plain.tracks.values(), noisy.tracks.values(), strict=True):
        assert abs(a.R0_ohm - b.R0_ohm) <= 1e-9 * a.R0_ohm and abs(a.kappa_per_J - b.kappa_per_J) <= 1e-9 * abs(
            a.kappa_per_J) + 1e-15
