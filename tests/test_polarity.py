"""A rig wired the other way round: recordings with a negative current (and bipolar ones).

The flux linkage of a solenoid without a permanent magnet is odd in the current and its force even, so a campaign
recorded with i < 0 is the mirror image of the same campaign with i > 0: every command that reads a campaign takes it
mirrored and must find what it finds on the original (negating a float is exact; the results are compared to 1e-9).
Before this a negative campaign crashed the identification inside numpy (``np.bincount``: negative elements) and
``solenoid-fmu flux`` printed 607 "peaks" and a flux of -0.3 mWb at the peak. A bipolar recording cannot be analysed
as excursions from zero: it is left out by file name and the time of its sign change, never a traceback.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from solenoid_fmu.cli import main
from solenoid_fmu.errors import RecordingError
from solenoid_fmu.identification import identify_from_recordings
from solenoid_fmu.maps import fit_eddy, load_maps
from solenoid_fmu.measure import flux_linkage, read_recording, unipolar, write_recording
from solenoid_fmu.measure.polarity import POLARITY_NOISE_SHARE, current_sign


def negated(rec):
    """The same measurement taken with the opposite polarity: i -> -i, U -> -U, force and position as they are."""
    return dataclasses.replace(rec, current_A=-rec.current_A,
                               voltage_V=None if rec.voltage_V is None else -rec.voltage_V)


def bipolar(rec):
    """``rec`` followed by its own negative (the triangle run again with the opposite sign, one sample period later):
    the recording and the index of its first negative sample."""
    t, dt = np.asarray(rec.time_s), float(rec.time_s[1] - rec.time_s[0])
    both = dataclasses.replace(rec, time_s=np.concatenate([t, t + t[-1] + dt - t[0]]),
                               current_A=np.concatenate([rec.current_A, -rec.current_A]),
                               voltage_V=np.concatenate([rec.voltage_V, -rec.voltage_V]))
    return both, t.size + int(np.argmax(-rec.current_A < -POLARITY_NOISE_SHARE * np.max(rec.current_A)))


def same(got, want):
    """Equal as far as the arithmetic goes: the mirrored recording's arrays are the original's to the bit, but a
    BLAS or MKL kernel may take another path for another memory alignment of the same numbers."""
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=0.0)


@pytest.fixture(scope="module")
def campaign(rig_campaign):
    return [read_recording(p) for p in rig_campaign("")]


def test_a_negative_recording_is_taken_as_its_exact_mirror(campaign):
    recs, turned, left = unipolar([negated(r) for r in campaign])
    assert not left and len(turned) == len(campaign)
    for got, want in zip(recs, campaign, strict=True):
        assert np.array_equal(got.current_A, want.current_A)
        assert (want.voltage_V is None) or np.array_equal(got.voltage_V, want.voltage_V)
        assert (want.force_N is None) or np.array_equal(got.force_N, want.force_N)
        assert got.header["polarity"].startswith("mirrored")
    assert unipolar(recs)[1] == []  # idempotent: a mirrored recording is positive
    assert unipolar(campaign)[0] == campaign  # positive recordings pass unchanged


def test_an_undershoot_is_not_a_second_polarity_a_sustained_excursion_is(campaign):
    rec = max(campaign, key=len)  # 5 samples are 0.14 % of it, under the 0.5 % percentile the excursions are read at
    i = np.array(rec.current_A)
    i[-5:] = -2.0 * POLARITY_NOISE_SHARE * np.max(i)  # a controller's undershoot of a few samples
    assert current_sign(dataclasses.replace(rec, current_A=i)) == (1, -1)
    m = i.size // 50  # the last 2 % of the recording at the same current: an excursion of the other sign
    i[-m:] = -2.0 * POLARITY_NOISE_SHARE * np.max(i)
    assert current_sign(dataclasses.replace(rec, current_A=i)) == (0, i.size - m)
    i[-m:] = -0.6 * POLARITY_NOISE_SHARE * np.max(i)  # as long, but within the noise share
    assert current_sign(dataclasses.replace(rec, current_A=i)) == (1, -1)


#: The identification's settings here (coarse: what is compared is the data that reach the fit, not the fit).
SMOKE = dict(mesh_size=4.0, max_nfev=2, prediction=False, progress=False, workers=1)


@pytest.fixture(scope="module")
def identified(campaign):
    return identify_from_recordings(campaign, **SMOKE)


def test_the_identification_of_a_negative_campaign_is_that_of_the_campaign(campaign, identified):
    got = identify_from_recordings([negated(r) for r in campaign], **SMOKE)
    same(got.curve.B_T, identified.curve.B_T)
    same(got.curve.H_A_per_m, identified.curve.H_A_per_m)
    assert sum("taken mirrored" in n for n in got.extra["notes"]) == len(campaign)


def test_a_force_column_of_the_opposite_sign_is_taken_negated(campaign, identified):
    """A load cell mounted the other way round: every force recording's column negated. Left as it was, the
    identification fitted a curve 140 % off the force points (DC03, seed 402)."""
    flipped = [dataclasses.replace(r, force_N=-r.force_N) if r.force_N is not None else r for r in campaign]
    recs, turned, left = unipolar(flipped)
    with_force = [r for r in campaign if r.force_N is not None]
    assert not left and len(turned) == len(with_force) >= 3
    assert all("force negative while the coil is energized" in t for t in turned)
    assert all(np.array_equal(a.force_N, b.force_N) for a, b in zip(recs, campaign, strict=True)
               if b.force_N is not None)
    got = identify_from_recordings(flipped, **SMOKE)
    same(got.curve.B_T, identified.curve.B_T)


def test_the_eddy_fit_of_negative_recordings_is_that_of_the_recordings(campaign, rig_maps):
    maps = load_maps(rig_maps[1])
    eddy = [r for r in campaign if r.kind == "eddy"]
    want, got = fit_eddy(eddy, maps), fit_eddy([negated(r) for r in eddy], maps)
    assert want.G_eddy_S > 0.0
    same([got.G_eddy_S, got.r2], [want.G_eddy_S, want.r2])


def test_a_bipolar_flux_recording_is_left_out_by_name_and_time(campaign, tmp_path):
    flux = [r for r in campaign if r.kind == "flux"]
    bip, k = bipolar(flux[0])
    path = write_recording(tmp_path / "bipolar.csv", bip)
    bip = read_recording(path)
    with pytest.raises(RecordingError) as err:  # the eq.-4 analysis itself says why, naming the file
        flux_linkage(bip)
    msg = str(err.value)
    assert "bipolar.csv" in msg and "bipolar current" in msg and f"t = {bip.time_s[k]:.6g} s" in msg
    res = identify_from_recordings([bip] + [r for r in campaign if r is not flux[0]], **SMOKE)
    assert any("left out" in n and "bipolar.csv" in n and "bipolar current" in n for n in res.extra["notes"])
    assert str(path) not in res.extra["recordings"]
    with pytest.raises(RecordingError, match="bipolar current"):  # nothing else to identify from: said, not a crash
        identify_from_recordings([bip], progress=False)


def test_the_flux_command_reads_a_negative_recording_as_the_positive_one(campaign, tmp_path, capsys):
    rec = next(r for r in campaign if r.kind == "flux")
    pos = write_recording(tmp_path / "pos.csv", rec)
    neg = write_recording(tmp_path / "neg.csv", negated(rec))
    assert main(["flux", str(pos), "--json"]) == 0
    want = json.loads(capsys.readouterr().out)
    assert main(["flux", str(neg), "--json"]) == 0
    out = capsys.readouterr()
    got = json.loads(out.out)
    assert "taken mirrored" in out.err
    assert want["psi_at_peak_Wb"] > 0.0
    same([got["psi_at_peak_Wb"], got["peak_current_A"]], [want["psi_at_peak_Wb"], want["peak_current_A"]])


def test_the_pipeline_mirrors_a_negative_recording_and_leaves_a_bipolar_one_out(tmp_path, monkeypatch):
    """Smoke preset (one evaluation per identification stage) on one unit of the test lot, one flux recording
    rewritten negative and one eddy recording bipolar (~30 s): both named in ``summary.json``; the negative one is
    identified from, the bipolar one validated on nowhere."""
    import lotdata

    from solenoid_fmu.pipeline import PRESETS, run_pipeline

    folder = lotdata.draw(tmp_path / "campaigns", units=[lotdata.plan()[0]])[0]
    paths = sorted((folder / "recordings").glob("*.csv"))
    recs = {p: read_recording(p) for p in paths}
    neg = next(p for p in paths if recs[p].kind == "flux")
    bip = next(p for p in paths if recs[p].kind == "eddy")
    write_recording(neg, negated(recs[neg]))
    write_recording(bip, bipolar(recs[bip])[0])
    monkeypatch.setitem(PRESETS, "smoke", dict(PRESETS["smoke"], identify_max_nfev=1))
    summary = run_pipeline(folder, tmp_path / "out", preset="smoke", workers=1, progress=None,
                           start_material=lotdata.NOMINAL_STEEL_CSV)
    assert [m.split(":")[0] for m in summary["polarity"]["mirrored"]] == [str(neg)]
    assert [m.split(":")[0] for m in summary["polarity"]["left_out"]] == [str(bip)]
    assert "bipolar current" in summary["polarity"]["left_out"][0]
    assert str(neg) in summary["identification"]["recordings"]
    files = {row["file"] for row in summary["errors"]}
    assert neg.name in files and bip.name not in files
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["polarity"] == summary["polarity"]
    page = (tmp_path / "out" / "report.html").read_text()
    assert f"Polarity: {neg}" in page and f"Left out: {bip}" in page
