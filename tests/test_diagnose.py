"""Residual diagnosis on synthetic residuals with one undeclared effect at a time.

The truths are generated with other model classes than the signatures (a Preisach operator for
hysteresis, a two-section eddy ladder, a thermal model with its own time constant), plus noise.
"""

import numpy as np
import pytest

from solenoid_fmu.loop import ResidualCase
from solenoid_fmu.loop.diagnosis import EFFECTS, diagnose, score_effect
from solenoid_fmu.realtime import PreisachHysteresis

RNG = np.random.default_rng(7)
R_OHM = 12.0


def psi_of_i(i):
    """A saturating flux linkage curve [Wb] (the 'simulated' Psi of the cases)."""
    return 0.45 * np.tanh(i / 0.9)


def triangle(peak_A, rate_A_per_s, fs=2000.0, rest_s=0.05):
    t_ramp = peak_A / rate_A_per_s
    t = np.arange(0.0, 2 * t_ramp + 2 * rest_s, 1.0 / fs)
    i = np.clip(np.minimum(t - rest_s, 2 * t_ramp + rest_s - t), 0, None) * rate_A_per_s
    return t, np.minimum(i, peak_A)


def case_from(t, i, x, residuals, measured, name):
    return ResidualCase(name, t, psi_of_i(i), i, x, R_OHM, residuals, measured)


def flux_cases(effect_current, peaks=(0.5, 1.0, 1.5, 2.0), rate=1.0, noise=2e-4, rest_s=0.05):
    cases = []
    for k, p in enumerate(peaks):
        t, i = triangle(p, rate, fs=200.0, rest_s=rest_s)
        x = np.full_like(t, 1.5e-3)
        res = effect_current(t, i) + noise * RNG.standard_normal(len(t))
        cases.append(case_from(t, i, x, {"current_A": res}, {"current_A": i}, f"flux{k}.csv"))
    return cases


def loops_only(t, i, h):
    """Remove the single-valued part of a hysteresis residual (the mean of the branches at equal
    current), as the B(H) identification from the commutation curve does."""
    k = int(np.argmax(i))
    grid = np.linspace(0, i[k], 200)
    up = np.interp(grid, i[: k + 1], h[: k + 1])
    down = np.interp(grid, i[k:][::-1], h[k:][::-1])
    return h - np.interp(i, grid, 0.5 * (up + down))


def preisach_loops(t, i):
    pre = PreisachHysteresis(b_sat=0.5, b_c=0.05, spread=0.08, amplitude=0.05)
    return loops_only(t, i, pre.run(psi_of_i(i)))


def test_hysteresis_is_named_first():
    eff = preisach_loops

    d = diagnose(flux_cases(eff))
    assert d.verdict == "hysteresis"
    assert d.ranking[0].explained > 0.8
    assert d.ranking[0].score > d.ranking[1].score + 0.2


def test_material_is_a_single_valued_function_of_psi():
    d = diagnose(flux_cases(lambda t, i: 0.04 * (psi_of_i(i) / 0.45) ** 3 - 0.01 * psi_of_i(i) / 0.45))
    assert d.verdict == "material"
    assert d.ranking[0].explained > 0.8


def test_frequency_dependent_eddy_grows_with_rate():
    """A ladder of two eddy paths, minus the single G_eddy the model already fitted."""
    cases = []
    for k, rate in enumerate((12.5, 25.0, 62.5, 125.0)):
        t, i = triangle(1.5, rate, fs=20000.0, rest_s=0.01)
        dpsi = np.gradient(psi_of_i(i), t)
        ladder = np.zeros_like(t)
        for g, tau in ((3e-3, 0.3e-3), (2e-3, 3e-3)):
            y = np.zeros_like(t)
            for n in range(1, len(t)):
                a = np.exp(-(t[n] - t[n - 1]) / tau)
                y[n] = a * y[n - 1] + (1 - a) * dpsi[n]
            ladder += g * y
        g_single = (ladder @ dpsi) / (dpsi @ dpsi)
        res = ladder - g_single * dpsi + 2e-5 * RNG.standard_normal(len(t))
        x = np.full_like(t, 1.5e-3)
        cases.append(case_from(t, i, x, {"current_A": res}, {"current_A": i}, f"eddy{k}.csv"))
    d = diagnose(cases)
    assert d.verdict == "eddy"
    assert d.ranking[0].explained > 0.7


def test_heating_grows_with_dissipated_energy():
    """Current-driven recordings over minutes: voltage residual i R alpha dT with a thermal
    time constant (400 s) that is not one of the signature's."""
    cases = []
    temp = 0.0
    for k, level in enumerate((1.0, 1.5, 2.0)):
        t = np.arange(0.0, 300.0, 0.5)
        i = level * (0.75 + 0.25 * np.sign(np.sin(2 * np.pi * t / 40.0)))
        dT = np.empty_like(t)
        for n in range(len(t)):
            dt = t[n] - t[n - 1] if n else 0.0
            temp += dt * (i[n] ** 2 * R_OHM * 1.0 - temp) / 400.0  # R_th = 1 K/W
            dT[n] = temp
        u_meas = i * R_OHM * (1 + 0.00393 * dT)
        # the simulation uses the header's R, measured just before the run: the residual is the
        # rise during the run
        res = i * R_OHM * 0.00393 * (dT - dT[0]) + 2e-3 * RNG.standard_normal(len(t))
        x = np.full_like(t, 1.5e-3)
        cases.append(case_from(t, i, x, {"voltage_V": res}, {"voltage_V": u_meas}, f"ramp{k}.csv"))
    d = diagnose(cases)
    assert d.verdict == "heating"
    assert d.ranking[0].explained > 0.8


def test_friction_flips_with_direction_of_motion():
    cases = []
    for k, cur in enumerate((0.5, 1.0, 1.5, 2.0)):
        t = np.arange(0.0, 20.0, 0.01)
        x = 0.5e-3 + 2.3e-3 * (1 - np.abs(1 - t / 10.0))  # out and back, 0.23 mm/s
        i = np.full_like(t, cur)
        force = 20 * cur + 5 * x / 1e-3
        res = 2.5 * np.sign(np.gradient(x, t)) + 0.05 * RNG.standard_normal(len(t))
        cases.append(case_from(t, i, x, {"force_N": res}, {"force_N": force}, f"stroke{k}.csv"))
    d = diagnose(cases)
    assert d.verdict == "friction"
    assert d.ranking[0].explained > 0.9


def test_sensor_offset():
    """A current-sensor offset is named 'sensor' (a gain error alone would look like a scaled
    B(H), i.e. 'material', as the paper notes for deviations that scale everything alike)."""
    d = diagnose(flux_cases(lambda t, i: 0.01 + 0.002 * i, rest_s=1.0))  # rig rest phases: 1 s
    assert d.verdict == "sensor"
    assert d.ranking[0].explained > 0.9


def test_noise_alone_is_unexplained():
    d = diagnose(flux_cases(lambda t, i: np.zeros_like(i), noise=1e-3))
    assert d.verdict == "unexplained"
    assert all(c.score < 0.1 for c in d.ranking)


def test_ranking_lists_every_effect_with_json_keys():
    d = diagnose(flux_cases(lambda t, i: np.zeros_like(i)))
    out = d.as_dict()
    assert sorted(c["effect"] for c in out["ranking"]) == sorted(EFFECTS)
    assert set(out["ranking"][0]) >= {"effect", "score", "explained"}
    assert out["verdict"] in EFFECTS + ("unexplained",)


def test_more_parameters_do_not_win_on_noise():
    """Held-out scoring: the material signature (6 parameters) does not beat friction's one
    parameter on pure noise, and its held-out score is not positive beyond noise level."""
    cases = flux_cases(lambda t, i: np.zeros_like(i), noise=1e-3)
    assert score_effect("material", cases).score < 0.02


def test_single_recording_uses_halves_in_time():
    t1, i1 = triangle(1.0, 1.0, fs=200.0)
    t2, i2 = triangle(2.0, 1.0, fs=200.0)
    t = np.concatenate([t1, t2 + t1[-1] + 0.005])
    i = np.concatenate([i1, i2])
    res = np.concatenate([preisach_loops(t1, i1), preisach_loops(t2, i2)]) + 2e-4 * RNG.standard_normal(len(t))
    c = case_from(t, i, np.full_like(t, 1.5e-3), {"current_A": res}, {"current_A": i}, "one.csv")
    assert diagnose([c]).verdict == "hysteresis"


def test_no_cases_is_an_error():
    with pytest.raises(ValueError, match="at least one recording"):
        diagnose([])


# -- end to end: rig campaigns with one undeclared effect, diagnosed through the real FMU ----------
@pytest.mark.parametrize(("effects", "expected"), [("friction", "friction"), ("hysteresis", "hysteresis"),
                                                   ("eddy-ladder", "eddy"), ("heating", "heating"),
                                                   ("", "unexplained")])
def test_cli_diagnose_names_the_undeclared_effect(rig_maps, rig_campaign, effects, expected, capsys):
    import json

    from solenoid_fmu.cli import main

    fmu = rig_maps[2]
    files = rig_campaign(effects)
    assert main(["diagnose", str(fmu), *files, "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["verdict"] == expected, d["ranking"]
    if expected != "unexplained":
        assert d["ranking"][0]["effect"] == expected and d["ranking"][0]["score"] > 0.4
    else:  # nothing named because the residual is at the sensors' level (below the significance floor) ...
        from solenoid_fmu.loop.diagnosis import DEFAULT_MIN_NRMS

        assert max(d["residual_nrms"].values()) < DEFAULT_MIN_NRMS, d["residual_nrms"]
        # ... and no effect explains much of it. The flux comparison keeps a timing floor: the model, fed the
        # interval means of the current, lags the eq.-4 flux of interval-mean samples by 0.37 samples on these
        # 200-Hz recordings (the eddy term's lag against the held input), a shape hysteresis explains 30 % of
        # (score 0.26 once the force compares on its own time base, 0.18 while the force's half-sample lead
        # diluted it): the bound sits above that floor, under any effect's score (0.4 and more, above).
        assert all(c["score"] < 0.3 for c in d["ranking"]), d["ranking"]
