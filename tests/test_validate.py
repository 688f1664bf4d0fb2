"""Validation: metrics on analytic signals, FMU runs on small rig campaigns, CLI, figures, bad input."""

import json

import numpy as np
import pytest

from solenoid_fmu.cli import main
from solenoid_fmu.errors import FmuInputError, RecordingError, SolenoidError
from solenoid_fmu.loop import ResidualCase, ValidationError, signal_metrics, validate, validate_cases

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


# -- metrics ------------------------------------------------------------------------------------------
def test_metrics_of_a_known_sine_error():
    """e = a sin(3 w t + phi) over whole periods: rms a/sqrt(2), max a; range of 3 + 2 sin(w t) is 4."""
    t = np.linspace(0.0, 1.0, 20001)
    w = 2 * np.pi * 5
    a = 0.5
    measured = 3.0 + 2.0 * np.sin(w * t)
    simulated = measured - a * np.sin(3 * w * t + 0.3)
    m = signal_metrics(measured, simulated)
    assert m["rms"] == pytest.approx(a / np.sqrt(2), rel=1e-3)
    assert m["max"] == pytest.approx(a, rel=1e-6)
    assert m["nrmse"] == pytest.approx(a / np.sqrt(2) / 4.0, rel=1e-3)
    assert m["n"] == t.size and m["n_excluded"] == 0


def test_metrics_of_a_constant_offset_are_the_offset():
    t = np.linspace(0.0, 2.0, 1001)
    measured = np.sin(2 * np.pi * t)
    m = signal_metrics(measured, measured + 0.1)
    assert m["rms"] == pytest.approx(0.1) and m["max"] == pytest.approx(0.1)
    assert m["nrmse"] == pytest.approx(0.1 / 2.0, rel=1e-6)  # range of a sine: 2


def test_zero_range_gives_no_nrmse_and_non_finite_samples_are_excluded():
    m = signal_metrics(np.full(10, 2.0), np.full(10, 2.5))
    assert m["nrmse"] is None and m["rms"] == pytest.approx(0.5)
    sim = np.arange(10.0)
    sim[3] = np.nan
    m = signal_metrics(np.arange(10.0) + 1.0, sim)
    assert m["n_excluded"] == 1 and m["n"] == 9 and m["rms"] == pytest.approx(1.0)
    assert signal_metrics([1.0, 2.0], [np.nan, np.inf])["rms"] is None


@pytest.mark.parametrize(("measured", "simulated", "match"), [
    pytest.param(np.zeros(3), np.zeros(4), "differ in length", id="length"),
    pytest.param(np.zeros(0), np.zeros(0), "empty", id="empty"),
    pytest.param(np.zeros((2, 2)), np.zeros((2, 2)), "one-dimensional", id="2d"),
])
def test_metrics_refuse_bad_input(measured, simulated, match):
    with pytest.raises(ValidationError, match=match):
        signal_metrics(measured, simulated)


def test_validate_cases_structure_and_simulated_is_measured_minus_residual():
    t = np.linspace(0.0, 1.0, 101)
    force = 10 * t
    case = ResidualCase("a.csv", t, 0.1 * t, t, np.full_like(t, 1e-3), 12.0,
                        residuals={"force_N": np.full_like(t, 0.2), "psi_Wb": 1e-3 * np.sin(2 * np.pi * t)},
                        measured={"force_N": force, "psi_Wb": 0.1 * t}, kind="ramp", drive="current")
    out = validate_cases([case])
    rec = out["recordings"][0]
    assert rec["file"] == "a.csv" and rec["kind"] == "ramp" and rec["drive"] == "current"
    assert set(rec["signals"]) == {"force_N", "psi_Wb"}
    assert rec["signals"]["force_N"]["rms"] == pytest.approx(0.2)
    assert rec["signals"]["force_N"]["nrmse"] == pytest.approx(0.2 / 10.0)
    assert rec["signals"]["psi_Wb"]["max"] == pytest.approx(1e-3, rel=1e-3)
    assert out["summary"]["force_N"]["n_recordings"] == 1
    json.dumps(out)  # JSON-able


# -- FMU runs on small rig campaigns ------------------------------------------------------------------
def _campaign():
    from solenoid_fmu.rig import CampaignConfig

    return CampaignConfig(
        tests=("flux", "force_stroke", "ramp", "eddy", "voltage_step"),
        flux_peaks_A=(1.5,), flux_cycles=1, flux_rate_A_per_s=5.0, flux_sample_rate_Hz=200.0,
        stroke_currents_A=(1.0,), stroke_from_m=2.5e-3, stroke_to_m=0.6e-3, stroke_speed_m_per_s=2e-3,
        stroke_sample_rate_Hz=50.0, ramp_sample_rate_Hz=1000.0, ramp_hold_s=0.1,
        eddy_rates_A_per_s=(25.0,), eddy_cycles=1, eddy_sample_rate_Hz=2000.0,
        step_hold_s=0.3, step_sample_rate_Hz=1000.0, pause_s=5.0)


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """Maps with G_eddy = 0.02 S, the FMU of those maps and one with a wrong G_eddy (0.06 S), and a
    noise-free campaign of the rig whose truth is the same maps (no effects)."""
    import mapsfixture

    from solenoid_fmu.fmu.export import build_fmu
    from solenoid_fmu.realtime.model import load_tables
    from solenoid_fmu.rig import Effects, run_campaign

    base = tmp_path_factory.mktemp("validate")
    maps_dir = mapsfixture.write_maps(base / "maps", G_eddy_S=0.02)
    wrong_dir = mapsfixture.write_maps(base / "maps-wrong-eddy", G_eddy_S=0.06)
    good = build_fmu(maps_dir, base / "good.fmu")
    wrong = build_fmu(wrong_dir, base / "wrong-eddy.fmu")
    camp = base / "campaign"
    run_campaign(load_tables(maps_dir), camp, effects=Effects.from_names(""), campaign=_campaign(), seed=1,
                 maps_dir=maps_dir)
    files = sorted((camp / "recordings").glob("*.csv"))
    return {"base": base, "good": good, "wrong": wrong, "files": files}


@pytest.fixture(scope="module")
def good_result(setup):
    names = []
    res = validate(setup["good"], setup["files"], report_dir=setup["base"] / "report-good", progress=names.append)
    return res, names


def test_the_true_model_validates_within_one_percent(setup, good_result):
    res, names = good_result
    assert names == [f.name for f in setup["files"]]
    assert [r["file"] for r in res["recordings"]] == names
    kinds = {r["kind"]: r for r in res["recordings"]}
    assert set(kinds) == {"flux", "force_stroke", "ramp", "eddy", "voltage_step"}
    assert kinds["voltage_step"]["drive"] == "voltage" and kinds["flux"]["drive"] == "current"
    assert set(kinds["voltage_step"]["signals"]) == {"current_A", "force_N"}
    assert "psi_Wb" in kinds["eddy"]["signals"] and "force_N" in kinds["force_stroke"]["signals"]
    for rec in res["recordings"]:
        assert rec["signals"], rec
        for sig, m in rec["signals"].items():
            assert m["nrmse"] < 0.01, (rec["file"], sig, m)
            assert m["max"] >= m["rms"] >= 0


def test_the_force_is_compared_on_its_own_time_base(setup, good_result):
    """The rig samples the force at the stamp and averages voltage and current over the interval: validate
    measures the half-sample lead and compares with it; compared as sampled, the voltage step's force error
    is several times larger (the current rises by a large share of its range within one 1-ms sample)."""
    from solenoid_fmu.measure import flux_linkage

    res, _ = good_result
    timing = res["force_timing"]
    assert timing["applied"] and abs(timing["lead_samples"] - 0.5) < 0.05, timing
    assert res["force_lead_samples"] == timing["lead_samples"]
    plain = validate(setup["good"], setup["files"], flux_of=flux_linkage)  # no cache: no lead
    assert plain["force_lead_samples"] == 0.0 and not plain["force_timing"]["applied"]

    def step_force(r):
        return next(x for x in r["recordings"] if x["kind"] == "voltage_step")["signals"]["force_N"]["rms"]

    assert step_force(res) < 0.3 * step_force(plain), (step_force(res), step_force(plain))


def test_a_wrong_eddy_conductance_gives_larger_errors(setup, good_result):
    good, _ = good_result
    wrong = validate(setup["wrong"], setup["files"])
    g = {r["kind"]: r["signals"] for r in good["recordings"]}
    w = {r["kind"]: r["signals"] for r in wrong["recordings"]}
    # the eddy triangle (25 A/s) sees G_eddy most: the flux lags by G dPsi/dt
    assert w["eddy"]["psi_Wb"]["nrmse"] > 0.02
    assert w["eddy"]["psi_Wb"]["nrmse"] > 5 * g["eddy"]["psi_Wb"]["nrmse"]
    assert w["voltage_step"]["current_A"]["nrmse"] > 3 * g["voltage_step"]["current_A"]["nrmse"]
    assert wrong["figures"] == [] and all(r["figures"] == {} for r in wrong["recordings"])


def test_a_wrong_coil_resistance_gives_a_larger_current_error(setup, good_result):
    """The voltage step simulated with R 20 % high (header value) ends at a current 1/1.2 of the measured."""
    import dataclasses

    from solenoid_fmu.measure import read_recording

    good, _ = good_result
    f = next(p for p in setup["files"] if "voltage_step" in p.name)
    rec = read_recording(f)
    header = dict(rec.header, coil_resistance_ohm=repr(1.2 * rec.coil_resistance_ohm))
    wrong = validate(setup["good"], [dataclasses.replace(rec, header=header)])["recordings"][0]["signals"]
    g = next(r for r in good["recordings"] if r["kind"] == "voltage_step")["signals"]
    i_end = float(rec.current_A[rec.time_s <= 0.3 + 0.29][-1])  # end of the 0.3 s step
    assert wrong["current_A"]["max"] == pytest.approx(i_end * (1 - 1 / 1.2), rel=0.1)
    assert wrong["current_A"]["nrmse"] > 5 * g["current_A"]["nrmse"]


def test_figures_are_png_and_listed(setup, good_result):
    res, _ = good_result
    report = setup["base"] / "report-good"
    assert len(res["figures"]) == 2 * len(setup["files"])
    for f in setup["files"]:
        for suffix in ("overlay", "residual"):
            p = report / f"{f.stem}_{suffix}.png"
            assert str(p) in res["figures"]
            assert p.read_bytes()[:8] == PNG_MAGIC and p.stat().st_size > 5000
    saved = json.loads((report / "validation.json").read_text())
    assert saved["recordings"] == json.loads(json.dumps(res["recordings"]))
    assert not [p for p in report.iterdir() if p.name.startswith(".")]  # no temporary files left


def test_cli_json_is_pure_and_has_the_structure(setup, tmp_path, capsys):
    files = [str(f) for f in setup["files"][:2]]
    assert main(["validate", str(setup["good"]), *files, "--json", "--report", str(tmp_path / "r")]) == 0
    cap = capsys.readouterr()
    out = json.loads(cap.out)
    assert len(out["recordings"]) == 2
    for rec, f in zip(out["recordings"], setup["files"][:2], strict=True):
        assert rec["file"] == f.name
        assert rec["signals"]
        for m in rec["signals"].values():
            assert {"rms", "max", "nrmse"} <= set(m)
            assert all(isinstance(m[k], float) for k in ("rms", "max", "nrmse"))
    assert "simulating" in cap.err and setup["files"][0].name in cap.err
    assert (tmp_path / "r" / "validation.json").is_file()


def test_cli_table(setup, capsys):
    f = next(p for p in setup["files"] if "voltage_step" in p.name)
    assert main(["validate", str(setup["good"]), str(f)]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].split() == ["file", "signal", "rms", "max", "nrmse"]
    assert f"{f.name}  current_A" in out and "force_N" in out


# -- bad input ----------------------------------------------------------------------------------------
def test_a_missing_recording_is_a_clear_error(setup, tmp_path, capsys):
    missing = tmp_path / "no_such_recording.csv"
    with pytest.raises(RecordingError, match="no_such_recording.csv"):
        validate(setup["good"], [setup["files"][0], missing])
    assert main(["validate", str(setup["good"]), str(missing)]) == 1
    err = capsys.readouterr().err
    assert "no_such_recording.csv" in err and "Traceback" not in err


def test_a_malformed_recording_names_file_and_line(setup, tmp_path):
    bad = tmp_path / "bad.csv"
    text = setup["files"][0].read_text().splitlines()
    text[-1] = "abc,def"
    bad.write_text("\n".join(text) + "\n")
    with pytest.raises(RecordingError) as info:
        validate(setup["good"], [bad])
    assert "bad.csv" in str(info.value) and f":{len(text)}" in str(info.value)


def test_a_missing_fmu_and_no_recordings_are_clear_errors(setup, tmp_path):
    with pytest.raises(FmuInputError, match="nope.fmu"):
        validate(tmp_path / "nope.fmu", setup["files"][:1])
    with pytest.raises(ValidationError, match="at least one recording"):
        validate(setup["good"], [])
    assert issubclass(ValidationError, SolenoidError)


# -- the residual's white noise (metrics.white_noise_rms) ---------------------------------------------------------
def _noisy(sigma, n=5000, seed=7):
    t = np.linspace(0.0, 1.0, n)
    smooth = 0.3 * np.sin(2 * np.pi * 3 * t) + 0.1 * t  # a model error, smooth at the sample rate
    return smooth, smooth + np.random.default_rng(seed).normal(0.0, sigma, n)


def test_white_noise_rms_finds_the_noise_under_a_smooth_error():
    from solenoid_fmu.loop.metrics import white_noise_rms

    smooth, noisy = _noisy(0.05)
    assert white_noise_rms(noisy) == pytest.approx(0.05, rel=0.05)
    assert white_noise_rms(smooth) < 1e-4 * 0.05  # no noise: the smooth error is not counted


def test_white_noise_rms_is_not_moved_by_steps_and_spikes():
    from solenoid_fmu.loop.metrics import white_noise_rms

    _, noisy = _noisy(0.05)
    jumpy = noisy.copy()
    jumpy[2500:] += 2.0  # a step forty sigma high
    jumpy[[100, 900, 4000]] += 1.0  # three spikes
    assert white_noise_rms(jumpy) == pytest.approx(white_noise_rms(noisy), rel=0.02)


def test_white_noise_rms_needs_three_finite_samples_and_is_reported_per_signal():
    from solenoid_fmu.loop.metrics import signal_metrics, white_noise_rms

    assert white_noise_rms([1.0, np.nan, 2.0]) is None
    smooth, noisy = _noisy(0.02)
    m = signal_metrics(noisy, smooth)
    assert m["noise_rms"] == pytest.approx(0.02, rel=0.05)
    assert m["noise_rms"] == pytest.approx(m["rms"], rel=0.05)  # the residual is all noise here
