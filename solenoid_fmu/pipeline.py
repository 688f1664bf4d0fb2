"""The main job: from a campaign folder of recordings to a validated, improved FMU with one report.

``solenoid-fmu pipeline fitting/NAME -o build/NAME`` runs, with progress on stderr:

1. **recordings**: every ``*.csv`` under the folder whose first line is the recording format's
   ``# recording:`` line (kinds from the headers; folders named ``truth`` are never entered, and
   files that are not recordings are listed as skipped);
2. **identify**: B(H) from the ``flux`` recordings (:mod:`solenoid_fmu.identification`) ->
   ``material/material.csv`` (+ ``.bh``, ``.tab``) and ``identify/`` (figures, JSON);
3. **maps**: FEM sweep with the identified steel -> ``maps/`` (:func:`solenoid_fmu.maps.build_maps`); the
   sweep's currents reach ``1.25 x`` the coil's rated current or ``1.25 x`` the largest |current| in the
   campaign's recordings, whichever is larger (:func:`solenoid_fmu.maps.maps_current_grid`), so the maps'
   flux range covers what was measured;
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
whose voltage is corrected with the fitted heating model (:func:`solenoid_fmu.loop.heating_corrected`, passed
in memory and written to ``heating-corrected/`` for the user); ``summary.json["first_round"]`` keeps what the first
round found.

``summary.json`` holds ``material``, ``fmu``, ``improved_fmu`` (paths), ``effects_added`` (the
words ``diagnose`` uses), ``effects_found`` (those and ``eddy`` where step 4 measured it,
:func:`effects_found`), ``errors`` (one row per recording and signal: RMS error ``before`` and
``after`` improvement in the signal's SI unit, and the same normalized by the measured range),
the diagnosis, the identification summary and the wall time of every step, and ``polarity``: the recordings
recorded with a negative current, taken mirrored, and the bipolar ones left out (:mod:`solenoid_fmu.measure.polarity`),
``header_resistance``: where every header resistance misses the data by one offset, that the headers were
shifted by it (:func:`solenoid_fmu.measure.headers.headers_from_data`), else null, and ``header_resistance_filled`` /
``header_resistance_missing``: the recordings without a header resistance that got one from their own data, and
those whose data do not pin it; ``names_not_read``: header keys and columns kept but not read for looking like
misspelt ones of ``recordings.md`` (``coil_resistance_Ohm``: the recording is taken as one without a header R).

Outputs are written to fresh files (atomic writes); a failing step stops the pipeline with its
error and leaves the results of the steps before it in place. Only one pipeline writes a folder at a time
(a lock; a second is refused). From its start until ``summary.json`` is written, the folder holds
``pipeline.incomplete`` (:data:`INCOMPLETE_MARKER`) and no ``summary.json`` or ``report.html``: a run that
was interrupted or failed over an earlier complete one leaves a folder that says it is mixed
(:func:`pipeline_incomplete`); a folder with ``summary.json`` and no marker is one complete run.
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import time
from pathlib import Path

from .argtypes import process_count
from .errors import SolenoidError
from .field import load_geometry
from .fileio import atomic_write_text, dir_lock, jsonable, refuse_overwriting_inputs, require_directory
from .fmu import build_fmu, start_excess_K
from .identification import identify_from_recordings
from .loop import FluxCache, ambient_resistance, effects_summary_lines, heating_corrected, improve
from .maps import (
    CAMPAIGN_CURRENT_POWER,
    DEFAULT_CURRENT_POWER,
    InlineExecutor,
    build_maps,
    default_positions,
    maps_current_grid,
    name_problem,
    process_pool,
    save_maps,
    with_fitted_eddy,
)
from .measure import headers_from_data, misspelt_in, read_recording, unipolar, write_recording
from .report import write_campaign_report

#: Grid presets of the FEM steps: "full" is the shipped quality, "quick" a coarse check (tests), "smoke" the
#: coarsest that still runs every step (a production lot's tests, ``solenoid-fmu batch --preset smoke``: a
#: coarser identification mesh, 4 currents per stroke, at most ``identify_max_nfev`` Levenberg-Marquardt
#: evaluations per stage, a 4 x 6 maps grid, no figures (``figures``: the report.html without them) and no native
#: FMU (``native``); ~12 s of CPU per unit on the end-of-line campaign, not product quality). "quick" stops
#: stage 2 of the identification after 16 evaluations (the default 32 converges the harder steels; the demo
#: steel is within a few per cent of its truth after 16). "medium" is "quick" with a 24 x 18 maps grid (four
#: times its operating points): on issue 20's twelve campaigns quick's 9 x 12 grid left 1.3-1.5 % of full scale
#: in the force at 1.8-1.9 A by interpolation alone, and it set the loop's verdict: random-1's error cut 0.34 on
#: quick, 0.21 on 12 x 18, 0.16 on full (tests/test_loop_identified.py runs medium). 24 positions since stop 37:
#: the maps are read linearly in x, and on 12 the force strokes of random-1 (an eddy ladder) kept a residual
#: wavy in x (-0.2 N at 1 mm, 0 at the position 1.6 mm, -0.18 N at 3 mm; the same on both passes) that a
#: Preisach term took up as hysteresis; on 24 the loop adds the ladder alone, and random-0's cut went 0.67 -> 0.46.
#: Since stop 38 "medium" runs the FEM at 12 positions and puts two columns into each interval by a cubic spline
#: in x (``refine_x``, :mod:`solenoid_fmu.maps.refine`): 34 columns for the FEM cost of 12. Against a 47-position
#: FEM of random-1's identified steel (0.2-2 A): F RMS 0.051 N (max 0.23 N), i_f RMS 0.06 mA, where 24 FEM
#: positions read linearly gave 0.071 N (0.34 N) and 0.09 mA, and 12 gave 0.30 N (1.35 N) and 0.41 mA.
PRESETS = {
    "full": {"identify_mesh_size": None, "maps_mesh_size": 1.0, "n_x": None, "n_i": None, "n_currents": 10,
             "i_power": CAMPAIGN_CURRENT_POWER},
    "quick": {"identify_mesh_size": None, "maps_mesh_size": 2.0, "n_x": 9, "n_i": 12, "n_currents": 6,
              "identify_max_nfev": 16},
    "medium": {"identify_mesh_size": None, "maps_mesh_size": 2.0, "n_x": 12, "refine_x": 3, "n_i": 18,
               "n_currents": 6, "identify_max_nfev": 16, "i_power": CAMPAIGN_CURRENT_POWER},
    "smoke": {"identify_mesh_size": 4.0, "maps_mesh_size": 3.0, "n_x": 4, "n_i": 6, "n_currents": 4,
              "identify_max_nfev": 2, "figures": False, "native": False, "prediction": False},
}


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


def _maps_grid(preset: dict, geometry, recordings=()):
    """Positions [m] and currents [A] of the maps sweep for a preset and campaign (None: the maps' defaults)."""
    x = None
    if preset["n_x"] is not None:
        x = default_positions(geometry.stroke.min_m, geometry.stroke.max_m, preset["n_x"])
    power = preset.get("i_power", DEFAULT_CURRENT_POWER)
    return x, maps_current_grid(geometry.coil.max_current_A, recordings, preset["n_i"], power)


def campaign_maps(geometry, curve, recordings, eddy_recordings=None, *, preset: str = "full", executor=None,
                  name: str = "identified", progress=None) -> tuple:
    """Steps 3 and 4 in memory: the characteristic maps of the identified steel, with the eddy conductance.

    Parameters
    ----------
    geometry : Geometry
    curve : BHCurve
        The identified steel.
    recordings : list of Recording
        The campaign (the sweep's current range covers their largest |current|,
        :func:`solenoid_fmu.maps.maps_current_grid`).
    eddy_recordings : list of Recording, optional
        Where G_eddy is fitted from (default: the ``eddy`` recordings among ``recordings``; the pipeline's
        second round passes the heating-corrected ones).
    preset : {"full", "medium", "quick", "smoke"}
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
                      executor=executor or InlineExecutor(), progress=progress is not None, name=name,
                      refine_x=cfg.get("refine_x", 1))
    eddy_recs = [r for r in (recordings if eddy_recordings is None else eddy_recordings) if r.kind == "eddy"]
    if not eddy_recs:
        say("   no eddy recording: G_eddy stays 0")
        return maps, None
    maps, eddy = with_fitted_eddy(maps, eddy_recs)
    say(f"   G_eddy = {eddy.G_model_S * 1e3:.4g} mS (R^2 {eddy.r2:.3f}); {eddy.message}")
    return maps, eddy


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


class _Run:
    """One pipeline run's settings, output folder, progress and step timer (:func:`_run_pipeline`)."""

    def __init__(self, folder, out_dir, *, geometry, preset: str, workers, progress, start_material):
        if preset not in PRESETS:
            raise PipelineError(f"unknown preset {preset!r}; use one of {', '.join(PRESETS)}")
        self.preset, self.cfg = preset, PRESETS[preset]
        self.figures = self.cfg.get("figures", True)
        self.say = progress or (lambda msg: None)
        self.progress = progress
        self.folder, self.out = Path(folder), _output_dir(folder, out_dir)
        self.out.mkdir(parents=True, exist_ok=True)
        self.name = self.folder.resolve().name
        self.geometry, self.workers, self.start_material = geometry, workers, start_material
        self.times: dict = {}
        # recordings taken mirrored or left out, headers shifted (step 1)
        self.polarity: dict = {"mirrored": [], "left_out": [], "header_resistance": None,
                               "header_resistance_filled": [], "header_resistance_missing": [], "names_not_read": []}
        self.t_all = time.perf_counter()

    def step(self, label: str) -> float:
        self.say(f"== {label}")
        return time.perf_counter()

    def done(self, key: str, t0: float) -> None:
        self.times[key] = time.perf_counter() - t0

    def figures_dir(self, name: str):
        return self.out / name if self.figures else None


def _read_campaign(run: _Run):
    """Step 1: the campaign's recordings (paths, records, skipped files) and the geometry."""
    t0 = run.step(f"recordings in {run.folder}")
    paths, skipped = find_recordings(run.folder)
    recs, turned, left = unipolar([read_recording(p) for p in paths])
    recs, shifted, filled, missing = headers_from_data(recs)
    run.polarity = {"mirrored": turned, "left_out": left, "header_resistance": shifted,
                    "header_resistance_filled": filled, "header_resistance_missing": missing,
                    "names_not_read": misspelt_in(recs)}
    kinds: dict = {}
    for r in recs:
        kinds[r.kind] = kinds.get(r.kind, 0) + 1
    run.say("   " + ", ".join(f"{n} {k}" for k, n in kinds.items())
            + (f"; skipped {len(skipped)} other CSV" if skipped else ""))
    for line in (turned + [f"left out {w}" for w in left] + [shifted] * bool(shifted) + filled + missing
                 + run.polarity["names_not_read"]):
        run.say(f"   {line}")
    if "flux" not in kinds:
        raise PipelineError(f"{run.folder}: no 'flux' recording: the B(H) identification needs one"
                            + "".join(f"; left out {w}" for w in left))
    geom = load_geometry(run.geometry)
    run.done("recordings", t0)
    return paths, skipped, recs, geom


def _identify(run: _Run, geom, ident_recs, suffix: str):
    """Step 2: B(H) from the flux recordings in memory (``material/``, ``identify/``; the figures also in memory)."""
    t0 = run.step(f"identify B(H) from the flux recordings{suffix}")
    cfg = run.cfg
    max_nfev = {"max_nfev": cfg["identify_max_nfev"]} if "identify_max_nfev" in cfg else {}
    ident = identify_from_recordings(ident_recs, geometry=geom, mesh_size=cfg["identify_mesh_size"],
                                     start_material=run.start_material, out_csv=run.out / "material" / "material.csv",
                                     report_dir=run.figures_dir("identify"), progress=run.progress is not None,
                                     n_currents=cfg["n_currents"], workers=run.workers,
                                     prediction=cfg.get("prediction", True), **max_nfev)
    sweeps = ident.summary().get("equivalent_sweeps", float("nan"))
    run.say(f"   flux error (RMS of peak) {ident.rms_before * 100:.2f} % -> {ident.rms_after * 100:.2f} %, "
            f"{sweeps:.0f} equivalent sweeps, {ident.wall_time_s:.0f} s")
    run.done("identify", t0)
    return ident


def _maps(run: _Run, geom, curve, recs, eddy_recs):
    """Steps 3 and 4: the maps with G_eddy, in memory, and written to ``maps/`` for the user."""
    t0 = run.step("characteristic maps (FEM sweep with the identified steel), eddy-current parameter")
    executor = InlineExecutor() if run.workers == 1 else process_pool(run.workers)
    try:
        maps, eddy = campaign_maps(geom, curve, recs, eddy_recs, preset=run.preset, executor=executor,
                                   name=f"{run.name}-identified",
                                   progress=run.say if run.progress is not None else None)
    finally:
        executor.shutdown()
    save_maps(maps, run.out / "maps")
    run.done("maps", t0)
    return maps, eddy


def _native(run: _Run, maps, dest: Path, what: str):
    """The native FMU of ``maps`` at ``dest``, or None (not wanted by the preset, or no C compiler here)."""
    if not run.cfg.get("native", True):
        return None
    try:
        return build_fmu(maps, dest, backend="c")
    except SolenoidError as exc:  # no C compiler on this machine: the pythonfmu export still stands
        run.say(f"   {what} not built: {exc}")
        return None


def _export(run: _Run, maps):
    """Step 5: the pythonfmu FMU and its native twin, from the maps in memory."""
    t0 = run.step("export the FMU")
    fmu = build_fmu(maps, run.out / f"{run.name}.fmu")
    native = _native(run, maps, run.out / f"{run.name}-native.fmu", "native FMU")
    run.say(f"   {fmu}" + (f", {native}" if native else ""))
    run.done("export", t0)
    return fmu, native


def _improve(run: _Run, maps, recs, fmu, native, eddy=None):
    """Steps 6 and 7: validate, diagnose and improve the model of ``maps`` (that of ``fmu``; ``eddy`` its eddy fit,
    whose measured eddy current lets the loop try the ladder); the improved FMUs."""
    t0 = run.step("validate and diagnose the FMU on every recording; improve")
    res = improve(maps, recs, run.out / f"{run.name}-improved.fmu", report_dir=run.figures_dir("improved"),
                  before_report_dir=run.figures_dir("validate"), progress=lambda m: run.say(f"   {m}"),
                  source=str(fmu), eddy_measured=eddy is not None and eddy.measurable)
    native_improved = None
    if native is not None:
        native_improved = _native(run, res.maps, run.out / f"{run.name}-improved-native.fmu", "improved native FMU")
    run.done("improve", t0)
    return res, native_improved


def _second_round_heating(res, ident) -> dict | None:
    """The heating section to correct the flux recordings with before identifying again, or None.

    Heating was added, or fitted but rejected while a B(H) error is left (the B(H) identified from the
    heating-drifted flux may itself be what spoiled the heating's validation); not when the identification
    integrated eq. 4 with the campaign's resistance tracks (its flux carries no heating drift)."""
    if ident.extra.get("resistance_tracks_used"):
        return None
    if "heating" in res.effects_added:
        return res.tables.effects.heating
    tried = next((st.params for st in res.steps if st.effect == "heating" and st.params), None)
    if tried is not None and res.diagnoses[-1]["verdict"] == "material":
        return tried
    return None


def _heating_corrected_campaign(run: _Run, recs, heating: dict):
    """The recordings with the voltage of :data:`HEATING_CORRECTED_KINDS` corrected for ``heating``, in memory,
    each from its start above ambient (the campaign's coldest resistance, as the loop starts the model's runs;
    each corrected one also written to ``heating-corrected/`` for the user: nothing reads it back)."""
    corr_dir = run.out / "heating-corrected"
    corr_dir.mkdir(parents=True, exist_ok=True)
    ambient = ambient_resistance(recs, FluxCache())
    out_recs = []
    for r in recs:
        if r.kind not in HEATING_CORRECTED_KINDS:
            out_recs.append(r)
            continue
        corrected = heating_corrected(r, heating, T_start_excess_K=start_excess_K(r.coil_resistance_ohm, ambient,
                                                                                 heating["alpha_per_K"]))
        path = write_recording(corr_dir / r.path.name, corrected)
        out_recs.append(dataclasses.replace(corrected, path=path))
    return out_recs


def _run_pipeline(folder, out_dir, *, geometry=None, preset: str = "full", workers: int | None = None,
                  progress=_progress, start_material=None) -> dict:
    run = _Run(folder, out_dir, geometry=geometry, preset=preset, workers=workers, progress=progress,
               start_material=start_material)
    paths, skipped, recs, geom = _read_campaign(run)
    ident_recs, first_round, suffix = recs, None, ""
    for round_no in (1, 2):
        ident = _identify(run, geom, ident_recs, suffix)
        maps, eddy = _maps(run, geom, ident.curve, recs, ident_recs)
        fmu, native = _export(run, maps)
        res, native_improved = _improve(run, maps, recs, fmu, native, eddy)
        heating = None if round_no == 2 else _second_round_heating(res, ident)
        if heating is None:
            break
        # the flux recordings the identification used carried the heating's eq.-4 drift (a B(H) error that the
        # diagnosis may not be able to separate from the other effects left): corrected, identify again
        run.say("== coil heating was " + ("added" if "heating" in res.effects_added else "fitted, B(H) error left")
                + ": identify B(H) again from heating-corrected flux")
        ident_recs = _heating_corrected_campaign(run, recs, heating)
        first_round = {"effects_added": res.effects_added, "identification": ident.summary(),
                       "final_verdict": res.diagnoses[-1]["verdict"]}
        suffix = " (heating-corrected)"
    t0 = run.step("report")
    summary = _summary(run, paths, skipped, ident, maps, eddy, (fmu, native, native_improved), res, first_round)
    html_path = write_campaign_report(run.out / "report.html", run.name, summary, ident, res.as_dict(), res.before,
                                      images=res.images)
    summary["report"] = str(html_path)
    run.done("report", t0)
    run.times["total"] = time.perf_counter() - run.t_all
    atomic_write_text(run.out / "summary.json", json.dumps(jsonable(summary), indent=1) + "\n")
    return summary


def _summary(run: _Run, paths, skipped, ident, maps, eddy, fmus, res, first_round) -> dict:
    """``summary.json``'s content (module docstring), without the report's path."""
    fmu, native, native_improved = fmus
    errors = []
    for row in res.recordings:
        for sig, m in row["signals"].items():
            errors.append({"file": row["file"], "signal": sig, "split": row["split"], "before": m["before"],
                           "after": m["after"], "before_nrmse": m["before_nrmse"], "after_nrmse": m["after_nrmse"],
                           "before_nrmse_fs": m["before_nrmse_fs"], "after_nrmse_fs": m["after_nrmse_fs"]})
    return {
        "campaign": str(run.folder), "material": str(run.out / "material" / "material.csv"),
        "maps": str(run.out / "maps"), "fmu": str(fmu),
        "native_fmu": None if native is None else str(native), "improved_fmu": str(res.improved_fmu),
        "improved_native_fmu": None if native_improved is None else str(native_improved),
        "improved_maps": str(res.maps_dir), "effects_added": res.effects_added,
        "effects_found": effects_found(res.effects_added, eddy), "errors": errors,
        "not_identifiable": res.not_identifiable,
        "diagnosis": res.diagnoses[0] if res.diagnoses else None, "improve_steps": [s.as_dict() for s in res.steps],
        "identification": ident.summary(),
        "eddy": None if eddy is None else eddy.as_dict(), "recordings": [str(p) for p in paths],
        "skipped_files": [str(p) for p in skipped], "polarity": run.polarity, "preset": run.preset,
        "times_s": run.times, "first_round": first_round,
    }


def add_cli(sub) -> None:
    """Register ``solenoid-fmu pipeline``."""
    p = sub.add_parser("pipeline", help="the main job: identify, maps, eddy, FMU, validate, diagnose, improve, report")
    p.add_argument("campaign", help="campaign folder with recordings (CSV, format v1)")
    p.add_argument("-o", "--output", required=True, help="output directory")
    p.add_argument("--geometry", help="geometry TOML (default: the packaged PS45)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="full",
                   help="FEM grid quality: full (default), medium (quick's meshes, a finer maps grid), quick (coarse, "
                   "for checks) or smoke (coarsest, tests)")
    p.add_argument("--workers", type=process_count,
                   help="processes for the identification's FEM points (at most 4 used) and the maps sweep "
                   "(default: all cores)")
    p.add_argument("--json", action="store_true", help="print summary.json's content on stdout")
    p.set_defaults(func=_cli)


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
