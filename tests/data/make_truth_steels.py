"""Make the truth steels of the identification tests: ``tests/data/truth-steels/<name>/``.

Run from the repository root (about 2 min per steel and core; ``--workers 2`` runs two steels at once)::

    python tests/data/make_truth_steels.py            # all truths
    python tests/data/make_truth_steels.py DC03 random-2 --workers 1

For every published steel of :data:`solenoid_fmu.field.STEELS` (Modelica FluxTubes records) and six
random steels (``random-<seed>``: :func:`solenoid_fmu.rig.random_steel_parameters` with
``numpy.random.default_rng(seed)``, seeds 0-5) it writes

- ``steel.csv``: the true B(H) (``H_A_per_m,B_T``): the Roschke table of the parameter set
  (:func:`solenoid_fmu.field.steels.roschke_table`), the parameters in the comment lines;
- ``maps.npz`` + ``maps.json``: the PS45 characteristic maps with that steel, by
  :func:`solenoid_fmu.maps.build_maps` and :func:`solenoid_fmu.maps.save_maps` (readable by
  :func:`solenoid_fmu.maps.load_maps`, :func:`solenoid_fmu.realtime.read_maps_dir`, the rig).

The FEM runs on the curve loaded back from ``steel.csv`` (so the file is the truth), with a
discretization other than the identification's (see ``tests/truthsteels.py``): a new mesh at every
stroke (no morph), mesh size ``TRUTH_MESH_SIZE`` (0.7; the identification: 2.0, morphed from
mid-stroke). Grid: the rig's 12 strokes (``default_positions`` over 0.2 ... 3.5 mm) and 31 currents
(``default_currents(2.5 A, 31, power=2)``), each joined with the yardstick's strokes and currents, so the
yardstick reads FEM nodes; then every stroke interval longer than :data:`MAX_STEP_M` (0.15 mm) split
evenly: 32 positions (the rig reads its maps linearly in x, and on the 16 positions alone that reading was
0.5-0.7 % of full scale off the truth's own FEM in the force between them). ``--extend`` adds the positions
a stored truth lacks (their FEM alone: each stroke is its own mesh and sweep, so the columns are the ones a
full run computes). ``maps.json`` records under ``provenance.test_truth`` that this is a
test truth, the mesh and the steel's parameters.

Deterministic: the same code gives the same arrays (``maps.npz`` byte for byte); ``maps.json``
also records the run's time, wall time and git commit.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/: truthsteels

import truthsteels as T  # noqa: E402

from solenoid_fmu.field import STEELS, load_geometry, load_material, write_bh_csv  # noqa: E402
from solenoid_fmu.field.steels import roschke_table  # noqa: E402
from solenoid_fmu.maps import (  # noqa: E402
    InlineExecutor,
    build_maps,
    default_currents,
    default_positions,
    invert_maps,
    save_maps,
)
from solenoid_fmu.rig import random_steel_parameters  # noqa: E402

N_X = 12
#: Currents: i_top (k / (N_I - 1))^2, from 2.6 mA up, so that the rig's flux at the low currents a
#: campaign samples (tens of mA) is the FEM, not the interpolation between far-apart nodes (with 16
#: nodes at power 1.5 the maps missed the FEM by 4-25 % at 10-30 mA and 1-1.6 % at 50-150 mA).
N_I = 31
I_POWER = 2.0
#: Flux nodes of the inverted tables i_f(Psi, x) the rig plays: None, the maps' own choice (the smallest of
#: 101 .. 3201 whose round trip is within 5e-4; the knee of a high-permeability steel at tens of mA takes
#: 3201, 1.3 MB).
NPSI = None
I_TOP_A = 2.5
#: Largest spacing of the truth's positions [m]. The rig reads the maps linearly in x between columns
#: (as the model does), and that reading is the rig's physics: on the rig's 12 strokes + the yardstick's
#: 4 (spacing up to 0.45 mm) it put the force 0.5-0.7 % of full scale above the truth's own FEM between
#: columns (random-0 at 0.7 and 1.3 mm, 2 A), more than the identified maps missed that FEM by. Intervals
#: split to 0.15 mm leave a quarter to a ninth of that.
MAX_STEP_M = 0.15e-3


def parameters(name: str):
    """The Roschke parameters of a truth (published record or seeded random draw)."""
    if T.is_published(name):
        return STEELS[name]
    seed = int(name.split("-", 1)[1])
    return random_steel_parameters(np.random.default_rng(seed), name)


def split_intervals(x_m, max_step_m: float = MAX_STEP_M) -> np.ndarray:
    """``x_m`` with every interval longer than ``max_step_m`` split evenly into the fewest parts that are
    not (rounded to 1e-12 m)."""
    x = np.asarray(x_m, dtype=float)
    parts = [x[:1]]
    for a, b in zip(x[:-1], x[1:], strict=True):
        k = max(1, int(np.ceil((b - a) / max_step_m - 1e-9)))
        parts.append(a + (b - a) * np.arange(1, k + 1) / k)
    return np.round(np.concatenate(parts), 12)


def grid(geometry) -> tuple[np.ndarray, np.ndarray]:
    """(x [m], i [A]) of the truth maps: the rig's usual grid joined with the yardstick's points, its
    intervals split to :data:`MAX_STEP_M` at most."""
    st = geometry.stroke
    x = split_intervals(np.union1d(np.round(default_positions(st.min_m, st.max_m, N_X), 12), T.EVAL_STROKES_M))
    i = np.union1d(np.round(default_currents(I_TOP_A, N_I, power=I_POWER), 12), T.EVAL_CURRENTS_A)
    return x, i


def make_truth(name: str, mesh_size: float = T.TRUTH_MESH_SIZE) -> tuple[str, float]:
    """Write one truth directory; returns (name, wall time [s])."""
    t0 = time.perf_counter()
    p = parameters(name)
    out = T.truth_dir(name)
    out.mkdir(parents=True, exist_ok=True)
    H, B = roschke_table(p, name)
    comment = (f"True B(H) of the test truth {name}: Roschke's mu_r(B) = 1 + (mu_i - 1 + c_a*B_N) / "
               f"(1 + c_b*B_N + B_N^n), B_N = |B|/B_myMax,\nmu_i = {p.mu_i!r}, B_myMax = {p.B_myMax_T!r} T, "
               f"c_a = {p.c_a!r}, c_b = {p.c_b!r}, n = {p.n!r} ({p.label}; {p.record}),\n"
               f"tabulated H = B/(mu0 mu_r(B)) at B = 0.05 ... {B[-1]:.2f} T "
               "(solenoid_fmu.field.steels.roschke_table); "
               "made by tests/data/make_truth_steels.py")
    write_bh_csv(out / "steel.csv", H, B, comment=comment)
    geometry = load_geometry()
    curve = load_material(out / "steel.csv")
    x, i = grid(geometry)
    maps = build_maps(geometry, curve, x_m=x, i_A=i, mesh_size=mesh_size, executor=InlineExecutor(),
                      progress=False, sweep=T.remeshed_sweep, name=f"truth-steel-{name}", npsi=NPSI)
    meta = maps.metadata
    meta["provenance"]["test_truth"] = {
        "purpose": "test truth of tests/test_truth_steels.py (not a product map)",
        "mesh": f"built at each stroke (x_ref_m = x, not morphed), mesh_size {mesh_size:g}",
        "mesh_size": float(mesh_size),
        "steel": {**dataclasses.asdict(p), "kind": "published" if T.is_published(name) else "random"},
    }
    save_maps(dataclasses.replace(maps, metadata=meta), out)
    return name, time.perf_counter() - t0


#: Metadata keys :func:`solenoid_fmu.maps.invert_maps` writes itself (dropped before inverting a stored truth again).
INVERSION_KEYS = ("units", "interpolation", "round_trip_max_rel_error", "round_trip_max_rel_error_between_positions",
                  "arrays")


def _kept_metadata(maps) -> dict:
    """A stored truth's metadata without the keys its inversion writes (:data:`INVERSION_KEYS`)."""
    return {k: v for k, v in maps.metadata.items() if k not in INVERSION_KEYS}


def extend(name: str, mesh_size: float = T.TRUTH_MESH_SIZE) -> tuple[str, float]:
    """Add the FEM columns of :func:`grid` that a stored truth lacks (each stroke's FEM is its own mesh and
    its own sweep, so the columns are those :func:`make_truth` would compute), then invert again."""
    t0 = time.perf_counter()
    maps = T.truth_maps.__wrapped__(name)
    x_all, i_A = grid(load_geometry())
    if not np.array_equal(np.round(maps.i_A, 12), i_A):
        raise SystemExit(f"{name}: stored currents differ from grid(): make it again instead")
    have = np.round(maps.x_m, 12)
    new_x = [x for x in x_all if not np.any(np.isclose(x, have, rtol=0, atol=1e-12))]
    curve = load_material(T.truth_dir(name) / "steel.csv")
    cols = {round(float(x), 12): (maps.psi_ix_Wb[:, j], maps.force_ix_N[:, j], maps.force_stress_ix_N[:, j])
            for j, x in enumerate(have)}
    solver_meta = dict(maps.metadata["provenance"]["solver"])
    for x in new_x:
        d = T.remeshed_sweep(load_geometry(), curve, float(x), i_A, mesh_size)
        cols[round(float(x), 12)] = (d["psi_Wb"], d["force_N"], d["force_stress_N"])
        solver_meta["newton_iterations_total"] += int(d["newton_iterations"].sum())
        solver_meta["newton_iterations_max"] = max(solver_meta["newton_iterations_max"],
                                                   int(d["newton_iterations"].max()))
        if d["newton_recovered"].any():
            raise SystemExit(f"{name}: Newton needed recovery at x = {x * 1e3:.3f} mm")
    xs = np.array(sorted(cols))
    psi, F, Fs = (np.column_stack([cols[x][k] for x in xs]) for k in range(3))
    solver_meta["operating_points"] = int(psi.size)
    solver_meta["wall_time_s"] = round(solver_meta["wall_time_s"] + time.perf_counter() - t0, 3)
    keep = _kept_metadata(maps)
    keep["provenance"] = {**keep["provenance"], "solver": solver_meta}
    new = invert_maps(xs, maps.i_A, psi, F, Fs, metadata=keep, npsi=NPSI)
    save_maps(new, T.truth_dir(name))
    return name, time.perf_counter() - t0


def reinvert(name: str) -> None:
    """Invert a stored truth's FEM tables again (:data:`NPSI` flux nodes; the last step of
    :func:`make_truth`, which gives the same arrays from the same FEM tables)."""
    maps = T.truth_maps.__wrapped__(name)
    keep = _kept_metadata(maps)
    new = invert_maps(maps.x_m, maps.i_A, maps.psi_ix_Wb, maps.force_ix_N, maps.force_stress_ix_N, metadata=keep,
                      npsi=NPSI)
    save_maps(new, T.truth_dir(name))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help=f"truths to make (default all: {', '.join(T.truth_names())})")
    ap.add_argument("--workers", type=int, default=2, help="steels made at once (processes)")
    ap.add_argument("--mesh-size", type=float, default=T.TRUTH_MESH_SIZE)
    ap.add_argument("--reinvert", action="store_true",
                    help="only invert the stored FEM tables again (no FEM; seconds)")
    ap.add_argument("--extend", action="store_true",
                    help="only add the positions of grid() a stored truth lacks (FEM at those alone)")
    args = ap.parse_args(argv)
    names = args.names or T.truth_names()
    for n in names:
        T.is_published(n)  # refuses unknown names before any work
    if args.reinvert:
        for n in names:
            reinvert(n)
            print(f"{n}: inverted again", flush=True)
        return 0
    t0 = time.perf_counter()
    job = extend if args.extend else make_truth
    with cf.ProcessPoolExecutor(max_workers=max(1, args.workers)) as pool:
        for name, wall in pool.map(job, names, [args.mesh_size] * len(names)):
            print(f"{name}: {wall:.1f} s", flush=True)
    print(f"{len(names)} truths in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
