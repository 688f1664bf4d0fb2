"""Command line of the FMU: ``export`` (maps -> FMU) and ``simulate`` (FMU + recording -> simulated recording)."""

from __future__ import annotations

import argparse
import math
import os
import sys
import sysconfig
import zipfile
from pathlib import Path

from ..argtypes import number
from ..errors import FmuInputError
from ..fileio import refuse_overwriting_inputs
from ..measure import write_recording
from .export import BACKENDS, build_fmu
from .interface import INTERFACES
from .native import skipped_platforms
from .simulate import simulate_recording

__all__ = ["add_cli", "backend_advice", "platforms_note"]


def add_cli(subparsers) -> None:
    """Register ``export`` (maps -> FMU) and ``simulate`` (FMU + recording -> simulated recording)."""
    p = subparsers.add_parser(
        "export", help="export the real-time model with a maps directory as an FMI 2.0 co-simulation FMU",
        description="Build an FMI 2.0 co-simulation FMU (paper eqs. 1-3) from maps/NAME; the result is "
                    "checked with fmpy.validation.validate_fmu.")
    p.add_argument("maps_dir", type=Path, help="maps directory with maps.npz and maps.json")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="FMU", help="FMU file to write")
    p.add_argument("--backend", choices=sorted(BACKENDS), default="python",
                   help="python: pythonfmu (the FMU needs Python 3 with numpy where it runs); c: native "
                        "FMU from generated C (co-simulation and model exchange, no Python at run time, "
                        "compiled with the machine's gcc/cc, sources/ inside)")
    p.add_argument("--interface", choices=INTERFACES, default=None,
                   help="FMI interfaces the FMU declares: cs+me (default of --backend c: co-simulation and "
                        "model exchange; the outputs declare their model-exchange dependencies on the inputs) "
                        "or cs (co-simulation only, outputs without direct feedthrough: no algebraic loops in "
                        "co-simulation masters such as OMSimulator; the only choice of --backend python)")
    p.add_argument("--name", help="modelName written into the FMU (default: 'solenoid <maps name>')")
    p.add_argument("--fmi", type=int, choices=(2, 3), default=2,
                   help="FMI version: 2 (default) or 3 (--backend c: an FMI 3.0 FMU from the same generated C, "
                        "co-simulation and model exchange, the same variables as Float64/Int32/Boolean)")
    p.set_defaults(func=_cmd_export)

    s = subparsers.add_parser(
        "simulate", help="drive an FMU with a recording's measured inputs; write the simulated recording",
        description="Simulate a recording (format v1) with an FMU through fmpy and write the result in the "
                    "same format (same header and time column, simulated voltage/current/force, extra "
                    "columns psi_Wb and i_eddy_A), so measured and simulated files compare column by column.")
    s.add_argument("fmu", type=Path, help="FMU built by 'solenoid-fmu export'")
    s.add_argument("recording", type=Path, help="measured recording CSV (format v1)")
    s.add_argument("-o", "--output", type=Path, required=True, metavar="CSV",
                   help="simulated recording to write")
    s.add_argument("--drive", choices=("auto", "voltage", "current"), default="auto",
                   help="auto: voltage-driven for voltage_step, current-driven for flux, force_stroke, "
                        "ramp, eddy")
    s.add_argument("--R-ohm", dest="R_ohm", type=number(0.0, lo_open=True),
                   help="coil resistance [ohm] (default: the recording's header, else the FMU's)")
    s.add_argument("--G-eddy-S", dest="G_eddy_S", type=number(0.0), help="eddy-current conductance [S]")
    s.set_defaults(func=_cmd_simulate)


def _cmd_export(args: argparse.Namespace) -> int:
    refuse_overwriting_inputs(args.output, [args.maps_dir / "maps.npz", args.maps_dir / "maps.json"])
    path = build_fmu(args.maps_dir, args.output, backend=args.backend, interface=args.interface,
                     model_name=args.name, fmi_version=args.fmi)
    interface = args.interface or BACKENDS[args.backend].default_interface
    where = "" if interface == BACKENDS[args.backend].default_interface else f", interface {interface}"
    where += ", FMI 3.0" if args.fmi == 3 else ""
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB, backend {args.backend}{where}; "
          "fmpy validation: no problems)")
    print(backend_advice(args.backend, interface).replace("FMI 2.0", "FMI 3.0") if args.fmi == 3
          else backend_advice(args.backend, interface))
    if args.backend == "c":
        print(platforms_note(path))
    return 0


def platforms_note(fmu_path) -> str:
    """Which platforms' binaries the native FMU carries, which it left out and why (printed by ``export``)."""
    with zipfile.ZipFile(fmu_path) as zf:
        folders = sorted({n.split("/")[1] for n in zf.namelist() if n.startswith("binaries/") and n.count("/") >= 2})
    note = f"binaries: {', '.join(folders)}; sources/ (CMakeLists.txt) builds it on any other platform"
    skipped = skipped_platforms()
    if skipped:
        note += "\nskipped " + "; ".join(f"{name}: {why}" for name, why in skipped.items())
    return note


def backend_advice(backend: str, interface: str = "cs+me") -> str:
    """Which FMU to use in which importer (printed by ``export``; README "Which export to use when")."""
    if backend == "c" and interface == "cs":
        return ("native FMU, co-simulation only: runs in any FMI 2.0 co-simulation master (fmpy, OMSimulator, "
                "libcosim, Ecos, Simulink, real-time targets) without algebraic loops, no Python at run time")
    if backend == "c":
        return ("native FMU: runs in any FMI 2.0 importer (fmpy, Simulink, OpenModelica/OMSimulator, libcosim, "
                "Ecos, real-time targets), co-simulation and model exchange, no Python at run time")
    lib = os.path.join(sysconfig.get_config_var("LIBDIR") or "", sysconfig.get_config_var("INSTSONAME") or "")
    return ("pythonfmu FMU: runs in Python hosts (fmpy, PyFMI) as it is; in C/C++ hosts (OMSimulator, libcosim, "
            f"Ecos, Simulink) start the host with LD_PRELOAD={lib} (this Python's libpython, with numpy), "
            "or export --backend c for those hosts")


def _cmd_simulate(args: argparse.Namespace) -> int:
    if args.R_ohm is not None and not (math.isfinite(args.R_ohm) and args.R_ohm > 0):
        raise FmuInputError(f"--R-ohm must be > 0, got {args.R_ohm!r}")
    refuse_overwriting_inputs(args.output, [args.fmu, args.recording])
    res = simulate_recording(args.fmu, args.recording, drive=args.drive, R_ohm=args.R_ohm,
                             G_eddy_S=args.G_eddy_S)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    write_recording(args.output, res.recording)
    for msg in res.messages:
        print(f"FMU: {msg}", file=sys.stderr)
    print(f"wrote {args.output} ({len(res.recording)} samples, {res.drive_mode}-driven)")
    return 0
