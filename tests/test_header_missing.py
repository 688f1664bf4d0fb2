"""Recordings without ``coil_resistance_ohm`` (recordings.md: the header key is optional).

Found by stripping the key from a randomized X6Cr17 campaign with coil heating (seed 501): ``identify`` died in a
``ZeroDivisionError`` deep in the resistance fit (a recording whose data could not pin R had R0 = 0 from the
pseudo-inverse, then a kappa prior of width 0), and once that was mended it left out the flux recordings that
start energized or do not come back to their start (no R for eq. 4) though the campaign's tracks pinned them.
Now a recording without a header R gets a loose prior of its own (its mean U/i, +-10 %), and where its data cannot
pin R, the campaign's (same coil); the pipeline's step 1 writes R at the start from the data into the header where
it is as good as a measured one (:func:`solenoid_fmu.measure.headers.headers_from_data`; a force stroke, whose
armature moves, from its flux coming back to zero with the current) and names the rest.
"""

from __future__ import annotations

import dataclasses
import html
import json

import numpy as np
import pytest
from truthsteels import truth_dir

from solenoid_fmu.identification import identify_from_recordings
from solenoid_fmu.measure import campaign_resistance, headers_from_data, read_recording
from solenoid_fmu.measure.headers import FILL_KEY
from solenoid_fmu.realtime import load_tables
from solenoid_fmu.rig.protocols import random_campaign

SMOKE = dict(mesh_size=4.0, max_nfev=2, prediction=False, progress=False, workers=1)


def stripped(rec):
    return dataclasses.replace(rec, header={k: v for k, v in rec.header.items()
                                            if k not in ("coil_resistance_ohm", "coil_temperature_C")})


def campaign(tmp_path_factory, name, effects, seed):
    folder = tmp_path_factory.mktemp(f"{name}-{seed}")
    random_campaign(load_tables(truth_dir(name)), folder, effects, seed=seed, max_samples=4000)
    return [read_recording(p) for p in sorted((folder / "recordings").glob("*.csv"))]


@pytest.fixture(scope="module")
def heated(tmp_path_factory):
    """X6Cr17 with coil heating (the rig's headers: R measured before each run, a few mohm apart)."""
    return campaign(tmp_path_factory, "X6Cr17", "heating", 501)


@pytest.fixture(scope="module")
def hysteretic(tmp_path_factory):
    """AISI 1008 with hysteresis: three fast eddy trapezoids whose own data cannot pin R."""
    return campaign(tmp_path_factory, "AISI_1008", "hysteresis", 116)


def test_missing_headers_are_filled_from_the_data_within_their_sigma(heated):
    fix = headers_from_data([stripped(r) for r in heated])
    n_filled = 0
    for rec, got in zip(heated, fix.recordings, strict=True):
        if got.coil_resistance_ohm is None:
            assert any(line.startswith(rec.label()) for line in fix.unfilled), rec.label()
            continue
        n_filled += 1
        sigma = float(got.header[FILL_KEY])
        assert sigma < 0.005 * got.coil_resistance_ohm
        # the rig's header is the truth's R at the start, written to 0.1 mohm
        assert abs(got.coil_resistance_ohm - rec.coil_resistance_ohm) < 3.0 * sigma + 1e-4, rec.label()
    assert n_filled == len(fix.filled) >= 6
    # the force strokes (the armature moves: no track) from the flux's return with the campaign's heating rate
    moving = [r for r in heated if r.kind == "force_stroke" and r.voltage_V is not None]
    assert moving and all(any(line.startswith(r.label()) and "flux back at zero" in line for line in fix.filled)
                          for r in moving)
    assert fix.shifted is None
    # with the headers as the rig wrote them, nothing is filled or shifted
    assert headers_from_data(heated) == (heated, None, [], [])


def test_a_recording_that_cannot_pin_its_r_takes_the_campaigns(hysteretic):
    """Its own mean U/i is 17.2 ohm on the fastest trapezoid (the coil: 12.09); the campaign's prior brings it back
    within the header's uncertainty, reported as not pinned as well as a header would."""
    recs = [stripped(r) for r in hysteretic if r.kind in ("flux", "ramp", "eddy") and r.voltage_V is not None]
    camp = campaign_resistance(recs)
    truth = {r.label(): r.coil_resistance_ohm for r in hysteretic}
    loose = [tr for tr in camp.tracks.values() if tr.R0_sigma_ohm > 0.005 * tr.R0_ohm]
    assert loose, "the campaign has no recording that cannot pin its R: the test lost its case"
    for tr in camp.tracks.values():
        assert abs(tr.R0_ohm - truth[tr.label]) < max(3.0 * tr.R0_sigma_ohm, 1e-4), tr.label
        assert abs(tr.R0_ohm / truth[tr.label] - 1.0) < 0.005, tr.label
    for tr in loose:
        assert "campaign's R" in " ".join(tr.constraints)


@pytest.mark.slow
def test_identification_without_headers_uses_every_flux_recording_the_headers_allow(heated):
    """Smoke preset: the same recordings used as with the rig's headers (none left out for want of an R), the
    recordings without a header named, and the curve within 1 % in B of the one identified with the headers."""
    with_hdr = identify_from_recordings(heated, **SMOKE)
    without = identify_from_recordings([stripped(r) for r in heated], **SMOKE)
    left = [n for n in without.extra["notes"] if n.startswith("left out")]
    assert left == [n for n in with_hdr.extra["notes"] if n.startswith("left out")]
    assert any("no header resistance" in n for n in without.extra["notes"])
    H = np.geomspace(100.0, 2.0e4, 12)
    b0, b1 = with_hdr.curve.B_of_H(H), without.curve.B_of_H(H)
    assert np.max(np.abs(b1 / b0 - 1.0)) < 0.01


def test_the_pipeline_fills_and_names_missing_header_resistances(tmp_path, monkeypatch):
    """Smoke preset on one unit of the test lot with every header resistance removed (~30 s): the filled ones and the
    ones left without in ``summary.json`` and the report, the model validated on every recording."""
    import lotdata

    from solenoid_fmu.measure import write_recording
    from solenoid_fmu.pipeline import PRESETS, run_pipeline

    folder = lotdata.draw(tmp_path / "campaigns", units=[lotdata.plan()[0]])[0]
    paths = sorted((folder / "recordings").glob("*.csv"))
    orig = {p: read_recording(p) for p in paths}
    typo = next(p for p in paths if orig[p].coil_resistance_ohm is not None)  # its header R under a misspelt key
    for p in paths:
        rec = stripped(orig[p])
        if p == typo:
            rec = dataclasses.replace(rec, header={**rec.header, "coil_resistance_Ohm": orig[p].header[
                "coil_resistance_ohm"]})
        write_recording(p, rec)
    monkeypatch.setitem(PRESETS, "smoke", dict(PRESETS["smoke"], identify_max_nfev=1))
    summary = run_pipeline(folder, tmp_path / "out", preset="smoke", workers=1, progress=None,
                           start_material=lotdata.NOMINAL_STEEL_CSV)
    pol = summary["polarity"]
    named = [line.split(":")[0] for line in pol["header_resistance_filled"] + pol["header_resistance_missing"]]
    assert sorted(named) == sorted(str(p) for p in paths if orig[p].voltage_V is not None)
    for line in pol["header_resistance_filled"]:
        path = line.split(":")[0]
        R = float(line.split("coil_resistance_ohm ")[1].split(" +-")[0])
        assert abs(R / orig[next(p for p in paths if str(p) == path)].coil_resistance_ohm - 1.0) < 0.005, line
    assert pol["header_resistance_filled"]
    assert {row["file"] for row in summary["errors"]} == {p.name for p in paths}
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["polarity"] == pol
    page = (tmp_path / "out" / "report.html").read_text()
    assert f"Coil resistance: {pol['header_resistance_filled'][0].split(':')[0]}" in page
    # the misspelt key is named (and not read: that recording is filled or missing like the others, above)
    assert pol["names_not_read"] == [f"{typo.name}: header 'coil_resistance_Ohm' is not read (recordings.md has "
                                     "'coil_resistance_ohm')"]
    assert "Not read: " + html.escape(pol["names_not_read"][0]) in page
    # the lot's coil feature from the filled headers (no coil_temperature_C either: taken at 20 degC), against the
    # median of the rig's own headers (R at the start of each run, before any temperature correction)
    from solenoid_fmu.lot.features import unit_features

    R20 = unit_features(paths, tmp_path / "out")["R20_ohm"]
    want = float(np.median([r.coil_resistance_ohm for r in orig.values() if r.coil_resistance_ohm is not None]))
    assert abs(R20 / want - 1.0) < 0.003, (R20, want)
