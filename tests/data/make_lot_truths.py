"""Make the truth maps of the test lot: ``tests/data/lot-truths/<unit>/`` (``maps.npz`` + ``maps.json``).

Run from the repository root (about 30 s per steel and core)::

    python tests/data/make_lot_truths.py [--workers 2] [--force]

The lot is :func:`solenoid_fmu.rig.lot.plan_lot` with :data:`N_UNITS` units and seed :data:`SEED` (``tests/lotdata.py``
draws the same plan). Every unit whose steel is a batch draw of the nominal one gets its own PS45 maps; the
``steel`` out-of-spec unit uses the published steel's truth in ``tests/data/truth-steels/``. As there, no
inverse crime: the FEM runs on a new mesh at every stroke (not morphed) with mesh size 0.7
(:data:`truthsteels.TRUTH_MESH_SIZE`; the identification's mesh is morphed from mid-stroke, size 2.0, and
4.0 in the ``smoke`` preset), on its own grid (:data:`N_X` strokes, :data:`N_I` currents to :data:`I_TOP_A`).
Deterministic: the same code gives the same arrays.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/: truthsteels, lotdata

import lotdata  # noqa: E402
import truthsteels as T  # noqa: E402

from solenoid_fmu.field import load_geometry, roschke_curve  # noqa: E402
from solenoid_fmu.maps import InlineExecutor, build_maps, default_currents, default_positions, save_maps  # noqa: E402

N_X = 8
N_I = 12
I_TOP_A = 2.5


def make_unit(unit) -> tuple[str, float]:
    """Write one unit's truth maps; returns (unit name, wall time [s])."""
    t0 = time.perf_counter()
    geometry = load_geometry()
    st = geometry.stroke
    curve = roschke_curve(unit.steel, unit.name)
    maps = build_maps(geometry, curve, x_m=default_positions(st.min_m, st.max_m, N_X),
                      i_A=default_currents(I_TOP_A, N_I), mesh_size=T.TRUTH_MESH_SIZE, executor=InlineExecutor(),
                      progress=False, sweep=T.remeshed_sweep, name=f"lot-truth-{unit.name}")
    meta = maps.metadata
    meta["provenance"]["test_truth"] = {
        "purpose": "truth of the test lot (tests/test_lot.py), not a product map",
        "mesh": f"built at each stroke (not morphed), mesh_size {T.TRUTH_MESH_SIZE:g}",
        "steel": dataclasses.asdict(unit.steel),
    }
    save_maps(dataclasses.replace(maps, metadata=meta), lotdata.LOT_TRUTHS_DIR / unit.name)
    return unit.name, time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2, help="units made at once (processes)")
    ap.add_argument("--force", action="store_true", help="make them all again (default: only the missing ones)")
    args = ap.parse_args(argv)
    units = [u for u in lotdata.plan() if u.steel_name == "nominal"
             and (args.force or not (lotdata.LOT_TRUTHS_DIR / u.name / "maps.json").is_file())]
    t0 = time.perf_counter()
    with cf.ProcessPoolExecutor(max_workers=max(1, args.workers)) as pool:
        for name, wall in pool.map(make_unit, units):
            print(f"{name}: {wall:.1f} s", flush=True)
    print(f"{len(units)} truths in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
