"""A coil that starts a run above ambient (issue 20): the loop's heating fit takes C_th and R_th from the
eq.-4 flux drift of runs that start warm and cool, the model starts each run at its temperature above ambient.

The synthetic drift is integrated from the full first-order thermal model (heating with R(T), cooling of the
start excess and of the rise, fine Euler steps), not from the fit's linearized regressors.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from solenoid_fmu.fmu.simulate import heating_start, start_excess_K
from solenoid_fmu.loop.heating_fit import R_TH_DEFAULT_K_PER_W, fit_heating, heating_corrected
from solenoid_fmu.loop.residuals import ResidualCase, ambient_resistance
from solenoid_fmu.measure import Recording, flux_linkage
from solenoid_fmu.realtime.model import COPPER_ALPHA_PER_K, heating_alpha

ALPHA = COPPER_ALPHA_PER_K
R_AMBIENT_OHM = 12.0


def _triangles(duration_s: float, peak_A: float, cycles: int, n: int = 4001) -> tuple:
    t = np.linspace(0.0, duration_s, n)
    phase = (t / duration_s * cycles) % 1.0
    return t, peak_A * (1.0 - np.abs(2.0 * phase - 1.0))


def _temperature(t, i, R_start, T0, C, R_th):
    """Temperature rise since the start [K]: C dT/dt = R(T) i^2 - (T + T0) / R_th, R(T) = R_start (1 + a T)."""
    a = heating_alpha(ALPHA, T0)
    T = np.zeros_like(t)
    for k in range(1, t.size):
        h = t[k] - t[k - 1]
        T[k] = T[k - 1] + h * (R_start * (1.0 + a * T[k - 1]) * i[k] ** 2 - (T[k - 1] + T0) / R_th) / C
    return T, a


def _case(name, t, i, T0, C, R_th) -> ResidualCase:
    """The eq.-4 flux residual of a heating-free model: int (R(T) - R) i dt with R the run's start resistance."""
    R_start = R_AMBIENT_OHM * (1.0 + ALPHA * T0)
    T, a = _temperature(t, i, R_start, T0, C, R_th)
    drift = np.concatenate([[0.0], np.cumsum(np.diff(t) * (R_start * a * T * i)[1:])])
    return ResidualCase(name, t, np.zeros_like(t), i, np.full_like(t, 1e-3), R_start, {"psi_Wb": drift},
                        {"psi_Wb": drift}, kind="flux", drive="current", ambient_R_ohm=R_AMBIENT_OHM)


TABLES = SimpleNamespace(coil=SimpleNamespace(alpha_per_K=ALPHA))


@pytest.mark.parametrize(("C", "R_th"), [(60.0, 2.0), (40.0, 1.2), (120.0, 4.0)])
def test_runs_that_start_warm_give_c_th_and_r_th(C, R_th):
    cases = [_case(f"r{k}", *_triangles(20.0, peak, 4), T0, C, R_th)
             for k, (peak, T0) in enumerate([(2.0, 0.0), (1.5, 3.0), (2.0, 6.0), (1.0, 9.0), (1.8, 5.0)])]
    section, note = fit_heating(TABLES, {}, cases)
    assert abs(section["C_th_J_per_K"] / C - 1.0) < 0.03, section
    assert abs(section["R_th_K_per_W"] / R_th - 1.0) < 0.10, section
    assert note["R_th"].startswith("fitted") and note["R_th_fitted"] is True


def test_runs_all_at_ambient_keep_the_default_r_th_and_still_give_c_th():
    cases = [_case(f"r{k}", *_triangles(20.0, peak, 4), 0.0, 60.0, R_TH_DEFAULT_K_PER_W)
             for k, peak in enumerate([2.0, 1.5, 1.0])]
    section, note = fit_heating(TABLES, {}, cases)
    assert section["R_th_K_per_W"] == R_TH_DEFAULT_K_PER_W
    assert abs(section["C_th_J_per_K"] / 60.0 - 1.0) < 0.03
    assert "no run starts measurably above ambient" in note["R_th"]


def test_a_drift_that_grows_with_the_start_excess_keeps_the_default():
    """A drift of the wrong sign for cooling (the runs that start warm drift up more) is no R_th."""
    cases = [_case(f"r{k}", *_triangles(20.0, 2.0, 4), T0, 60.0, 2.0) for k, T0 in enumerate([0.0, 4.0, 8.0])]
    for c in cases:  # the start excess with the opposite sign: runs that start warm warm faster
        t, i = c.time_s, c.current_A
        T0 = start_excess_K(c.R_ohm, R_AMBIENT_OHM, ALPHA)
        c.residuals["psi_Wb"] = c.residuals["psi_Wb"] + ALPHA * c.R_ohm * T0 / 120.0 * np.concatenate(
            [[0.0], np.cumsum(np.diff(t) * (i * (t - t[0]))[1:])]) * 2.0
    section, note = fit_heating(TABLES, {}, cases)
    assert section["R_th_K_per_W"] == R_TH_DEFAULT_K_PER_W
    assert note["R_th"].startswith("default: the runs' cooling gives no thermal time constant")


def test_start_excess_from_resistances():
    assert start_excess_K(R_AMBIENT_OHM * (1.0 + ALPHA * 4.0), R_AMBIENT_OHM, ALPHA) == pytest.approx(4.0, rel=1e-12)
    assert start_excess_K(None, R_AMBIENT_OHM, ALPHA) == 0.0
    assert start_excess_K(12.5, None, ALPHA) == 0.0
    assert start_excess_K(12.5, R_AMBIENT_OHM, 0.0) == 0.0
    assert start_excess_K(10.0 * R_AMBIENT_OHM, R_AMBIENT_OHM, ALPHA) == 160.0  # the model's range


def test_heating_start_only_for_maps_with_heating():
    with_heat = SimpleNamespace(effects=SimpleNamespace(heating={"alpha_per_K": ALPHA}),
                                coil=SimpleNamespace(alpha_per_K=0.5))
    without = SimpleNamespace(effects=SimpleNamespace(heating=None), coil=SimpleNamespace(alpha_per_K=ALPHA))
    R = R_AMBIENT_OHM * (1.0 + ALPHA * 2.5)
    assert heating_start(with_heat, R, R_AMBIENT_OHM) == {"T_start_excess_K": pytest.approx(2.5, rel=1e-12)}
    assert heating_start(with_heat, R, None) == {}
    assert heating_start(without, R, R_AMBIENT_OHM) == {}
    # a section without alpha: the model's default (copper's), not the maps' coil value, as model.py takes it
    no_alpha = SimpleNamespace(effects=SimpleNamespace(heating={"C_th_J_per_K": 50.0}),
                               coil=SimpleNamespace(alpha_per_K=0.5))
    assert heating_start(no_alpha, R, R_AMBIENT_OHM) == {"T_start_excess_K": pytest.approx(2.5, rel=1e-12)}


def _recording(kind, R_header_ohm, t=None, i=None, voltage_V=None):
    """A recording of ``kind`` with the columns it needs (zero current unless given) and a header resistance."""
    t = np.linspace(0.0, 1.0, 101) if t is None else t
    i = np.sin(np.pi * t) ** 2 if i is None else i
    if voltage_V is None and kind != "force_stroke":
        voltage_V = (R_header_ohm or 12.0) * i
    force = None if kind in ("flux", "eddy") else np.zeros_like(t)
    position = np.full_like(t, 1e-3) if kind == "force_stroke" else None
    header = {} if kind == "force_stroke" else {"position_mm": "1.0"}
    if R_header_ohm is not None:
        header["coil_resistance_ohm"] = repr(R_header_ohm)
    return Recording(kind, "PS45", header, t, i, voltage_V, force, position, {})


def test_ambient_is_the_coldest_run_start():
    recs = [_recording("flux", 12.3), _recording("voltage_step", 12.1), _recording("force_stroke", 12.05),
            _recording("flux", 12.2)]
    assert ambient_resistance(recs, flux_linkage) == pytest.approx(12.05)
    assert ambient_resistance(recs[:1] + recs[3:], flux_linkage) == pytest.approx(12.2)
    assert ambient_resistance([_recording("force_stroke", None)], flux_linkage) is None


def test_heating_corrected_from_a_warm_start_removes_the_drift():
    """The voltage of a coil that starts 6 K above ambient and cools while driven, corrected with the start
    excess: eq. 4 with the start resistance gives the heating-free flux; without the excess it does not."""
    C, R_th, T0 = 50.0, 2.0, 6.0
    t, i = _triangles(20.0, 2.0, 4)
    R_start = R_AMBIENT_OHM * (1.0 + ALPHA * T0)
    T, a = _temperature(t, i, R_start, T0, C, R_th)
    psi = 0.1 * i  # a linear coil: its flux follows the current
    dpsi = np.gradient(psi, t)
    rec = _recording("flux", R_start, t, i, R_start * (1.0 + a * T) * i + dpsi)
    heat = {"C_th_J_per_K": C, "R_th_K_per_W": R_th, "alpha_per_K": ALPHA}

    def end_error(r):
        return abs(float(np.sum(np.diff(t) * (r.voltage_V - R_start * i)[1:]) - (psi[-1] - psi[0])))

    drift = end_error(rec)
    assert drift > 0.05  # the uncorrected drift is large
    assert end_error(heating_corrected(rec, heat, T_start_excess_K=T0)) < 2e-3 * drift
    assert end_error(heating_corrected(rec, heat)) > 0.1 * drift
