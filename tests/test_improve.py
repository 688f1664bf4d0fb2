"""The improvement loop on rig campaigns with undeclared effects (issue 7, "Must show")."""

import json

import numpy as np
import pytest

from solenoid_fmu.loop import ImproveError, improve_tables, split_recordings
from solenoid_fmu.measure import read_recording

#: Which residual signal each effect shows in.
AFFECTED = {"hysteresis": "psi_Wb", "heating": "psi_Wb", "eddy": "psi_Wb", "friction": "force_N"}


_CACHE = {}


def _improved(rig_maps, rig_campaign, effects):
    """improve_tables on a campaign, once per test process."""
    if effects not in _CACHE:
        recs = [read_recording(p) for p in rig_campaign(effects)]
        _CACHE[effects] = improve_tables(rig_maps[0], recs)
    return _CACHE[effects]


def _rms(cases, signal):
    res = [c.residuals[signal] for c in cases if signal in c.residuals]
    return float(np.sqrt(np.mean(np.concatenate(res) ** 2)))


@pytest.mark.parametrize(("effects", "expected"), [("hysteresis", "hysteresis"), ("heating", "heating"),
                                                   ("eddy-ladder", "eddy"), ("friction", "friction")])
def test_one_undeclared_effect_is_named_added_and_cuts_the_error(rig_maps, rig_campaign, effects, expected):
    res = _improved(rig_maps, rig_campaign, effects)
    assert res.diagnoses[0]["ranking"][0]["effect"] == expected
    assert res.diagnoses[0]["verdict"] == expected
    assert [s.effect for s in res.steps if s.accepted and not s.refit] == [expected]
    sig = AFFECTED[expected]
    before, after = _rms(res.cases_before, sig), _rms(res.cases_after, sig)
    assert after < before / 3.0, (before, after)
    if expected == "heating":  # the rig's thermal model: C_th = 300 J/K
        assert res.steps[0].params["C_th_J_per_K"] == pytest.approx(300.0, rel=0.08)
    if expected == "friction":  # the rig's friction: 2.5 N, presliding 20 um
        assert res.steps[0].params["force_N"] == pytest.approx(2.5, rel=0.05)
        assert res.steps[0].params["presliding_m"] == pytest.approx(20e-6, rel=0.5)


def test_no_effect_adds_nothing(rig_maps, rig_campaign):
    res = _improved(rig_maps, rig_campaign, "")
    assert res.steps == []
    assert res.diagnoses[-1]["verdict"] == "unexplained"
    assert not res.tables.meta.get("effects")


def test_two_effects_are_both_found_in_order_of_size(rig_maps, rig_campaign):
    kept = [s for s in _improved(rig_maps, rig_campaign, "heating,eddy-ladder").steps
            if s.accepted and not s.refit]
    assert sorted(s.effect for s in kept) == ["eddy", "heating"]
    gains = [s.heldout_before - s.heldout_after for s in kept]
    assert gains[0] > gains[1] > 0  # the first one added is the larger


def test_split_keeps_the_largest_excitation_for_fitting_and_validates_on_the_rest(rig_campaign):
    recs = [read_recording(p) for p in rig_campaign("")]
    fit, val = split_recordings(recs)
    names = lambda rs: sorted(r.path.name for r in rs)  # noqa: E731
    assert set(names(fit)).isdisjoint(names(val)) and len(fit) + len(val) == len(recs)
    assert "03_flux_1p50A.csv" in names(fit) and "02_flux_1p00A.csv" in names(val)
    assert all(r.kind not in ("ramp", "voltage_step") for r in fit)  # single recordings: validation only


@pytest.mark.slow
def test_cli_improve_builds_a_switchable_fmu_and_reports_before_after(rig_maps, rig_campaign, tmp_path, capsys):
    import fmpy.validation

    from solenoid_fmu.cli import main
    from solenoid_fmu.fmu import simulate_recording

    fmu = rig_maps[2]
    files = rig_campaign("hysteresis,friction")
    out = tmp_path / "improved.fmu"
    assert main(["improve", str(fmu), *files, "-o", str(out), "--json", "--report", str(tmp_path / "rep")]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["effects_added"] == ["hysteresis", "friction"]
    assert fmpy.validation.validate_fmu(str(out)) == []
    rows = {r["file"]: r for r in res["recordings"]}
    assert {r["split"] for r in rows.values()} == {"fit", "validate"}
    stroke = rows["05_force_stroke_1p00A.csv"]["signals"]["force_N"]  # a validation recording
    assert stroke["after"] < stroke["before"] / 3.0
    flux = rows["02_flux_1p00A.csv"]["signals"]["psi_Wb"]
    assert flux["after"] < flux["before"] / 2.0
    assert (tmp_path / "rep" / "improve.json").is_file()
    # the effects are switchable: switched off, the improved FMU is the plain one
    rec = read_recording(files[4])
    plain = simulate_recording(fmu, rec).recording
    off = simulate_recording(out, rec, params={"hysteresis_on": False, "friction_on": False}).recording
    np.testing.assert_allclose(off.force_N, plain.force_N, rtol=1e-12, atol=1e-12)
    on = simulate_recording(out, rec).recording
    assert np.max(np.abs(on.force_N - plain.force_N)) > 1.0


def test_improve_refuses_a_file_that_is_not_an_fmu(tmp_path, rig_campaign):
    from solenoid_fmu.loop import improve

    bad = tmp_path / "x.fmu"
    bad.write_text("not a zip")
    with pytest.raises(ImproveError, match="x.fmu"):
        improve(bad, rig_campaign("")[:2], tmp_path / "o.fmu")


def test_heating_correction_removes_the_eq4_flux_drift(rig_campaign):
    """The rig's heating (C_th 300 J/K, R_th 1 K/W, copper) leaves eq. 4's flux open at the end of a
    closed current cycle; the voltage corrected with the heating model closes it again."""
    from solenoid_fmu.loop import heating_corrected
    from solenoid_fmu.measure import flux_linkage

    heating = {"C_th_J_per_K": 300.0, "R_th_K_per_W": 1.0, "alpha_per_K": 0.00393}
    for path in rig_campaign("heating"):
        rec = read_recording(path)
        if rec.kind != "force_stroke":  # long recordings at constant current: the largest drift
            continue
        raw = flux_linkage(rec).psi_Wb
        fixed = flux_linkage(heating_corrected(rec, heating)).psi_Wb
        peak = np.max(np.abs(fixed))
        assert abs(raw[-1] - raw[0]) > 0.01 * peak
        assert abs(fixed[-1] - fixed[0]) < 0.1 * abs(raw[-1] - raw[0])
        assert "coil heating" in heating_corrected(rec, heating).header["notes"]


def test_hysteresis_is_fitted_along_the_heating_corrected_flux():
    """The demo campaign's coil warms by 0.4 K in the 2 A triangles: with the header resistance their eq.-4
    flux drifts by 17 % of the peak, and a play operator fitted along it absorbs the drift (misfit larger
    than the loop itself). With the model's heating (here the truth's) taken out of the voltage first, the
    fit leaves only the difference between the rig's Preisach loops and the play model, and the noise."""
    import glob
    from pathlib import Path

    from solenoid_fmu.loop.effects import fit_hysteresis
    from solenoid_fmu.realtime import load_tables

    demo = Path(__file__).resolve().parents[1] / "fitting" / "ps45-demo"
    truth = json.loads((demo / "truth.json").read_text())  # tests may read the truth
    tables = load_tables(demo / "truth" / "maps")
    heating = dict(truth["effects"]["heating"], alpha_per_K=truth["coil"]["alpha_per_K"])
    half_width_A = 0.03 * truth["coil"]["max_current_A"]  # the rig's hysteresis: 3 % of the rated current
    recs = [read_recording(p) for p in sorted(glob.glob(str(demo / "recordings" / "0[1-4]_flux_*.csv")))]
    _, drifting = fit_hysteresis(tables, {}, recs)
    _, corrected = fit_hysteresis(tables, {"heating": heating}, recs)
    assert drifting["rms_A"] > half_width_A, drifting
    assert corrected["rms_A"] < 0.2 * half_width_A, corrected


@pytest.mark.parametrize("if_error", [0.0, 0.03])
def test_hysteresis_fit_beside_a_b_h_error_is_chosen_on_recordings_it_was_not_fitted_on(if_error):
    """An identified B(H) leaves a single-valued error in i_f. Here the demo's true maps with i_f raised by up to
    ``if_error`` (a sine over the flux range, zero at both ends). The plays fitted alone along the flux triangles
    take that error in. Fitted beside a single-valued correction (then dropped), they keep only the loops.
    The eddy recordings, on which neither fit was made, tell the two apart:
    - on the true maps, the plain fit is kept (the correction would take a unipolar loop's offset from the plays);
    - with i_f 3 % high, the corrected fit is kept, and it predicts the eddy recordings many times better."""
    import glob
    from pathlib import Path

    from solenoid_fmu.loop.gates import hysteresis_chosen
    from solenoid_fmu.measure import flux_linkage
    from solenoid_fmu.realtime import MapTables, load_tables

    demo = Path(__file__).resolve().parents[1] / "fitting" / "ps45-demo"
    truth = json.loads((demo / "truth.json").read_text())  # tests may read the truth
    t = load_tables(demo / "truth" / "maps")
    heating = dict(truth["effects"]["heating"], alpha_per_K=truth["coil"]["alpha_per_K"])
    psi = np.arange(t.n_psi) * t.dpsi_Wb
    i_f = t._i_f_np * (1.0 + if_error * np.sin(np.pi * psi / psi[-1]))[:, None]
    tables = MapTables(psi, t.x_m, i_f, t._force_np, meta=t.meta)
    recs = [read_recording(p) for p in sorted(glob.glob(str(demo / "recordings" / "0[1-4]_flux_*.csv")))
            + sorted(glob.glob(str(demo / "recordings" / "1[03]_eddy_*.csv")))]
    _, note = hysteresis_chosen(tables, {"heating": heating}, recs, flux_linkage)
    errors = note["chosen_by"]
    assert errors["judged_on"] == ["10_eddy_12p5Aps.csv", "13_eddy_125Aps.csv"]
    assert note["fitted_on"] == [p.path.name for p in recs[:4]]
    if if_error == 0.0:
        assert "single_valued_correction" not in note
        assert errors["plain"] < errors["with_correction"]
    else:
        assert "single_valued_correction" in note
        assert errors["with_correction"] < 0.2 * errors["plain"], errors
