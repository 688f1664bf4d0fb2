"""FEM sweeps that do not stop on one point, and maps that cover what was measured (issue 12, items 5-6).

The FEM cases use PS45 at mesh 2.0 (~1 s to build, 0.1-0.5 s a solve) at the operating point where a
campaign's sweep once stopped: x = 2.787 mm, i = 0.632 A. The map cases use the synthetic maps fixture.
"""

import logging
from types import SimpleNamespace

import mapsfixture
import numpy as np
import pytest

from solenoid_fmu.errors import MapsError, SolverError
from solenoid_fmu.field import fem
from solenoid_fmu.field.geometry import load_geometry
from solenoid_fmu.field.linear_solver import BACKENDS as LINEAR_BACKENDS
from solenoid_fmu.field.material import load_material
from solenoid_fmu.maps import (
    CAMPAIGN_CURRENT_MARGIN,
    CAMPAIGN_CURRENT_POWER,
    InlineExecutor,
    build_maps,
    default_currents,
    fit_eddy,
    i_f_at,
    load_maps,
    maps_current_grid,
)
from solenoid_fmu.maps.interpolate import FLUX_EXTRAPOLATION_LIMIT
from solenoid_fmu.measure import make_recording
from solenoid_fmu.pipeline import PRESETS, _maps_grid

X_M, I_A, I_PREV_A = 2.787e-3, 0.632, 0.6


@pytest.fixture(scope="module")
def ps45():
    geom, mat = load_geometry(), load_material()
    solver = fem.get_solver(geom, mat, 2.0)
    ref = solver.solve(I_A, X_M)
    prev = solver.solve(I_PREV_A, X_M)
    assert not ref.note and not prev.note  # the plain solve converges to NEWTON_RTOL
    return geom, mat, solver, ref, prev


# -- item 5: Newton stall and retry -------------------------------------------------------------------------


def test_stall_below_the_stall_tolerance_is_accepted_with_a_note(ps45, monkeypatch, caplog):
    """An unreachable target (below the rounding floor) makes Newton stall: accepted, logged, same result."""
    _, _, solver, ref, _ = ps45
    monkeypatch.setattr(fem, "NEWTON_RTOL", 1e-30)
    monkeypatch.setattr(fem, "NEWTON_FLOOR_FACTOR", 0.0)
    with caplog.at_level(logging.INFO, logger="solenoid_fmu.field.fem"):
        sol = solver.solve(I_A, X_M)
    assert "accepted as converged" in sol.note
    assert sol.residual_history[-1] < fem.NEWTON_STALL_RTOL
    assert any("x = 2.787 mm" in r.getMessage() and "stall tolerance" in r.getMessage() for r in caplog.records)
    assert sol.psi_Wb == pytest.approx(ref.psi_Wb, rel=1e-6)
    assert sol.force_N == pytest.approx(ref.force_N, rel=1e-6)


def test_stall_above_the_stall_tolerance_is_not_accepted(ps45, monkeypatch):
    """The stall rule has a limit: with a stall tolerance nothing reaches, the point fails (naming x and i)."""
    _, _, solver, _, _ = ps45
    monkeypatch.setattr(fem, "NEWTON_RTOL", 1e-30)
    monkeypatch.setattr(fem, "NEWTON_FLOOR_FACTOR", 0.0)
    monkeypatch.setattr(fem, "NEWTON_STALL_RTOL", 1e-30)
    monkeypatch.setattr(fem, "NEWTON_MAXIT", 12)
    monkeypatch.setattr(fem, "RETRY_LOAD_STEPS", (2,))
    with pytest.raises(SolverError, match=r"did not converge at i = 0\.632 A, x = 2\.787 mm"):
        solver.solve(I_A, X_M)


def test_failed_point_is_recovered_by_load_stepping_from_the_neighbour(ps45, monkeypatch, caplog):
    """Too few iterations for the step 0.6 -> 0.632 A: the retry steps the load from the neighbour's solution."""
    _, _, solver, ref, prev = ps45
    monkeypatch.setattr(fem, "NEWTON_MAXIT", 3)
    with pytest.raises(fem._NewtonFailure):  # the plain solve cannot make it in 3 iterations
        solver._solve(I_A, X_M, prev.u)
    with caplog.at_level(logging.INFO, logger="solenoid_fmu.field.fem"):
        sol = solver.solve(I_A, X_M, u0=prev.u, i0_A=I_PREV_A)
    assert sol.note.startswith("recovered by load stepping in current (4 steps from the neighbour's solution at 0.6 A)")
    assert any("recovered by load stepping" in r.getMessage() for r in caplog.records)
    assert sol.newton_iterations > 3
    assert sol.psi_Wb == pytest.approx(ref.psi_Wb, rel=1e-6)
    assert sol.force_N == pytest.approx(ref.force_N, rel=1e-6)


def test_sweep_retries_a_failed_point_from_the_previous_current(ps45, monkeypatch):
    """sweep_currents hands the previous current's solution to the retry and flags the recovered point."""
    geom, mat, solver, _, _ = ps45
    currents = [0.0, 0.3, I_PREV_A, I_A]
    plain = fem.sweep_currents(geom, mat, X_M, currents, mesh_size=2.0)
    assert not plain["newton_recovered"].any()
    original, calls = fem.Solver._solve, []

    def flaky(self, i_A, x_m, u0=None, forces=True):
        calls.append((i_A, u0 is not None))
        if i_A == I_A and u0 is not None and sum(c == (I_A, True) for c in calls) == 1:
            raise fem._NewtonFailure(f"Newton did not converge at i = {i_A:g} A (forced)")
        return original(self, i_A, x_m, u0, forces)

    monkeypatch.setattr(fem.Solver, "_solve", flaky)
    out = fem.sweep_currents(geom, mat, X_M, currents, mesh_size=2.0)
    np.testing.assert_array_equal(out["newton_recovered"], [0, 0, 0, 1])
    first_step = I_PREV_A + (I_A - I_PREV_A) / fem.RETRY_LOAD_STEPS[0]
    assert (pytest.approx(first_step), True) in calls  # load stepping started at the neighbour, warm
    np.testing.assert_allclose(out["psi_Wb"], plain["psi_Wb"], rtol=1e-6)
    np.testing.assert_allclose(out["force_N"], plain["force_N"], rtol=1e-6)


def test_unrecoverable_point_names_x_and_i(ps45, monkeypatch):
    _, _, solver, _, prev = ps45
    monkeypatch.setattr(fem, "NEWTON_MAXIT", 1)
    with pytest.raises(SolverError) as err:
        solver.solve(I_A, X_M, u0=prev.u, i0_A=I_PREV_A)
    msg = str(err.value)
    assert "did not converge at i = 0.632 A, x = 2.787 mm" in msg
    assert "16 steps from the neighbour's solution at 0.6 A; 4 steps from zero" in msg
    assert msg.endswith("did not converge either")


def test_unrecoverable_point_stops_the_map_sweep_naming_x_and_i(ps45, monkeypatch):
    geom, mat, _, _, _ = ps45
    monkeypatch.setattr(fem, "NEWTON_MAXIT", 1)
    with pytest.raises(MapsError, match=r"FEM sweep at x = 2\.787 mm failed: .*i = 0\.3 A, x = 2\.787 mm"):
        build_maps(geom, mat, x_m=[X_M, 3.0e-3], i_A=[0.0, 0.3, I_A], mesh_size=2.0, executor=InlineExecutor(),
                   progress=False)


# -- the Newton verdict does not depend on the CPU's rounding path (MKL kernels, SuperLU) ----------------------

SWEEP_A = (0.0, 0.3, I_PREV_A, I_A, 1.5)


def _target(sol):
    """The relative residual Newton had to reach at this point (see fem.NEWTON_RTOL)."""
    return max(fem.NEWTON_RTOL, fem.NEWTON_FLOOR_FACTOR * sol.residual_floor)


def _warm_sweep(solver, u_noise=0.0, seed=0):
    """Solutions along SWEEP_A at X_M, each warm-started from the previous one (times 1 + u_noise * N(0, 1))."""
    rng = np.random.default_rng(seed)
    sols, u, i_prev = [], None, None
    for i in SWEEP_A:
        u0 = None if u is None else u * (1.0 + u_noise * rng.standard_normal(u.size))
        sol = solver.solve(i, X_M, u0=u0, i0_A=i_prev)
        sols.append(sol)
        u, i_prev = (sol.u, i) if i else (None, None)
    return sols


def _assert_same_verdict(got, ref, how):
    for g, r in zip(got, ref, strict=True):
        where = f"{how}, i = {r.i_A:g} A"
        assert g.note == r.note == "", where  # converged by the target: no stall or retry (newton_recovered 0)
        assert g.newton_iterations == r.newton_iterations, where
        # converged to 1e-9 of the source: far above rounding (1e-16), far below the maps' 5e-4
        assert g.psi_Wb == pytest.approx(r.psi_Wb, rel=1e-7, abs=1e-12), where
        assert g.force_N == pytest.approx(r.force_N, rel=1e-7, abs=1e-9), where


def test_newton_verdict_is_the_same_on_another_rounding_path(ps45, monkeypatch):
    """Issue: a point 'converged' or stalled (flagged newton_recovered) depending on the CPU's floating-point path.

    The same sweep with the warm starts perturbed by a relative 1e-13, through SuperLU instead of PARDISO (where
    PARDISO is installed) and with the source perturbed by a relative 1e-13 gives the same iteration counts, no
    notes (no newton_recovered flags) and the same results.
    """
    geom, mat, solver, _, _ = ps45
    ref = _warm_sweep(solver)
    for sol in ref:  # the test itself is robust: no residual lies within rounding of its target
        assert all(abs(h / _target(sol) - 1.0) > 0.1 for h in sol.residual_history), sol.residual_history
    _assert_same_verdict(_warm_sweep(solver, u_noise=1e-13), ref, "warm starts perturbed by 1e-13")
    for other in set(LINEAR_BACKENDS) - {solver.linear_solver.backend}:  # SuperLU, where PARDISO is installed
        twin = fem.Solver(geom, mat, 2.0, mesh=solver.mesh, linear_backend=other)
        _assert_same_verdict(_warm_sweep(twin), ref, other)
    cfg = solver.config(X_M)
    f_coil = cfg.f_coil
    for seed in range(8):  # the point, 0.3 -> 0.6 A: the old criterion flagged 2 of these 8 as stalls
        noise = 1e-13 * np.random.default_rng(seed).standard_normal(f_coil.size)
        monkeypatch.setattr(cfg, "f_coil", f_coil * (1.0 + noise))
        sol = solver.solve(I_PREV_A, X_M, u0=ref[1].u, i0_A=0.3)
        _assert_same_verdict([sol], [ref[2]], f"source perturbed by 1e-13 (seed {seed})")
    _assert_same_verdict(_warm_sweep(solver), ref, "source perturbed by 1e-13")


def test_newton_takes_the_full_step_near_the_solution(ps45):
    """From starts 0.5e-9..2.5e-9 off (relative residual 2e-8..1e-7), one full Newton step converges
    (quadratically): the line search must not halve the step on the energy's rounding noise (the predicted decrease
    is then below one ulp of the energy; the old Armijo test halved it at 2 of these 12 starts on an Intel Xeon)."""
    _, _, solver, ref, _ = ps45
    for delta in np.array([5, 7, 10, 15, 20, 25]) * 1e-10:
        for scale in (1 + delta, 1 - delta):
            sol = solver.solve(I_A, X_M, u0=ref.u * scale)
            assert sol.residual_history[0] > 10 * _target(sol)  # a real step to make, not already converged
            assert sol.newton_iterations == 1 and not sol.note, (scale, sol.residual_history)
            assert sol.psi_Wb == pytest.approx(ref.psi_Wb, rel=1e-9)


# -- item 6a: flux lookups just past the map's last node ----------------------------------------------------


@pytest.fixture(scope="module")
def smaps(tmp_path_factory):
    return load_maps(mapsfixture.write_maps(tmp_path_factory.mktemp("robustmaps") / "m", G_eddy_S=None))


def test_flux_just_past_the_last_node_extrapolates_with_one_warning(smaps, caplog):
    top = smaps.psi_Wb[-1]
    x = smaps.x_m[0]
    psi = np.array([0.5 * top, top, top * (1 + 2e-4), top * (1 + 1e-3)])
    with caplog.at_level(logging.WARNING, logger="solenoid_fmu.maps.interpolate"):
        i_f = i_f_at(smaps, psi, x, where="run7.csv")
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1  # one per lookup batch, not one per sample
    assert "run7.csv: 2 of 4 flux-linkage lookups" in warnings[0].getMessage()
    assert "extrapolated linearly" in warnings[0].getMessage()
    slope = (smaps.i_f_A[-1, 0] - smaps.i_f_A[-2, 0]) / (smaps.psi_Wb[-1] - smaps.psi_Wb[-2])
    np.testing.assert_allclose(i_f[2:], smaps.i_f_A[-1, 0] + slope * (psi[2:] - top), rtol=1e-12)
    np.testing.assert_allclose(i_f, mapsfixture.i_f_analytic(psi, x), rtol=5e-3)


def test_flux_far_past_the_table_is_refused_clearly(smaps):
    top = smaps.psi_Wb[-1]
    psi = top * (1 + 1.2 * FLUX_EXTRAPOLATION_LIMIT)
    with pytest.raises(MapsError, match=r"run7.csv: flux linkage .* Wb is outside the map's table \[0, .*\] Wb by "
                       r"more than 5 % of its span .*: sweep the maps to a higher current"):
        i_f_at(smaps, psi, smaps.x_m[0], where="run7.csv")


def _eddy_recording_past_the_map(top_Wb, x_m, G_S, peak_factor, fs=10000.0):
    """Eddy recording (analytic circuit) whose flux triangle peaks at ``peak_factor`` x the map's top [Wb]."""
    t_ramp, rest, cycles = 0.05, 0.05, 2
    t = np.arange(0.0, 2 * rest + cycles * 2 * t_ramp, 1.0 / fs)
    ph = np.clip(t - rest, 0.0, None) % (2 * t_ramp)
    psi = np.where(t < rest, 0.0, np.minimum(ph, 2 * t_ramp - ph) / t_ramp * peak_factor * top_Wb)
    psi[t > rest + cycles * 2 * t_ramp] = 0.0
    e = np.gradient(psi, t)
    i = mapsfixture.i_f_analytic(psi, x_m) + G_S * e
    u = mapsfixture.R_OHM * i + e
    return make_recording("eddy", "synthetic", t, i, voltage_V=u, position_m=x_m,
                          coil_resistance_ohm=mapsfixture.R_OHM)


def test_eddy_fit_on_flux_just_past_the_map_warns_and_recovers_g(smaps, caplog):
    """Regression: the eddy fit stopped with 'flux linkage ... is outside the map's table' 0.02 % past it."""
    from solenoid_fmu.measure import flux_linkage

    top, x, G = smaps.psi_Wb[-1], smaps.x_m[0], 0.02
    # eq. 4 (trapezoid) cuts the triangle's sharp peak by ~0.1 %: scale the peak so the *measured* flux is 0.02 % past
    lost = float(np.max(flux_linkage(_eddy_recording_past_the_map(top, x, G, 1.0)).psi_Wb)) / top
    rec = _eddy_recording_past_the_map(top, x, G, peak_factor=1.0002 / lost)
    past = float(np.max(np.abs(flux_linkage(rec).psi_Wb))) / top - 1
    assert 1e-4 < past < 3e-4  # the measured flux is about 0.02 % past the map's last node
    with caplog.at_level(logging.WARNING, logger="solenoid_fmu.maps.interpolate"):
        fit = fit_eddy([rec], smaps)
    assert any("past the map's last flux node" in r.getMessage() for r in caplog.records)
    assert np.isfinite(fit.G_eddy_S) and np.isfinite(fit.r2)
    assert fit.G_eddy_S == pytest.approx(G, rel=0.05)
    assert fit.r2 > 0.9


# -- item 6b: the pipeline's current range covers the campaign -----------------------------------------------


def _recs(*peaks_A):
    return [SimpleNamespace(current_A=np.array([0.0, p, 0.5 * p, np.nan])) for p in peaks_A]


def test_current_grid_keeps_the_rated_range_when_the_campaign_stays_inside():
    grid = maps_current_grid(2.0, _recs(1.5, -1.9, 2.0))
    np.testing.assert_array_equal(grid, default_currents(2.5, 26))  # exactly the maps' default grid
    # the medium and full presets' spacing: the same number, denser at low currents
    dense = maps_current_grid(2.0, _recs(1.5, -1.9, 2.0), power=CAMPAIGN_CURRENT_POWER)
    np.testing.assert_array_equal(dense, default_currents(2.5, 26, CAMPAIGN_CURRENT_POWER))
    assert CAMPAIGN_CURRENT_POWER == 2.0 and dense[1] < 0.5 * grid[1]


def test_current_grid_reaches_1p25_x_the_campaign_peak_with_the_same_first_step():
    grid = maps_current_grid(2.0, _recs(1.0, -2.4), n_i=12)  # |-2.4 A| counts; NaN samples are ignored
    assert grid[0] == 0.0 and np.all(np.diff(grid) > 0)
    assert grid[-1] == pytest.approx(CAMPAIGN_CURRENT_MARGIN * 2.4)
    assert len(grid) == 14  # ceil(11 * 1.2^(2/3)) + 1
    assert grid[1] <= default_currents(2.5, 12)[1] * 1.002
    dense = maps_current_grid(2.0, _recs(1.0, -2.4), n_i=12, power=2.0)  # top^(1/2): the first step kept too
    assert len(dense) == 14 and dense[1] <= default_currents(2.5, 12, 2.0)[1] * 1.002  # ceil(11 * 1.2^(1/2)) + 1
    noisy = maps_current_grid(2.0, _recs(2.0018), n_i=12)  # a peak 0.09 % over rated (noise): no extra current
    assert len(noisy) == 12 and noisy[-1] == pytest.approx(1.25 * 2.0018)


def test_pipeline_preset_grids_follow_the_rule():
    geom = load_geometry()
    rated = geom.coil.max_current_A
    for name, preset in PRESETS.items():
        x, i = _maps_grid(preset, geom, _recs(0.8 * rated))
        assert i[-1] == pytest.approx(1.25 * rated), name
        x, i = _maps_grid(preset, geom, _recs(1.6 * rated))
        assert i[-1] == pytest.approx(2.0 * rated), name
        assert (x is None) == (preset["n_x"] is None)
