"""The public Python API (``import solenoid_fmu as sf``) and its examples, one per verb (issue 15).

Each example in ``examples/`` has a ``run()`` that returns numbers; these tests run it and check
physics or behaviour that could fail: energy consistency of the FEM force, the maps' round trip,
Ohm's law at the end of a voltage step, the true model validating within noise, the diagnosed
and the added effect. The pipeline example runs in ``tests/test_pipeline.py`` (its fixture).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import solenoid_fmu as sf
from solenoid_fmu import api

ROOT = Path(__file__).resolve().parents[1]
MAPS = ROOT / "maps" / "ps45-literature"
DEMO = ROOT / "fitting" / "ps45-demo"
sys.path.insert(0, str(ROOT / "examples"))


def _example(name):
    import importlib

    return importlib.import_module(name)


def test_public_names_are_the_api_and_load_lazily():
    assert sorted(sf.__all__) == sorted(api.__all__)
    assert all(callable(getattr(sf, n)) for n in sf.__all__)
    with pytest.raises(AttributeError, match="no attribute 'nonexistent'"):
        sf.nonexistent  # noqa: B018
    code = "import sys, solenoid_fmu; print(sorted(m for m in ('skfem', 'fmpy', 'scipy') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"  # the FEM and FMU tool chains load on first use only


def test_every_verb_has_an_example():
    verbs = {"solve", "build_maps", "load_maps", "read_recording", "identify", "export_fmu", "simulate",
             "validate", "diagnose", "improve", "run_rig", "run_pipeline"}
    for verb in verbs:
        name = {"run_pipeline": "pipeline"}.get(verb, verb)
        src = (ROOT / "examples" / f"ex_{name}.py").read_text()
        assert f"sf.{verb}(" in src, verb


def test_solve_forces_by_coenergy_and_maxwell_stress_agree():
    r = _example("ex_solve").run(i_A=1.0, x_m=1.5e-3, mesh_size=2.0)
    for p in r.values():
        assert p["F_coenergy_N"] > 0 and p["psi_Wb"] > 0  # the force closes the gap
        assert abs(p["F_stress_N"] / p["F_coenergy_N"] - 1.0) < 0.03  # energy consistency
    assert r["two"]["psi_Wb"] > r["one"]["psi_Wb"] and r["two"]["F_coenergy_N"] > r["one"]["F_coenergy_N"]


def test_load_maps_round_trip_of_the_inverse_maps():
    r = _example("ex_load_maps").run(MAPS)
    assert np.max(np.abs(r["i_back_A"] - r["i_A"])) < 1e-3 * r["i_top_A"]  # paper eq. 2 inverts Psi(i, x)
    F_scale = np.max(np.abs(r["F_ix_N"]))
    assert np.max(np.abs(r["F_psix_N"] - r["F_ix_N"])) < 1e-2 * F_scale  # eq. 3 is F(i, x) on the Psi grid


def test_read_recording_round_trip_and_eq4_flux(rig_campaign):
    flux_rec = next(p for p in rig_campaign("") if "flux" in Path(p).name)
    r = _example("ex_read_recording").run(flux_rec)
    assert r["kind"] == "flux" and r["round_trip_equal"]
    psi, i = r["flux"].psi_Wb, r["flux"].current_A
    assert np.corrcoef(psi, i)[0, 1] > 0.95  # the flux follows the current through the triangles
    assert r["flux"].psi_Wb[np.argmax(i)] > 0


@pytest.mark.slow
def test_build_maps_at_the_nodes_is_the_fem(tmp_path):
    r = _example("ex_build_maps").run(tmp_path / "maps", n_x=2, n_i=3, mesh_size=2.0)
    maps, loaded = r["maps"], r["loaded"]
    for name, arr in maps.arrays().items():
        np.testing.assert_array_equal(loaded.arrays()[name], arr, err_msg=name)
    k, j = 2, 1
    sol = sf.solve(float(maps.i_A[k]), float(maps.x_m[j]), mesh_size=r["mesh_size"])
    assert maps.psi_ix_Wb[k, j] == pytest.approx(sol.psi_Wb, rel=1e-6)


@pytest.mark.fmu
def test_export_both_backends_valid_with_one_interface(tmp_path):
    r = _example("ex_export_fmu").run(MAPS, tmp_path)
    assert r["python"]["problems"] == [] and r["c"]["problems"] == []
    py, c = r["python"]["variables"], r["c"]["variables"]
    assert py and all(c[name] == py[name] for name in py)  # same names, value references, units


@pytest.mark.fmu
def test_simulate_voltage_step_settles_at_U_over_R(tmp_path):
    r = _example("ex_simulate").run(MAPS, tmp_path, U_V=12.0, duration_s=0.5)
    i = r["result"].recording.current_A
    assert i[-1] == pytest.approx(r["U_V"] / r["R_ohm"], rel=5e-3)  # Ohm's law once the flux is steady
    assert i[np.searchsorted(r["time_s"], 0.012)] < 0.5 * i[-1]  # the inductance delays the rise


def test_run_rig_writes_every_kind_and_the_truth(rig_maps, tmp_path):
    r = _example("ex_run_rig").run(rig_maps[1], tmp_path / "camp", effects="friction,noise", seed=2)
    assert set(r["by_kind"]) == set(r["kinds"])
    assert r["truth_effects"]["friction"] and r["truth_effects"]["noise"]
    assert not r["truth_effects"].get("hysteresis")


@pytest.mark.fmu
def test_validate_true_model_within_noise_friction_not(rig_maps, rig_campaign):
    ex = _example("ex_validate")
    clean = ex.run(rig_maps[2], rig_campaign(""))["summary"]
    rubbing = ex.run(rig_maps[2], rig_campaign("friction"))["summary"]
    assert all(s["nrmse_fs_max"] < 0.01 for s in clean.values()), clean
    assert rubbing["force_N"]["nrmse_fs_max"] > 3 * clean["force_N"]["nrmse_fs_max"]


@pytest.mark.fmu
def test_diagnose_names_the_undeclared_friction(rig_maps, rig_campaign):
    r = _example("ex_diagnose").run(rig_maps[2], rig_campaign("friction"))
    assert r["verdict"] == "friction" and r["ranking"][0][0] == "friction"


@pytest.mark.slow
@pytest.mark.fmu
def test_improve_adds_friction_and_cuts_the_force_error(rig_maps, rig_campaign, tmp_path):
    r = _example("ex_improve").run(rig_maps[2], rig_campaign("friction"), tmp_path / "improved.fmu")
    assert r["effects_added"] == ["friction"]
    assert Path(r["improved_fmu"]).is_file()
    assert r["totals"]["force_N"]["after"] < r["totals"]["force_N"]["before"] / 3


@pytest.mark.slow
def test_identify_recovers_the_demo_steel(tmp_path):
    paths = sorted(str(p) for p in (DEMO / "recordings").glob("*.csv"))
    r = _example("ex_identify").run(paths, tmp_path / "material.csv", n_currents=6)
    res, true = r["result"], sf.load_material(DEMO / "truth" / "true-steel.csv")
    lo, hi = res.identified_H_range_A_per_m
    H = np.geomspace(max(lo, 10.0), hi, 40)
    assert np.max(np.abs(res.curve.B_of_H(H) / true.B_of_H(H) - 1.0)) < 0.05
    assert sf.load_material(tmp_path / "material.csv").name  # written and physical (passes the checks)
    assert json.loads(json.dumps(list(res.identified_H_range_A_per_m)))[1] > 5 * max(lo, 1.0)
