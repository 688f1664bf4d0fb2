"""Command line of the identification: ``solenoid-fmu identify``."""

from __future__ import annotations

import json
from pathlib import Path

from ..argtypes import process_count
from ..errors import SolenoidError
from ..fileio import refuse_overwriting_inputs, require_directory
from .campaign import identify_from_recordings
from .fit import DEFAULT_MESH_SIZE
from .result import h_range_text

__all__ = ["add_cli"]


def add_cli(sub) -> None:
    """Register ``solenoid-fmu identify``."""
    p = sub.add_parser("identify",
                       help="identify the steel's B(H) from flux recordings (FEM + optimizer, paper sec. 4)")
    p.add_argument("recordings", nargs="+", help="recordings (CSV, format v1); flux ones are used, others ignored "
                   "(force_stroke ones validate in the report)")
    p.add_argument("--geometry", help="solenoid TOML (default: packaged PS45)")
    p.add_argument("--start-material", help="start B(H) CSV H_A_per_m,B_T (default: literature 9SMnPb28)")
    p.add_argument("-o", "--output", required=True, help="identified curve CSV (also writes .bh and .tab beside it)")
    p.add_argument("--report", help="directory for figures and identification.json")
    p.add_argument("--method", choices=("gn", "auglag"), default="gn",
                   help="gn: Gauss-Newton with adjoint Jacobians (default); auglag: nlopt AUGLAG+BOBYQA (paper)")
    p.add_argument("--mesh-size", type=float, default=None, help=f"FEM mesh size (default {DEFAULT_MESH_SIZE:g})")
    p.add_argument("--max-evals", type=int, default=None, help="budget of FEM sweeps of the optimizer")
    p.add_argument("--workers", type=process_count, default=None,
                   help="processes for the FEM points of method gn, whole strokes each (default: all cores, at most 4)")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=_cli)


def _cli(args) -> int:
    kw = {}
    if args.max_evals is not None and args.max_evals < 1:
        raise SolenoidError(f"--max-evals must be >= 1, got {args.max_evals}")
    if args.max_evals is not None:
        kw["max_nfev" if args.method == "gn" else "max_eval_auglag"] = args.max_evals
    inputs = [*args.recordings, args.geometry, args.start_material]
    out = Path(args.output)
    require_directory(out.parent, "-o")
    refuse_overwriting_inputs(out, inputs, written=[out, out.with_suffix(".bh"), out.with_suffix(".tab")])
    if args.report is not None:
        refuse_overwriting_inputs(require_directory(args.report, "--report"), inputs, written=[])
    res = identify_from_recordings(args.recordings, geometry=args.geometry, start_material=args.start_material,
                                   mesh_size=args.mesh_size, out_csv=args.output, report_dir=args.report,
                                   progress=not args.json, method=args.method, workers=args.workers, **kw)
    if args.json:
        s = res.summary()
        s.pop("measured_commutation", None)
        s.pop("B_uncertainty", None)
        print(json.dumps(s))
        return 0
    lo, hi = res.identified_H_range_A_per_m
    print(f"identified B(H) at x = {res.x_m * 1e3:g} mm ({res.method}: {res.status})")
    s = res.summary()
    wb, wa = s["flux_error_before"]["rms_weighted_rel_peak"], s["flux_error_after"]["rms_weighted_rel_peak"]
    print(f"  flux error   MAE {res.mae_before * 100:.3f} % -> {res.mae_after * 100:.3f} %, "
          f"RMS {res.rms_before * 100:.3f} % -> {res.rms_after * 100:.3f} % of peak "
          f"(weighted by the hysteresis width: {wb * 100:.3f} % -> {wa * 100:.3f} %)")
    print(f"  identified H range {h_range_text((lo, hi))} (steel reaches {res.H_max_steel_A_per_m:.4g} A/m)")
    print(f"  FEM solves {res.fem_solves}, sweeps {res.sweeps:.1f}, equivalent sweeps {res.equivalent_sweeps:.1f}, "
          f"wall {res.wall_time_s:.1f} s")
    print(f"  constraint residuals {res.constraint_residuals}")
    if res.extra.get("held_out"):
        print(f"  chosen by held-out prediction: {res.extra['chosen']}; error per held-out group "
              "(in-sample -> predicted without the group, RMS % of measured):")
        for row in res.extra["held_out"]:
            print(f"    {row['kind']:5s} {row['group']:<36.36s} {row['rms_in_pct']:6.2f} % -> "
                  f"{row['rms_held_out_pct']:6.2f} % (max {row['max_held_out_pct']:.2f} %)")
    for w in res.extra.get("warnings", []):
        print(f"  WARNING: {w}")
    print(f"  wrote {args.output} (+ .bh, .tab)" + (f", report in {args.report}" if args.report else ""))
    return 0
