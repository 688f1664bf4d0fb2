"""The campaign report in a real headless browser (Chromium, Debian package ``chromium``): every image
decodes, no table cell overflows its box, no number wraps, the before/after table is there, and the
improvement notes are readable text (not raw JSON cut mid-string)."""

import json
import shutil
import subprocess

import pytest
from matplotlib.figure import Figure

from solenoid_fmu.report import write_campaign_report
from solenoid_fmu.report.campaign import NOTE_MAX_CHARS, note_text

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")

_CHECK = """
<script>
window.addEventListener("load", () => {
  const out = {broken: [], overflow: [], wrapped: [], tables: [], images: document.images.length};
  for (const img of document.images) if (!(img.complete && img.naturalWidth > 0)) out.broken.push(img.alt);
  for (const cell of document.querySelectorAll("td, th")) {
    if (cell.scrollWidth > cell.clientWidth + 1) out.overflow.push(cell.textContent.slice(0, 60));
    if (cell.classList.contains("num")) {
      const range = document.createRange();
      range.selectNodeContents(cell);
      const lines = new Set([...range.getClientRects()].map(r => Math.round(r.top)));
      if (lines.size > 1) out.wrapped.push(cell.textContent);
    }
  }
  for (const t of document.querySelectorAll("table"))
    out.tables.push([...t.querySelectorAll("th")].map(th => th.textContent));
  out.notes = [...document.querySelectorAll("tr")].map(tr => tr.lastElementChild.textContent)
    .filter(t => t.includes("G_eddy_S"));
  out.bodyOverflow = document.documentElement.scrollWidth > document.documentElement.clientWidth;
  document.body.setAttribute("data-check", JSON.stringify(out));
});
</script>
"""


def _figure(path, w=6.0):
    fig = Figure(figsize=(w, 3))
    fig.add_subplot().plot([0, 1, 2], [0, 1, 4])
    fig.savefig(path)
    return path


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    base = tmp_path_factory.mktemp("browser")
    (base / "identify").mkdir()
    (base / "material").mkdir()
    figs = [_figure(base / "identify" / f"fig{k}.png") for k in range(3)]
    val = [_figure(base / f"val{k}.png", 9.0) for k in range(2)]
    eddy_note = {"G_eddy_S": {"maps": 0.0012345678, "refit": 0.00098765432, "kept": True},
                 "tau_s": [1e-4, 3.1622776e-4, 1e-3, 3.1622776e-3, 1e-2],
                 "G_k_S": [1.2e-5, 0.0, 3.4e-4, 5.6e-6, 7.8e-7],
                 "fitted_on": [f"{k:02d}_eddy_{r}A_per_s_with_a_long_file_name.csv"
                               for k, r in enumerate((25, 50, 100))]}
    signals = {s: {"rms": 1.234567e-05 * (k + 1), "max": 3.2e-5, "nrmse": 0.01, "nrmse_fs": 0.02}
               for k, s in enumerate(("force_N", "psi_Wb", "i_A"))}
    recs = [{"file": f"{k:02d}_flux_0p{k}0A_a_long_recording_name.csv", "signals": signals} for k in range(4)]
    before = {"recordings": recs, "figures": [str(p) for p in val]}
    after = {"recordings": [{"file": r["file"], "signals": {s: dict(m, rms=m["rms"] * 0.1234)
                                                          for s, m in r["signals"].items()}} for r in recs],
             "figures": [str(p) for p in val]}
    summary = {
        "campaign": "fitting/demo", "recordings": [r["file"] for r in recs], "effects_added": ["eddy", "heating"],
        "not_identifiable": {}, "fmu": "b/demo.fmu", "improved_fmu": "b/demo-improved.fmu",
        "material": str(base / "material" / "material.csv"),
        "identification": {"method": "gn", "status": "converged", "identified_H_range_A_per_m": [5e3, 1.9e5],
                           "fem_solves": 321, "wall_time_s": 42.0},
        "eddy": {"G_model_S": 1.2e-3, "message": "one G_eddy fits"},
        "diagnosis": {"verdict": "eddy", "ranking": [{"effect": "eddy", "score": 0.91234, "explained": 0.8765}]},
        "improve_steps": [
            {"effect": "eddy", "accepted": True, "heldout_error_before": 1.234567e-05,
             "heldout_error_after": 2.345678e-06, "note": json.dumps(eddy_note)},
            {"effect": "heating", "accepted": True, "heldout_error_before": 0.0123, "heldout_error_after": 0.00456,
             "note": json.dumps({"C_th_J_per_K": 12.345678, "R_th_K_per_W": 1.0})},
            {"effect": "friction", "accepted": False, "heldout_error_before": None, "heldout_error_after": None,
             "note": "not identifiable from these recordings: add a force_stroke recording"}],
        "errors": [{"signal": "force_N", "before_nrmse_fs": 0.02, "after_nrmse_fs": 0.002}],
    }

    class Ident:
        rms_before, rms_after = 0.0234, 0.00123
        figures = {p.name: p.read_bytes() for p in figs}  # the identification's figures in memory

    path = write_campaign_report(base / "report.html", "demo", summary, Ident(), {"before": before, "after": after},
                                 before)
    return path, len(figs) + 2 * len(val)


def test_improvement_notes_are_text_never_cut_inside_a_value():
    note = note_text(json.dumps({"G_eddy_S": {"maps": 0.0012345678, "refit": None}, "names": ["a" * 50] * 20}))
    assert note.startswith("G_eddy_S: (maps 0.001235, refit None)") and "{" not in note and '"' not in note
    assert len(note) <= NOTE_MAX_CHARS + 20 and note.endswith("... (1 more)")
    assert note_text("plain words") == "plain words"


@pytest.mark.skipif(CHROMIUM is None, reason="needs Chromium: Debian package chromium (make setup-system as root)")
def test_the_report_renders_in_a_headless_browser(report, tmp_path):
    path, n_figures = report
    page = tmp_path / "page.html"
    page.write_text(path.read_text().replace("</body>", _CHECK + "</body>"))
    proc = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--window-size=1280,2000",
                           "--virtual-time-budget=5000", "--dump-dom", page.as_uri()],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-1000:]
    html = proc.stdout
    start = html.index('data-check="') + len('data-check="')
    import html as html_mod

    out = json.loads(html_mod.unescape(html[start:html.index('"', start)]))
    assert out["images"] == n_figures and out["broken"] == []
    assert out["overflow"] == [] and out["wrapped"] == [] and not out["bodyOverflow"], out
    assert ["file", "signal", "rms before", "rms after", "ratio (after/before)"] in out["tables"]
    assert out["notes"] and all("{" not in n and '"' not in n for n in out["notes"]), out["notes"]
    assert "refit 0.0009877" in out["notes"][0]
