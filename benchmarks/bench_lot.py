"""Benchmark: units per hour of a production lot, local process pool against a Dask LocalCluster, same run.

Draws the test lot (``tests/lotdata.py``: PS45 around DC03, batch variation, undeclared effects, out-of-spec
units; the rig's end-of-line campaign) and runs ``solenoid_fmu.lot.run_batch`` on it twice (every unit's
identification starting from the nominal steel, ``--start-material``), into fresh output folders:

1. ``scheduler="local"``: a process pool of ``--workers`` processes (default 2);
2. a ``distributed.LocalCluster`` of ``--workers`` worker processes with one thread each, by its address, as
   ``solenoid-fmu batch --scheduler tcp://...`` would (the cluster's start-up is not counted; the client's
   connection is);

and prints, per engine, the wall time, units per hour, the mean unit cost [s] and the ratio cluster/local,
plus whether the goal (>= 60 units per hour on 2 cores, ``quick`` preset) is met.

Usage::

    python benchmarks/bench_lot.py [--units 4] [--workers 2] [--preset quick]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the test lot's truth maps

import lotdata  # noqa: E402

from solenoid_fmu.lot import run_batch  # noqa: E402

GOAL_UNITS_PER_HOUR = 60.0


def _run(dirs, out, scheduler, workers, preset) -> dict:
    t0 = time.perf_counter()
    res = run_batch(dirs, out, scheduler=scheduler, workers=workers, preset=preset,
                    start_material=lotdata.NOMINAL_STEEL_CSV, progress=False)
    wall = time.perf_counter() - t0
    unit_s = [r["wall_s"] for r in res["rows"] if r.get("wall_s")]
    return {"wall_s": wall, "units_per_hour": 3600.0 * len(res["ran"]) / wall,
            "mean_unit_s": sum(unit_s) / max(1, len(unit_s)), "failed": len(res["failed"]),
            "flagged": res["flagged"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=4, help="units of the lot run by each engine (<= 8)")
    ap.add_argument("--workers", type=int, default=2, help="processes (local) and worker processes (cluster)")
    ap.add_argument("--preset", default="quick", help="pipeline preset (quick: the goal's)")
    args = ap.parse_args(argv)
    from distributed import LocalCluster

    with tempfile.TemporaryDirectory(prefix="bench-lot-") as tmp:
        base = Path(tmp)
        dirs = lotdata.draw(base / "campaigns")[: args.units]
        print(f"lot: {len(dirs)} units ({', '.join(d.name for d in dirs)}), preset {args.preset}, "
              f"{args.workers} workers", flush=True)
        local = _run(dirs, base / "out-local", "local", args.workers, args.preset)
        print(f"local pool:        {local['wall_s']:7.1f} s  {local['units_per_hour']:6.1f} units/h  "
              f"mean unit {local['mean_unit_s']:.1f} s  failed {local['failed']}", flush=True)
        with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster:
            dask = _run(dirs, base / "out-cluster", cluster.scheduler_address, None, args.preset)
        print(f"Dask LocalCluster: {dask['wall_s']:7.1f} s  {dask['units_per_hour']:6.1f} units/h  "
              f"mean unit {dask['mean_unit_s']:.1f} s  failed {dask['failed']}", flush=True)
    ratio = dask["units_per_hour"] / local["units_per_hour"]
    print(f"ratio cluster/local (units per hour): {ratio:.2f}")
    for label, r in (("local pool", local), ("Dask LocalCluster", dask)):
        v = r["units_per_hour"]
        verdict = "met" if v >= GOAL_UNITS_PER_HOUR else f"missed by {GOAL_UNITS_PER_HOUR - v:.0f} units/h"
        print(f"goal >= {GOAL_UNITS_PER_HOUR:.0f} units/h on {args.workers} cores ({args.preset}), {label}: {verdict}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
