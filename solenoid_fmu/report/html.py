"""One self-contained HTML report: text, tables and figures in a single file.

Figures are embedded as base64 ``data:`` URIs (PNG, JPEG or SVG), so the report has no external
files and can be mailed or archived as it is. Text is plain text (HTML-escaped; blank lines
separate paragraphs); a section may add raw HTML of its own under ``"html"``. Numbers in tables
are written with 4 significant digits. The file is written atomically (:mod:`solenoid_fmu.fileio`).

A section is a dict::

    {"heading": "Validation",                       # required
     "text": "plain text, paragraphs split on blank lines",
     "table": {"columns": [...], "rows": [[...], ...]},
     "figures": ["a.png", matplotlib_figure, ("b.png", "caption"), ...],
     "html": "<p>raw html, inserted as it is</p>"}

:func:`errors_table` turns two validation results (:func:`solenoid_fmu.loop.validate`) into a
before/after table; :func:`validation_section` turns one into a section.
"""

from __future__ import annotations

import base64
import html
import io
import math
import numbers
from datetime import UTC, datetime
from pathlib import Path

from .._version import __version__
from ..errors import SolenoidError
from ..fileio import atomic_write_text

__all__ = ["ReportError", "errors_table", "figure_to_data_uri", "format_cell", "validation_section",
           "write_html_report"]

_MIME = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".svg": "image/svg+xml"}

_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 60rem; margin: 2rem auto;
       padding: 0 1rem; color: #222; line-height: 1.45; }
h1 { border-bottom: 2px solid #444; padding-bottom: .3rem; }
h2 { margin-top: 2.2rem; border-bottom: 1px solid #bbb; }
table { border-collapse: collapse; margin: 1rem 0; font-size: .9rem; }
th, td { border: 1px solid #ccc; padding: .25rem .6rem; }
th { background: #f0f0f0; text-align: left; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td { overflow-wrap: anywhere; }
figure { margin: 1rem 0; }
figure img { max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { font-size: .85rem; color: #555; }
nav ul { columns: 2; }
footer { margin-top: 3rem; font-size: .8rem; color: #777; }
""".strip()


class ReportError(SolenoidError):
    """A report input is unusable (a figure file missing or of an unknown format, a bad section)."""


def figure_to_data_uri(figure, data: bytes | None = None) -> str:
    """A figure as a ``data:`` URI with base64 content.

    Parameters
    ----------
    figure : path-like or matplotlib.figure.Figure
        An image file (``.png``, ``.jpg``/``.jpeg``, ``.svg``; PNG and JPEG also recognized by
        content) or a matplotlib figure (rendered to PNG at 100 dpi).
    data : bytes, optional
        The image file's content, when the caller has it (the file is then not read).

    Returns
    -------
    str
        ``"data:image/png;base64,..."`` (or ``image/jpeg``, ``image/svg+xml``).

    Raises
    ------
    ReportError
        The file cannot be read or is not an image of a known format.
    """
    if hasattr(figure, "savefig"):
        buf = io.BytesIO()
        figure.savefig(buf, format="png", dpi=100)
        data, mime = buf.getvalue(), "image/png"
    else:
        path = Path(figure)
        try:
            data = path.read_bytes() if data is None else data
        except OSError as exc:
            raise ReportError(f"{path}: cannot read figure: {exc.strerror or exc}") from None
        if data.startswith(b"\x89PNG\r\n\x1a\n"):
            mime = "image/png"
        elif data.startswith(b"\xff\xd8\xff"):
            mime = "image/jpeg"
        elif path.suffix.lower() == ".svg" and b"<svg" in data[:4096]:
            mime = "image/svg+xml"
        else:
            raise ReportError(f"{path}: not a PNG, JPEG or SVG image (suffix {path.suffix or 'none'!r})")
    return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"


def format_cell(value) -> tuple[str, bool]:
    """Text of a table cell (escaped) and whether it is a number.

    Reals get 4 significant digits (``1.235e-05``, ``0.01235``, ``1235``), integers are written in
    full, ``None`` and non-finite numbers as ``-`` / ``nan`` / ``inf``, anything else with ``str``.
    """
    if value is None:
        return "-", False
    if isinstance(value, bool):
        return str(value), False
    if isinstance(value, numbers.Integral):
        return str(int(value)), True
    if isinstance(value, numbers.Real):
        v = float(value)
        if not math.isfinite(v):
            return str(v), True
        return f"{v:.4g}", True
    return html.escape(str(value)), False


def _paragraphs(text: str) -> str:
    blocks = [b.strip() for b in str(text).replace("\r\n", "\n").split("\n\n")]
    return "\n".join(f"<p>{html.escape(b)}</p>" for b in blocks if b)


def _table(table: dict, where: str) -> str:
    if not isinstance(table, dict) or "columns" not in table or "rows" not in table:
        raise ReportError(f"{where}: a table needs 'columns' and 'rows'")
    cols = list(table["columns"])
    out = ["<table>", "<thead><tr>" + "".join(f"<th>{html.escape(str(c))}</th>" for c in cols) + "</tr></thead>",
           "<tbody>"]
    for k, row in enumerate(table["rows"]):
        row = list(row)
        if len(row) != len(cols):
            raise ReportError(f"{where}: table row {k + 1} has {len(row)} cells, the header {len(cols)}")
        cells = []
        for v in row:
            text, num = format_cell(v)
            cells.append(f'<td class="num">{text}</td>' if num else f"<td>{text}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out += ["</tbody>", "</table>"]
    return "\n".join(out)


def _figure(item, where: str, images: dict) -> str:
    caption = None
    if isinstance(item, tuple):
        if len(item) != 2:
            raise ReportError(f"{where}: a figure tuple is (figure, caption)")
        item, caption = item
    if caption is None and not hasattr(item, "savefig"):
        caption = Path(item).name
    uri = figure_to_data_uri(item, None if hasattr(item, "savefig") else images.get(str(item)))
    alt = html.escape(caption or "figure", quote=True)
    cap = f"<figcaption>{html.escape(caption)}</figcaption>" if caption else ""
    return f'<figure><img src="{uri}" alt="{alt}">{cap}</figure>'


def write_html_report(path, title: str, sections, images: dict | None = None) -> Path:
    """Write one self-contained HTML5 report (figures embedded, inline CSS), atomically.

    Parameters
    ----------
    path : path-like
        The ``.html`` file to write (parent directories are created).
    title : str
        Page title and top heading (escaped).
    sections : list of dict
        Each ``{"heading": str, "text": str, "table": {"columns", "rows"}, "figures": [...],
        "html": str}``; only ``heading`` is required. ``text`` is plain text (escaped; blank lines
        separate paragraphs); table numbers get 4 significant digits; figures are paths,
        matplotlib figures or ``(figure, caption)`` tuples; ``html`` is inserted unescaped.
    images : dict, optional
        ``{str(path): bytes}``: the content of figure files the caller wrote and still has (embedded from
        memory, the files are not read back).

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    ReportError
        A section without a heading, a malformed table, or a figure that cannot be embedded.
    """
    parts = []
    toc = []
    for k, sec in enumerate(sections):
        if not isinstance(sec, dict) or not sec.get("heading"):
            raise ReportError(f"report section {k + 1}: needs a dict with a 'heading'")
        where = f"report section {k + 1} ({sec['heading']!s})"
        unknown = sorted(set(sec) - {"heading", "text", "table", "figures", "html"})
        if unknown:
            raise ReportError(f"{where}: unknown key(s) {unknown}")
        anchor = f"s{k + 1}"
        heading = html.escape(str(sec["heading"]))
        toc.append(f'<li><a href="#{anchor}">{heading}</a></li>')
        body = [f'<section id="{anchor}">', f"<h2>{heading}</h2>"]
        if sec.get("text"):
            body.append(_paragraphs(sec["text"]))
        if sec.get("table") is not None:
            body.append(_table(sec["table"], where))
        for fig in sec.get("figures") or []:
            body.append(_figure(fig, where, images or {}))
        if sec.get("html"):
            body.append(str(sec["html"]))
        body.append("</section>")
        parts.append("\n".join(body))
    t = html.escape(str(title))
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    nav = f"<nav><ul>\n{chr(10).join(toc)}\n</ul></nav>" if len(toc) > 1 else ""
    doc = "\n".join([
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{t}</title>",
        f"<style>\n{_CSS}\n</style>",
        "</head>",
        "<body>",
        f"<h1>{t}</h1>",
        nav,
        *parts,
        f"<footer>generated by solenoid-fmu {html.escape(__version__)} on {stamp}</footer>",
        "</body>",
        "</html>",
        "",
    ])
    return atomic_write_text(Path(path), doc)


# -- validation results as tables and sections ------------------------------------------------------------
def _rows_by_file(result: dict | None) -> dict:
    out = {}
    if not result:
        return out
    for rec in result.get("recordings", []):
        out[rec.get("file")] = rec.get("signals") or {}
    return out


def errors_table(before: dict, after: dict | None = None) -> dict:
    """A table of validation errors, or of errors before and after a model change.

    Parameters
    ----------
    before : dict
        A validation result (:func:`solenoid_fmu.loop.validate` or ``validate_cases``).
    after : dict, optional
        A second validation result of the same recordings (e.g. after ``improve``).

    Returns
    -------
    dict
        ``{"columns", "rows"}`` for :func:`write_html_report`. With ``after``: columns
        ``file, signal, rms before, rms after, ratio (after/before)``, one row per recording and
        signal found in either result (matched by ``file``, in the order of ``before`` then new
        ones of ``after``); a value missing on one side is ``None``, as is the ratio then or
        when the rms before is zero. Without ``after``: columns ``file, signal, rms, max, nrmse,
        nrmse_fs`` (range-normalized and full-scale-per-kind NRMSE, see :mod:`solenoid_fmu.loop.metrics`).
        rms and max are in the signal's SI unit (see the signal name).
    """
    b = _rows_by_file(before)
    if after is None:
        rows = [[f, sig, m.get("rms"), m.get("max"), m.get("nrmse"), m.get("nrmse_fs")] for f, sigs in b.items()
                for sig, m in sigs.items()]
        return {"columns": ["file", "signal", "rms", "max", "nrmse", "nrmse_fs"], "rows": rows}
    a = _rows_by_file(after)
    files = list(b) + [f for f in a if f not in b]
    rows = []
    for f in files:
        sb, sa = b.get(f, {}), a.get(f, {})
        for sig in list(sb) + [s for s in sa if s not in sb]:
            rb = sb.get(sig, {}).get("rms")
            ra = sa.get(sig, {}).get("rms")
            ratio = ra / rb if rb is not None and ra is not None and rb > 0 else None
            rows.append([f, sig, rb, ra, ratio])
    return {"columns": ["file", "signal", "rms before", "rms after", "ratio (after/before)"], "rows": rows}


def validation_section(result: dict, heading: str = "Validation", text: str = "", figures: bool = True) -> dict:
    """A report section from one validation result: its error table and (optionally) its figures.

    Parameters
    ----------
    result : dict
        From :func:`solenoid_fmu.loop.validate`.
    heading, text : str
        Section heading and plain-text introduction.
    figures : bool
        Embed the overlay and residual plots listed in ``result["figures"]``.
    """
    return {"heading": heading, "text": text, "table": errors_table(result),
            "figures": list(result.get("figures", [])) if figures else []}
