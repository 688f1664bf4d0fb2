"""The loop's shared parts (issue 15): one excitation ordering for the split and the folds, one fit per parameter."""

from types import SimpleNamespace

import numpy as np
import pytest

from solenoid_fmu.loop.effects import fit_eddy_ladder, g_eddy_source
from solenoid_fmu.loop.split import cv_folds, split_recordings
from solenoid_fmu.loop.tables import with_effects
from solenoid_fmu.measure import read_recording


def _triangle(name, peak_A, rate_A_per_s, kind="eddy", fs=4000.0):
    t = np.arange(0.0, 2 * peak_A / rate_A_per_s, 1.0 / fs)
    i = peak_A - np.abs(rate_A_per_s * t - peak_A)
    return SimpleNamespace(name=name, path=None, kind=kind, time_s=t, current_A=i)


def test_split_and_folds_order_by_the_same_excitation_size():
    """Equal peaks (to 10 %), rates 25 .. 200 A/s, names in the opposite order: both deal out by rate."""
    recs = [_triangle(f"{k}.csv", peak, rate) for k, (peak, rate) in
            enumerate([(1.0, 25.0), (1.02, 50.0), (0.99, 100.0), (1.01, 200.0)])]
    fit, val = split_recordings(recs)
    assert [r.name for r in fit] == ["3.csv", "1.csv"] and [r.name for r in val] == ["2.csv", "0.csv"]
    (a, b), _ = cv_folds(recs)
    assert [k for k, _m in a] == [3, 1] and [k for k, _m in b] == [2, 0]


def test_the_eddy_ladder_names_its_g_eddy_as_the_maps_replacement(rig_maps, rig_campaign):
    """One fit per parameter: the ladder's refit of G_eddy says that it replaces the maps' value."""
    tables = rig_maps[0]
    recs = [read_recording(p) for p in rig_campaign("eddy-ladder")]
    section, note = fit_eddy_ladder(tables, {}, recs)
    g = note["G_eddy_S"]
    assert g["maps"] == tables.G_eddy_S and g["refit"] >= 0.0
    improved = with_effects(tables, {"eddy_ladder": section}, G_eddy_S=g["refit"],
                            G_eddy_source=g_eddy_source(tables, note))
    assert improved.G_eddy_S == pytest.approx(g["refit"])
    source = improved.meta["eddy"]["source"]
    assert "replaces the maps' G_eddy" in source and tables.meta["eddy"]["source"] in source
    assert with_effects(tables, {}).meta["eddy"] == tables.meta["eddy"]  # nothing replaced without a refit


def test_hysteresis_is_tried_on_its_flux_evidence_alone():
    """Steel hysteresis shows in the flux-current relation: a candidate that explains the force alone (random-2's
    clean campaign: a force-map error the stop operators followed along the strokes) is not tried, whatever its
    pooled score; the same shares on the flux are; other effects count every signal (friction: the force)."""
    from solenoid_fmu.loop.diagnosis import Candidate
    from solenoid_fmu.loop.gates import TRY_THRESHOLD, try_score

    force_only = Candidate("hysteresis", score=0.61, explained=0.64, per_signal={"force_N": 0.74, "psi_Wb": 0.016})
    on_flux = Candidate("hysteresis", score=0.61, explained=0.64, per_signal={"force_N": 0.0, "psi_Wb": 0.74})
    friction = Candidate("friction", score=0.61, explained=0.64, per_signal={"force_N": 0.74})
    assert try_score(force_only) == pytest.approx(0.016) and try_score(force_only) < TRY_THRESHOLD
    assert try_score(on_flux) == pytest.approx(0.74)
    assert try_score(friction) == pytest.approx(0.74)
