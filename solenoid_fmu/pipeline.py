"""The main job: from a campaign folder of recordings to a validated, improved FMU with one report.

``solenoid-fmu pipeline fitting/NAME -o build/NAME`` runs, with progress on stderr:

1. **recordings**: every ``*.csv`` under the folder whose first line is the recording format's
   ``# recording:`` line (kinds from the headers; folders named ``truth`` are never entered, and
   files that are not recordings are listed as skipped);
2. **identify**: B(H) from the ``flux`` recordings (:mod:`solenoid_fmu.identification`) ->
   ``material/material.csv`` (+ ``.bh``, ``.tab``) and ``identify/`` (figures, JSON);
3. **maps**: FEM sweep with the identified steel -> ``maps/`` (:func:`solenoid_fmu.maps.build_maps`); the
   sweep's currents reach ``1.25 x`` the coil's rated current or ``1.25 x`` the largest |current| in the
   campaign's recordings, whichever is larger (:func:`maps_current_grid`), so the maps' flux range covers
   what was measured;
4. **eddy**: the single eddy conductance from the ``eddy`` recordings, stored in ``maps/maps.json``;
5. **export**: ``NAME.fmu`` (pythonfmu) and, when a C compiler is there, ``NAME-native.fmu``;
6. **validate** and **diagnose** the FMU on every recording;
7. **improve**: add the diagnosed effects -> ``NAME-improved.fmu`` (:mod:`solenoid_fmu.loop.improvement`) and
   its native twin ``NAME-improved-native.fmu``;
8. **report**: ``report.html`` (self-contained) and ``summary.json``.

When ``improve`` adds coil heating and the identification did not already integrate eq. 4 with the
campaign's resistance tracks (it does where they show the coil heating), the flux recordings it used
carried the heating's eq.-4 drift (a B(H) error the diagnosis cannot always separate from the effects
left, e.g. hysteresis explains part of a force residual a wrong B(H) leaves): steps 2-7 run once more on recordings
whose voltage is corrected with the fitted heating model (:func:`solenoid_fmu.loop.heating_corrected`,
written to ``heating-corrected/``); ``summary.json["first_round"]`` keeps what the first round found.

``summary.json`` holds ``material``, ``fmu``, ``improved_fmu`` (paths), ``effects_added`` (the
words ``diagnose`` uses), ``effects_found`` (those and ``eddy`` where step 4 measured it,
:func:`effects_found`), ``errors`` (one row per recording and signal: RMS error ``before`` and
``after`` improvement in the signal's SI unit, and the same normalized by the measured range),
the diagnosis, the identification summary and the wall time of every step.

Outputs are written to fresh files (atomic writes); a failing step stops the pipeline with its
error and leaves the results of the steps before it in place. Only one pipeline writes a folder at a time
(a lock; a second is refused). From its start until ``summary.json`` is written, the folder holds
``pipeline.incomplete`` (:data:`INCOMPLETE_MARKER`) and no ``summary.json`` or ``report.html``: a run that
was interrupted or failed over an earlier complete one leaves a folder that says it is mixed
(:func:`pipeline_incomplete`); a folder with ``summary.json`` and no marker is one complete run.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from .errors import SolenoidError
from .field import load_geometry
from .fileio import atomic_write_text, dir_lock, jsonable, refuse_overwriting_inputs, require_directory
from .fmu import build_fmu
from .identification import identify_from_recordings
from .loop import effects_summary_lines, heating_corrected, improve, tables_from_fmu
from .maps import (
    DEFAULT_CURRENT_FACTOR,
    DEFAULT_NI,
    InlineExecutor,
    build_maps,
    default_currents,
    default_positions,
    fit_eddy,
    name_problem,
    process_pool,
    save_maps,
)
from .measure import read_recording, write_recording
from .report import write_campaign_report

#: Grid presets of the FEM steps: "full" is the shipped quality, "quick" a coarse check (tests), "smoke" the
#: coarsest that still runs every step (a production lot's tests, ``solenoid-fmu batch --preset smoke``: a
#: coarser identification mesh, 4 currents per stroke, at most ``identify_max_nfev`` Levenberg-Marquardt
#: evaluations per stage, a 4 x 6 maps grid, no figures (``figures``: the report.html without them) and no native
#: FMU (``native``); ~12 s of CPU per unit on the end-of-line campaign, not product quality).
PRESETS = {
    "full": {"identify_mesh_size": None, "maps_mesh_size": 1.0, "n_x": None, "n_i": None, "n_currents": 10},
    "quick": {"identify_mesh_size": None, "maps_mesh_size": 2.0, "n_x": 9, "n_i": 12, "n_currents": 6},
    "smoke": {"identify_mesh_size": 4.0, "maps_mesh_size": 3.0, "n_x": 4, "n_i": 6, "n_currents": 4,
              "identify_max_nfev": 2, "figures": False, "native": False},
}


#: The maps sweep reaches at least this multiple of the largest |current| [A] in the campaign's recordings.
CAMPAIGN_CURRENT_MARGIN = 1.25
#: Kinds of recording whose voltage the second round corrects for the fitted heating: those the identification
#: reads the flux or the coil's heating rate from (flux points, eddy split, heating rate: a ramp's hold pins it).
HEATING_CORRECTED_KINDS = ("flux", "ramp", "eddy")


class PipelineError(SolenoidError):
    """The campaign folder cannot be processed (no recordings, no flux recording, ...)."""


def find_recordings(folder) -> tuple[list[Path], list[Path]]:
    """Recording files under ``folder`` (sorted) and other CSV files skipped (never inside ``truth``)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise PipelineError(f"{folder}: campaign folder not found")
    found, skipped = [], []
    for path in sorted(folder.rglob("*.csv")):
        rel = path.relative_to(folder)
        if any(part == "truth" or part.startswith(".") for part in rel.parts[:-1]):
            continue
        with open(path, encoding="utf-8", errors="replace") as fh:
            first = fh.readline()
        (found if first.startswith("# recording:") else skipped).append(path)
    if not found:
        raise PipelineError(f"{folder}: no recording (CSV starting with '# recording:') found")
    return found, skipped


def _progress(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def maps_current_grid(rated_current_A: float, recordings, n_i: int | None = None) -> np.ndarray:
    """Currents [A] of the maps sweep, from 0 to the larger of ``DEFAULT_CURRENT_FACTOR`` (1.25) x the coil's
    rated current and ``CAMPAIGN_CURRENT_MARGIN`` (1.25) x the largest |current| in ``recordings``.

    The spacing is :func:`solenoid_fmu.maps.default_currents`'s (denser at low currents). When the
    campaign pushes the top up, the number of currents grows with ``top^(2/3)`` so the first step (near the
    iron's knee) stays as fine as with ``n_i`` currents up to the rated top (within 0.2 %: a top pushed up by
    measurement noise adds no current).

    Parameters
    ----------
    rated_current_A : float
        The coil's rated current ``geometry.coil.max_current_A`` [A].
    recordings : iterable of Recording
        The campaign; their ``current_A`` columns (non-finite samples ignored).
    n_i : int, optional
        Number of currents up to the rated top (default ``maps.DEFAULT_NI``).
    """
    n_i = DEFAULT_NI if n_i is None else int(n_i)
    rated_top = DEFAULT_CURRENT_FACTOR * rated_current_A
    peaks = [float(np.max(np.abs(c[np.isfinite(c)]), initial=0.0))
             for c in (np.asarray(r.current_A, dtype=float) for r in recordings)]
    top = max([rated_top] + [CAMPAIGN_CURRENT_MARGIN * p for p in peaks])
    if top > rated_top:
        n_i = math.ceil((n_i - 1) * (top / rated_top) ** (2 / 3) - 0.01) + 1  # 0.01: no extra point for noise
    return default_currents(top, n_i)


def _maps_grid(preset: dict, geometry, recordings=()):
    """Positions [m] and currents [A] of the maps sweep for a preset and campaign (None: the maps' defaults)."""
    x = None
    if preset["n_x"] is not None:
        x = default_positions(geometry.stroke.min_m, geometry.stroke.max_m, preset["n_x"])
    return x, maps_current_grid(geometry.coil.max_current_A, recordings, preset["n_i"])


def campaign_maps(geometry, curve, recordings, eddy_recordings=None, *, preset: str = "full", executor=None,
                  name: str = "identified", progress=None) -> tuple:
    """Steps 3 and 4 in memory: the characteristic maps of the identified steel, with the eddy conductance.

    Parameters
    ----------
    geometry : Geometry
    curve : BHCurve
        The identified steel.
    recordings : list of Recording
        The campaign (the sweep's current range covers their largest |current|, :func:`maps_current_grid`).
    eddy_recordings : list of Recording, optional
        Where G_eddy is fitted from (default: the ``eddy`` recordings among ``recordings``; the pipeline's
        second round passes the heating-corrected ones).
    preset : {"full", "quick", "smoke"}
        The FEM grid (:data:`PRESETS`).
    executor : concurrent.futures.Executor, optional
        Runs the sweep (default: in this process).
    progress : callable(str), optional
        Receives one line per step.

    Returns
    -------
    (CharacteristicMaps, EddyFit or None)
        The maps (``eddy.G_eddy_S`` set when there are eddy recordings) and the eddy fit.
    """
    cfg = PRESETS[preset]
    say = progress or (lambda msg: None)
    x_m, i_A = _maps_grid(cfg, geometry, recordings)
    say(f"   currents 0 .. {i_A[-1]:.4g} A ({len(i_A)}): 1.25 x the larger of the rated current and the "
        "campaign's largest |current|")
    maps = build_maps(geometry, curve, x_m=x_m, i_A=i_A, mesh_size=cfg["maps_mesh_size"],
                      executor=executor or InlineExecutor(), progress=progress is not None, name=name)
    eddy_recs = [r for r in (recordings if eddy_recordings is None else eddy_recordings) if r.kind == "eddy"]
    if not eddy_recs:
        say("   no eddy recording: G_eddy stays 0")
        return maps, None
    eddy = fit_eddy(eddy_recs, maps)
    say(f"   G_eddy = {eddy.G_model_S * 1e3:.4g} mS (R^2 {eddy.r2:.3f}); {eddy.message}")
    return maps.with_eddy(eddy.G_model_S, source=", ".join(r.path.name if r.path is not None else r.kind
                                                                     for r in eddy_recs)), eddy


def effects_found(effects_added, eddy) -> list[str]:
    """The effects the final model carries, in the diagnosis's words: those the loop added and ``eddy``
    when step 4 measured an eddy current (:attr:`solenoid_fmu.maps.EddyFit.measurable`; the paper's
    eddy term is the maps' ``G_eddy``, the loop's ladder only refines it)."""
    found = set(effects_added)
    if eddy is not None and eddy.measurable:
        found.add("eddy")
    return sorted(found)


def _output_dir(folder, out_dir) -> Path:
    """``out_dir`` checked before any work: not under a file, neither inside the campaign folder
    (its recordings would be read back as campaign recordings) nor holding it, and the campaign's
    name (the maps name) one line without control characters."""
    out = refuse_overwriting_inputs(require_directory(out_dir, "-o"), [folder])
    if (problem := name_problem(Path(folder).resolve().name)) is not None:
        raise PipelineError(f"{folder}: the campaign folder's name names the maps: {problem}")
    return out


#: Present in a pipeline's output folder from the start of a run until its summary.json is written.
INCOMPLETE_MARKER = "pipeline.incomplete"


def pipeline_incomplete(out_dir) -> str | None:
    """Why the pipeline output folder ``out_dir`` is not one complete run (None if it is)."""
    marker = Path(out_dir) / INCOMPLETE_MARKER
    if marker.exists():
        return (f"{out_dir}: incomplete: a pipeline run started there did not finish ({marker}); its files mix that "
                "run's and an earlier one's: run the pipeline again")
    return None


def run_pipeline(folder, out_dir, *, geometry=None, preset: str = "full", workers: int | None = None,
                 progress=_progress, start_material=None) -> dict:
    """Run the main job (module docstring) and return the summary dict (also in ``summary.json``).

    ``start_material`` (a B(H) CSV or curve; default the literature curve) is where the identification starts
    (``solenoid-fmu batch --start-material``: a lot's nominal steel).

    Every argument is checked before any work; the output folder is locked for the run and marked
    incomplete (:data:`INCOMPLETE_MARKER`, the earlier ``summary.json`` and ``report.html`` removed) until
    the new ``summary.json`` is written."""
    if preset not in PRESETS:
        raise PipelineError(f"unknown preset {preset!r}; use one of {', '.join(PRESETS)}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise PipelineError(f"workers must be a whole number >= 1, got {workers!r}")
    out = _output_dir(folder, out_dir)
    with dir_lock(out):
        marker = {"campaign": str(folder), "pid": os.getpid(), "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ",
                                                                                          time.gmtime()),
                  "note": "pipeline run incomplete until summary.json is written; the folder may mix this run's "
                          "files with an earlier run's"}
        atomic_write_text(out / INCOMPLETE_MARKER, json.dumps(marker, indent=1) + "\n")
        for name in ("summary.json", "report.html"):
            (out / name).unlink(missing_ok=True)
        summary = _run_pipeline(folder, out_dir, geometry=geometry, preset=preset, workers=workers,
                                progress=progress, start_material=start_material)
        (out / INCOMPLETE_MARKER).unlink()
    return summary


def _run_pipeline(folder, out_dir, *, geometry=None, preset: str = "full", workers: int | None = None,
                  progress=_progress, start_material=None) -> dict:
    if preset not in PRESETS:
        raise PipelineError(f"unknown preset {preset!r}; use one of {', '.join(PRESETS)}")
    cfg = PRESETS[preset]
    figures = cfg.get("figures", True)
    say = progress or (lambda msg: None)
    folder, out = Path(folder), _output_dir(folder, out_dir)
    out.mkdir(parents=True, exist_ok=True)
    name = folder.resolve().name
    times: dict = {}
    t_all = time.perf_counter()

    def step(label):
        say(f"== {label}")
        return time.perf_counter()

    t0 = step(f"recordings in {folder}")
    paths, skipped = find_recordings(folder)
    recs = [read_recording(p) for p in paths]
    kinds: dict = {}
    for r in recs:
        kinds[r.kind] = kinds.get(r.kind, 0) + 1
    say("   " + ", ".join(f"{n} {k}" for k, n in kinds.items()) + (f"; skipped {len(skipped)} other CSV" if skipped
                                                                    else ""))
    if "flux" not in kinds:
        raise PipelineError(f"{folder}: no 'flux' recording: the B(H) identification needs one")
    geom = load_geometry(geometry)
    times["recordings"] = time.perf_counter() - t0

    ident_paths, ident_recs, first_round, suffix = paths, recs, None, ""
    for round_no in (1, 2):
        t0 = step(f"identify B(H) from the flux recordings{suffix}")
        material_csv = out / "material" / "material.csv"
        max_nfev = {"max_nfev": cfg["identify_max_nfev"]} if "identify_max_nfev" in cfg else {}
        ident = identify_from_recordings(ident_paths, geometry=geom, mesh_size=cfg["identify_mesh_size"],
                                         start_material=start_material,
                                         out_csv=material_csv, report_dir=out / "identify" if figures else None,
                                         progress=progress is not None, n_currents=cfg["n_currents"],
                                         **max_nfev)
        ident_summary = ident.summary()
        say(f"   flux error (RMS of peak) {ident.rms_before * 100:.2f} % -> {ident.rms_after * 100:.2f} %, "
            f"{ident_summary.get('equivalent_sweeps', float('nan')):.0f} equivalent sweeps, {ident.wall_time_s:.0f} s")
        times["identify"] = time.perf_counter() - t0

        t0 = step("characteristic maps (FEM sweep with the identified steel), eddy-current parameter")
        maps_dir = out / "maps"
        executor = InlineExecutor() if workers == 1 else process_pool(workers)
        try:
            maps, eddy = campaign_maps(geom, ident.curve, recs, ident_recs, preset=preset, executor=executor,
                                       name=f"{name}-identified", progress=say if progress is not None else None)
        finally:
            executor.shutdown()
        save_maps(maps, maps_dir)
        times["maps"] = time.perf_counter() - t0

        t0 = step("export the FMU")
        fmu = build_fmu(maps_dir, out / f"{name}.fmu")
        native = None
        try:
            if cfg.get("native", True):
                native = build_fmu(maps_dir, out / f"{name}-native.fmu", backend="c")
        except SolenoidError as exc:  # no C compiler on this machine: the pythonfmu export still stands
            say(f"   native FMU not built: {exc}")
        say(f"   {fmu}" + (f", {native}" if native else ""))
        times["export"] = time.perf_counter() - t0

        t0 = step("validate and diagnose the FMU on every recording; improve")
        res = improve(fmu, recs, out / f"{name}-improved.fmu", report_dir=out / "improved" if figures else None,
                      before_report_dir=out / "validate" if figures else None, progress=lambda m: say(f"   {m}"))
        native_improved = None
        if native is not None:
            try:
                native_improved = build_fmu(res["maps"], out / f"{name}-improved-native.fmu", backend="c")
            except SolenoidError as exc:
                say(f"   improved native FMU not built: {exc}")
        times["improve"] = time.perf_counter() - t0
        heat = "heating" in res["effects_added"]
        # heating fitted but rejected while a B(H) error is left: the B(H) identified from the heating-drifted
        # flux may itself be what spoiled the heating's validation (the material error swamps it)
        tried_heat = next((st["params"] for st in res["steps"] if st["effect"] == "heating" and st["params"]), None)
        heat_suspected = not heat and tried_heat is not None and res["diagnoses"][-1]["verdict"] == "material"
        # the identification integrated eq. 4 with the campaign's resistance tracks: its flux carries no
        # heating drift, a second round would only repeat it
        tracks_used = bool(ident.extra.get("resistance_tracks_used"))
        if round_no == 2 or tracks_used or not (heat or heat_suspected):
            break
        # Coil heating was found: the flux recordings the identification used carried the heating's eq.-4
        # drift (a B(H) error that the diagnosis may not be able to separate from the other effects left).
        # Correct them with the fitted heating model and identify again.
        say("== coil heating was " + ("added" if heat else "fitted, B(H) error left") +
            ": identify B(H) again from heating-corrected flux")
        heating = tables_from_fmu(res["improved_fmu"]).meta["effects"]["heating"] if heat else tried_heat
        corr_dir = out / "heating-corrected"
        corr_dir.mkdir(parents=True, exist_ok=True)
        ident_recs = [heating_corrected(r, heating) if r.kind in HEATING_CORRECTED_KINDS else r for r in recs]
        ident_paths = [write_recording(corr_dir / r.path.name, c) if r.kind in HEATING_CORRECTED_KINDS else r.path
                       for r, c in zip(recs, ident_recs, strict=True)]
        ident_recs = [read_recording(p) for p in ident_paths]
        first_round = {"effects_added": res["effects_added"], "identification": ident.summary(),
                       "final_verdict": res["diagnoses"][-1]["verdict"]}
        suffix = " (heating-corrected)"

    t0 = step("report")
    errors = []
    for row in res["recordings"]:
        for sig, m in row["signals"].items():
            errors.append({"file": row["file"], "signal": sig, "split": row["split"], "before": m["before"],
                           "after": m["after"], "before_nrmse": m["before_nrmse"], "after_nrmse": m["after_nrmse"],
                           "before_nrmse_fs": m["before_nrmse_fs"], "after_nrmse_fs": m["after_nrmse_fs"]})
    summary = {
        "campaign": str(folder), "material": str(material_csv), "maps": str(maps_dir), "fmu": str(fmu),
        "native_fmu": None if native is None else str(native), "improved_fmu": res["improved_fmu"],
        "improved_native_fmu": None if native_improved is None else str(native_improved),
        "improved_maps": res["maps"], "effects_added": res["effects_added"],
        "effects_found": effects_found(res["effects_added"], eddy), "errors": errors,
        "not_identifiable": res.get("not_identifiable", {}),
        "diagnosis": res["diagnoses"][0] if res["diagnoses"] else None, "improve_steps": res["steps"],
        "identification": ident_summary,
        "eddy": None if eddy is None else eddy.as_dict(), "recordings": [str(p) for p in paths],
        "skipped_files": [str(p) for p in skipped], "preset": preset, "times_s": times,
        "first_round": first_round,
    }
    html_path = write_campaign_report(out / "report.html", name, summary, ident, res, res["before"])
    summary["report"] = str(html_path)
    times["report"] = time.perf_counter() - t0
    times["total"] = time.perf_counter() - t_all
    atomic_write_text(out / "summary.json", json.dumps(jsonable(summary), indent=1) + "\n")
    return summary


def add_cli(sub) -> None:
    """Register ``solenoid-fmu pipeline``."""
    p = sub.add_parser("pipeline", help="the main job: identify, maps, eddy, FMU, validate, diagnose, improve, report")
    p.add_argument("campaign", help="campaign folder with recordings (CSV, format v1)")
    p.add_argument("-o", "--output", required=True, help="output directory")
    p.add_argument("--geometry", help="geometry TOML (default: the packaged PS45)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="full",
                   help="FEM grid quality: full (default), quick (coarse, for checks) or smoke (coarsest, tests)")
    p.add_argument("--workers", type=_workers, help="processes for the maps sweep (default: all cores)")
    p.add_argument("--json", action="store_true", help="print summary.json's content on stdout")
    p.set_defaults(func=_cli)


def _workers(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return n


def _cli(args) -> int:
    s = run_pipeline(args.campaign, args.output, geometry=args.geometry, preset=args.preset, workers=args.workers)
    if args.json:
        print(json.dumps(jsonable(s)))
        return 0
    print("\n".join(effects_summary_lines(s)))
    print(f"{'file':<28} {'signal':<10} {'NRMSE(FS) before':>17} {'after':>9}")
    for e in s["errors"]:
        b = "n/a" if e["before_nrmse_fs"] is None else f"{e['before_nrmse_fs'] * 100:.3f} %"
        a = "n/a" if e["after_nrmse_fs"] is None else f"{e['after_nrmse_fs'] * 100:.3f} %"
        print(f"{e['file']:<28} {e['signal']:<10} {b:>17} {a:>9}")
    print(f"total {s['times_s']['total']:.0f} s; report: {s['report']}")
    return 0
