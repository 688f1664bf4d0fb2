"""Command line of the loop: ``solenoid-fmu validate``, ``diagnose`` and ``improve``."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from ..argtypes import integer, number
from ..fileio import jsonable, refuse_overwriting_inputs, require_directory
from .diagnosis import DEFAULT_THRESHOLD, diagnose
from .improvement import DEFAULT_MAX_EFFECTS, DEFAULT_MIN_GAIN, effects_summary_lines, improve
from .metrics import fmt
from .validation import timed_cases, validate


def add_cli(sub) -> None:
    """Register ``solenoid-fmu validate``, ``diagnose`` and ``improve`` (in this order)."""
    _add_validate(sub)
    _add_diagnose(sub)
    _add_improve(sub)


def _fmu_and_recordings(p, fmu_help: str, **kind) -> None:
    """The positional arguments every loop command takes: the FMU, then one or more recordings."""
    p.add_argument("fmu", help=fmu_help, **kind)
    p.add_argument("recordings", nargs="+", help="recording CSV files (format v1)", **kind)


# -- validate ---------------------------------------------------------------------------------------
def _add_validate(sub) -> None:
    p = sub.add_parser(
        "validate", help="run the FMU on recordings' measured inputs; RMS, max and normalized errors per signal",
        description="Drive the FMU with each recording's measured inputs (current, or voltage for voltage_step) "
                    "and compare every output the recording has: force, flux linkage (from the measured "
                    "voltage, paper eq. 4), current. nrmse = RMS error / range of the measured signal.")
    _fmu_and_recordings(p, "the FMU (solenoid-fmu export)", type=Path)
    p.add_argument("--report", type=Path, metavar="DIR",
                   help="write overlay and residual plots per recording and validation.json into DIR")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout (progress stays on stderr)")
    p.set_defaults(func=_cli_validate)


def _cli_validate(args) -> int:
    if args.report is not None:  # checked before the simulations, not after them
        refuse_overwriting_inputs(require_directory(args.report, "--report"), [args.fmu, *args.recordings], written=[])
    n = len(args.recordings)
    count = iter(range(1, n + 1))

    def progress(name):
        print(f"[{next(count)}/{n}] simulating {name} ...", file=sys.stderr, flush=True)

    result = validate(args.fmu, args.recordings, report_dir=args.report, progress=progress)
    _say_not_read(result["names_not_read"])
    if args.json:
        print(json.dumps(result))
        return 0
    w = max([len("file")] + [len(r["file"]) for r in result["recordings"]])
    print(f"{'file':<{w}}  {'signal':<10} {'rms':>11} {'max':>11} {'nrmse':>9}")
    for rec in result["recordings"]:
        if not rec["signals"]:
            print(f"{rec['file']:<{w}}  {rec.get('note', 'nothing to compare')}")
        for sig, m in rec["signals"].items():
            print(f"{rec['file']:<{w}}  {sig:<10} {fmt(m['rms']):>11} {fmt(m['max']):>11} {fmt(m['nrmse']):>9}")
    for sig, s in result["summary"].items():
        print(f"{sig}: nrmse mean {fmt(s['nrmse_mean'])}, max {fmt(s['nrmse_max'])} "
              f"over {s['n_recordings']} recording(s)")
    if args.report is not None:
        print(f"wrote {args.report / 'validation.json'} and {len(result['figures'])} figure(s)")
    return 0


# -- diagnose ---------------------------------------------------------------------------------------
def _say_not_read(lines) -> None:
    """Names kept but not read for looking like misspelt ones, as notes on stderr (a misspelt header resistance is
    a recording without one: the user must hear it)."""
    for line in lines:
        print(f"note: {line}", file=sys.stderr)


def _add_diagnose(sub) -> None:
    p = sub.add_parser("diagnose", help="trace the FMU-vs-recording residual to the effect the model lacks")
    _fmu_and_recordings(p, "the FMU (solenoid-fmu export)")
    p.add_argument("--threshold", type=number(0.0, 1.0), default=DEFAULT_THRESHOLD,
                   help=f"held-out explained share needed for a verdict (default {DEFAULT_THRESHOLD})")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cli_diagnose)


def _cli_diagnose(args) -> int:
    def progress(name):
        if not args.json:
            print(f"simulating {name} ...", file=sys.stderr)

    not_read = []
    cases = timed_cases(args.fmu, args.recordings, progress=progress, not_read=not_read)
    _say_not_read(not_read)
    if not cases:
        print("error: no recording has a signal to compare (voltage, current or force)", file=sys.stderr)
        return 1
    d = diagnose(cases, threshold=args.threshold)
    if args.json:
        out = d.as_dict()
        out["ranking"] = [{k: c[k] for k in ("effect", "score", "explained", "per_signal")} for c in out["ranking"]]
        out["names_not_read"] = not_read
        print(json.dumps(out))
        return 0
    print(f"{'effect':<12} {'score':>8} {'explained':>10}   per signal (held-out explained share)")
    for c in d.ranking:
        sig = ", ".join(f"{k} {v:.2f}" for k, v in c.per_signal.items())
        print(f"{c.effect:<12} {c.score:8.3f} {c.explained:10.3f}   {sig}")
    print(f"verdict: {d.verdict} (threshold {d.threshold:g})")
    return 0


# -- improve ----------------------------------------------------------------------------------------
def _add_improve(sub) -> None:
    p = sub.add_parser("improve", help="add the diagnosed effects to the model, fit, validate, export")
    _fmu_and_recordings(p, "the FMU to improve (solenoid-fmu export)")
    p.add_argument("-o", "--output", required=True, help="the improved FMU to write")
    p.add_argument("--report", help="directory for figures and improve.json")
    p.add_argument("--max-effects", type=integer(0), default=DEFAULT_MAX_EFFECTS)
    p.add_argument("--min-gain", type=number(0.0, 1.0), default=DEFAULT_MIN_GAIN,
                   help="relative fall of the validation error an effect must bring (default 0.1)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cli_improve)


def _cli_improve(args) -> int:
    def progress(msg):
        print(msg, file=sys.stderr, flush=True)

    refuse_overwriting_inputs(args.output, [args.fmu, *args.recordings])
    if args.report is not None:
        refuse_overwriting_inputs(require_directory(args.report, "--report"), [args.fmu, *args.recordings], written=[])
    res = improve(args.fmu, args.recordings, args.output, report_dir=args.report, max_effects=args.max_effects,
                  min_gain=args.min_gain, progress=progress).as_dict()
    if args.json:
        out = {k: res[k] for k in ("effects_added", "steps", "recordings", "fmu", "improved_fmu", "not_identifiable")}
        print(json.dumps(jsonable(out)))
        return 0
    print("\n".join(effects_summary_lines(res)))
    print(f"{'file':<28} {'split':<9} {'signal':<10} {'rms before':>12} {'rms after':>12} {'ratio':>7}")
    for row in res["recordings"]:
        for sig, m in row["signals"].items():
            b, a = m["before"], m["after"]
            ratio = a / b if b and a is not None else math.nan
            print(f"{row['file']:<28} {row['split']:<9} {sig:<10} {b:12.4g} {a:12.4g} {ratio:7.3f}")
    print(f"wrote {res['improved_fmu']}")
    return 0
