"""``solenoid-fmu batch``: a production lot through the pipeline, on this machine or a Dask cluster."""

from __future__ import annotations

import json

from ..argtypes import process_count
from ..fileio import jsonable
from ..pipeline import PRESETS
from .execute import run_batch

__all__ = ["add_cli"]


def add_cli(sub) -> None:
    """Register ``solenoid-fmu batch``."""
    p = sub.add_parser("batch", help="every unit of a lot through the pipeline (local or Dask); lot.csv, lot.html")
    p.add_argument("campaigns", nargs="+", metavar="CAMPAIGN_DIR", help="one campaign folder per unit (its name "
                   "is the unit's)")
    p.add_argument("-o", "--output", required=True, help="output folder: OUT/<unit>/, lot.csv, lot.html")
    p.add_argument("--scheduler", default="local", help="'local' (a process pool here, default) or a Dask "
                   "scheduler address (tcp://host:8786)")
    p.add_argument("--workers", type=process_count, help="processes of the local pool (default: all cores)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="quick", help="pipeline preset of every unit "
                   "(default quick)")
    p.add_argument("--geometry", help="geometry TOML of the lot's solenoid (default: the packaged PS45)")
    p.add_argument("--start-material", help="B(H) CSV the identification of every unit starts from (the lot's "
                   "nominal steel; default: the literature curve)")
    p.add_argument("--json", action="store_true", help="print the lot's rows as JSON on stdout")
    p.set_defaults(func=_cli)


def _cli(args) -> int:
    res = run_batch(args.campaigns, args.output, scheduler=args.scheduler, workers=args.workers, preset=args.preset,
                    geometry=args.geometry, start_material=args.start_material)
    if args.json:
        print(json.dumps(jsonable(res["rows"])))
    else:
        for r in res["rows"]:
            mark = "STANDS OUT " + r["flagged_by"].replace(";", ", ") if r["stands_out"] else ""
            print(f"{r['unit']:<20} {r['status']:<8} {mark}{r['error'] or ''}")
        print(f"{len(res['rows'])} units: {len(res['ran'])} run, {len(res['skipped'])} complete already, "
              f"{len(res['failed'])} failed; {res['n_flagged']} stand out; {res['lot_csv']}, {res['lot_html']}")
    return 1 if res["failed"] else 0
