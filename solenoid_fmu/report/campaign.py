"""The campaign report of ``solenoid-fmu pipeline``: its sections from the pipeline's results, as one HTML file."""

from __future__ import annotations

from pathlib import Path

from .html import errors_table, write_html_report


def write_campaign_report(path, name, summary, ident, res, before) -> Path:
    """The pipeline's ``report.html``: summary, identification, eddy, diagnosis, improvement steps,
    errors before and after, validation figures.

    ``summary`` is the pipeline's summary dict (``summary.json``), ``ident`` the identification
    result (``rms_before``, ``rms_after``; figures in ``identify/`` beside ``material/``), ``res``
    the result of :func:`solenoid_fmu.loop.improve` and ``before`` its validation of the FMU
    before improvement.
    """
    ident_dir = Path(summary["material"]).parent.parent / "identify"
    ident_figs = sorted(ident_dir.glob("*.png"))
    s = summary["identification"]
    sections = [
        {"heading": "Summary",
         "text": (f"Campaign {summary['campaign']}: {len(summary['recordings'])} recordings. "
                  f"Effects added to the real-time model: {', '.join(summary['effects_added']) or 'none'}.\n\n"
                  + "".join(f"{k}: not identifiable from these recordings: {v}\n"
                            for k, v in summary["not_identifiable"].items())
                  + f"FMU: {summary['fmu']}\nImproved FMU: {summary['improved_fmu']}\n"
                  f"Identified material: {summary['material']}"),
         "table": summary_table(summary)},
        {"heading": "B(H) identification",
         "text": (f"Method {s.get('method')}, {s.get('status')}; flux error (RMS of peak) "
                  f"{ident.rms_before * 100:.3g} % with the start curve, {ident.rms_after * 100:.3g} % after; "
                  f"identified H range {s['identified_H_range_A_per_m'][0]:.3g} .. "
                  f"{s['identified_H_range_A_per_m'][1]:.3g} A/m; {s.get('fem_solves')} FEM solves, "
                  f"{s.get('wall_time_s', 0):.0f} s."
                  + "".join(f"\n{n}" for n in s.get("notes", []))
                  + "".join(f"\nWARNING: {w}" for w in s.get("warnings", []))),
         "figures": ident_figs},
        {"heading": "B(H) identification: prediction of points held out of the fit (paper figs. 16-17)",
         "text": (f"Chosen by held-out prediction: {s.get('chosen', 'n/a')}. Each group of measured points (a "
                  "stroke's flux, a band of currents, a force-stroke recording) is predicted by the fit without it; "
                  "errors in % of the measured values (flux: of the stroke's peak)."),
         "table": held_out_table(s)},
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
                 "recordings falls by at least 10 % (mean squared NRMSE by the full scale per kind, each capped at 1).",
         "table": {"columns": ["effect", "kept", "validation error before", "after", "note"],
                   "rows": [[st["effect"], "yes" if st["accepted"] else "no", st["heldout_error_before"],
                             st["heldout_error_after"], st["note"][:120]] for st in summary["improve_steps"]]}},
        {"heading": "Errors before and after improvement (RMS, SI units)",
         "table": errors_table(res["before"], res["after"])},
        {"heading": "Validation of the improved FMU", "figures": res["after"].get("figures", [])},
        {"heading": "Validation of the FMU before improvement", "figures": before.get("figures", [])},
    ]
    return write_html_report(path, f"solenoid-fmu pipeline: {name}", sections)


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


def held_out_table(ident_summary) -> dict:
    """The identification's held-out errors per group of points (``identification.json`` ``held_out``)."""
    rows = [[r["kind"], r["group"], ", ".join(f"{v:g}" for v in r["x_mm"]), ", ".join(f"{v:g}" for v in r["i_A"]),
             r["rms_in_pct"], r["rms_held_out_pct"], r["max_held_out_pct"]] for r in ident_summary.get("held_out", [])]
    return {"columns": ["kind", "group", "x [mm]", "i [A]", "RMS in fit [%]", "RMS held out [%]", "max held out [%]"],
            "rows": rows}
