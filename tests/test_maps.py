"""Characteristic maps (issue 3): sweep, inversion, file format, interpolation, energy, exports, CLI.

Most tests run on an analytic stand-in for the FEM: a magnetic circuit of a saturating iron path
in series with a working gap whose reluctance depends on x. Psi(i, x) solves
N i = Phi (R_gap(x) + R_fe(Phi)) exactly, and the force is the co-energy derivative
F = -dW'/dx|_i = Phi^2 R_gap'(x) / 2 (positive closes the gap), so the truth is known everywhere.
The tests marked ``fem`` build a coarse map with the real FEM and compare with direct solves.
"""

from __future__ import annotations

import argparse
import dataclasses
import fcntl
import hashlib
import json
import math
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from solenoid_fmu import maps as M
from solenoid_fmu.cli import main as cli_main
from solenoid_fmu.errors import MapsError
from solenoid_fmu.maps.cli import parse_range
from solenoid_fmu.maps.tables import ARRAY_UNITS

# ---------------------------------------------------------------------------------------------
# The analytic stand-in
# ---------------------------------------------------------------------------------------------

MU0 = 4e-7 * math.pi
N_TURNS = 1500.0
A_GAP_M2 = math.pi * 6.1e-3**2  # armature face
L_FE_M = 0.09  # iron path length
MU_R = 2000.0
B_SAT_T = 1.6
P_SAT = 10  # sharpness of the saturation knee
G_PAR_M = 0.15e-3  # parasitic gap in series with the working gap
K_X_PER_M = 150.0  # makes R_gap(x) curved in x (fringing-like)


def r_gap(x_m):
    """Gap reluctance [A/Wb] at working gap x [m]."""
    return (x_m + G_PAR_M) * (1 + K_X_PER_M * x_m) / (MU0 * A_GAP_M2)


def dr_gap_dx(x_m):
    """d R_gap / dx [A/(Wb m)]."""
    return (1 + K_X_PER_M * G_PAR_M + 2 * K_X_PER_M * x_m) / (MU0 * A_GAP_M2)


def h_fe(b_T):
    """Iron H(B) [A/m]: linear with mu_r at low B, saturating steeply above B_SAT_T."""
    return b_T / (MU0 * MU_R) * (1 + (b_T / B_SAT_T) ** P_SAT)


def exact_i(psi_Wb, x_m):
    """The current [A] that produces flux linkage psi at gap x: N i = Phi R_gap + l H(B)."""
    phi = np.asarray(psi_Wb, dtype=float) / N_TURNS
    return (phi * r_gap(x_m) + L_FE_M * h_fe(phi / A_GAP_M2)) / N_TURNS


def exact_psi(i_A, x_m):
    """Flux linkage [Wb] by bisection on the strictly increasing exact_i."""
    i, x = np.broadcast_arrays(np.asarray(i_A, dtype=float), np.asarray(x_m, dtype=float))
    lo, hi = np.zeros(i.shape), np.ones(i.shape)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        below = exact_i(mid, x) < i
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def exact_force(i_A, x_m):
    """F = -dW'/dx at constant i = Phi^2 R_gap'(x) / 2 [N] (positive closes the gap)."""
    phi = exact_psi(i_A, x_m) / N_TURNS
    return 0.5 * phi**2 * dr_gap_dx(x_m)


def exact_coenergy(i_A, x_m):
    """W'(i, x) = integral of Psi di from 0 to i [J]."""
    return quad(lambda s: float(exact_psi(s, x_m)), 0.0, i_A, epsabs=1e-12, epsrel=1e-10, limit=200)[0]


@dataclasses.dataclass(frozen=True)
class Coil:
    turns: float = N_TURNS
    resistance_ohm_20C: float = 12.0
    temperature_coefficient_per_K: float = 0.00393
    max_current_A: float = 2.0


@dataclasses.dataclass(frozen=True)
class Stroke:
    min_m: float = 0.2e-3
    max_m: float = 3.5e-3
    working_min_m: float = 0.5e-3
    working_max_m: float = 2.8e-3


@dataclasses.dataclass(frozen=True)
class FakeGeometry:
    name: str = "analytic"
    coil: Coil = Coil()
    stroke: Stroke = Stroke()
    source_path: Path | None = None
    sha256: str = "ab" * 32


@dataclasses.dataclass(frozen=True)
class FakeMaterial:
    name: str = "analytic-steel"
    source_path: Path | None = None
    sha256: str = "cd" * 32


def analytic_sweep(geometry, material, x_m, i_A, mesh_size=1.0):
    """Drop-in for fem.sweep_currents: exact Psi and co-energy force; 'stress' force 1 % off."""
    i_A = np.asarray(i_A, dtype=float)
    force = exact_force(i_A, x_m)
    return {"psi_Wb": exact_psi(i_A, x_m), "force_N": force, "force_stress_N": 1.01 * force,
            "newton_iterations": np.full(len(i_A), 3.0)}


@pytest.fixture(scope="module")
def amaps():
    """Maps of the stand-in on the default grid (27 positions x 26 currents)."""
    return M.build_maps(FakeGeometry(), FakeMaterial(), executor=M.InlineExecutor(), progress=False,
                        sweep=analytic_sweep)


def test_standin_force_is_minus_coenergy_derivative():
    # the stand-in's closed-form force must be -dW'/dx at constant i, or nothing below means anything
    for i, x in ((0.4, 0.6e-3), (1.5, 1.2e-3), (2.5, 2.9e-3)):
        h = 1e-7
        numeric = -(exact_coenergy(i, x + h) - exact_coenergy(i, x - h)) / (2 * h)
        assert numeric == pytest.approx(float(exact_force(i, x)), rel=1e-5)


# ---------------------------------------------------------------------------------------------
# Grid, sweep, executor
# ---------------------------------------------------------------------------------------------


def test_default_grid_covers_stroke_and_currents(amaps):
    ni, nx, npsi = amaps.shape
    assert (ni, nx) == (26, 27)
    assert amaps.x_m[0] == pytest.approx(0.2e-3, abs=1e-15)
    assert amaps.x_m[-1] == pytest.approx(3.5e-3, abs=1e-15)
    assert amaps.i_A[0] == 0.0 and amaps.i_A[-1] == pytest.approx(2.5)
    steps = np.diff(amaps.x_m)
    assert steps[0] < steps[nx // 2] and steps[-1] < steps[nx // 2]  # clustered at both stops
    np.testing.assert_allclose(steps, steps[::-1], rtol=1e-9)
    assert amaps.psi_Wb[0] == 0.0
    assert amaps.psi_Wb[-1] == pytest.approx(amaps.psi_ix_Wb[-1].max(), rel=1e-15)


def test_thread_pool_gives_same_maps_and_is_not_shut_down(amaps):
    with ThreadPoolExecutor(max_workers=2) as ex:
        threaded = M.build_maps(FakeGeometry(), FakeMaterial(), executor=ex, progress=False,
                                sweep=analytic_sweep)
        assert ex.submit(lambda: 7).result() == 7  # the caller's executor is left running
    for name, arr in amaps.arrays().items():
        np.testing.assert_array_equal(getattr(threaded, name), arr, err_msg=name)
    assert threaded.metadata["provenance"]["solver"]["executor"] == "ThreadPoolExecutor"


def test_tasks_are_one_per_position_and_run_in_parallel():
    seen, lock = [], threading.Lock()
    barrier = threading.Barrier(2, timeout=10)

    def sweep(geometry, material, x_m, i_A, mesh_size=1.0):
        with lock:
            seen.append((x_m, len(i_A), mesh_size))
        barrier.wait()  # deadlocks (BrokenBarrierError) unless two tasks run at the same time
        return analytic_sweep(geometry, material, x_m, i_A)

    x = np.linspace(0.5e-3, 2.5e-3, 4)
    M.build_maps(FakeGeometry(), FakeMaterial(), x_m=x, i_A=np.linspace(0, 2, 5), mesh_size=2.5,
                 executor=ThreadPoolExecutor(2), progress=False, sweep=sweep)
    assert sorted(s[0] for s in seen) == pytest.approx(list(x))
    assert {s[1] for s in seen} == {5} and {s[2] for s in seen} == {2.5}


def test_progress_bar_on_stderr(capsys):
    M.build_maps(FakeGeometry(), FakeMaterial(), x_m=[1e-3, 2e-3], i_A=[0, 1, 2], progress=True,
                 executor=M.InlineExecutor(), sweep=analytic_sweep)
    err = capsys.readouterr().err
    assert "FEM sweep" in err and "6/6" in err


def test_failed_fem_task_names_the_position():
    from solenoid_fmu.errors import SolverError

    calls = []

    def sweep(geometry, material, x_m, i_A, mesh_size=1.0):
        calls.append(x_m)
        if abs(x_m - 1.5e-3) < 1e-9:
            raise SolverError("Newton did not converge: residuals 1e-2, 5e-3")
        return analytic_sweep(geometry, material, x_m, i_A)

    with pytest.raises(MapsError, match=r"x = 1\.5 mm.*Newton did not converge"):
        M.build_maps(FakeGeometry(), FakeMaterial(), x_m=[1e-3, 1.5e-3, 2e-3], i_A=[0, 1, 2],
                     executor=M.InlineExecutor(), progress=False, sweep=sweep)
    assert len(calls) == 2  # in-process runs stop at the first failure


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        pytest.param({"x_m": [0.1e-3, 1e-3]}, r"0\.1 mm is outside the stroke", id="x-outside-stroke"),
        pytest.param({"x_m": [2e-3, 1e-3]}, "strictly increasing", id="x-decreasing"),
        pytest.param({"i_A": [0.5, 1.0, 2.0]}, "must start at 0 A", id="i-not-from-zero"),
        pytest.param({"i_A": [0.0, 1.0]}, "at least 3 currents", id="too-few-currents"),
        pytest.param({"mesh_size": -1.0}, "mesh_size", id="bad-mesh-size"),
    ],
)
def test_bad_grids_are_refused(kwargs, message):
    with pytest.raises(MapsError, match=message):
        M.build_maps(FakeGeometry(), FakeMaterial(), executor=M.InlineExecutor(), progress=False,
                     sweep=analytic_sweep, **kwargs)


# ---------------------------------------------------------------------------------------------
# Inversion
# ---------------------------------------------------------------------------------------------


def test_round_trip_below_0p1_percent_on_and_between_flux_nodes(amaps):
    # nodes, midpoints and quarter points of the flux grid at every map position
    assert M.round_trip_error(amaps, points_per_interval=4) < 1e-3
    # the nodes themselves are exact inverses of the Psi(i) interpolant
    for j, x in enumerate(amaps.x_m):
        inside = amaps.extrapolated[:, j] == 0
        back = M.psi_at(amaps, amaps.i_f_A[inside, j], x)
        np.testing.assert_allclose(back, amaps.psi_Wb[inside], rtol=1e-9, atol=1e-12)


def test_i_f_and_force_psi_maps_match_the_analytic_truth(amaps):
    # i_f(Psi, x) and F(Psi, x) at the map positions against the exact circuit
    for j, x in enumerate(amaps.x_m):
        inside = (amaps.extrapolated[:, j] == 0) & (amaps.psi_Wb > 0.05 * amaps.psi_Wb[-1])
        p = amaps.psi_Wb[inside]
        np.testing.assert_allclose(amaps.i_f_A[inside, j], exact_i(p, x), rtol=5e-3)
        f_true = 0.5 * (p / N_TURNS) ** 2 * dr_gap_dx(x)
        np.testing.assert_allclose(amaps.force_N[inside, j], f_true, rtol=1e-2)


def test_extrapolated_flags_mark_flux_beyond_each_column(amaps):
    for j in range(len(amaps.x_m)):
        beyond = amaps.psi_Wb > amaps.psi_ix_Wb[-1, j] * (1 + 1e-12)
        np.testing.assert_array_equal(amaps.extrapolated[:, j] == 1.0, beyond)
    # the smallest gap carries the largest flux and needs no extrapolation
    assert amaps.extrapolated[:, 0].sum() == 0
    assert amaps.extrapolated[:, -1].sum() > 0
    # extrapolated nodes continue the last two sweep points linearly
    j = len(amaps.x_m) - 1
    k = np.flatnonzero(amaps.extrapolated[:, j])[-1]
    psi2, i2 = amaps.psi_ix_Wb[-2:, j], amaps.i_A[-2:]
    expected = i2[1] + (amaps.psi_Wb[k] - psi2[1]) * (i2[1] - i2[0]) / (psi2[1] - psi2[0])
    assert amaps.i_f_A[k, j] == pytest.approx(expected, rel=1e-12)


def test_inversion_refuses_non_monotone_flux_naming_x_and_i():
    x = np.array([0.5e-3, 1.0e-3, 1.5e-3])
    i = np.linspace(0, 2, 9)
    psi = exact_psi(i[:, None], x[None, :])
    psi[6, 1] = psi[5, 1] * 0.999  # Psi falls between 1.25 A and 1.5 A at x = 1 mm
    force = exact_force(i[:, None], x[None, :])
    with pytest.raises(MapsError) as info:
        M.invert_maps(x, i, psi, force, force)
    msg = str(info.value)
    assert "x = 1 mm" in msg and "i = 1.25 A" in msg and "i = 1.5 A" in msg
    assert "x = 0.5 mm" not in msg  # only the broken column is named


def test_build_maps_refuses_non_monotone_fem_output():
    def sweep(geometry, material, x_m, i_A, mesh_size=1.0):
        out = analytic_sweep(geometry, material, x_m, i_A)
        if x_m > 2e-3:
            out["psi_Wb"][3] = out["psi_Wb"][2]  # flat: not strictly rising
        return out

    with pytest.raises(MapsError, match=r"x = 2\.5 mm.*between i = 1 A"):
        M.build_maps(FakeGeometry(), FakeMaterial(), x_m=[1e-3, 2.5e-3], i_A=[0, 0.5, 1, 1.5, 2],
                     executor=M.InlineExecutor(), progress=False, sweep=sweep)


# ---------------------------------------------------------------------------------------------
# Interpolation of the (i, x) tables and energy consistency
# ---------------------------------------------------------------------------------------------


def test_psi_and_force_interpolation_against_truth_off_grid(amaps):
    rng = np.random.default_rng(3)
    i = rng.uniform(0.1, 2.5, 300)
    x = rng.uniform(0.5e-3, 2.8e-3, 300)  # working range
    np.testing.assert_allclose(M.psi_at(amaps, i, x), exact_psi(i, x), rtol=5e-3)
    np.testing.assert_allclose(M.force_at(amaps, i, x), exact_force(i, x), rtol=1e-2)
    # on the grid the interpolants reproduce the table
    np.testing.assert_allclose(M.psi_at(amaps, amaps.i_A[:, None], amaps.x_m[None, :]), amaps.psi_ix_Wb,
                               rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize(
    ("func", "args", "message"),
    [
        pytest.param(M.psi_at, (3.0, 1e-3), r"current 3 A is outside", id="psi-current"),
        pytest.param(M.force_at, (1.0, 4e-3), r"position 4 mm is outside", id="force-position"),
        pytest.param(M.i_f_at, (1.0, 1e-3), r"flux linkage 1 Wb is outside", id="i_f-flux"),
        pytest.param(M.psi_at, (float("nan"), 1e-3), "NaN", id="nan"),
    ],
)
def test_queries_outside_the_table_are_refused(amaps, func, args, message):
    with pytest.raises(MapsError, match=message):
        func(amaps, *args)


@pytest.mark.parametrize(
    "cycle",
    [
        pytest.param((0.0, 2.0, 2.5e-3, 1.0e-3), id="close-at-2A"),
        pytest.param((0.0, 2.5, 3.5e-3, 0.2e-3), id="full-stroke-2.5A"),
        pytest.param((0.5, 1.5, 0.6e-3, 2.8e-3), id="open-between-0.5-and-1.5A"),
    ],
)
def test_energy_cycle_balances_on_i_x_tables(amaps, cycle):
    result = M.cycle_energy_balance(amaps, M.rectangle_cycle(*cycle))
    assert result.relative_error < 1e-2
    assert abs(result.mechanical_J) > 0.05  # a real cycle, not two zeros
    # the mechanical work also matches the exact co-energy difference along the two moves
    i_lo, i_hi, x1, x2 = cycle
    exact = (exact_coenergy(i_hi, x2) - exact_coenergy(i_hi, x1)) - (
        exact_coenergy(i_lo, x2) - exact_coenergy(i_lo, x1))
    assert result.mechanical_J == pytest.approx(exact, rel=1e-2)


def test_energy_cycle_balances_on_psi_x_maps(amaps):
    cycle = [[0.0, 2.5e-3], [0.25, 2.5e-3], [0.25, 0.8e-3], [0.0, 0.8e-3]]  # (Psi [Wb], x [m])
    result = M.cycle_energy_balance(amaps, cycle, tables="psi_x")
    assert result.relative_error < 1e-2
    # flux raised at the wide gap, gap closed at constant flux: the magnet does net work
    # W = Psi^2 / (2 N^2) (R_gap(2.5 mm) - R_gap(0.8 mm)), exactly for the circuit
    exact = 0.25**2 / (2 * N_TURNS**2) * (r_gap(2.5e-3) - r_gap(0.8e-3))
    assert result.mechanical_J == pytest.approx(exact, rel=1e-2)


def test_energy_cycle_detects_an_inconsistent_force(amaps):
    bad = dataclasses.replace(amaps, force_ix_N=amaps.force_ix_N * 1.05)
    result = M.cycle_energy_balance(bad, M.rectangle_cycle(0.0, 2.0, 2.5e-3, 1.0e-3))
    assert result.relative_error == pytest.approx(0.05 / 1.05, rel=0.05)


# ---------------------------------------------------------------------------------------------
# File format
# ---------------------------------------------------------------------------------------------


def test_save_load_identity(amaps, tmp_path):
    directory = M.save_maps(amaps, tmp_path / "maps" / "analytic")
    assert sorted(p.name for p in directory.iterdir()) == ["maps.json", "maps.npz"]  # no temp files left
    loaded = M.load_maps(directory)
    for name, arr in amaps.arrays().items():
        np.testing.assert_array_equal(getattr(loaded, name), arr, err_msg=name)
        assert getattr(loaded, name).dtype == np.float64
    assert loaded.metadata == amaps.metadata
    meta = json.loads((directory / "maps.json").read_text())
    assert meta["schema"] == "solenoid-fmu-maps" and meta["schema_version"] == 1
    assert meta["force_method"] == "coenergy"
    assert meta["units"]["psi_Wb"] == "Wb" and meta["units"]["x_m"] == "m"
    prov = meta["provenance"]
    assert prov["geometry"]["sha256"] == "ab" * 32 and prov["material"]["sha256"] == "cd" * 32
    assert prov["code_version"].startswith("0.") and "created_utc" in prov
    assert prov["solver"]["operating_points"] == 26 * 27
    assert meta["eddy"] == {"G_eddy_S": None, "source": "not identified (the FEM is magnetostatic)"}
    with np.load(directory / "maps.npz", allow_pickle=False) as data:  # plain arrays, no pickle
        assert set(data.files) == set(ARRAY_UNITS)
    # loading a file path inside the directory works the same
    assert M.load_maps(directory / "maps.json").shape == amaps.shape


def test_with_eddy_round_trips(amaps, tmp_path):
    maps = amaps.with_eddy(0.012, "fit to 3 recordings")
    assert amaps.metadata["eddy"]["G_eddy_S"] is None  # the original is untouched
    loaded = M.load_maps(M.save_maps(maps, tmp_path / "m"))
    assert loaded.metadata["eddy"] == {"G_eddy_S": 0.012, "source": "fit to 3 recordings"}
    with pytest.raises(MapsError, match="G_eddy_S"):
        amaps.with_eddy(-1.0, "x")


def test_with_eddy_keeps_whether_the_fit_measured_an_eddy_current(amaps, tmp_path):
    from solenoid_fmu.realtime import load_tables

    loaded = M.load_maps(M.save_maps(amaps.with_eddy(0.004, "3 recordings", measured=True), tmp_path / "m"))
    assert loaded.metadata["eddy"] == {"G_eddy_S": 0.004, "source": "3 recordings", "measured": True}
    assert load_tables(tmp_path / "m").eddy.measured is True
    assert "measured" not in amaps.with_eddy(0.004, "by hand").metadata["eddy"]  # not said: not written
    with pytest.raises(MapsError, match="measured"):
        amaps.with_eddy(0.004, "x", measured="yes")
    # a maps.json that says it in another type is refused, naming the key
    meta = json.loads((tmp_path / "m" / "maps.json").read_text())
    meta["eddy"]["measured"] = "yes"
    (tmp_path / "m" / "maps.json").write_text(json.dumps(meta))
    with pytest.raises(Exception, match="eddy.measured"):
        load_tables(tmp_path / "m")


def test_maps_are_immutable(amaps):
    with pytest.raises(ValueError, match="read-only"):
        amaps.psi_ix_Wb[0, 0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        amaps.x_m = np.zeros(3)


def _rewrite(directory: Path, arrays_edit=None, meta_edit=None, fix_hash=True):
    """Tamper with a saved map: edit arrays and/or the sidecar, keeping the hash consistent."""
    npz, js = directory / "maps.npz", directory / "maps.json"
    meta = json.loads(js.read_text())
    if arrays_edit is not None:
        with np.load(npz, allow_pickle=False) as data:
            arrays = {k: data[k].copy() for k in data.files}
        arrays_edit(arrays)
        np.savez(npz, **arrays)
        if fix_hash:
            meta["arrays"]["sha256"] = hashlib.sha256(npz.read_bytes()).hexdigest()
    if meta_edit is not None:
        meta_edit(meta)
    js.write_text(json.dumps(meta))


def _set(d, key, value):
    d[key] = value


def _nan(a):
    a["force_N"][3, 4] = np.nan


def _x_non_monotone(a):
    a["x_m"][5] = a["x_m"][4]


BAD_FILES = [
    pytest.param(None, lambda m: _set(m, "schema_version", 2), r"schema_version 2 is not supported",
                 id="wrong-version"),
    pytest.param(None, lambda m: _set(m, "schema", "something-else"), "not a map file", id="wrong-schema"),
    pytest.param(lambda a: a.pop("i_f_A"), None, r"missing array\(s\): i_f_A", id="missing-array"),
    pytest.param(_nan, None, r"force_N has 1 NaN/inf value\(s\), first at index \(3, 4\)", id="nan"),
    pytest.param(_x_non_monotone, None, r"grid x_m is not strictly increasing: x_m\[4\]",
                 id="x-not-monotone"),
    pytest.param(lambda a: _set(a, "psi_ix_Wb", a["psi_ix_Wb"][:-1]), None,
                 r"psi_ix_Wb has shape \(25, 27\), expected \(26, 27\)", id="wrong-shape"),
    pytest.param(None, lambda m: m["units"].__setitem__("x_m", "mm"), "units of x_m must be 'm'",
                 id="wrong-unit"),
    pytest.param(lambda a: _set(a, "i_f_A", a["i_f_A"].astype(object)), None, "without pickle|dtype",
                 id="object-array"),
]


@pytest.mark.parametrize(("arrays_edit", "meta_edit", "message"), BAD_FILES)
def test_reader_refuses_bad_files_naming_the_problem(amaps, tmp_path, arrays_edit, meta_edit, message):
    directory = M.save_maps(amaps, tmp_path / "bad")
    _rewrite(directory, arrays_edit, meta_edit)
    with pytest.raises(MapsError, match=message) as info:
        M.load_maps(directory)
    assert str(directory) in str(info.value)  # names the file


def test_reader_refuses_npz_from_another_save(amaps, tmp_path):
    directory = M.save_maps(amaps, tmp_path / "a")
    _rewrite(directory, lambda a: a["force_N"].__imul__(1.0), fix_hash=False)  # same data, new bytes
    (directory / "maps.npz").write_bytes((directory / "maps.npz").read_bytes() + b"\0")
    with pytest.raises(MapsError, match="were not written together"):
        M.load_maps(directory)


def test_reader_accepts_shared_format_without_hash_entry(amaps, tmp_path):
    # other tools write the shared format without our "arrays" entry: no hash to check, still loads
    directory = M.save_maps(amaps, tmp_path / "plain")
    _rewrite(directory, meta_edit=lambda m: m.pop("arrays"))
    np.testing.assert_array_equal(M.load_maps(directory).i_f_A, amaps.i_f_A)


def test_reader_reports_invalid_json_with_line(tmp_path, amaps):
    directory = M.save_maps(amaps, tmp_path / "j")
    (directory / "maps.json").write_text('{\n "schema": "solenoid-fmu-maps",\n oops\n}')
    with pytest.raises(MapsError, match=r"maps\.json:3: not valid JSON"):
        M.load_maps(directory)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(MapsError, match=r"empty/maps\.json: missing"):
        M.load_maps(empty)


# ---------------------------------------------------------------------------------------------
# Exports and plots
# ---------------------------------------------------------------------------------------------


def test_combitable2d_files_parse_back_to_the_tables(amaps, tmp_path):
    paths = M.export_combitable2d(amaps, tmp_path)
    assert [p.name for p in paths] == ["i_f_A.txt", "force_N.txt"]
    text = paths[0].read_text()
    assert text.startswith("#1\n")
    npsi, nx = amaps.i_f_A.shape
    assert f"double i_f_A({npsi + 1},{nx + 1})" in text
    for path, name, table in ((paths[0], "i_f_A", amaps.i_f_A), (paths[1], "force_N", amaps.force_N)):
        t = M.read_combitable2d(path, name)
        assert t.shape == (npsi + 1, nx + 1)
        np.testing.assert_array_equal(t[0, 1:], amaps.x_m)  # u2 = x in the first row
        np.testing.assert_array_equal(t[1:, 0], amaps.psi_Wb)  # u1 = Psi in the first column
        np.testing.assert_array_equal(t[1:, 1:], table)
    with pytest.raises(MapsError, match="no table named"):
        M.read_combitable2d(paths[0], "force_N")


def test_mat_file_has_the_documented_variables(amaps, tmp_path):
    from scipy.io import loadmat

    path = M.export_mat(amaps, tmp_path / "maps.mat")
    mat = loadmat(path)
    ni, nx, npsi = amaps.shape
    assert mat["i_A"].shape == (1, ni) and mat["x_m"].shape == (1, nx) and mat["psi_Wb"].shape == (1, npsi)
    np.testing.assert_array_equal(mat["Phi_ix_Wb"], amaps.psi_ix_Wb)
    np.testing.assert_array_equal(mat["F_ix_N"], amaps.force_ix_N)
    np.testing.assert_array_equal(mat["F_simscape_ix_N"], -amaps.force_ix_N)
    np.testing.assert_array_equal(mat["i_f_psix_A"], amaps.i_f_A)
    np.testing.assert_array_equal(mat["F_psix_N"], amaps.force_N)
    # partial derivatives agree with the analytic circuit at a mid-stroke grid point
    k, j = 10, 7
    i, x = amaps.i_A[k], amaps.x_m[j]
    dpsi_di = (exact_psi(i + 1e-5, x) - exact_psi(i - 1e-5, x)) / 2e-5
    dpsi_dx = (exact_psi(i, x + 1e-8) - exact_psi(i, x - 1e-8)) / 2e-8
    assert mat["dPhi_di_ix_H"][k, j] == pytest.approx(dpsi_di, rel=2e-2)
    assert mat["dPhi_dx_ix_Wb_per_m"][k, j] == pytest.approx(dpsi_dx, rel=2e-2)
    assert "rows = i_A" in str(mat["info"][0])


# ---------------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "message"),
    [
        pytest.param("0.2:3.5", "expected START:STOP:N", id="two-fields"),
        pytest.param("0.2:3.5:15:1", "expected START:STOP:N", id="four-fields"),
        pytest.param("a:3.5:15", "must be numbers", id="not-a-number"),
        pytest.param("0.2:inf:15", "finite", id="infinite"),
        pytest.param("0.2:3.5:15.5", "whole number", id="fractional-n"),
        pytest.param("0.2:3.5:1", "at least 2", id="n-too-small"),
        pytest.param("3.5:0.2:15", "START must be smaller", id="reversed"),
    ],
)
def test_range_parser_is_strict(text, message):
    with pytest.raises(argparse.ArgumentTypeError, match=message):
        parse_range(text, "--x-mm")


def test_range_parser_accepts_good_ranges():
    assert parse_range("0.2:3.5:15") == (0.2, 3.5, 15)
    assert parse_range("0:2.5:26") == (0.0, 2.5, 26)


def test_cli_plots_and_exports_an_existing_map(amaps, tmp_path, capsys):
    directory = M.save_maps(amaps, tmp_path / "maps" / "analytic")
    plots = tmp_path / "plots"
    code = cli_main(["maps", "--from", str(directory), "--plot", str(plots), "--modelica", "--mat"])
    assert code == 0
    names = sorted(p.name for p in plots.iterdir())
    assert names == ["force_psi_x.png", "force_x_per_i.png", "i_f_psi_x.png", "psi_i_per_x.png"]
    for p in plots.iterdir():
        data = p.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
    assert (directory / "i_f_A.txt").is_file() and (directory / "maps.mat").is_file()
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        pytest.param(["maps", "--from", "{d}"], "needs something to do", id="from-without-action"),
        pytest.param(["maps", "--from", "{d}", "-o", "x", "--plot", "p"], "either -o", id="from-and-o"),
        pytest.param(["maps", "--from", "{d}", "--x-mm", "0.5:1:3", "--plot", "p"],
                     "only apply to a new sweep", id="from-with-sweep-option"),
        pytest.param(["maps"], "missing -o", id="no-output"),
        pytest.param(["maps", "--from", "{d}/../nowhere", "--plot", "p"], "no such map directory",
                     id="from-missing"),
    ],
)
def test_cli_usage_errors_exit_1_with_message(amaps, tmp_path, capsys, argv, message):
    directory = M.save_maps(amaps, tmp_path / "m")
    code = cli_main([a.replace("{d}", str(directory)) for a in argv])
    assert code == 1
    assert message in capsys.readouterr().err


def test_cli_bad_range_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as info:
        cli_main(["maps", "--x-mm", "1:0.5:4", "-o", "x"])
    assert info.value.code == 2
    assert "START must be smaller than STOP" in capsys.readouterr().err


# ---------------------------------------------------------------------------------------------
# With the real FEM (coarse mesh)
# ---------------------------------------------------------------------------------------------

FEM_MESH = 3.0  # coarse: the comparison is map interpolation vs a direct solve on the same mesh


@pytest.fixture(scope="session")
def fem_maps(tmp_path_factory, worker_id):
    """PS45 maps on a coarse mesh over the working range (11 positions x 21 currents to i_max).

    The default grid's spacing (graded positions and currents) restricted to the working range
    with a margin, for speed. Built once per test run: pytest-xdist workers share one copy through
    a file lock in the run's temp root.
    """
    from solenoid_fmu.field.geometry import load_geometry
    from solenoid_fmu.field.material import load_material

    root = tmp_path_factory.getbasetemp()
    if worker_id != "master":
        root = root.parent
    directory = root / "fem-maps-coarse"
    with open(root / "fem-maps-coarse.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (directory / "maps.json").is_file():
            geometry = load_geometry()
            x_m = M.default_positions(geometry.stroke.working_min_m - 0.1e-3,
                                      geometry.stroke.working_max_m + 0.2e-3, 11)
            i_A = M.default_currents(geometry.coil.max_current_A, 21)
            maps = M.build_maps(geometry, load_material(), x_m=x_m, i_A=i_A, mesh_size=FEM_MESH,
                                progress=False)
            M.save_maps(maps, directory)
    return M.load_maps(directory)


@pytest.mark.slow
def test_fem_map_interpolation_matches_direct_solves(fem_maps):
    from solenoid_fmu.field.fem import solve_point
    from solenoid_fmu.field.geometry import load_geometry
    from solenoid_fmu.field.material import load_material

    geometry, material = load_geometry(), load_material()
    rng = np.random.default_rng(20240611)
    n = 20
    x = rng.uniform(geometry.stroke.working_min_m, geometry.stroke.working_max_m, n)
    i = rng.uniform(0.05, 1.0, n) * geometry.coil.max_current_A  # includes the saturation knee
    direct = [solve_point(geometry, material, float(a), float(b), mesh_size=FEM_MESH)
              for a, b in zip(i, x, strict=True)]
    psi_direct = np.array([s.psi_Wb for s in direct])
    force_direct = np.array([s.force_coenergy_N for s in direct])
    np.testing.assert_allclose(M.psi_at(fem_maps, i, x), psi_direct, rtol=5e-3)
    np.testing.assert_allclose(M.force_at(fem_maps, i, x), force_direct, rtol=1e-2)


@pytest.mark.slow
@pytest.mark.parametrize(
    "cycle",
    [
        pytest.param((0.0, 2.0, 2.8e-3, 0.5e-3), id="close-working-range-at-2A"),
        pytest.param((0.4, 1.2, 1.0e-3, 2.2e-3), id="open-between-0.4-and-1.2A"),
    ],
)
def test_fem_map_energy_cycle_balances(fem_maps, cycle):
    result = M.cycle_energy_balance(fem_maps, M.rectangle_cycle(*cycle))
    assert abs(result.mechanical_J) > 0.01
    assert result.relative_error < 1e-2
    # the real-time (Psi, x) maps balance too, around the cycle at the flux reached at the wide gap
    psi_top = float(M.psi_at(fem_maps, cycle[1], max(cycle[2:])))
    psi_cycle = [[0.0, cycle[2]], [psi_top, cycle[2]], [psi_top, cycle[3]], [0.0, cycle[3]]]
    assert M.cycle_energy_balance(fem_maps, psi_cycle, tables="psi_x").relative_error < 1e-2


@pytest.mark.slow
def test_fem_map_round_trip_and_provenance(fem_maps):
    from solenoid_fmu.field.geometry import load_geometry
    from solenoid_fmu.field.material import load_material

    assert M.round_trip_error(fem_maps, points_per_interval=4) < 1e-3
    prov = fem_maps.metadata["provenance"]
    assert prov["geometry"]["sha256"] == load_geometry().sha256
    assert prov["geometry"]["path"] == "solenoid_fmu/data/ps45.toml"  # portable: relative to the checkout
    assert prov["material"]["sha256"] == load_material().sha256
    assert prov["mesh_size"] == FEM_MESH
    assert prov["solver"]["sweep"] == "solenoid_fmu.field.fem.sweep_currents"
    # Psi at the working-range end points rises with current and falls with the gap
    assert np.all(np.diff(fem_maps.psi_ix_Wb, axis=0) > 0)
    assert np.all(fem_maps.psi_ix_Wb[-1, :-1] > fem_maps.psi_ix_Wb[-1, 1:])


def test_cli_sweeps_a_small_fem_map(tmp_path, capsys):
    out = tmp_path / "maps" / "tiny"
    code = cli_main(["maps", "--x-mm", "1:2:2", "--i-A", "0:1.5:3", "--mesh-size", "3", "--workers", "1",
                     "--quiet", "-o", str(out), "--mat"])
    assert code == 0
    maps = M.load_maps(out)
    assert maps.name == "tiny" and maps.shape[:2] == (3, 2)
    np.testing.assert_allclose(maps.x_m, [1e-3, 2e-3])
    assert maps.metadata["provenance"]["solver"]["executor"] == "InlineExecutor"
    assert (out / "maps.mat").is_file()
    assert "wrote" in capsys.readouterr().out


def test_shipped_ps45_map_round_trip_between_positions():
    """The shipped map (maps/ps45-literature): Psi -> i_f -> Psi within 0.1 % at the midpoints
    between all positions (the model reads the maps linearly in x), and built from the packaged
    PS45 geometry and literature steel."""
    from pathlib import Path

    from solenoid_fmu.field.geometry import load_geometry
    from solenoid_fmu.field.material import load_material

    shipped = M.load_maps(Path(__file__).resolve().parents[1] / "maps" / "ps45-literature")
    mid = 0.5 * (shipped.x_m[1:] + shipped.x_m[:-1])
    assert M.round_trip_error(shipped, x_m=mid) < 1e-3
    assert M.round_trip_error(shipped) < 1e-3
    prov = shipped.metadata["provenance"]
    assert prov["geometry"]["sha256"] == load_geometry().sha256
    assert prov["material"]["sha256"] == load_material().sha256
