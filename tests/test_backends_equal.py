"""The two implementations of the real-time step give the same numbers, bit for bit (issue 24, item 2).

The step is written twice: in Python (:mod:`solenoid_fmu.realtime.model`, which the pythonfmu FMU runs,
numpy only, readable, the reference) and in C (``solenoid_fmu/fmu/c/sol_*.c``, the native FMU: real time
without Python, no allocation in the step; also the fits' simulations where a compiler is there,
:mod:`solenoid_fmu.fmu.native_sim`). Both stay: generating the C from the Python would cost the readable
reference or the numpy-only FMU. So this
differential test makes any difference fail: Hypothesis draws random maps (grid sizes, monotone but
otherwise random ``i_f``, random force, random effect data), parameters (R, G_eddy, h_sub_max, Psi0 and
the effect scalars), effect sets (each switch on or off), drive modes and input sequences (step sizes,
drive, gaps in and out of the map, gaps held to reuse the last lookup), runs the model and the compiled
C step side by side and compares every output after every step.

Tolerance: none. Both sides do the same IEEE-754 double operations in the same order, the C is built
with ``-ffp-contract=off`` (no fused multiply-add) and calls the same libm ``exp`` as Python's ``math``,
so the outputs agree exactly (the existing CS tests allow 1e-9 relative; in practice they are equal).
Exact equality is what makes a one-character change of either side's arithmetic fail here: a reordered
sum or a changed constant moves the last bits at least.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from fmpy.fmi2 import FMU2Slave
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from solenoid_fmu import fmu as F
from solenoid_fmu.fmu import native
from solenoid_fmu.fmu.c_sources import generate_sources
from solenoid_fmu.fmu.interface import MODEL_IDENTIFIER, interface_for
from solenoid_fmu.realtime import model as M

pytestmark = pytest.mark.fmu

SWITCHES = {"hysteresis": "hysteresis_on", "eddy_ladder": "eddy_ladder_on", "heating": "heating_on",
            "friction": "friction_on"}
#: Effect sections of the random maps (index = map seed): all four, a part, none.
MAP_EFFECTS = (tuple(SWITCHES), tuple(SWITCHES), ("hysteresis", "friction"), ("eddy_ladder", "heating"), ())
OUTS = ("i_out_A", "U_out_V", "F_N", "psi_Wb", "dpsi_dt_V", "i_eddy_A")
MODEL_OUTS = ("i_A", "U_V", "F_N", "psi_Wb", "dpsi_dt_V", "i_eddy_A")


def _random_effects(rng, psi_max: float, names) -> dict:
    """Random, valid effect data (maps.json ``effects``) of the named effects."""
    fx = {}
    if "hysteresis" in names:
        n = int(rng.integers(1, 5))
        shape = None
        if rng.random() < 0.7:
            b = np.sort(rng.uniform(0.0, psi_max, int(rng.integers(2, 5))))
            shape = {"b_nodes": np.unique(b).tolist(), "g_nodes": []}
            shape["g_nodes"] = rng.uniform(0.3, 2.0, len(shape["b_nodes"])).tolist()
        fx["hysteresis"] = {"thresholds": np.sort(rng.uniform(0.01, 0.5, n) * psi_max).tolist(),
                            "weights": rng.uniform(0.0, 20.0, n).tolist(), "shape": shape}
    if "eddy_ladder" in names:
        n = int(rng.integers(1, 4))
        fx["eddy_ladder"] = {"G_S": rng.uniform(0.0, 0.01, n).tolist(), "tau_s": rng.uniform(1e-4, 5e-3, n).tolist()}
    if "heating" in names:
        fx["heating"] = {"C_th_J_per_K": float(rng.uniform(0.1, 5.0)), "R_th_K_per_W": float(rng.uniform(1.0, 100.0)),
                         "alpha_per_K": float(rng.uniform(0.0, 0.006))}
    if "friction" in names:
        fx["friction"] = {"force_N": float(rng.uniform(0.0, 5.0)), "presliding_m": float(rng.uniform(5e-6, 1e-4))}
    return fx


def write_random_maps(maps_dir, seed: int, effects=()) -> None:
    """A maps directory with random grids and tables: ``i_f`` strictly increasing in Psi from 0 (what the
    model requires), anything else random; the FEM sweep ends inside the map (extrapolation events)."""
    rng = np.random.default_rng(seed)
    n_psi, n_x = int(rng.integers(4, 25)), int(rng.integers(2, 7))
    x_m = rng.uniform(0.1e-3, 0.5e-3) + np.concatenate([[0.0], np.cumsum(rng.uniform(0.1e-3, 1e-3, n_x - 1))])
    psi_max = float(rng.uniform(0.05, 0.6))
    psi_Wb = np.linspace(0.0, psi_max, n_psi)
    steps = rng.uniform(0.05, 1.0, (n_psi - 1, n_x)) * np.linspace(1.0, 3.0, n_x) * rng.uniform(0.5, 5.0)
    i_f = np.vstack([np.zeros((1, n_x)), np.cumsum(steps, axis=0)])
    force = rng.uniform(-5.0, 50.0, (n_psi, n_x))
    i_max = float(rng.uniform(0.5, 1.0) * i_f.max())
    maps_dir.mkdir(parents=True)
    np.savez(maps_dir / "maps.npz", psi_Wb=psi_Wb, x_m=x_m, i_f_A=i_f, force_N=force, i_A=np.linspace(0.0, i_max, 5))
    meta = {"schema": M.MAPS_SCHEMA, "schema_version": M.MAPS_SCHEMA_VERSION, "name": f"random-{seed}",
            "coil": {"resistance_ohm_20C": float(rng.uniform(1.0, 20.0)), "max_current_A": i_max},
            "eddy": {"G_eddy_S": float(rng.uniform(0.0, 0.02)) if rng.random() < 0.7 else None}}
    if effects:
        meta["effects"] = _random_effects(rng, psi_max, effects)
    (maps_dir / "maps.json").write_text(json.dumps(meta), encoding="utf-8")


class Backend:
    """One random map: its tables and the native step compiled from its generated C sources."""

    def __init__(self, root, seed: int):
        d = root / f"maps{seed}"
        write_random_maps(d, seed, MAP_EFFECTS[seed])
        self.tab = M.load_tables(d)
        self.guid = generate_sources(self.tab, root / f"src{seed}")
        self.lib = native.compile_shared_library(root / f"src{seed}", root / f"lib{seed}" / f"{MODEL_IDENTIFIER}.so")
        self.root = root
        self.vr = {v.name: k for k, v in enumerate(interface_for(self.tab))}
        self.fx = "i_hyst_A" in self.vr


@pytest.fixture(scope="module")
def backends(tmp_path_factory):
    root = tmp_path_factory.mktemp("backends")
    return [Backend(root, seed) for seed in range(len(MAP_EFFECTS))]


def _run_c(b: Backend, mode: str, params: dict, u0: float, x0: float, steps) -> tuple[np.ndarray, int]:
    """Outputs of the native step after initialization and after each step; number of warnings logged."""
    messages = []
    cb = F.fmi2_callbacks(lambda status, category, message: messages.append(status))
    fmu = FMU2Slave(guid=b.guid, unzipDirectory=str(b.root), modelIdentifier=MODEL_IDENTIFIER,
                    libraryPath=str(b.lib), instanceName="differential")
    fmu.instantiate(callbacks=cb, loggingOn=True)
    try:
        vr = b.vr
        outs = [vr[k] for k in OUTS + (("i_hyst_A", "T_rise_K") if b.fx else ())]
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setInteger([vr["drive_mode"]], [M.DRIVE_VOLTAGE if mode == "voltage" else M.DRIVE_CURRENT])
        for key, value in params.items():
            (fmu.setBoolean if isinstance(value, bool) else fmu.setReal)([vr[key]], [value])
        u_vr = vr["U_V" if mode == "voltage" else "i_A"]
        fmu.setReal([u_vr, vr["x_m"]], [u0, x0])
        fmu.exitInitializationMode()
        rows = [fmu.getReal(outs) + [float(fmu.getBoolean([vr["out_of_map"]])[0])]]
        t = 0.0
        for h, u, x in steps:
            fmu.setReal([u_vr, vr["x_m"]], [u, x])
            fmu.doStep(t, h)
            t += h
            rows.append(fmu.getReal(outs) + [float(fmu.getBoolean([vr["out_of_map"]])[0])])
        fmu.terminate()
    finally:
        fmu.freeInstance()
        F.release_fmi2_callbacks(cb)
    return np.array(rows), sum(1 for s in messages if s == 1)


def _run_python(b: Backend, mode: str, params: dict, u0: float, x0: float, steps) -> tuple[np.ndarray, int]:
    """The same run of :class:`solenoid_fmu.realtime.model.SolenoidModel`."""
    model = M.SolenoidModel(b.tab, dict(params, drive_mode=mode))
    model.initialize(u0, x0, 0.0)
    names = MODEL_OUTS + (("i_hyst_A", "T_rise_K") if b.fx else ()) + ("out_of_map",)

    def row():
        out = model.outputs()
        return [float(out[k]) for k in names]

    rows = [row()]
    t = 0.0
    for h, u, x in steps:
        model.step(h, u, x, t)
        t += h
        rows.append(row())
    return np.array(rows), len(model.events)


def _fraction(lo: float, hi: float):
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


@st.composite
def scenarios(draw):
    """A map, a drive mode, parameters with an effect set, a start and a sequence of held inputs."""
    seed = draw(st.integers(0, len(MAP_EFFECTS) - 1))
    mode = draw(st.sampled_from(("voltage", "current")))
    params = {"R_ohm": draw(_fraction(0.5, 20.0)),
              "G_eddy_S": draw(st.one_of(st.just(0.0), _fraction(1e-4, 0.05))),
              "h_sub_max_s": draw(_fraction(2e-5, 5e-4)),
              "Psi0_Wb": draw(_fraction(-1.2, 1.2))}  # times psi_max (below)
    for name in MAP_EFFECTS[seed]:
        params[SWITCHES[name]] = draw(st.booleans())
    if MAP_EFFECTS[seed]:
        params.update(hyst_gain=draw(_fraction(0.0, 3.0)), friction_N=draw(_fraction(0.0, 5.0)))
    if "heating" in MAP_EFFECTS[seed]:
        params.update(C_th_J_per_K=draw(_fraction(0.05, 5.0)), R_th_K_per_W=draw(_fraction(1.0, 100.0)),
                      alpha_per_K=draw(_fraction(0.0, 0.01)), T_start_excess_K=draw(_fraction(-50.0, 160.0)))
    if "friction" in MAP_EFFECTS[seed]:
        params["presliding_m"] = draw(_fraction(1e-6, 1e-4))
    u0 = draw(_fraction(-1.5, 1.5))
    x0 = draw(_fraction(-0.3, 1.3))
    gap = st.one_of(st.none(), _fraction(-0.3, 1.3), st.tuples(st.just("move"), _fraction(-1.0, 1.0)))
    steps = draw(st.lists(st.tuples(_fraction(1e-5, 2e-3), _fraction(-1.5, 1.5), gap), min_size=1, max_size=30))
    return seed, mode, params, u0, x0, steps


def _in_units(b: Backend, mode: str, params: dict, u0: float, x0: float, steps):
    """Scale the drawn fractions to the map: drive to ~R i_max or i_max, gap to the grid (beyond it
    too), Psi0 to psi_max; a gap of None holds the previous one (the model's cached lookups), a
    ``("move", f)`` moves it by ``f`` times 50 um (the presliding range of the friction)."""
    tab = b.tab
    i_max = tab.i_fem_max_A
    R = params["R_ohm"]
    scale = R * i_max if mode == "voltage" else i_max
    span = tab.x_max_m - tab.x_min_m
    params = dict(params, Psi0_Wb=params["Psi0_Wb"] * tab.psi_max_Wb)
    x_prev = tab.x_min_m + x0 * span
    out = []
    for h, u, x in steps:
        if isinstance(x, tuple):
            x_prev += x[1] * 50e-6
        elif x is not None:
            x_prev = tab.x_min_m + x * span
        out.append((h, u * scale, x_prev))
    return params, u0 * scale, tab.x_min_m + x0 * span, out


@settings(max_examples=300, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(case=scenarios())
def test_python_and_c_steps_are_equal_bit_for_bit(backends, case):
    seed, mode, params, u0, x0, steps = case
    b = backends[seed]
    event(f"{mode} drive, G_eddy {'= 0' if params['G_eddy_S'] == 0.0 else '> 0'}")  # --hypothesis-show-statistics
    event("effects on: " + (", ".join(k for k in SWITCHES.values() if params.get(k)) or "none"))
    params, u0, x0, steps = _in_units(b, mode, params, u0, x0, steps)
    got_c, warnings_c = _run_c(b, mode, params, u0, x0, steps)
    got_py, events_py = _run_python(b, mode, params, u0, x0, steps)
    np.testing.assert_array_equal(got_c, got_py)  # bit for bit: see the module docstring
    assert warnings_c == events_py  # the same excursions began


def test_the_random_maps_exercise_every_path(backends):
    """The draws reach what the equality must cover: maps with and without effects, several grids,
    gaps and fluxes beyond the map, the extrapolated region, the algebraic current drive."""
    assert {b.fx for b in backends} == {True, False}
    assert len({(b.tab.n_psi, b.tab.n_x) for b in backends}) == len(backends)
    b = backends[0]
    steps = [(1e-3, 1.4 * b.tab.i_fem_max_A, b.tab.x_max_m + 1e-3)] * 5
    got_py, events = _run_python(b, "current", {"G_eddy_S": 0.0}, 0.0, b.tab.x_min_m, steps)
    got_c, warnings = _run_c(b, "current", {"G_eddy_S": 0.0}, 0.0, b.tab.x_min_m, steps)
    np.testing.assert_array_equal(got_c, got_py)
    assert events == warnings >= 2 and got_py[-1, -1] == 1.0  # x and Psi (or the extrapolation) left the map
