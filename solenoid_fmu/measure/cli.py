"""Command line of the measurement: ``solenoid-fmu flux`` and ``solenoid-fmu check-recording``."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from ..argtypes import number
from ..errors import RecordingError
from ..fileio import refuse_overwriting_inputs, require_directory
from .flux import flux_linkage
from .format import misspelt_in
from .plots import plot_flux
from .polarity import read_unipolar
from .reader import validate_recording

__all__ = ["add_cli"]


def add_cli(subparsers) -> None:
    """Register ``flux`` and ``check-recording``."""
    p = subparsers.add_parser(
        "flux", help="flux linkage Psi(i) from a recording's voltage and current (paper eq. 4)",
        description="Integrate Psi = int (U - R(t) i) dt with the coil resistance tracked over the recording "
                    "(plateaus, cycle closure; R(t) = R0 (1 + kappa E), E the Joule energy), remove the voltage "
                    "offset, split the triangles into branches; print R at start and end, kappa, offset, Psi at "
                    "the peak and the hysteresis width.")
    p.add_argument("recording", type=Path, help="recording CSV (format v1) with a voltage_V column")
    p.add_argument("--plot", type=Path, metavar="PNG", help="draw Psi(i) branches and the commutation curve")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.add_argument("--resistance-ohm", type=number(0.0, lo_open=True), metavar="R",
                   help="coil resistance [ohm] at the start (overrides the header; the prior of the R track)")
    p.add_argument("--constant-resistance", action="store_true",
                   help="integrate with one R (the header's or --resistance-ohm) instead of the R(t) track "
                        "estimated from the recording")
    p.set_defaults(func=_cmd_flux)
    c = subparsers.add_parser("check-recording", help="validate recording files; print every problem",
                              description="Check recording CSV files against format v1; "
                                          "exit 1 if any problem.")
    c.add_argument("files", nargs="+", type=Path, metavar="FILE")
    c.set_defaults(func=_cmd_check)


def _cmd_flux(args: argparse.Namespace) -> int:
    if args.plot is not None:  # what matplotlib writes: a PNG, never over the recording
        if args.plot.suffix.lower() != ".png":
            args.plot = args.plot.with_name(args.plot.name + ".png")
        require_directory(args.plot.parent, "--plot")
        refuse_overwriting_inputs(args.plot, [args.recording])
    recs, turned, left = read_unipolar([args.recording])
    if left:
        raise RecordingError("flux", left)
    rec = recs[0]
    not_read = misspelt_in(recs)  # a misspelt header resistance is a recording without one: say so
    for line in turned + not_read:
        print(f"note: {line}", file=sys.stderr)
    res = flux_linkage(rec, args.resistance_ohm, resistance=None if args.constant_resistance else "track")
    if args.plot is not None:
        plot_flux(res, args.plot, title=f"{args.recording.name}: Psi(i)")
    if args.json:
        out = {"file": str(args.recording), **res.summary(), "names_not_read": not_read}
        print(json.dumps(out))
        return 0
    x = rec.positions_m()
    print(f"recording: {args.recording} (kind {rec.kind}, solenoid {rec.solenoid}, "
          f"x = {np.mean(x) * 1e3:.3f} mm, {len(rec)} samples)")
    origin = {"header": "from the header", "given": "given", "plateau": "estimated from current plateaus",
              "closure": "estimated from flux closure", "track": "track"}[res.resistance_method]
    tr = res.track
    if tr is None:
        print(f"resistance used: {res.R_ohm:.4f} ohm ({origin})")
    else:
        print(f"resistance track: R start {tr.R0_ohm:.4f} +- {tr.R0_sigma_ohm:.4f} ohm, end {tr.R_end_ohm:.4f} +- "
              f"{tr.R_end_sigma_ohm:.4f} ohm, kappa {tr.kappa_per_J:.3g} +- {tr.kappa_sigma_per_J:.2g} 1/J "
              f"(Joule energy {float(tr.energy_J[-1]):.4g} J; from {', '.join(tr.constraints)})")
        print(f"resistance track pinned: {'yes' if tr.pinned else 'no'} (Psi at the peak +- "
              f"{tr.psi_peak_sigma_Wb * 1e3:.4g} mWb)")
        if tr.header_R_ohm is not None:
            print(f"header resistance: {tr.header_R_ohm:.4f} ohm"
                  + (" (disagrees with the data, see the note)" if tr.header_disagrees else "")
                  + (f" (the recording's own data overrule it: {tr.header_off_sigmas:.0f} sigma off)"
                     if tr.header_overruled else ""))
    print(f"offset removed: {res.offset_V * 1e3:.3f} mV (drift {res.offset_drift_V_per_s * 1e3:.4f} mV/s)")
    print(f"peak current: {res.peak_current_A:.4f} A")
    print(f"Psi at peak: {res.psi_at_peak_Wb * 1e3:.4f} mWb")
    if math.isfinite(res.hysteresis_width_Wb):
        print(f"hysteresis width: max {res.hysteresis_width_Wb * 1e3:.4f} mWb, "
              f"mean {res.hysteresis_mean_width_Wb * 1e3:.4f} mWb ({len(res.branches) // 2} peak(s))")
    else:
        print("hysteresis width: n/a (no current peak)")
    for note in res.notes:
        print(f"note: {note}")
    if args.plot is not None:
        print(f"plot: {args.plot}")
    return 0


def _cmd_check(args: argparse.Namespace) -> int:
    status = 0
    for path in args.files:
        problems = validate_recording(path)
        if problems:
            status = 1
            for line in problems:
                print(line)
        else:
            print(f"{path}: ok")
    sys.stdout.flush()
    return status
