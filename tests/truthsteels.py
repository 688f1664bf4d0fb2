"""Truths for the B(H) identification: steels it was not tuned to, and the yardstick that scores a curve.

``tests/data/truth-steels/<name>/`` holds, for each published steel of
:data:`solenoid_fmu.field.STEELS` (the Modelica FluxTubes records) and for six random steels
(:func:`solenoid_fmu.rig.random_steel_parameters` with seeds 0-5), the true B(H) (``steel.csv``,
the Roschke table) and the characteristic maps of PS45 with that steel (``maps.npz`` +
``maps.json``), made by ``tests/data/make_truth_steels.py``.

No inverse crime: the truth's FEM differs in discretization from the identification's. The
identification solves on one mesh built at mid-stroke and morphed to each gap, with mesh size
2.0 (:data:`solenoid_fmu.identification.DEFAULT_MESH_SIZE`); the truth builds a new mesh at every
stroke (``x_ref_m = x``, no morph) with mesh size :data:`TRUTH_MESH_SIZE`.

The yardstick: :data:`EVAL_STROKES_M` x :data:`EVAL_CURRENTS_A` (20 points inside the working
range, all nodes of the truth maps, so :func:`truth_values` are FEM values, not interpolated);
:func:`prediction_errors` runs the FEM of a curve there as a user of an identified curve would
(the morphed default mesh, warm-started sweeps along the currents) and returns the relative errors
against the truth.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from solenoid_fmu.field import BHCurve, Solver, load_geometry, load_material, steel_names
from solenoid_fmu.field.mesh import build_mesh
from solenoid_fmu.identification import DEFAULT_MESH_SIZE
from solenoid_fmu.maps import CharacteristicMaps, force_at, load_maps, psi_at

#: Where the truths live.
TRUTHS_DIR = Path(__file__).resolve().parent / "data" / "truth-steels"
#: Mesh size of the truth maps (the identification uses 2.0 on a morphed mesh).
TRUTH_MESH_SIZE = 0.7
#: Seeds of the random truths (``random-<seed>``).
RANDOM_SEEDS = tuple(range(6))
#: Working-gap strokes [m] and currents [A] of the yardstick (arrays are [current, stroke]).
EVAL_STROKES_M = (0.5e-3, 1e-3, 2e-3, 3e-3)
EVAL_CURRENTS_A = (0.25, 0.5, 1.0, 1.5, 2.0)


def published_names() -> list[str]:
    """Names of the truths made from published steels (the keys of :data:`solenoid_fmu.field.STEELS`)."""
    return list(steel_names())


def random_names() -> list[str]:
    """Names of the truths made from random steels: ``random-<seed>`` (and those of :func:`use_unseen`)."""
    return [f"random-{seed}" for seed in RANDOM_SEEDS + _UNSEEN["seeds"]]


#: Random steels no test uses, known after :func:`use_unseen`: their seeds and the directory of their truths.
_UNSEEN: dict = {"seeds": (), "dir": None}


def use_unseen(directory, seeds) -> list[str]:
    """Also know the random steels ``random-<seed>`` for ``seeds`` (none of :data:`RANDOM_SEEDS`), their truths in
    ``directory`` (made there on demand by ``tests/data/make_truth_steels.py``: ``benchmarks/
    bench_identify_campaigns.py --unseen-steels``, the check on steels nothing was tuned to); returns their names."""
    seeds = tuple(int(s) for s in seeds)
    if set(seeds) & set(RANDOM_SEEDS):
        raise ValueError(f"seeds {sorted(set(seeds) & set(RANDOM_SEEDS))} are the tests' own random steels")
    _UNSEEN.update(seeds=seeds, dir=Path(directory))
    return [f"random-{s}" for s in seeds]


def truth_names(published: bool | None = None) -> list[str]:
    """Names of the truths: published (``published=True``), random (``False``) or both (None)."""
    if published is None:
        return published_names() + random_names()
    return published_names() if published else random_names()


def is_published(name: str) -> bool:
    """True for a truth made from a published steel, False for a random one (KeyError for others)."""
    if name in published_names():
        return True
    if name in random_names():
        return False
    raise KeyError(f"no truth named {name!r}; known: {', '.join(truth_names())}")


def truth_dir(name: str) -> Path:
    """The directory of a truth (``steel.csv``, ``maps.npz``, ``maps.json``)."""
    if not is_published(name) and int(name.split("-", 1)[1]) in _UNSEEN["seeds"]:  # (refuses unknown names)
        return _UNSEEN["dir"] / name
    return TRUTHS_DIR / name


def truth_curve(name: str) -> BHCurve:
    """The true B(H) curve: ``steel.csv`` loaded and checked (the very curve the truth's FEM used)."""
    return load_material(truth_dir(name) / "steel.csv")


@functools.lru_cache(maxsize=32)
def truth_maps(name: str) -> CharacteristicMaps:
    """The truth's characteristic maps (:func:`solenoid_fmu.maps.load_maps`, all its checks)."""
    return load_maps(truth_dir(name))


def eval_grid() -> tuple[np.ndarray, np.ndarray]:
    """(i [A], x [m]) of the yardstick, each of shape (5, 4) = (currents, strokes)."""
    return np.meshgrid(np.array(EVAL_CURRENTS_A), np.array(EVAL_STROKES_M), indexing="ij")


def truth_values(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(Psi [Wb], F [N]) of the truth at the yardstick's points, shape (5, 4), from its maps
    (``psi_ix_Wb``, ``force_ix_N`` through :func:`solenoid_fmu.maps.psi_at` / ``force_at``)."""
    maps = truth_maps(name)
    i, x = eval_grid()
    return psi_at(maps, i, x), force_at(maps, i, x)


def remeshed_sweep(geometry, material: BHCurve, x_m: float, i_A, mesh_size: float) -> dict:
    """The truth's FEM at one stroke: a mesh built at ``x_m`` (not morphed), warm-started along ``i_A``.

    The sweep signature of :func:`solenoid_fmu.maps.build_maps` (``psi_Wb``, ``force_N`` (co-energy),
    ``force_stress_N``, ``newton_iterations``, ``newton_recovered``; arrays of len(i_A)).
    """
    solver = Solver(geometry, material, mesh_size, mesh=build_mesh(geometry, mesh_size, x_ref_m=float(x_m)))
    i_A = np.asarray(i_A, dtype=float)
    keys = ("psi_Wb", "force_N", "force_stress_N", "newton_iterations", "newton_recovered")
    out = {k: np.zeros(len(i_A)) for k in keys}
    u, i_prev = None, None
    for k, i in enumerate(i_A):
        sol = solver.solve(float(i), float(x_m), u0=u, i0_A=i_prev)
        u, i_prev = (sol.u, float(i)) if i != 0 else (None, None)
        out["psi_Wb"][k] = sol.psi_Wb
        out["force_N"][k] = sol.force_coenergy_N
        out["force_stress_N"][k] = sol.force_stress_N
        out["newton_iterations"][k] = sol.newton_iterations
        out["newton_recovered"][k] = 1.0 if sol.note else 0.0
    return out


@functools.lru_cache(maxsize=1)
def _geometry():
    return load_geometry()


#: fem_values already computed in this process, by (curve table, mesh size): the literature curve is
#: scored against every truth, and its FEM values do not depend on the truth.
_FEM_CACHE: dict = {}


def fem_values(curve: BHCurve, mesh_size: float = DEFAULT_MESH_SIZE) -> tuple[np.ndarray, np.ndarray]:
    """(Psi [Wb], F [N]) of ``curve`` at the yardstick's points, shape (5, 4): the identification's FEM
    (one mesh at mid-stroke, morphed), a sweep over the currents warm-started at each stroke (cached
    per process by the curve's table, so a curve scored against several truths is solved once)."""
    key = (np.asarray(curve.B_T, dtype=float).tobytes(), np.asarray(curve.H_A_per_m, dtype=float).tobytes(),
           float(mesh_size))
    if key not in _FEM_CACHE:
        _FEM_CACHE[key] = _fem_values(curve, mesh_size)
    psi, force = _FEM_CACHE[key]
    return psi.copy(), force.copy()


def _fem_values(curve: BHCurve, mesh_size: float) -> tuple[np.ndarray, np.ndarray]:
    solver = Solver(_geometry(), curve, mesh_size)
    psi = np.empty((len(EVAL_CURRENTS_A), len(EVAL_STROKES_M)))
    force = np.empty_like(psi)
    for j, x in enumerate(EVAL_STROKES_M):
        u = None
        for k, i in enumerate(EVAL_CURRENTS_A):
            sol = solver.solve(float(i), float(x), u0=u)
            u = sol.u
            psi[k, j], force[k, j] = sol.psi_Wb, sol.force_coenergy_N
    return psi, force


def prediction_errors(curve: BHCurve, name: str, mesh_size: float = DEFAULT_MESH_SIZE) -> dict:
    """Relative errors of the FEM of ``curve`` (see :func:`fem_values`) against the truth ``name``.

    Returns
    -------
    dict
        ``psi_rel``, ``F_rel``: (predicted - true) / true, shape (5, 4) = (currents, strokes);
        ``psi_max_rel``, ``F_max_rel``: the largest magnitudes (floats).
    """
    psi_true, F_true = truth_values(name)
    psi, F = fem_values(curve, mesh_size)
    psi_rel = (psi - psi_true) / psi_true
    F_rel = (F - F_true) / F_true
    return {"psi_rel": psi_rel, "F_rel": F_rel,
            "psi_max_rel": float(np.max(np.abs(psi_rel))), "F_max_rel": float(np.max(np.abs(F_rel)))}
