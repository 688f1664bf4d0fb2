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


def test_friction_is_fitted_on_moving_strokes_only_not_on_noisy_fixed_ones():
    """A fixed stroke's noisy column is no motion: before stop 53 it joined the friction fit (``np.ptp > 0``)."""
    from types import SimpleNamespace

    from solenoid_fmu.loop.effects import PRESLIDING_M, fit_friction

    rng = np.random.default_rng(11)
    t = np.linspace(0.0, 1.0, 4000)
    x_run = 1.5e-3 + 1.0e-3 * np.sin(2 * np.pi * t)  # a force stroke there and back
    sign = np.sign(np.gradient(x_run))
    Fc, p = 0.8, PRESLIDING_M[1]
    moving = SimpleNamespace(name="run", position_m=x_run,
                             residuals={"force_N": Fc * sign + rng.normal(0.0, 0.05, t.size)})
    fixed = [SimpleNamespace(name=f"fixed-{k}", position_m=np.round((x0 + rng.normal(0.0, 2e-6, t.size)) * 1e6) * 1e-6,
                             residuals={"force_N": 0.3 * np.sin(2 * np.pi * 3 * t) + rng.normal(0.0, 0.05, t.size)})
             for k, x0 in enumerate((0.5e-3, 1.0e-3, 2.0e-3))]
    params, info = fit_friction(None, {}, [moving, *fixed])
    assert info["fitted_on"] == ["run"]
    assert abs(params["force_N"] - Fc) < 0.05 * Fc and params["presliding_m"] <= 2 * p


def test_the_force_timing_reads_noisy_fixed_strokes_as_at_rest(recs):
    """The force channel's lead is measured on recordings at rest: a noisy column must not take them out."""
    from solenoid_fmu.loop.force_timing import measure_force_timing
    from solenoid_fmu.loop.residuals import FluxCache

    tables = load_tables(truth_dir("X6Cr17"))
    rng = np.random.default_rng(3)
    with_force = [r for r in recs if r.force_N is not None]
    assert with_force
    plain = measure_force_timing(tables, with_force, FluxCache())
    noisy = measure_force_timing(tables, [noisy_position(r, 2e-6, rng) for r in with_force], FluxCache())
    assert len(plain.recordings) == len(noisy.recordings) == len(with_force)
    assert abs(plain.lead_samples - noisy.lead_samples) <= max(0.2 * plain.se_samples, 0.01)
