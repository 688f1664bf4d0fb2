"""The real-time lumped model (paper eqs. 1-3): lookups, integrator accuracy, events, state."""

from __future__ import annotations

import ast
import json
import math
import sys
from pathlib import Path

import mapsfixture as mf
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from solenoid_fmu.realtime import model as M

X_M = 1.0e-3  # working gap of the fixed-stroke cases [m]
R_OHM = mf.R_OHM


@pytest.fixture(scope="module")
def maps_dir(tmp_path_factory):
    return mf.write_maps(tmp_path_factory.mktemp("maps") / "synthetic")


@pytest.fixture(scope="module")
def tab(maps_dir):
    return M.load_tables(maps_dir)


def make(tab, **params):
    return M.SolenoidModel(tab, params)


# -- lookups ---------------------------------------------------------------------------------------
def test_lookup_reproduces_table_nodes(tab, maps_dir):
    with np.load(maps_dir / "maps.npz", allow_pickle=False) as d:
        psi, x, i_f, force = d["psi_Wb"], d["x_m"], d["i_f_A"], d["force_N"]
    for k in (0, 7, 20, len(psi) - 1):
        for j in (0, 5, len(x) - 1):
            assert tab.i_f_A(psi[k], x[j]) == pytest.approx(i_f[k, j], rel=1e-12, abs=1e-15)
            assert tab.force_N(psi[k], x[j]) == pytest.approx(force[k, j], rel=1e-12, abs=1e-12)


def test_lookup_is_c1_and_monotone_in_psi(tab):
    """PCHIP along Psi: slope continuous across nodes, i_f strictly increasing (unique inverse)."""
    d = tab.dpsi_Wb
    for x in (0.25e-3, X_M, 3.0e-3):
        for k in (1, 10, 25, tab.n_psi - 2):
            left = tab.di_f_dpsi(k * d - 1e-9 * d, x)
            right = tab.di_f_dpsi(k * d + 1e-9 * d, x)
            assert left == pytest.approx(right, rel=1e-6)
        fine = np.linspace(0.0, tab.psi_max_Wb, 2001)
        vals = np.array([tab.i_f_A(p, x) for p in fine])
        assert np.all(np.diff(vals) > 0.0)
        # the analytic slope agrees with a central difference of the values
        p = 0.37 * tab.psi_max_Wb
        fd = (tab.i_f_A(p + 1e-7, x) - tab.i_f_A(p - 1e-7, x)) / 2e-7
        assert tab.di_f_dpsi(p, x) == pytest.approx(fd, rel=1e-6)


def test_lookup_close_to_the_analytic_circuit(tab):
    """The interpolated map is the analytic circuit to within the grid's interpolation error."""
    for x in (0.3e-3, X_M, 3.0e-3):
        for p in np.linspace(0.02, 0.95 * tab.psi_max_Wb, 6):
            assert tab.i_f_A(p, x) == pytest.approx(float(mf.i_f_analytic(p, x)), rel=5e-3)
            assert tab.force_N(p, x) == pytest.approx(float(mf.force_analytic(p, x)), rel=5e-3)


def test_negative_flux_uses_the_symmetry(tab):
    for p in (0.01, 0.1, 0.25):
        assert tab.i_f_A(-p, X_M) == -tab.i_f_A(p, X_M)
        assert tab.force_N(-p, X_M) == tab.force_N(p, X_M)
        assert tab.di_f_dpsi(-p, X_M) == tab.di_f_dpsi(p, X_M)


def test_inverse_map(tab):
    for i in (-1.5, 0.0, 0.3, 1.2, 1.9):
        psi = tab.psi_of_current(i, X_M)
        assert tab.i_f_A(psi, X_M) == pytest.approx(i, abs=1e-10)


def test_newton_started_at_the_root_stops_at_once(tab, monkeypatch):
    """A current-driven step at a held current starts the flux solve at its root. Newton's update there is
    below the rounding of Psi, lands on the bracket's end and must be taken as converged: before stop 50 it
    fell back to bisection from the whole bracket (31-44 map lookups instead of 2-3, a third of the loop's
    simulation time on the demo). Every start: at most three lookups, the root unchanged within the tolerance."""
    from solenoid_fmu.realtime.model import tables as T

    calls = [0]
    lookup = T.cell_cubic

    def counted(*args):
        calls[0] += 1
        return lookup(*args)

    rng = np.random.default_rng(7)
    worst = 0
    for i_A, x_m in zip(rng.uniform(0.02, 1.9, 300), rng.uniform(tab.x_m[0], tab.x_m[-1], 300), strict=True):
        j, w, _ = tab.x_cell(float(x_m))
        root, _ = T.solve_psi(tab, float(i_A), j, w, 0.5 * tab.psi_max_Wb)
        monkeypatch.setattr(T, "cell_cubic", counted)
        calls[0] = 0
        again, _ = T.solve_psi(tab, float(i_A), j, w, root)
        monkeypatch.setattr(T, "cell_cubic", lookup)
        worst = max(worst, calls[0])
        assert abs(again - root) <= 2 * M.NEWTON_TOL_REL * tab.psi_max_Wb
    assert worst <= 3


# -- references ------------------------------------------------------------------------------------
def reference_zoh(tab, mode, G, u_steps, h, psi0, x_m=X_M):
    """Psi at the communication points of the continuous model with held inputs (solve_ivp)."""
    if mode == "voltage":
        m, c = 1.0 + R_OHM * G, R_OHM
    else:
        m, c = G, 1.0
    out = [psi0]
    psi = psi0
    for k, u in enumerate(u_steps):
        if m == 0.0:
            psi = brentq(lambda p, u=u: tab.i_f_A(p, x_m) - u, -tab.psi_max_Wb, tab.psi_max_Wb, xtol=1e-15)
        else:
            sol = solve_ivp(lambda t, y, u=u: [(u - c * tab.i_f_A(y[0], x_m)) / m], (k * h, (k + 1) * h),
                            [psi], method="DOP853", rtol=1e-10, atol=1e-15)
            psi = float(sol.y[0, -1])
        out.append(psi)
    return np.array(out)


def run(model, u_steps, h, x_m=X_M):
    rows = []
    for u in u_steps:
        model.step(h, u, x_m)
        rows.append([model.psi_Wb, model.i_A, model.U_V, model.F_N, model.dpsi_dt_V, model.i_eddy_A])
    return np.array(rows)


def rel_err(a, b):
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(b)))


# -- accuracy against solve_ivp ------------------------------------------------------------------
@pytest.mark.parametrize("G", [0.0, 0.02])
@pytest.mark.parametrize("h", [1e-5, 1e-4, 1e-3, 1e-2])
def test_voltage_step_matches_solve_ivp(tab, h, G):
    """24 V step from rest into saturation: Psi, i, F within 0.1 % of the reference at every step."""
    U = 24.0
    T = 0.002 if h == 1e-5 else 0.15
    n = int(round(T / h))
    model = make(tab, drive_mode="voltage", G_eddy_S=G)
    model.initialize(U, X_M)
    got = run(model, [U] * n, h)
    tt = np.arange(1, n + 1) * h
    m = 1.0 + R_OHM * G
    sol = solve_ivp(lambda t, y: [(U - R_OHM * tab.i_f_A(y[0], X_M)) / m], (0.0, tt[-1]), [0.0],
                    method="DOP853", rtol=1e-10, atol=1e-15, t_eval=tt)
    psi_ref = sol.y[0]
    i_f_ref = np.array([tab.i_f_A(p, X_M) for p in psi_ref])
    dpsi_ref = (U - R_OHM * i_f_ref) / m
    i_ref = i_f_ref + G * dpsi_ref
    f_ref = np.array([tab.force_N(p, X_M) for p in psi_ref])
    assert rel_err(got[:, 0], psi_ref) < 1e-3
    assert rel_err(got[:, 1], i_ref) < 1e-3
    assert rel_err(got[:, 3], f_ref) < 1e-3
    assert rel_err(got[:, 4], dpsi_ref) < 1e-3
    # circuit equation (paper eq. 1) holds at every output point
    np.testing.assert_allclose(got[:, 2], R_OHM * got[:, 1] + got[:, 4], rtol=0, atol=1e-9)
    if T > 0.1:
        assert got[-1, 1] == pytest.approx(U / R_OHM, rel=1e-3)  # reaches the steady current


@pytest.mark.parametrize("h", [1e-5, 1e-4, 1e-3, 1e-2])
def test_current_ramp_with_eddy_matches_solve_ivp(tab, h):
    """10 A/s current ramp, current mode with G = 0.02 S: Psi and the mean induced voltage."""
    G = 0.02
    i0 = 1.2 if h == 1e-5 else 0.2  # small steps: a short ramp through the saturation knee
    n = 400 if h == 1e-5 else int(round(0.15 / h))
    i_steps = i0 + 10.0 * h * np.arange(n)
    psi0 = tab.psi_of_current(i0, X_M)
    model = make(tab, drive_mode="current", G_eddy_S=G, Psi0_Wb=psi0)
    model.initialize(i0, X_M)
    got = run(model, i_steps, h)
    ref = reference_zoh(tab, "current", G, i_steps, h, psi0)
    dpsi_ref = np.diff(ref) / h
    assert rel_err(got[:, 0], ref[1:]) < 1e-3
    assert rel_err(got[:, 4], dpsi_ref) < 1e-3
    assert rel_err(got[:, 2], R_OHM * i_steps + dpsi_ref) < 1e-3
    np.testing.assert_allclose(got[:, 5], G * got[:, 4], rtol=1e-15)  # eq. 2 eddy term
    np.testing.assert_array_equal(got[:, 1], i_steps)  # current echoed


@pytest.mark.parametrize("h", [1e-4, 1e-2])
def test_current_ramp_without_eddy_is_algebraic(tab, h):
    """G = 0: Psi = i_f^-1(i, x) at every communication point; U = R i + Delta Psi / h."""
    n = int(round(0.15 / h))
    i_steps = 10.0 * h * np.arange(1, n + 1)
    model = make(tab, drive_mode="current", G_eddy_S=0.0)
    model.initialize(0.0, X_M)
    got = run(model, i_steps, h)
    ref = reference_zoh(tab, "current", 0.0, i_steps, h, 0.0)
    np.testing.assert_allclose(got[:, 0], ref[1:], rtol=0, atol=1e-12)
    np.testing.assert_allclose(got[:, 2], R_OHM * i_steps + np.diff(ref) / h, rtol=1e-9)
    assert np.all(got[:, 5] == 0.0)


def test_small_eddy_conductance_approaches_the_algebraic_limit(tab):
    """Stiff case (G L ~ 3e-8 s) at h = 1e-2: L-stable, no ringing, converges to G = 0."""
    h = 1e-2
    i_steps = [0.5, 1.0, 1.5, 1.5, 1.0]
    stiff = make(tab, drive_mode="current", G_eddy_S=1e-7)
    alg = make(tab, drive_mode="current", G_eddy_S=0.0)
    stiff.initialize(0.0, X_M)
    alg.initialize(0.0, X_M)
    a = run(stiff, i_steps, h)
    b = run(alg, i_steps, h)
    np.testing.assert_allclose(a[:, 0], b[:, 0], rtol=1e-6)
    np.testing.assert_allclose(a[:, 2], b[:, 2], rtol=1e-5)


def test_substep_count_follows_the_communication_step(tab):
    """One doStep of 1e-2 s gives the same flux as 100 doSteps of 1e-4 s (sub-steps of 1e-4 s)."""
    one = make(tab, drive_mode="voltage")
    many = make(tab, drive_mode="voltage")
    one.initialize(24.0, X_M)
    many.initialize(24.0, X_M)
    one.step(1e-2, 24.0, X_M)
    for _ in range(100):
        many.step(1e-4, 24.0, X_M)
    assert one.psi_Wb == pytest.approx(many.psi_Wb, rel=1e-12)
    assert one.time_s == pytest.approx(1e-2, rel=1e-12)


# -- out-of-map inputs -----------------------------------------------------------------------------
def test_gap_excursion_is_clamped_and_reported_once(tab):
    model = make(tab, drive_mode="current", G_eddy_S=0.0)
    model.initialize(1.0, X_M)
    model.step(1e-3, 1.0, tab.x_max_m)
    f_edge = model.F_N
    assert model.events == []
    for x in (5e-3, 6e-3, 7e-3):
        model.step(1e-3, 1.0, x)
        assert model.F_N == pytest.approx(f_edge, rel=1e-12)  # clamped to the map edge
        assert model.out_of_map
    assert [e[0] for e in model.events] == ["x"]
    assert "x_m = 0.005 m" in model.events[0][2]
    model.events.clear()
    model.step(1e-3, 1.0, X_M)  # back inside: flag clears, no new message
    assert not model.out_of_map and model.events == []
    model.step(1e-3, 1.0, -1e-3)  # a second excursion is a second event
    assert [e[0] for e in model.events] == ["x"]


def test_flux_excursion_holds_psi_at_the_limit(tab):
    model = make(tab, drive_mode="voltage")
    model.initialize(0.0, X_M)
    for _ in range(50):
        model.step(1e-2, 200.0, X_M)  # far beyond the coil's rating
    assert model.psi_Wb == tab.psi_max_Wb
    assert model.out_of_map
    assert [e[0] for e in model.events] == ["psi"]  # one message for the whole excursion
    model.events.clear()
    for _ in range(20):
        model.step(1e-2, 0.0, X_M)  # switched off: Psi decays back into the map at once
    assert model.psi_Wb < 0.5 * tab.psi_max_Wb and not model.out_of_map
    assert model.events == []


def test_extrapolated_region_is_reported(tab):
    """26 V drives 2.17 A, beyond the 2 A FEM sweep but inside the flux grid: one event, no clamp."""
    model = make(tab, drive_mode="voltage")
    model.initialize(0.0, X_M)
    for _ in range(40):
        model.step(1e-2, 26.0, X_M)
    assert model.i_A == pytest.approx(26.0 / R_OHM, rel=1e-6)
    assert model.psi_Wb < tab.psi_max_Wb and not model.out_of_map
    assert [e[0] for e in model.events] == ["extrapolated"]
    assert "2 A" in model.events[0][2]


def test_current_beyond_the_map_in_algebraic_mode(tab):
    model = make(tab, drive_mode="current", G_eddy_S=0.0)
    model.initialize(0.0, X_M)
    model.step(1e-3, 50.0, X_M)
    assert model.psi_Wb == tab.psi_max_Wb
    model.step(1e-3, -50.0, X_M)
    assert model.psi_Wb == -tab.psi_max_Wb
    assert [e[0] for e in model.events] == ["psi"]  # one excursion: the flag never cleared


# -- bad input -------------------------------------------------------------------------------------
@pytest.mark.parametrize(("mode", "u", "x", "match"), [
    pytest.param("voltage", math.nan, X_M, "U_V", id="nan-voltage"),
    pytest.param("current", math.inf, X_M, "i_A", id="inf-current"),
    pytest.param("voltage", 1.0, math.nan, "x_m", id="nan-gap"),
])
def test_non_finite_input_raises_and_keeps_the_state(tab, mode, u, x, match):
    model = make(tab, drive_mode=mode)
    model.initialize(0.5, X_M)
    model.step(1e-3, 0.5, X_M)
    before = model.get_state()
    with pytest.raises(M.ModelInputError, match=match):
        model.step(1e-3, u, x)
    assert model.get_state() == before


@pytest.mark.parametrize(("params", "match"), [
    pytest.param({"R_ohm": 0.0}, "R_ohm must be > 0", id="R-zero"),
    pytest.param({"R_ohm": -3.0}, "R_ohm must be > 0", id="R-negative"),
    pytest.param({"R_ohm": math.nan}, "R_ohm must be finite", id="R-nan"),
    pytest.param({"G_eddy_S": -1e-3}, "G_eddy_S must be >= 0", id="G-negative"),
    pytest.param({"drive_mode": "pwm"}, "drive_mode", id="mode-name"),
    pytest.param({"drive_mode": 0}, "drive_mode", id="mode-code"),
    pytest.param({"h_sub_max_s": 0.0}, "h_sub_max_s", id="substep"),
    pytest.param({"R": 12.0}, "unknown parameter 'R'", id="unknown-key"),
])
def test_bad_parameters_are_refused(tab, params, match):
    model = make(tab)
    before = dict(model.params)
    with pytest.raises(M.ModelInputError, match=match):
        model.set_params(**params)
    assert model.params == before


def test_parameter_defaults_come_from_the_sidecar(tab):
    model = make(tab)
    assert model.params["R_ohm"] == R_OHM
    assert model.params["G_eddy_S"] == 0.02
    assert model.drive_mode == "voltage"


def test_step_before_initialize_raises(tab):
    with pytest.raises(M.ModelInputError, match="initialize"):
        make(tab).step(1e-3, 1.0, X_M)


# -- state -----------------------------------------------------------------------------------------
def test_state_round_trip_is_exact(tab):
    model = make(tab, drive_mode="voltage")
    model.initialize(24.0, X_M)
    for _ in range(30):
        model.step(1e-3, 24.0, X_M)
    saved = model.get_state()
    assert len(saved) == len(M.STATE_NAMES)
    first = run(model, [24.0] * 10 + [0.0] * 10, 1e-3)
    model.set_state(saved)
    second = run(model, [24.0] * 10 + [0.0] * 10, 1e-3)
    np.testing.assert_array_equal(first, second)
    # the saved list is a copy, and JSON keeps it bit for bit
    assert model.set_state(json.loads(json.dumps(saved))) is None
    assert model.get_state() == saved


def test_set_state_refuses_a_foreign_layout(tab):
    model = make(tab)
    model.initialize(0.0, X_M)
    bad = model.get_state()[:-1]
    with pytest.raises(M.ModelInputError, match="layout"):
        model.set_state(bad)


# -- maps checks -----------------------------------------------------------------------------------
def test_non_monotone_map_is_refused(tab, maps_dir, tmp_path):
    with np.load(maps_dir / "maps.npz", allow_pickle=False) as d:
        arrays = {k: d[k] for k in d.files}
    arrays["i_f_A"] = arrays["i_f_A"].copy()
    arrays["i_f_A"][10, 3] = arrays["i_f_A"][9, 3]
    np.savez(tmp_path / "maps.npz", **arrays)
    (tmp_path / "maps.json").write_text((maps_dir / "maps.json").read_text())
    with pytest.raises(M.ModelMapsError, match="increase strictly"):
        M.load_tables(tmp_path)


def test_wrong_schema_version_is_refused(maps_dir, tmp_path):
    (tmp_path / "maps.npz").write_bytes((maps_dir / "maps.npz").read_bytes())
    meta = json.loads((maps_dir / "maps.json").read_text())
    meta["schema_version"] = 99
    (tmp_path / "maps.json").write_text(json.dumps(meta))
    with pytest.raises(M.ModelMapsError, match="schema_version"):
        M.load_tables(tmp_path)


def test_missing_maps_file(tmp_path):
    with pytest.raises(M.ModelMapsError, match="maps.npz"):
        M.load_tables(tmp_path)


def test_model_module_imports_only_numpy_and_stdlib():
    """The model package ships inside the FMU: its modules must not import the package (or scipy); a
    relative import reaches only a module of the model package itself (it travels with them)."""
    files = sorted(Path(M.__file__).parent.glob("*.py"))
    assert Path(M.__file__) in files and len(files) > 1
    own = {f.stem for f in files}
    names = set()
    for f in files:
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Import):
                names |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    assert node.level == 1 and node.module in own, f"{f.name}: relative import beyond the model package"
                    continue
                names.add(node.module.split(".")[0])
    assert names - {"numpy"} <= set(sys.stdlib_module_names), names - set(sys.stdlib_module_names)
