"""Command line of the maps: ``solenoid-fmu maps`` (FEM sweep, plots, exports) and ``solenoid-fmu eddy`` (G_eddy)."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
from pathlib import Path

import numpy as np

from ..argtypes import integer, number, process_count
from ..errors import MapsError
from ..field import MIN_MESH_SIZE, load_geometry, load_material
from ..fileio import dir_lock, refuse_overwriting_inputs, require_directory
from ..realtime import MAPS_JSON, MAPS_NPZ
from .eddy import with_fitted_eddy
from .export import DERIVED_FILES, DERIVED_PLOTS, export_combitable2d, export_mat, remove_stale_exports
from .io import load_maps, name_problem, save_maps
from .plots import plot_maps
from .refine import MAX_REFINE_X
from .sweep import MAX_GRID_POINTS, InlineExecutor, build_maps, process_pool

__all__ = ["add_cli", "parse_range"]


def parse_range(text: str, what: str = "range") -> tuple[float, float, int]:
    """Parse ``START:STOP:N`` strictly: two finite numbers with START < STOP and an integer N >= 2.

    Raises
    ------
    argparse.ArgumentTypeError
        With a message naming the text and what is wrong.
    """
    parts = text.split(":")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"{what} {text!r}: expected START:STOP:N, e.g. 0.2:3.5:15")
    try:
        start, stop = float(parts[0]), float(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"{what} {text!r}: START and STOP must be numbers") from None
    if not (math.isfinite(start) and math.isfinite(stop)):
        raise argparse.ArgumentTypeError(f"{what} {text!r}: START and STOP must be finite")
    try:
        n = int(parts[2].strip())
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{what} {text!r}: N must be a whole number, got {parts[2]!r}"
        ) from None
    if n < 2:
        raise argparse.ArgumentTypeError(f"{what} {text!r}: N must be at least 2, got {n}")
    if n > MAX_GRID_POINTS:
        raise argparse.ArgumentTypeError(f"{what} {text!r}: N = {n} is more than {MAX_GRID_POINTS} points "
                                         "(each is a FEM solve per point of the other grid)")
    if not start < stop:
        raise argparse.ArgumentTypeError(f"{what} {text!r}: START must be smaller than STOP")
    return start, stop, n


def add_cli(subparsers) -> None:
    """Register ``solenoid-fmu maps`` (``eddy`` comes later in the help: :func:`add_eddy_cli`)."""
    _add_maps_cli(subparsers)


def _add_maps_cli(subparsers) -> None:
    """Register ``solenoid-fmu maps``."""
    p = subparsers.add_parser(
        "maps",
        help="sweep the FEM over (i, x) and build the characteristic maps i_f(Psi, x), F(Psi, x)",
        description=(
            "Sweep the FEM over working-gap positions and currents, invert to the real-time maps "
            "i_f(Psi, x) and F(Psi, x) (paper eqs. 2-3), write maps.npz + maps.json. With --from, "
            "plot or export an existing map without a sweep."
        ),
        epilog=(
            "examples:\n"
            "  solenoid-fmu maps -o maps/ps45-literature --plot build/maps-plots --modelica --mat\n"
            "  solenoid-fmu maps --x-mm 0.5:2.8:12 --i-A 0:2.5:26 --mesh-size 2 -o maps/coarse\n"
            "  solenoid-fmu maps --from maps/ps45-literature --plot build/maps-plots\n"
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--geometry", metavar="G.toml", help="solenoid geometry (default: packaged PS45)")
    p.add_argument("--material", metavar="M.csv", help="B(H) curve (default: literature 9SMnPb28)")
    p.add_argument("--x-mm", metavar="START:STOP:N", type=lambda t: parse_range(t, "--x-mm"),
                   help="evenly spaced positions in mm (default: the whole stroke, 27 positions "
                        "clustered at both stops)")
    p.add_argument("--i-A", metavar="START:STOP:N", type=lambda t: parse_range(t, "--i-A"),
                   help="evenly spaced currents in A, START must be 0 (default: 0 to 1.25 x max "
                        "current, 26 currents, denser at low currents)")
    p.add_argument("--mesh-size", metavar="H", type=number(MIN_MESH_SIZE), default=1.0,
                   help="mesh-size factor (default 1.0; larger is coarser)")
    p.add_argument("--refine-x", metavar="R", type=integer(1, MAX_REFINE_X), default=1,
                   help="map columns per FEM interval in x: R - 1 more by a cubic spline at fixed flux between the "
                        "FEM positions (default 1: the FEM positions alone; the model reads the maps linearly in x)")
    p.add_argument("--workers", metavar="N", type=process_count, default=None,
                   help="parallel processes (default: all cores; 1 runs in this process)")
    p.add_argument("-o", "--output", metavar="maps/NAME", help="map directory to write")
    p.add_argument("--from", dest="source", metavar="maps/NAME", help="use an existing map, no sweep")
    p.add_argument("--plot", metavar="DIR", help="write PNG plots (figs. 12, 13, Psi(i), F(x)) into DIR")
    p.add_argument("--modelica", action="store_true", help="also write CombiTable2D files into the map dir")
    p.add_argument("--mat", action="store_true",
                   help="also write maps.mat (Simulink/Simscape) into the map dir")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_maps_cli)


def _output_map_dir(output, inputs) -> Path:
    """The map directory ``output`` of a new sweep, checked before the sweep: not under a file, its
    name a valid maps name, and none of the files a build writes or removes (maps.npz, maps.json,
    exports, plots) one of ``inputs``."""
    directory = require_directory(output, "-o")
    if (problem := name_problem(directory.name)) is not None:
        raise MapsError(f"-o {output}: the directory name is the maps name: {problem}")
    written = [directory / n for n in (MAPS_NPZ, MAPS_JSON, *DERIVED_FILES)] + [directory / "plots"]
    return refuse_overwriting_inputs(directory, inputs, written=written)


def _output_plot_dir(plot_dir, inputs) -> Path:
    """``--plot DIR`` checked before any work: not under a file, no input among the plots written."""
    plot_dir = require_directory(plot_dir, "--plot")
    return refuse_overwriting_inputs(plot_dir, inputs, written=[plot_dir / n for n in DERIVED_PLOTS])


def _maps_cli(args) -> int:
    with contextlib.ExitStack() as stack:
        if args.output is not None and args.source is None:  # one writer per map directory, before any work
            stack.enter_context(dir_lock(_output_map_dir(args.output, [args.geometry, args.material])))
        return _maps_run(args)


def _maps_run(args) -> int:
    if args.plot:  # checked before any work, not after the sweep
        source = [] if args.source is None else [Path(args.source) / n for n in (MAPS_NPZ, MAPS_JSON)]
        _output_plot_dir(args.plot, [args.geometry, args.material, *source])
    if args.source is not None:
        if args.output is not None:
            raise MapsError("use either -o (build a new map) or --from (use an existing one), not both")
        sweep_opts = [o for o, v in (("--geometry", args.geometry), ("--material", args.material),
                                     ("--x-mm", args.x_mm), ("--i-A", args.i_A), ("--workers", args.workers),
                                     ("--refine-x", None if args.refine_x == 1 else args.refine_x))
                      if v is not None]
        if sweep_opts:
            raise MapsError(f"{', '.join(sweep_opts)} only apply to a new sweep, not with --from")
        if not (args.plot or args.modelica or args.mat):
            raise MapsError("--from needs something to do: --plot DIR, --modelica or --mat")
        directory = Path(args.source)
        maps = load_maps(directory)
    else:
        if args.output is None:
            raise MapsError("missing -o maps/NAME (or --from maps/NAME to use an existing map)")
        directory = _output_map_dir(args.output, [args.geometry, args.material])
        geometry = load_geometry(args.geometry)
        material = load_material(args.material)
        x_m = None if args.x_mm is None else np.linspace(*args.x_mm) * 1e-3
        i_A = None
        if args.i_A is not None:
            if args.i_A[0] != 0.0:
                raise MapsError(f"--i-A must start at 0 A (maps hold i_f from Psi = 0), got {args.i_A[0]:g}")
            i_A = np.linspace(*args.i_A)
        executor = None
        if args.workers == 1:
            executor = InlineExecutor()
        elif args.workers is not None:
            executor = process_pool(args.workers)
        try:
            maps = build_maps(geometry, material, x_m=x_m, i_A=i_A, mesh_size=args.mesh_size,
                              executor=executor, progress=not args.quiet, name=directory.name, refine_x=args.refine_x)
        finally:
            if executor is not None:
                executor.shutdown()
        save_maps(maps, directory)
        removed = remove_stale_exports(directory)
        if removed:
            print(f"removed {len(removed)} export(s) of the earlier build in {directory}: "
                  + ", ".join(p.name for p in removed))
        solver = maps.metadata["provenance"]["solver"]
        ni, nx, npsi = maps.shape
        print(f"wrote {directory}/{MAPS_NPZ}, {MAPS_JSON}: {nx} positions x {ni} currents, "
              f"{npsi} flux points, {solver['wall_time_s']:.1f} s "
              f"({solver['operating_points'] / max(solver['wall_time_s'], 1e-9):.1f} points/s), "
              f"round trip {maps.metadata['round_trip_max_rel_error'] * 100:.3g} %")
    if args.modelica:
        for path in export_combitable2d(maps, directory):
            print(f"wrote {path}")
    if args.mat:
        print(f"wrote {export_mat(maps, directory / 'maps.mat')}")
    if args.plot:
        for path in plot_maps(maps, args.plot):
            print(f"wrote {path}")
    return 0


def add_eddy_cli(sub) -> None:
    """Register ``solenoid-fmu eddy``."""
    p = sub.add_parser("eddy", help="fit the eddy-current parameter G_eddy from eddy recordings (paper fig. 14)")
    p.add_argument("recordings", nargs="+", help="eddy recordings (CSV, format v1)")
    p.add_argument("--maps", required=True, help="maps directory of the same solenoid")
    p.add_argument("--write", action="store_true", help="store the fitted G_eddy in the maps (maps.json eddy)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_eddy_cli)


def _eddy_cli(args) -> int:
    fitted, fit = with_fitted_eddy(load_maps(args.maps), args.recordings)
    if args.write:
        save_maps(fitted, args.maps)
    if args.json:
        print(json.dumps(fit.as_dict()))
        return 0
    for p in fit.per_recording:
        print(f"{p['file']:<28} {p['rate_A_per_s']:8.3g} A/s   G = {p['G_eddy_S'] * 1e3:8.4g} mS   R^2 = {p['r2']:.3f}")
    print(f"pooled: G_eddy = {fit.G_eddy_S * 1e3:.4g} mS, R^2 = {fit.r2:.3f}")
    print(fit.message)
    if args.write:
        print(f"stored in {args.maps}/maps.json")
    return 0
