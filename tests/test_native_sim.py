"""simulate_model's compiled fast path (:mod:`solenoid_fmu.fmu.native_sim`) gives the Python model's numbers.

The loop simulates the lumped model over every recording many times; the native FMU's step, compiled once per
model structure and run over a whole recording in one call, replaces the Python step there. It must change
nothing but the time: every output of every sample equal bit for bit to the Python model's, with and without
effects, in both drive modes and with parameters set; the Python model's error where an input is refused; the
Python model where no compiler is there (``auto``), an error naming it where the native one is asked for.
"""

from __future__ import annotations

import json
import re

import mapsfixture as mf
import numpy as np
import pytest
from test_fmu_c_effects import EFFECTS  # all four effects, small data

from solenoid_fmu.errors import FmuBuildError, FmuInputError
from solenoid_fmu.fmu import native_sim, simulate_model
from solenoid_fmu.fmu.c_sources import default_params, maps_header
from solenoid_fmu.measure import Recording
from solenoid_fmu.realtime import load_tables

OUTPUTS = ("current_A", "voltage_V", "force_N")


def _maps(path, effects=None, G_eddy_S=0.01, n_x=12):
    d = mf.write_maps(path, G_eddy_S=G_eddy_S, n_x=n_x)
    if effects:
        meta = json.loads((d / "maps.json").read_text())
        meta["effects"] = effects
        (d / "maps.json").write_text(json.dumps(meta))
    return load_tables(d)


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    root = tmp_path_factory.mktemp("native_sim")
    return {"plain": _maps(root / "plain"), "effects": _maps(root / "effects", EFFECTS)}


def _recording(kind="voltage_step", n=3000, seed=0) -> Recording:
    """Voltage steps and a current triangle at a moving gap (two time steps), with a header resistance."""
    rng = np.random.default_rng(seed)
    t = np.concatenate([np.arange(n // 2) * 1e-4, (n // 2) * 1e-4 + np.arange(n - n // 2) * 2.5e-4])
    phase = np.arange(n) / n
    voltage = np.where((phase * 6).astype(int) % 2 == 0, 12.0, 1.0) + 0.01 * rng.standard_normal(n)
    current = 1.5 * (1.0 - np.abs(2.0 * ((3 * phase) % 1.0) - 1.0))
    position = 1e-3 + 1e-3 * np.sin(2 * np.pi * 2 * phase)
    return Recording(kind=kind, solenoid="synthetic", header={"coil_resistance_ohm": "6.0"}, time_s=t,
                     current_A=current, voltage_V=voltage, force_N=np.zeros(n), position_m=position, extra={})


def _both(monkeypatch, tab, rec, **kw):
    out = {}
    for mode in ("native", "python"):
        monkeypatch.setenv("SOLENOID_FMU_SIMULATOR", mode)
        out[mode] = simulate_model(tab, rec, **kw)
    return out["native"], out["python"]


@pytest.mark.parametrize("maps", ["plain", "effects"])
@pytest.mark.parametrize("drive", ["voltage", "current"])
@pytest.mark.parametrize("params", [None, {"h_sub_max_s": 3e-5, "Psi0_Wb": 0.02}],
                         ids=["defaults", "parameters"])
def test_native_and_python_simulations_are_equal_bit_for_bit(monkeypatch, tables, maps, drive, params):
    tab = tables[maps]
    if params and maps == "effects":
        params = {**params, "hyst_gain": 0.6, "heating_on": False, "friction_N": 1.0}
    native, python = _both(monkeypatch, tab, _recording(), drive=drive, params=params)
    assert "native step" in native.recording.header["simulated_by"]
    assert "native" not in python.recording.header["simulated_by"]
    for name in OUTPUTS:
        a, b = getattr(native.recording, name), getattr(python.recording, name)
        assert np.array_equal(a, b), (name, float(np.max(np.abs(a - b))))
    assert set(native.recording.extra) == set(python.recording.extra)
    assert ("T_rise_K" in python.recording.extra) == (maps == "effects")
    for name, values in python.recording.extra.items():
        assert np.array_equal(native.recording.extra[name], values), name
    assert np.ptp(python.recording.current_A) > 0.1  # the recording moves the model


def test_a_refused_input_gives_the_python_models_error(monkeypatch, tables):
    rec = _recording()
    errors = {}
    for mode in ("native", "python"):
        monkeypatch.setenv("SOLENOID_FMU_SIMULATOR", mode)
        with pytest.raises(FmuInputError) as exc:
            simulate_model(tables["effects"], rec, drive="voltage", params={"h_sub_max_s": 1e-12})
        errors[mode] = str(exc.value)
    assert errors["native"] == errors["python"] and "sub-steps" in errors["python"]


def test_one_library_per_model_structure(monkeypatch, tmp_path, tables):
    """Maps of other values and sizes share a library; another effect set is another structure. The library is
    built in the cache folder once and found there."""
    monkeypatch.setenv("SOLENOID_FMU_CACHE", str(tmp_path / "cache"))
    other = _maps(tmp_path / "other", G_eddy_S=0.02, n_x=9)
    files = [native_sim.library_file(native_sim.sim_maps_header(t, default_params(t)))
             for t in (tables["plain"], other, tables["effects"])]
    assert files[0] == files[1] != files[2]
    assert sorted((tmp_path / "cache" / "simulator").iterdir()) == sorted(set(files))  # no build left behind
    stamp = files[0].stat().st_mtime_ns
    assert native_sim.library_file(native_sim.sim_maps_header(other, default_params(other))) == files[0]
    assert files[0].stat().st_mtime_ns == stamp  # found, not built again
    monkeypatch.setenv("SOLENOID_FMU_SIMULATOR", "native")
    got = simulate_model(other, _recording(n=400), drive="voltage")
    assert "native step" in got.recording.header["simulated_by"]


def test_without_a_compiler_auto_runs_the_python_model_and_native_says_why(monkeypatch, tmp_path, tables):
    monkeypatch.setenv("SOLENOID_FMU_CACHE", str(tmp_path / "empty-cache"))
    monkeypatch.setenv("PATH", str(tmp_path))  # no gcc, no cc
    monkeypatch.delenv("CC", raising=False)
    rec = _recording(n=400)
    monkeypatch.setenv("SOLENOID_FMU_SIMULATOR", "auto")
    got = simulate_model(tables["plain"], rec, drive="voltage")
    assert "native" not in got.recording.header["simulated_by"]
    monkeypatch.setenv("SOLENOID_FMU_SIMULATOR", "python")
    assert np.array_equal(simulate_model(tables["plain"], rec, drive="voltage").recording.current_A,
                          got.recording.current_A)
    monkeypatch.setenv("SOLENOID_FMU_SIMULATOR", "native")
    with pytest.raises(FmuBuildError, match="no C compiler"):
        simulate_model(tables["plain"], rec, drive="voltage")


def test_an_unknown_simulator_setting_is_named(monkeypatch, tables):
    monkeypatch.setenv("SOLENOID_FMU_SIMULATOR", "fast")
    with pytest.raises(FmuBuildError, match="SOLENOID_FMU_SIMULATOR='fast'"):
        simulate_model(tables["plain"], _recording(n=100), drive="voltage")


def test_the_runtime_header_declares_the_data_the_fmu_header_writes_as_literals(tables):
    """Every name the FMU's maps header defines is declared by the simulator's, so the model source compiles
    against either; the simulator's holds no number of the maps (one library serves every maps)."""
    tab = tables["effects"]
    params = default_params(tab)
    fmu_names = set(re.findall(r"\b(SOL_[A-Z0-9_]+)\b", maps_header(tab, params, "{guid}")))
    sim = native_sim.sim_maps_header(tab, params)
    assert fmu_names <= set(re.findall(r"\b(SOL_[A-Z0-9_]+)\b", sim))
    assert repr(float(tab.psi_max_Wb)) not in sim and repr(float(tab.x_m[1])) not in sim


def test_an_unwritable_cache_falls_back_to_the_temporary_folder(monkeypatch, tmp_path, tables):
    blocked = tmp_path / "a-file"
    blocked.write_text("not a folder")
    monkeypatch.setenv("SOLENOID_FMU_CACHE", str(blocked))
    lib = native_sim.library_file(native_sim.sim_maps_header(tables["plain"], default_params(tables["plain"])))
    assert lib.is_file() and blocked not in lib.parents and lib.parent.name.startswith("solenoid-fmu-simulator-")
