"""The identification report: figures like the paper's 10, 11 and 15-17, validation against the other
recordings (FEM with the start and the identified curve) and ``identification.json``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import RecordingError
from ..fileio import atomic_write_bytes, atomic_write_text
from ..measure import commutation_curve
from .fit import choose_currents
from .flux_model import as_geometry, fem_flux, fem_force_vs_stroke
from .measured import force_stroke_curve
from .plots import plot_bh, plot_flux_fit, plot_flux_other_strokes, plot_force_stroke
from .result import IdentificationResult

__all__ = ["write_report"]


def _rel_rms(a, b, scale) -> float:
    return float(np.sqrt(np.mean(((np.asarray(a) - np.asarray(b)) / scale) ** 2)))


def write_report(result: IdentificationResult, report_dir, *, geometry=None, other_flux=(),
                 force_recordings=()) -> dict:
    """Figures like the paper's 10, 11 and 15-17 and ``identification.json`` into ``report_dir``.

    - ``fig10_flux.png``: measured commutation Psi(i), FEM with the start and the identified curve.
    - ``fig11_bh.png``: B(H) before and after, identified H range shaded, 1-sigma band of B.
    - ``fig15_force_stroke.png``: force vs stroke per ``force_stroke`` recording (friction averaged
      out), FEM with both curves (if any such recording).
    - ``fig16_flux_other_strokes.png``: Psi(i) at the other strokes with flux recordings (if any).
    The JSON is :meth:`IdentificationResult.summary` plus the validation errors (relative RMS).
    Returns the summary dict; the figures are also kept in memory, ``result.figures`` (file name -> PNG bytes:
    the pipeline's report embeds them without reading the files back).
    """
    out = Path(report_dir)
    out.mkdir(parents=True, exist_ok=True)
    geom = as_geometry(geometry)
    r = result
    summary = r.summary()
    summary.pop("measured_commutation", None)
    ms = r.mesh_size
    r.figures = {}

    def keep(name: str, png: bytes) -> None:
        atomic_write_bytes(out / name, png)
        r.figures[name] = png

    keep("fig10_flux.png", plot_flux_fit(r, summary))
    keep("fig11_bh.png", plot_bh(r))
    validation: dict = {}
    if force_recordings:
        rows, curves = [], []
        for k, rec in enumerate(force_recordings):
            try:
                fc = force_stroke_curve(rec)
            except RecordingError as err:
                rows.append({"file": str(rec.path), "error": str(err)})
                continue
            x = fc["x_m"]
            xs = np.linspace(x.min(), x.max(), 8)
            f0 = fem_force_vs_stroke(geom, r.start_curve, fc["i_A"], xs, ms)
            f1 = fem_force_vs_stroke(geom, r.curve, fc["i_A"], xs, ms)
            fm_ = np.interp(xs, x, fc["force_N"])
            sc = float(np.max(np.abs(fm_)))
            rows.append({"file": Path(str(rec.path)).name, "i_A": fc["i_A"], "rms_rel_before": _rel_rms(f0, fm_, sc),
                         "rms_rel_after": _rel_rms(f1, fm_, sc)})
            curves.append((k, fc, xs, f0, f1))
        keep("fig15_force_stroke.png", plot_force_stroke(curves))
        validation["force_stroke"] = rows
    if other_flux:
        rows, curves = [], []
        for k, group in enumerate(other_flux):
            cc = commutation_curve(group)
            i_sel, psi_m = choose_currents(cc.i_A, cc.psi_Wb, 8)
            p0 = fem_flux(geom, r.start_curve, i_sel, cc.position_m, ms)
            p1 = fem_flux(geom, r.curve, i_sel, cc.position_m, ms)
            sc = float(np.max(np.abs(psi_m)))
            rows.append({"x_mm": cc.position_m * 1e3, "rms_rel_before": _rel_rms(p0, psi_m, sc),
                         "rms_rel_after": _rel_rms(p1, psi_m, sc)})
            curves.append((k, cc, i_sel, p0, p1))
        keep("fig16_flux_other_strokes.png", plot_flux_other_strokes(curves))
        validation["flux_other_strokes"] = rows
    summary["validation"] = validation
    atomic_write_text(out / "identification.json", json.dumps(summary, indent=2) + "\n")
    return summary
