"""``solenoid-fmu rig``: run the campaign on a truth built from a true B(H) (or true maps).

Command line: ``solenoid-fmu rig --geometry G --material TRUE.csv --effects hysteresis,friction
-o DIR [--maps MAPSDIR] [--seed N]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
from pathlib import Path

from ..argtypes import integer, number
from ..field import MIN_MESH_SIZE, load_geometry, load_material
from ..fileio import refuse_overwriting_inputs, require_directory
from ..maps import build_maps, default_currents, default_positions, save_maps
from ..realtime import ModelError, load_tables
from .campaign import run_campaign
from .effects import EFFECT_NAMES, Effects
from .errors import RigError
from .excitation import CampaignConfig

__all__ = ["add_cli"]


def add_cli(subparsers) -> None:
    """Register ``solenoid-fmu rig``."""
    p = subparsers.add_parser(
        "rig", help="virtual test rig: run the test campaign on a known truth and write recordings",
        description=("Run the paper's test campaign (flux triangles, force-stroke sweeps, current ramp, eddy "
                     "triangles, voltage step) on a truth model = FEM maps with the given true B(H) plus "
                     "effects, and write one recording per test into DIR/recordings and the truth into "
                     "DIR/truth.json (for tests only)."),
        epilog=("examples:\n"
                "  solenoid-fmu rig --material true.csv --effects hysteresis,friction -o build/campaign\n"
                "  solenoid-fmu rig --maps maps/ps45-true --effects all --seed 3 -o build/campaign\n"),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--geometry", metavar="G.toml", help="solenoid geometry (default: packaged PS45)")
    p.add_argument("--material", metavar="TRUE.csv", help="true B(H) curve (copied into DIR/truth/)")
    p.add_argument("--maps", metavar="MAPSDIR", help="use these true maps instead of running the FEM")
    p.add_argument("--effects", default="", metavar="LIST",
                   help=f"comma-separated effects: {','.join(EFFECT_NAMES)}, or 'all' (default: none)")
    p.add_argument("--seed", type=integer(0), default=0, help="seed of the sensor noise, >= 0 (default 0)")
    p.add_argument("--mesh-size", type=number(MIN_MESH_SIZE), default=1.0,
                   help="FEM mesh-size factor when building maps")
    p.add_argument("--campaign", metavar="JSON", help="campaign parameters (keys of CampaignConfig) as JSON file")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="campaign directory to write")
    p.set_defaults(func=_cli)


def _cli(args) -> int:
    out = require_directory(args.output, "-o")
    written = [out / "recordings", out / "truth.json"] + ([] if args.maps else [out / "truth" / "maps"])
    refuse_overwriting_inputs(out, [args.geometry, args.material, args.maps, args.campaign], written=written)
    names = ",".join(EFFECT_NAMES) if args.effects.strip().lower() == "all" else args.effects
    effects = Effects.from_names(names)
    cfg = CampaignConfig()
    if args.campaign:
        try:
            cfg = CampaignConfig.from_dict(json.loads(Path(args.campaign).read_text(encoding="utf-8")))
        except json.JSONDecodeError as exc:
            raise RigError(f"{args.campaign}:{exc.lineno}: not valid JSON: {exc.msg}") from None
    truth_dir = out / "truth"
    material_path = None
    if args.material:
        src = Path(args.material)
        if not src.is_file():
            raise RigError(f"{src}: no such material file")
        truth_dir.mkdir(parents=True, exist_ok=True)
        material_path = truth_dir / src.name
        if src.resolve() != material_path.resolve():
            shutil.copyfile(src, material_path)
    if args.maps:
        maps_dir = Path(args.maps)
    else:
        if material_path is None:
            raise RigError("give --material TRUE.csv (the FEM builds the true maps) or --maps MAPSDIR")
        geometry = load_geometry(args.geometry)
        material = load_material(material_path)
        st = geometry.stroke
        maps = build_maps(geometry, material, x_m=default_positions(st.min_m, st.max_m, 12),
                          i_A=default_currents(1.25 * geometry.coil.max_current_A, 16),
                          mesh_size=args.mesh_size, name="truth")
        maps_dir = truth_dir / "maps"
        save_maps(maps, maps_dir)
    try:
        tables = load_tables(maps_dir)
    except ModelError as exc:
        raise RigError(f"cannot use the maps: {exc}") from None
    geometry_name = (tables.provenance.get("geometry") or {}).get("name")
    if not args.campaign and isinstance(geometry_name, str) and geometry_name.strip():
        cfg = dataclasses.replace(cfg, solenoid=geometry_name.strip())
    print(f"rig: {cfg.solenoid}, effects: {', '.join(effects.names()) or 'none'}, maps: {maps_dir}")
    truth = run_campaign(tables, out, effects=effects, campaign=cfg, seed=args.seed,
                         material_path=material_path, maps_dir=maps_dir, progress=True)
    print(f"wrote {len(truth.recordings)} recordings to {out / 'recordings'} and {out / 'truth.json'}")
    return 0
