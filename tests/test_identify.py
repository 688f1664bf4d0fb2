"""Tests of the B(H) identification (paper sec. 4) on cases with a known true curve.

Budget: the FEM cases run at the identification's default mesh size (2.0) with few currents; the
demo-campaign case (hysteresis + noise) goes through the command line once.
"""

import dataclasses
import glob
import json

import numpy as np
import pytest

from solenoid_fmu import cli
from solenoid_fmu.errors import RecordingError, SolenoidError
from solenoid_fmu.field.geometry import load_geometry
from solenoid_fmu.field.material import MU_0, bh_curve_from_table, load_material, read_bh_csv
from solenoid_fmu.identification import (
    NLOPT_CODES,
    FluxModel,
    SusceptibilityModel,
    choose_currents,
    fem_flux,
    fem_force_vs_stroke,
    fit_to_curve,
    identify_bh,
    identify_from_recordings,
    nlopt_code_name,
    scaled_curve,
)
from solenoid_fmu.maps import force_at, load_maps, psi_at

DEMO = "fitting/ps45-demo"
X_ID = 1.5e-3


@pytest.fixture(scope="module")
def fitted():
    lit = load_material()
    model, theta = fit_to_curve(lit)
    return lit, model, theta


def test_fit_reproduces_literature_curve(fitted):
    lit, model, theta = fitted
    H = np.geomspace(100.0, 1e5, 40)
    err = np.abs(model.curve(theta).B_of_H(H) / lit.B_of_H(H) - 1.0)
    assert err.max() < 0.05


def test_parameterization_is_physical_for_any_parameters_within_bounds():
    model = SusceptibilityModel(np.geomspace(50.0, 2e5, 7), peak=3)
    lo, hi = model.bounds()
    rng = np.random.default_rng(1)
    for _ in range(5):
        theta = rng.uniform(np.maximum(lo, -8.0), np.minimum(hi, 8.0))
        H, B = model.table(theta)
        assert np.all(np.diff(B) > 0)
        chi = model.chi(H[1:], theta)
        k = int(np.argmax(chi))
        assert np.all(np.diff(chi[: k + 1]) >= -1e-12 * chi.max())
        assert np.all(np.diff(chi[k:]) <= 1e-12 * chi.max())
        # slope tends to mu0 at high field
        slope = (B[-1] - B[-2]) / (H[-1] - H[-2])
        assert slope / MU_0 < 1.0 + 0.05 * chi.max()


def test_scaled_curve_is_the_polarization_scaled_and_stretched():
    lit = load_material()
    a, s = 0.95, 1.3
    c = scaled_curve(lit, np.log(a), np.log(s))
    H = np.geomspace(50.0, 1e5, 30)
    expect = MU_0 * H + a * (lit.B_of_H(H / s) - MU_0 * H / s)
    assert np.max(np.abs(c.B_of_H(H) / expect - 1.0)) < 2e-3
    assert abs(c.dH_dB(3.0) * MU_0 - 1.0) < 1e-9  # beyond the last knot: slope mu0


def test_bad_input_raises():
    lit = load_material()
    with pytest.raises(SolenoidError, match="at least 3"):
        identify_bh([1.0, 2.0], [0.1, 0.2], 0.0005, None, lit)
    with pytest.raises(SolenoidError, match="unknown method"):
        identify_bh([0.5, 1.0, 1.5], [0.1, 0.2, 0.25], 0.0015, load_geometry(), lit, method="pattern")
    assert nlopt_code_name(4) == "XTOL_REACHED" and nlopt_code_name(-4) == "ROUNDOFF_LIMITED"


def test_no_flux_recording_is_a_clear_error():
    from solenoid_fmu.measure import read_recording

    with pytest.raises(RecordingError, match="no 'flux' recording"):
        identify_from_recordings([f"{DEMO}/recordings/10_eddy_12p5Aps.csv"], progress=False)
    # recordings in memory are taken as they are (the pipeline's heating-corrected ones), with or without a file
    rec = read_recording(f"{DEMO}/recordings/10_eddy_12p5Aps.csv")
    with pytest.raises(RecordingError, match=r"among 2 file\(s\): 10_eddy_12p5Aps.csv \(eddy\), in memory \(eddy\)"):
        identify_from_recordings([rec, dataclasses.replace(rec, path=None)], progress=False)


def _central_differences(f, p, h: float = 1e-3):
    """d f / d p_k by central differences, one array per parameter k."""
    out = []
    for k in range(len(p)):
        e = np.zeros(len(p))
        e[k] = h
        out.append((f(p + e) - f(p - e)) / (2 * h))
    return out


def test_adjoint_jacobian_matches_finite_differences():
    geom = load_geometry()
    lit = load_material()
    fm = FluxModel(geom, X_ID, [0.3, 1.0, 2.0], lambda p: scaled_curve(lit, p[0], p[1]), 3.0, lit)
    p = np.array([0.02, 0.2])
    J = fm.jacobian(p)
    for k, fd in enumerate(_central_differences(fm.psi, p)):
        assert np.allclose(J[:, k], fd, rtol=2e-3, atol=1e-4 * np.abs(J).max())
    assert fm.adjoint_solves == 3


def _hill_steel():
    """A true steel of a different shape than the literature one (Hill-type polarization)."""
    H = np.concatenate([[0.0], np.geomspace(1.0, 3e5, 200)])
    n, Hk = 1.8, 1300.0
    return bh_curve_from_table(H, MU_0 * H + 1.95 * (H / Hk) ** n / (1 + (H / Hk) ** n), name="hill")


@pytest.mark.slow
def test_synthetic_truth_of_another_shape_recovered():
    """True steel of another shape than the start: stage 1 cannot match it, stage 2 must."""
    geom = load_geometry()
    true = _hill_steel()
    i_grid = np.linspace(0.0, 2.0, 101)
    i_sel, _ = choose_currents(i_grid, i_grid)
    psi = fem_flux(geom, true, i_sel, X_ID, 2.0)
    res = identify_bh(i_sel, psi, X_ID, geom, load_material(), mesh_size=2.0)
    assert res.extra["stage2"]["accepted"]
    lo, hi = res.identified_H_range_A_per_m
    assert hi > 5 * max(lo, 1.0)  # a real range, reaching into saturation
    H = np.geomspace(max(lo, 10.0), hi, 40)
    err = np.abs(res.curve.B_of_H(H) / true.B_of_H(H) - 1.0)
    assert err.max() < 0.03
    assert res.rms_after < 0.005 < res.rms_before
    assert res.mae_after <= res.rms_after
    assert all(v == 0.0 for v in res.constraint_residuals.values())
    s = res.summary()
    json.dumps(s)
    assert s["fem_solves"] == res.fem_solves > 0 and s["equivalent_sweeps"] > 0


    # the other strokes and the force at 0.5 .. 2 A (same FEM mesh as the truth)
    i = np.array([0.25, 0.5, 1.0, 1.5, 2.0])
    for x in (0.6e-3, 2.6e-3):
        p_true = fem_flux(geom, true, i, x, 2.0)
        p_id = fem_flux(geom, res.curve, i, x, 2.0)
        assert np.sqrt(np.mean(((p_id - p_true) / p_true.max()) ** 2)) < 0.02
    xs = np.array([0.6e-3, 1.5e-3, 2.6e-3])
    for i_A in (0.5, 2.0):
        f_true = fem_force_vs_stroke(geom, true, i_A, xs, 2.0)
        f_id = fem_force_vs_stroke(geom, res.curve, i_A, xs, 2.0)
        assert np.max(np.abs(f_id / f_true - 1.0)) < 0.02


def test_auglag_reference_reports_in_words_and_stays_feasible():
    geom = load_geometry()
    lit = load_material()
    i = np.array([0.3, 1.0, 2.0])
    psi = fem_flux(geom, scaled_curve(lit, 0.0, np.log(1.3)), i, X_ID, 3.0)
    res = identify_bh(i, psi, X_ID, geom, lit, mesh_size=3.0, method="auglag", max_eval_auglag=6)
    assert res.status in NLOPT_CODES.values()
    assert res.fem_solves >= 6 * len(i)
    assert all(v <= 1e-6 for v in res.constraint_residuals.values())
    # the best point may be the start, re-solved along another warm-start path: equal to the FEM's convergence
    # (Psi within ~1e-8 relative), so the slack is 1e-7 of the peak flux (the units of the mae), not rounding level
    assert res.mae_after <= res.extra["auglag_mae_at_start_parameters"] + 1e-7


@pytest.mark.slow
def test_demo_campaign_with_hysteresis_and_noise(tmp_path):
    """The command line on the demo campaign (all kinds of recordings; hysteresis, noise, eddy
    ladder, friction): curve within 5 % of the truth over the identified range, force within 5 %."""
    csv = tmp_path / "material.csv"
    rep = tmp_path / "report"
    paths = sorted(glob.glob(f"{DEMO}/recordings/*.csv"))
    rc = cli.main(["identify", *paths, "-o", str(csv), "--report", str(rep), "--max-evals", "6", "--json"])
    assert rc == 0
    summary = json.loads((rep / "identification.json").read_text())
    true = load_material(f"{DEMO}/truth/true-steel.csv")
    ident = load_material(csv)  # physical: passes the material checks
    lo, hi = summary["identified_H_range_A_per_m"]
    assert hi > 5 * max(lo, 1.0)
    H = np.geomspace(max(lo, 10.0), hi, 40)
    assert np.max(np.abs(ident.B_of_H(H) / true.B_of_H(H) - 1.0)) < 0.05
    assert summary["flux_error_after"]["rms_rel_peak"] < summary["flux_error_before"]["rms_rel_peak"]
    assert len(summary["recordings"]) == 4  # the flux ones; other kinds ignored
    # force vs stroke against the truth model (maps built at mesh 1.0) at 0.5 .. 2 A
    maps = load_maps(f"{DEMO}/truth/maps")
    geom = load_geometry()
    xs = np.array([0.6e-3, 1.5e-3, 2.6e-3])
    for i_A in (0.5, 1.0, 2.0):
        f_id = fem_force_vs_stroke(geom, ident, i_A, xs, summary["mesh_size"])
        f_true = force_at(maps, np.full_like(xs, i_A), xs)
        assert np.max(np.abs(f_id / f_true - 1.0)) < 0.05
    # flux at other strokes against the truth maps
    i = np.array([0.25, 0.5, 1.0, 1.5, 2.0])
    for x in (0.6e-3, 2.6e-3):
        p_id = fem_flux(geom, ident, i, x, summary["mesh_size"])
        p_true = psi_at(maps, i, np.full_like(i, x))
        assert np.sqrt(np.mean(((p_id - p_true) / p_true.max()) ** 2)) < 0.02
    for row in summary["validation"]["force_stroke"]:
        assert row["rms_rel_after"] < row["rms_rel_before"]
    # exports for commercial FEM and the report
    H, B = read_bh_csv(csv)
    bh = np.loadtxt(csv.with_suffix(".bh"))
    tab = np.loadtxt(csv.with_suffix(".tab"))
    assert np.allclose(bh[:, 0], B) and np.allclose(bh[:, 1], H)
    assert np.allclose(tab[:, 0], H) and np.allclose(tab[:, 1], B)
    for name in ("fig10_flux.png", "fig11_bh.png", "fig15_force_stroke.png"):
        assert (rep / name).stat().st_size > 10_000
    assert summary["status"] and summary["method"] == "gn"


def test_flux_at_other_strokes_validates_in_the_report(tmp_path):
    """Flux recordings at two strokes: the stroke with more recordings is identified, the other
    one is compared in fig. 16 and the JSON (here copies of demo recordings relabelled 2.0 mm)."""
    from solenoid_fmu.identification import group_flux, write_report
    from solenoid_fmu.measure import read_recording

    src = sorted(glob.glob(f"{DEMO}/recordings/0[1-4]_flux_*.csv"))
    moved = []
    for p in src[:2]:
        text = open(p).read().replace("# position_mm: 1.5\n", "# position_mm: 2.0\n")
        q = tmp_path / ("moved_" + p.rsplit("/", 1)[-1])
        q.write_text(text)
        moved.append(q)
    recs = [read_recording(p) for p in [*src, *moved]]
    main, others = group_flux(recs)
    assert len(main) == 4 and {float(np.median(r.positions_m())) for r in main} == {X_ID}
    assert len(others) == 1 and abs(float(np.median(others[0][0].positions_m())) - 2.0e-3) < 1e-9
    geom = load_geometry()
    lit = load_material()
    i = np.array([0.3, 1.0, 2.0])
    psi = fem_flux(geom, scaled_curve(lit, 0.0, np.log(1.3)), i, X_ID, 3.0)
    res = identify_bh(i, psi, X_ID, geom, lit, mesh_size=3.0, stage2=False)
    summary = write_report(res, tmp_path / "rep", geometry=geom, other_flux=others)
    assert (tmp_path / "rep" / "fig16_flux_other_strokes.png").stat().st_size > 10_000
    # the figures written are also in memory, as the pipeline's report embeds them
    assert sorted(res.figures) == sorted(p.name for p in (tmp_path / "rep").glob("*.png"))
    assert all(res.figures[p.name] == p.read_bytes() for p in (tmp_path / "rep").glob("*.png"))
    (row,) = summary["validation"]["flux_other_strokes"]
    assert row["x_mm"] == pytest.approx(2.0)
    # the relabelled data were measured at 1.5 mm: both curves must miss them by the stroke's effect
    assert 0.005 < row["rms_rel_after"] < 0.2 and 0.005 < row["rms_rel_before"] < 0.2
    saved = json.loads((tmp_path / "rep" / "identification.json").read_text())
    assert saved["validation"] == json.loads(json.dumps(summary["validation"]))
    assert saved["flux_error_after"]["rms_weighted_rel_peak"] < saved["flux_error_before"]["rms_weighted_rel_peak"]


def test_curves_within_bounds_pass_the_material_checks(tmp_path, fitted):
    """Any parameter vector within the bounds gives a table that load_material accepts."""
    from solenoid_fmu.field.material import write_bh_csv

    lit, model, theta = fitted
    lo, hi = model.bounds()
    rng = np.random.default_rng(3)
    for k in range(4):
        t = np.clip(theta + rng.normal(0.0, 0.5, len(theta)), lo, hi)
        H, B = model.curve(t).table(n=200)
        path = write_bh_csv(tmp_path / f"c{k}.csv", H, B)
        back = load_material(path)
        assert np.max(np.abs(back.B_of_H(H[1:]) / B[1:] - 1.0)) < 0.01


def test_point_model_jacobian_matches_finite_differences_in_the_curve():
    """PointModel's Jacobian (flux by the adjoint, force by the one-sided x-difference of dW'/dtheta) against
    central differences of the values themselves in both curve parameters, at four strokes (0.5 mm, where
    the truncation error is largest) and at the stroke's end (where the x-step turns inwards)."""
    from solenoid_fmu.identification.point_model import PointModel

    geom = load_geometry()
    lit = load_material()
    x_end = geom.stroke.max_m
    pts = [("psi", 0.5, 1.0e-3), ("psi", 1.5, 2.0e-3), ("force", 0.8, 1.0e-3), ("force", 1.6, 2.5e-3),
           ("force", 1.2, x_end), ("force", 0.3, 0.5e-3)]
    pm = PointModel(geom, pts, lambda p: scaled_curve(lit, p[0], p[1]), 3.0, lit)
    p = np.array([0.05, 0.3])
    J = pm.jacobian(p)
    for k, fd in enumerate(_central_differences(pm.values, p)):
        np.testing.assert_allclose(J[:, k], fd, rtol=5e-3, atol=1e-4 * np.abs(fd).max())


def _points(curve, sigma_rel, mesh_size=3.0):
    """Flux points of ``curve`` at two strokes and three currents (exact FEM values, ``sigma_rel`` of each)."""
    from solenoid_fmu.identification.campaign_data import MeasuredPoint

    geom = load_geometry()
    pts = []
    for x in (1.0e-3, 2.5e-3):
        i = np.array([0.3, 0.8, 1.8])
        psi = fem_flux(geom, curve, i, x, mesh_size)
        pts += [MeasuredPoint("psi", float(a), x, float(p), sigma_rel * float(p), f"flux@{x * 1e3:g}mm", "test")
                for a, p in zip(i, psi, strict=True)]
    return pts


def test_stage_2_runs_only_where_stage_1_leaves_something_to_predict():
    """joint.stage1_enough: points a scaled and stretched literature curve predicts held out within their
    sigma stop after stage 1 (its two parameters fit them); points of another shape, 0.2 % sigma, go on to stage 2."""
    from solenoid_fmu.identification.joint import STAGE1_ENOUGH_HELD_OUT, identify_joint, stage1_enough

    geom = load_geometry()
    lit = load_material()
    near = identify_joint(_points(scaled_curve(lit, np.log(1.05), np.log(0.8)), 0.002), geom, lit, 3.0, max_nfev=3)
    assert list(near.candidates) == ["stage 1"] and near.chosen == "stage 1"
    assert stage1_enough(near.candidates["stage 1"]["r_out"])
    other = identify_joint(_points(_hill_steel(), 0.002), geom, lit, 3.0, max_nfev=3)
    assert other.candidates["stage 1"]["rms_out"] > STAGE1_ENOUGH_HELD_OUT
    assert "stage 2 (prior 1)" in other.candidates


def test_stage_1_is_enough_only_clearly_inside_the_noise_of_its_held_out_rms():
    """An RMS just under 1 sigma over 20 points is within the RMS's own scatter (about 0.16) of a wrong shape: stage
    2 runs (random-0 #108 of the fresh draw stopped at 0.955 with F 2.6 % off); well under it, or over many points,
    stage 1 is enough."""
    from solenoid_fmu.identification.joint import stage1_enough

    unit = np.resize([1.0, -1.0], 20)
    assert not stage1_enough(0.955 * unit)
    assert stage1_enough(0.44 * unit)
    assert stage1_enough(0.955 * np.resize(unit, 2000)) and not stage1_enough(1.01 * np.resize(unit, 2000))
    assert not stage1_enough([])


def test_the_band_belongs_to_the_chosen_curve_when_stage_2_loses(monkeypatch):
    """Stage 2 run (the held-out shortcut switched off) on points stage 1 fits exactly: held-out prediction
    keeps stage 1, and the fit's theta (the B(H) band's linearization point) is stage 1's curve, not the
    stage-2 run's."""
    from solenoid_fmu.identification import joint

    monkeypatch.setattr(joint, "STAGE1_ENOUGH_HELD_OUT", -1.0)
    geom = load_geometry()
    lit = load_material()
    fit = joint.identify_joint(_points(scaled_curve(lit, np.log(1.05), np.log(0.8)), 0.002), geom, lit, 3.0,
                               max_nfev=3)
    assert "stage 2 (prior 1)" in fit.candidates and fit.chosen == "stage 1"
    theta2 = fit.candidates["stage 2 (prior 1)"]["theta"]
    assert np.max(np.abs(theta2 - fit.theta_stage1)) > 1e-3  # the stage-2 run moved
    np.testing.assert_array_equal(fit.theta, fit.theta_stage1)  # the band is linearized at stage 1's curve
    assert fit.J_w.shape == (len(fit.points), len(fit.theta))


def test_the_weaker_prior_runs_only_where_the_stronger_leaves_held_out_error(monkeypatch):
    """joint.PRIOR_WEIGHTS: stage 2 runs at the next, weaker prior only while the last run predicts its held-out
    groups worse than STAGE1_ENOUGH_HELD_OUT; with every run forced, the band is linearized at the chosen
    candidate's curve, not at the last run's."""
    from solenoid_fmu.identification import joint

    geom = load_geometry()
    lit = load_material()
    weak = f"stage 2 (prior {joint.PRIOR_WEIGHTS[1]:g})"
    fit = joint.identify_joint(_points(_hill_steel(), 0.002), geom, lit, 3.0, max_nfev=3)
    assert (weak in fit.candidates) == (fit.candidates["stage 2 (prior 1)"]["rms_out"] > joint.STAGE1_ENOUGH_HELD_OUT)
    monkeypatch.setattr(joint, "STAGE1_ENOUGH_HELD_OUT", -1.0)
    fit = joint.identify_joint(_points(_hill_steel(), 0.002), geom, lit, 3.0, max_nfev=3)
    assert list(fit.candidates) == ["stage 1", "stage 2 (prior 1)", weak]
    assert fit.chosen == min(fit.candidates, key=lambda k: fit.candidates[k]["rms_out"])
    want = fit.theta_stage1 if fit.chosen == "stage 1" else fit.candidates[fit.chosen]["theta"]
    np.testing.assert_array_equal(fit.theta, want)


def test_grid_tabulated_curve_sensitivities_match_the_curves_themselves():
    """point_model._GridTable: sum_q w_q (f_plus - f_minus)(B_q) / 2h from the tabulated difference against the
    perturbed curves evaluated at every B_q (what the Jacobian did before), for nu(B^2) and the energy density."""
    from solenoid_fmu.identification.point_model import _GridTable

    lit = load_material()
    h = 1e-4
    pairs = [(scaled_curve(lit, a + h, b), scaled_curve(lit, a - h, b)) for a, b in ((0.0, 0.1), (0.05, -0.2))]
    curves = [c for pair in pairs for c in pair]
    rng = np.random.default_rng(5)
    B = np.concatenate([rng.uniform(0.0, 0.3, 400), rng.uniform(0.3, 2.2, 4000)])  # low field and the knee
    w = rng.uniform(0.5, 1.5, B.size)
    for fns in ([lambda x, c=c: c.nu_of_b2(x * x)[0] for c in curves], [c.energy_density for c in curves]):
        got = _GridTable(float(B.max()), fns, h).weighted(B, w)
        want = np.array([np.sum(w * (fns[2 * p](B) - fns[2 * p + 1](B))) / (2 * h) for p in range(len(pairs))])
        np.testing.assert_allclose(got, want, rtol=1e-5)  # 2e-7 at 8192 points, 6e-5 at 512


def test_an_identification_that_pins_b_nowhere_says_so_in_words(monkeypatch, tmp_path, capsys):
    """Stop 54: where no field strength is pinned to 1 % (the demo's four flux recordings alone, at the default
    settings: their loops at one rate all count as hysteresis), the range was printed as "0 .. 0 A/m", a number to
    misread. Forced here on a smoke identification (the real case costs ~20 s): a warning, and "none" in the command
    line's output and the curve file's comment."""
    import solenoid_fmu.identification.joint_result as jr

    real = jr.identified_range
    monkeypatch.setattr(jr, "identified_range", lambda *a: ((0.0, 0.0),) + real(*a)[1:])
    paths = sorted(glob.glob(f"{DEMO}/recordings/*_flux_*.csv"))
    csv = tmp_path / "m.csv"
    assert cli.main(["identify", *paths, "-o", str(csv), "--mesh-size", "4", "--max-evals", "2", "--workers", "1"]) == 0
    out = capsys.readouterr()
    assert "identified H range none (the data pin B(H) nowhere" in out.out
    assert "pin B(H) to 1 % (1 sigma) at no field strength" in out.out + out.err
    assert "identified H range none" in csv.read_text()
