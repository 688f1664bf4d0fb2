"""Identify B(H) from a campaign's recordings (the pipeline's entry point): pick the flux
recordings, build the measured commutation curve, fit, write the curve files and the report."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..errors import RecordingError
from ..measure import commutation_curve, misspelt_in, read_unipolar
from .campaign_data import HOLD_KINDS, corrected_curve, flux_points, force_points, hold_points
from .fit import DEFAULT_MESH_SIZE, DEFAULT_N_CURRENTS, choose_currents, identify_bh
from .flux_model import as_curve, as_geometry
from .io import write_curve_files
from .joint import identify_joint
from .joint_result import result_from_joint
from .measured import absolute_flux, group_flux, groups_of
from .point_pool import default_workers
from .prediction import prediction_band, prediction_warnings
from .report import write_report
from .result import IdentificationResult
from .virgin_side import on_virgin_side

__all__ = ["identify_from_recordings"]


def identify_from_recordings(recordings, *, geometry=None, start_material=None, mesh_size=None, out_csv=None,
                             report_dir=None, progress=True, method: str = "gn", n_currents: int = DEFAULT_N_CURRENTS,
                             workers: int | None = None, prediction: bool = True, **kwargs) -> IdentificationResult:
    """Identify B(H) from test-rig recordings (the pipeline's entry point).

    Parameters
    ----------
    recordings : iterable of path or Recording
        Recordings (CSV files, format v1, or :class:`~solenoid_fmu.measure.Recording` in memory) of any kinds; the
        ``flux`` ones (by header kind) are used: the stroke with the most of them is identified, flux at other
        strokes and ``force_stroke`` recordings validate (report). Other kinds are ignored.
    geometry : Geometry or path, optional
        Default: packaged PS45.
    start_material : BHCurve or path, optional
        Start curve (default: the literature curve).
    mesh_size : float, optional
        FEM mesh size (default :data:`DEFAULT_MESH_SIZE`).
    out_csv : path, optional
        Write the curve there (+ ``.bh`` and ``.tab`` beside it).
    report_dir : path, optional
        Write figures (paper figs. 10, 11, 15-17; also kept in memory, ``figures`` of the result) and
        ``identification.json``.
    progress : bool
        Progress bar on stderr.
    method : {"gn", "auglag"}
    n_currents : int
        Currents of the measured commutation curve used by the fit (:func:`choose_currents`).
    workers : int, optional
        Processes that solve the joint fit's FEM points (method ``gn``), whole strokes each; default: the cores
        this process may use, at most 4 (:func:`~.point_pool.default_workers`); the curve does not depend on it.
    prediction : bool
        Method ``gn``: Psi and F on the working range with the 1-sigma the campaign leaves (summary ``prediction``,
        warned where twice it exceeds the goal; :mod:`.prediction`, ~3 s at the default mesh). False skips it.
    **kwargs
        Passed to :func:`identify_bh` (``auglag``) or :func:`~.joint.identify_joint` (``gn``).

    Raises
    ------
    RecordingError
        No ``flux`` recording (or unreadable ones), or none whose branches give a commutation curve.
    """
    recs, flux, unusable, turned = _flux_recordings(recordings)
    geom = as_geometry(geometry)
    start = as_curve(start_material)
    mesh_size = DEFAULT_MESH_SIZE if mesh_size is None else float(mesh_size)
    main, others = group_flux(flux)
    bar = None
    cb = None
    if progress:
        bar = tqdm(desc=f"identify B(H) ({method})", unit="FEM evaluation", file=sys.stderr)

        def cb(n, rms):  # auglag: the relative flux RMS; the joint fit: the RMS of all points in sigma units
            bar.update(1)
            bar.set_postfix_str(f"flux RMS {rms * 100:.3f} %" if method == "auglag" else f"RMS {rms:.2f} sigma")
    try:
        if method == "auglag":  # the paper's method: one stroke, flux only
            res, cc, others_used = _by_auglag(main, others, geom, start, mesh_size, cb, n_currents, kwargs)
        else:
            res, cc, others_used = _by_joint_fit(recs, flux, unusable, geom, start, mesh_size, cb, n_currents,
                                                 {**kwargs, "workers": workers}, prediction)
    finally:
        if bar is not None:
            bar.close()
    if turned:
        res.extra["notes"] = turned + list(res.extra.get("notes", []))
    res.extra["measured_commutation"] = {"i_A": [float(v) for v in cc.i_A], "psi_Wb": [float(v) for v in cc.psi_Wb]}
    if out_csv is not None:
        write_curve_files(res, out_csv, sources=[r.path for r in main])
    if report_dir is not None:
        write_report(res, report_dir, geometry=geom, other_flux=others_used,
                     force_recordings=[r for r in recs if r.kind == "force_stroke"])
    return res


def _flux_recordings(recordings) -> tuple[list, list, list[str], list[str]]:
    """(every recording, those with a rig's negative current mirrored; the flux recordings to identify from; why
    each other one was left out: bipolar, :func:`~solenoid_fmu.measure.unipolar`, or not absolute,
    :func:`~.measured.absolute_flux`; what was mirrored and the header keys and columns not read for looking like
    misspelt ones, :func:`~solenoid_fmu.measure.misspelt_in`), both lists also printed. Raises RecordingError where
    no flux recording is left."""
    recs, turned, bipolar = read_unipolar(recordings)
    flux = [r for r in recs if r.kind == "flux"]
    if not flux:
        raise RecordingError("identify", [f"no 'flux' recording among {len(recs)} file(s): "
                                          + ", ".join(f"{Path(r.path).name if r.path else 'in memory'} ({r.kind})"
                                                      for r in recs)] + bipolar)
    flux, unusable = absolute_flux(flux)
    unusable = bipolar + unusable
    if not flux:
        raise RecordingError("identify", unusable)
    turned = turned + misspelt_in(recs)  # a misspelt header resistance or stroke is read as missing: say so
    for line in turned:
        print(f"identify: {line}", file=sys.stderr)
    for why in unusable:
        print(f"identify: left out {why}", file=sys.stderr)
    return recs, flux, unusable, turned


def _by_auglag(main: list, others, geom, start, mesh_size: float, cb, n_currents: int, kwargs: dict):
    """Method ``auglag`` of :func:`identify_from_recordings` (the paper's): the commutation curve at one stroke,
    flux only. The result, the commutation curve and the other strokes' flux recordings for the report."""
    cc = commutation_curve(main)
    com_i, com_psi, half = corrected_curve(cc, 0.0)  # the joint fit's branch means (virgin_and_top)
    i_sel, psi_sel = choose_currents(com_i, com_psi, n_currents)
    sigma = np.interp(i_sel, com_i, half)
    res = identify_bh(i_sel, psi_sel, cc.position_m, geom, start, mesh_size=mesh_size, method="auglag",
                      progress=cb, sigma_Wb=sigma, **kwargs)
    res.extra["recordings"] = [str(r.path) for r in main]
    return res, cc, others


def _by_joint_fit(recs: list, flux: list, unusable: list, geom, start, mesh_size: float, cb, n_currents: int,
                  kwargs: dict, prediction: bool = True):
    """The joint fit of :func:`identify_from_recordings` (method ``gn``): flux points at every stroke, force and
    hold points. The result, the commutation curve of the stroke with the most flux recordings, and ``()``."""
    force_recs = [r for r in recs if r.kind == "force_stroke"]
    eddy = [r for r in recs if r.kind == "eddy" and r.voltage_V is not None]
    # the coil's heating rate from every current-driven recording at a fixed stroke (a ramp's hold pins it)
    heat = [r for r in recs if r.kind in ("ramp", "eddy") and r.voltage_V is not None]
    pts, notes, details = flux_points(flux, n_currents, choose_currents, eddy_recs=eddy, heat_recs=heat)
    if not details["strokes"]:
        raise RecordingError("identify", details["left_out"])
    fpts, fnotes = force_points(force_recs)
    hold_recs = [r for r in recs if r.kind in HOLD_KINDS and r.voltage_V is not None]
    remanence = max((float(np.max(d["half_width_Wb"], initial=0.0)) for d in details["strokes"].values()),
                    default=0.0)
    hpts, hnotes = hold_points(hold_recs, details["camp"], details["heated"], 2.0 * remanence)
    fpts, shift_note = on_virgin_side(fpts + hpts, details["strokes"], details["G_eddy_S"])
    fnotes = fnotes + hnotes + ([shift_note] if shift_note else [])
    fit = identify_joint(pts + fpts, geom, start, mesh_size, progress=cb, **kwargs)
    cc = details["strokes"][max(details["strokes"], key=lambda k: len(groups_of(flux)[k]))]["cc"]
    res = result_from_joint(fit, start, mesh_size, {
        "recordings": [str(r.path) for r in flux],
        "force_recordings": [str(r.path) for r in force_recs],
        "notes": notes + fnotes + [f"left out {why}" for why in unusable],
        "G_eddy_loops_S": details["G_eddy_S"], "resistance": details["resistance"],
        "resistance_tracks_used": details["heated"]})
    if prediction:
        band = prediction_band(fit, geom, mesh_size, res.extra["B_uncertainty"]["noise_scale"],
                               workers=default_workers() if kwargs.get("workers") is None else kwargs["workers"])
        res.extra["prediction"] = {k: np.asarray(v).tolist() for k, v in band.items()}
        res.extra["warnings"] += prediction_warnings(band)
    for w in res.extra["warnings"]:
        print(f"identify: warning: {w}", file=sys.stderr)
    return res, cc, ()
