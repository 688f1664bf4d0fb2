"""The lot's summary: ``lot.csv`` (one row per unit) and ``lot.html`` (distributions, the units that stand out).

A row holds the unit's status and one-line error, the features (:data:`solenoid_fmu.lot.features.FEATURES`)
and their robust z-scores (:mod:`solenoid_fmu.lot.outliers`), whether it stands out and by which features,
the effects the loop found with their parameters (JSON), the validation errors before/after improvement (median
NRMSE by full scale over the recordings, per signal), the wall time and the run id.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

from ..fileio import atomic_write_text
from ..report import write_html_report
from .features import FEATURES
from .outliers import RULE, Z_THRESHOLD, stand_out

__all__ = ["LOT_COLUMNS", "write_lot_summary"]

#: Error columns: (column, signal, "before"/"after").
_ERRORS = [(f"{sig}_nrmse_fs_{when}", sig, when) for sig in ("psi_Wb", "force_N") for when in ("before", "after")]
#: The columns of lot.csv, in order.
LOT_COLUMNS = (["unit", "status", "error", "stands_out", "flagged_by", *FEATURES, *(f"z_{f}" for f in FEATURES),
                "effects_found", "effect_parameters", *(c for c, _, _ in _ERRORS), "wall_s", "run_id", "preset",
                "input_sha256"])


def _median(values) -> float:
    v = sorted(x for x in values if x is not None and math.isfinite(x))
    if not v:
        return math.nan
    m = len(v) // 2
    return v[m] if len(v) % 2 else 0.5 * (v[m - 1] + v[m])


def _summary_fields(unit_dir: Path) -> dict:
    try:
        s = json.loads((unit_dir / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    params = {st["effect"]: st.get("params") for st in s.get("improve_steps", []) if st.get("accepted")}
    if s.get("eddy"):
        params.setdefault("eddy", {"G_eddy_S": s["eddy"].get("G_model_S")})
    row = {"effects_found": ";".join(s.get("effects_found", [])),
           "effect_parameters": json.dumps(params, sort_keys=True, default=float)}
    for col, sig, when in _ERRORS:
        row[col] = _median(e.get(f"{when}_nrmse_fs") for e in s.get("errors", []) if e.get("signal") == sig)
    return row


def _cell(v):
    if isinstance(v, float):
        return "" if not math.isfinite(v) else repr(v)
    return "" if v is None else v


def write_lot_summary(out_dir, names, records) -> dict:
    """Write ``lot.csv`` and ``lot.html`` into ``out_dir`` from the units' records (``unit.json`` contents).

    Returns
    -------
    dict
        ``rows`` (dicts with :data:`LOT_COLUMNS`), ``flagged`` (units that stand out), ``n_flagged``,
        ``lot_csv``, ``lot_html`` (paths).
    """
    out = Path(out_dir)
    rows = []
    for name, rec in zip(names, records, strict=True):
        row = {"unit": name, "status": rec.get("status"), "error": rec.get("error"), "wall_s": rec.get("wall_s"),
               "run_id": rec.get("run_id"), "preset": rec.get("preset"), "input_sha256": rec.get("input_sha256")}
        feats = rec.get("features") or {}
        row.update({f: float(feats.get(f, math.nan)) if feats.get(f) is not None else math.nan for f in FEATURES})
        if rec.get("status") == "ok":
            row.update(_summary_fields(out / name))
        rows.append(row)
    ok = [r for r in rows if r["status"] == "ok"]
    flags = stand_out(ok, FEATURES)
    for r in rows:
        f = flags.get(r["unit"])
        r["stands_out"] = bool(f and f["flagged_by"])
        r["flagged_by"] = ";".join(f["flagged_by"]) if f else ""
        for feat in FEATURES:
            r[f"z_{feat}"] = f["z"][feat] if f else math.nan
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(LOT_COLUMNS)
    for r in rows:
        w.writerow([_cell(r.get(c)) for c in LOT_COLUMNS])
    lot_csv = atomic_write_text(out / "lot.csv", buf.getvalue())
    flagged = [r["unit"] for r in rows if r["stands_out"]]
    lot_html = _write_html(out / "lot.html", rows, ok, flagged)
    return {"rows": rows, "flagged": flagged, "n_flagged": len(flagged), "lot_csv": str(lot_csv),
            "lot_html": str(lot_html)}


def _distributions(ok, flagged):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    feats = list(FEATURES)
    fig, axes = plt.subplots(len(feats), 1, figsize=(7.5, 0.9 * len(feats) + 0.6), squeeze=False)
    for ax, f in zip(axes[:, 0], feats, strict=True):
        z = [r[f"z_{f}"] for r in ok]
        for r, zk in zip(ok, z, strict=True):
            if not math.isfinite(zk):
                continue
            out = r["unit"] in flagged and f in r["flagged_by"].split(";")
            ax.plot(max(min(zk, 12), -12), 0, "o", color="C3" if out else "C0", alpha=0.8)
            if out:
                ax.annotate(r["unit"], (max(min(zk, 12), -12), 0), xytext=(0, 6), textcoords="offset points",
                            ha="center", fontsize=7)
        ax.axvspan(-Z_THRESHOLD, Z_THRESHOLD, color="0.9")
        ax.set_xlim(-12.5, 12.5)
        ax.set_yticks([])
        ax.set_ylabel(f, rotation=0, ha="right", va="center", fontsize=7)
    axes[-1, 0].set_xlabel(f"robust z (clipped at +-12; grey: |z| <= {Z_THRESHOLD:g})")
    fig.tight_layout()
    return fig


def _write_html(path: Path, rows, ok, flagged) -> Path:
    failed = [r for r in rows if r["status"] != "ok"]
    sections = [
        {"heading": "Lot", "text": f"{len(rows)} units: {len(ok)} ok, {len(failed)} failed or not run; "
                                   f"{len(flagged)} stand out: {', '.join(flagged) or 'none'}.\n\nRule: {RULE}."},
        {"heading": "Units that stand out", "table": {
            "columns": ["unit", "flagged by", "largest |z|"],
            "rows": [[r["unit"], r["flagged_by"].replace(";", ", "),
                      max(abs(r[f"z_{f}"]) for f in FEATURES if math.isfinite(r[f"z_{f}"]))]
                     for r in rows if r["stands_out"]]}},
    ]
    if ok:
        import matplotlib.pyplot as plt

        fig = _distributions(ok, flagged)
        sections.append({"heading": "Distributions", "text": "Each feature's robust z per unit (red: stands out).",
                         "figures": [(fig, "robust z of every feature")]})
        sections.append({"heading": "Features", "table": {
            "columns": ["unit", *FEATURES],
            "rows": [[r["unit"], *(r[f] for f in FEATURES)] for r in ok]}})
        sections.append({"heading": "Feature definitions", "table": {
            "columns": ["feature", "meaning"], "rows": [[k, v] for k, v in FEATURES.items()]}})
    sections.append({"heading": "Effects and errors", "table": {
        "columns": ["unit", "effects found", "psi NRMSE(FS) before", "after", "force before", "after", "wall [s]"],
        "rows": [[r["unit"], r.get("effects_found", ""), *(r.get(c) for c, _, _ in _ERRORS), r.get("wall_s")]
                 for r in ok]}})
    if failed:
        sections.append({"heading": "Failed units", "table": {
            "columns": ["unit", "status", "error"], "rows": [[r["unit"], r["status"], r["error"] or ""]
                                                              for r in failed]}})
    try:
        return write_html_report(path, "Production lot", sections)
    finally:
        if ok:
            plt.close("all")
