"""The campaign report of ``solenoid-fmu pipeline``: its sections from the pipeline's results, as one HTML file."""

from __future__ import annotations

import json
import math
import numbers
from pathlib import Path

from ..identification import h_range_text
from .html import errors_table, write_html_report

#: Longest note shown in the improvement table [characters]; longer ones end at a "; " with " ...".
NOTE_MAX_CHARS = 400


def note_text(note) -> str:
    """An improvement step's note as plain text: a JSON object (as ``improve`` stores fitted values) becomes
    ``key: value; ...`` (nested objects in parentheses, numbers with 4 significant digits); never cut
    inside a value: beyond :data:`NOTE_MAX_CHARS` the text ends at the last whole item with `` ...``."""
    if not note:
        return ""
    try:
        value = json.loads(note) if isinstance(note, str) else note
    except ValueError:
        value = note
    if not isinstance(value, dict):
        text = str(value)
        return text if len(text) <= NOTE_MAX_CHARS else text[:NOTE_MAX_CHARS].rsplit(" ", 1)[0] + " ..."
    items = [f"{k}: {_plain(v)}" for k, v in value.items()]
    out = ""
    for k, item in enumerate(items):
        nxt = item if not out else f"{out}; {item}"
        if len(nxt) > NOTE_MAX_CHARS:
            return (out or item[:NOTE_MAX_CHARS].rsplit(" ", 1)[0]) + f" ... ({len(items) - k} more)"
        out = nxt
    return out


def _plain(v) -> str:
    if isinstance(v, dict):
        return "(" + ", ".join(f"{k} {_plain(x)}" for k, x in v.items()) + ")"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_plain(x) for x in v) + "]"
    if isinstance(v, bool) or v is None:
        return str(v)
    if isinstance(v, numbers.Real):
        return f"{v:.4g}" if math.isfinite(v) else str(v)
    return str(v)


def write_campaign_report(path, name, summary, ident, res, before, images: dict | None = None) -> Path:
    """The pipeline's ``report.html``: summary, identification, eddy, diagnosis, improvement steps,
    errors before and after, validation figures.

    ``summary`` is the pipeline's summary dict (``summary.json``), ``ident`` the identification
    result (``rms_before``, ``rms_after``; ``figures``: its figures in memory, file name -> PNG, written to
    ``identify/`` beside ``material/``), ``res`` the result of :func:`solenoid_fmu.loop.improve` (its ``as_dict()``)
    and ``before`` its validation of the model before improvement; ``images`` (``{str(path): bytes}``,
    :attr:`solenoid_fmu.loop.ImproveResult.images`) the validation figures in memory. No figure file is read back.
    """
    ident_dir = Path(summary["material"]).parent.parent / "identify"
    ident_pngs = {str(ident_dir / name): png for name, png in sorted(ident.figures.items())}
    ident_figs = [Path(p) for p in ident_pngs]
    images = {**(images or {}), **ident_pngs}
    s = summary["identification"]
    sections = [
        {"heading": "Summary",
         "text": (f"Campaign {summary['campaign']}: {len(summary['recordings'])} recordings. "
                  f"Effects added to the real-time model: {', '.join(summary['effects_added']) or 'none'}.\n\n"
                  + "".join(f"{k}: not identifiable from these recordings: {v}\n"
                            for k, v in summary["not_identifiable"].items())
                  + "".join(f"Polarity: {line}\n" for line in summary.get("polarity", {}).get("mirrored", []))
                  + "".join(f"Left out: {line}\n" for line in summary.get("polarity", {}).get("left_out", []))
                  + "".join(f"Coil resistance: {line}\n" for line in _resistance_lines(summary.get("polarity", {})))
                  + "".join(f"Not read: {line}\n" for line in summary.get("polarity", {}).get("names_not_read", []))
                  + f"FMU: {summary['fmu']}\nImproved FMU: {summary['improved_fmu']}\n"
                  f"Identified material: {summary['material']}"),
         "table": summary_table(summary)},
        {"heading": "B(H) identification",
         "text": (f"Method {s.get('method')}, {s.get('status')}; flux error (RMS of peak) "
                  f"{ident.rms_before * 100:.3g} % with the start curve, {ident.rms_after * 100:.3g} % after; "
                  f"identified H range {h_range_text(s['identified_H_range_A_per_m'])}; {s.get('fem_solves')} "
                  "FEM solves, "
                  f"{s.get('wall_time_s', 0):.0f} s."
                  + "".join(f"\n{n}" for n in s.get("notes", []))
                  + "".join(f"\nWARNING: {w}" for w in s.get("warnings", []))),
         "figures": ident_figs},
        {"heading": "B(H) identification: prediction of points held out of the fit (paper figs. 16-17)",
         "text": (f"Chosen by held-out prediction: {s.get('chosen', 'n/a')}. Each group of measured points (a "
                  "stroke's flux, a band of currents, a force-stroke recording) is predicted by the fit without it; "
                  "errors in % of the measured values (flux: of the stroke's peak)."),
         "table": held_out_table(s)},
        {"heading": "B(H) identification: what the curve predicts on the working range, with its 1-sigma uncertainty",
         "text": ("Psi and F of the identified curve (FEM) on a grid of the working strokes and currents; the "
                  "uncertainty is what the campaign's points leave of it (linearized, every node of the curve free, "
                  "their sigmas scaled by the held-out error). Twice the sigma above 1 % (Psi) or 2 % (F) is warned "
                  "about above: the campaign does not pin the curve down there."),
         "table": prediction_table(s)},
        {"heading": "Eddy currents",
         "text": "No eddy recording." if summary["eddy"] is None else
         f"G_eddy = {summary['eddy']['G_model_S'] * 1e3:.4g} mS. {summary['eddy'].get('message', '')}"},
        {"heading": "Diagnosis of the FMU's residual",
         "text": f"Verdict: {summary['diagnosis']['verdict'] if summary['diagnosis'] else 'n/a'}.",
         "table": {"columns": ["effect", "score", "explained"],
                   "rows": [[c["effect"], c["score"], c["explained"]]
                            for c in (summary["diagnosis"] or {}).get("ranking", [])]}},
        {"heading": "Improvement steps",
         "text": "Each effect is fitted on the 'fit' recordings and kept only if the error on the 'validate' "
                 "recordings falls by at least 10 % (mean squared NRMSE by the full scale per kind, each capped at 1); "
                 "a refit (of an effect fitted along the eq.-4 flux, once coil heating is in the model) replaces "
                 "the earlier fit if that error falls.",
         "table": {"columns": ["effect", "kept", "validation error before", "after", "note"],
                   "rows": [[st["effect"] + (" (refit)" if st.get("refit") else ""), "yes" if st["accepted"] else "no",
                             st["heldout_error_before"],
                             st["heldout_error_after"], note_text(st["note"])] for st in summary["improve_steps"]]}},
        {"heading": "Errors before and after improvement (RMS, SI units)",
         "table": errors_table(res["before"], res["after"])},
        {"heading": "Validation of the improved FMU", "figures": res["after"].get("figures", [])},
        {"heading": "Validation of the FMU before improvement", "figures": before.get("figures", [])},
    ]
    return write_html_report(path, f"solenoid-fmu pipeline: {name}", sections, images=images)


def summary_table(summary) -> dict:
    """Mean full-scale NRMSE per signal before and after improvement, over the summary's error rows."""
    by_signal: dict = {}
    for e in summary["errors"]:
        if e["before_nrmse_fs"] is None or e["after_nrmse_fs"] is None:
            continue
        by_signal.setdefault(e["signal"], []).append((e["before_nrmse_fs"], e["after_nrmse_fs"]))
    rows = []
    for sig, vals in by_signal.items():
        b = sum(v[0] for v in vals) / len(vals)
        a = sum(v[1] for v in vals) / len(vals)
        rows.append([sig, len(vals), b, a, a / b if b else None])
    return {"columns": ["signal", "recordings", "mean NRMSE (full scale) before", "after", "ratio"], "rows": rows}


def prediction_table(ident_summary) -> dict:
    """The identified curve's Psi and F with their relative 1-sigma on the prediction grid
    (``identification.json`` ``prediction``); empty without one."""
    p = ident_summary.get("prediction")
    rows = []
    if p:
        for a, i in enumerate(p["i_A"]):
            for b, x in enumerate(p["x_mm"]):
                rows.append([i, x, p["psi_Wb"][a][b] * 1e3, p["psi_sigma_rel"][a][b] * 100, p["F_N"][a][b],
                             p["F_sigma_rel"][a][b] * 100])
    return {"columns": ["i [A]", "x [mm]", "Psi [mWb]", "1 sigma [%]", "F [N]", "1 sigma [%]"], "rows": rows}


def held_out_table(ident_summary) -> dict:
    """The identification's held-out errors per group of points (``identification.json`` ``held_out``)."""
    rows = [[r["kind"], r["group"], ", ".join(f"{v:g}" for v in r["x_mm"]), ", ".join(f"{v:g}" for v in r["i_A"]),
             r["rms_in_pct"], r["rms_held_out_pct"], r["max_held_out_pct"]] for r in ident_summary.get("held_out", [])]
    return {"columns": ["kind", "group", "x [mm]", "i [A]", "RMS in fit [%]", "RMS held out [%]", "max held out [%]"],
            "rows": rows}


def _resistance_lines(polarity: dict) -> list[str]:
    """The summary's lines on header resistances shifted, filled in from the data, or missing."""
    shifted = polarity.get("header_resistance")
    return ([shifted] if shifted else []) + list(polarity.get("header_resistance_filled", [])) + \
        [f"{line}: simulated with the model's resistance" for line in polarity.get("header_resistance_missing", [])]
