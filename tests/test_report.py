"""The self-contained HTML report: embedded figures, escaping, tables, before/after errors."""

import base64
import re
from html.parser import HTMLParser

import pytest
from matplotlib.figure import Figure

from solenoid_fmu.errors import SolenoidError
from solenoid_fmu.report.html import (
    ReportError,
    errors_table,
    figure_to_data_uri,
    format_cell,
    validation_section,
    write_html_report,
)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
VOID = {"meta", "img", "br", "hr", "link", "input"}


def _figure():
    fig = Figure(figsize=(2, 1.5))
    fig.add_subplot().plot([0, 1, 2], [0, 1, 4])
    return fig


@pytest.fixture
def png(tmp_path):
    path = tmp_path / "plot.png"
    _figure().savefig(path)
    return path


class _Checker(HTMLParser):
    """Records unbalanced tags and every src/href (a self-contained page has only data: and #)."""

    def __init__(self):
        super().__init__()
        self.stack, self.errors, self.links = [], [], []

    def handle_starttag(self, tag, attrs):
        self.links += [v for k, v in attrs if k in ("src", "href")]
        if tag not in VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"unexpected </{tag}> with open {self.stack}")
        else:
            self.stack.pop()


def _check(text):
    c = _Checker()
    c.feed(text)
    return c


def test_data_uri_of_a_file_and_of_a_figure(png):
    uri = figure_to_data_uri(png)
    assert uri.startswith("data:image/png;base64,")
    assert base64.b64decode(uri.split(",", 1)[1]) == png.read_bytes()
    raw = base64.b64decode(figure_to_data_uri(_figure()).split(",", 1)[1])
    assert raw[:8] == PNG_MAGIC


def test_data_uri_refuses_missing_and_non_image_files(tmp_path):
    with pytest.raises(ReportError, match="missing.png"):
        figure_to_data_uri(tmp_path / "missing.png")
    txt = tmp_path / "notes.png"
    txt.write_text("not an image")
    with pytest.raises(ReportError, match="notes.png.*not a PNG"):
        figure_to_data_uri(txt)
    assert issubclass(ReportError, SolenoidError)


def test_report_embeds_figures_escapes_text_and_formats_numbers(png, tmp_path):
    sections = [
        {"heading": "Fit <results>", "text": "R = 12 ohm & <script>alert(1)</script>\n\nsecond paragraph",
         "table": {"columns": ["name", "value", "count"], "rows": [["a<b", 0.0123456789, 7], ["c", 12345.678, None]]},
         "figures": [png, (_figure(), "a caption")]},
        {"heading": "Raw", "html": "<p class='raw'>kept <b>as is</b></p>"},
    ]
    out = write_html_report(tmp_path / "sub" / "report.html", "Report & co", sections)
    text = out.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    assert text.count("data:image/png;base64,") == 2
    assert "<script>" not in text and "&lt;script&gt;alert(1)&lt;/script&gt;" in text
    assert "Fit &lt;results&gt;" in text and "Report &amp; co" in text and "a&lt;b" in text
    assert text.count("<p>") >= 2 and "second paragraph" in text
    assert ">0.01235<" in text and ">1.235e+04<" in text and ">7<" in text
    assert "<p class='raw'>kept <b>as is</b></p>" in text
    assert "a caption" in text and "plot.png" in text
    c = _check(text)
    assert c.errors == [] and c.stack == []
    assert all(link.startswith(("data:", "#")) for link in c.links), c.links
    assert not [p for p in out.parent.iterdir() if p.name != "report.html"]  # atomic: no temp left


def test_bad_sections_are_clear_errors(tmp_path):
    with pytest.raises(ReportError, match="section 1"):
        write_html_report(tmp_path / "r.html", "t", [{"text": "no heading"}])
    with pytest.raises(ReportError, match="row 1 has 1 cells"):
        write_html_report(tmp_path / "r.html", "t", [{"heading": "h", "table": {"columns": ["a", "b"], "rows": [[1]]}}])
    with pytest.raises(ReportError, match="unknown key"):
        write_html_report(tmp_path / "r.html", "t", [{"heading": "h", "figure": "x.png"}])
    assert not (tmp_path / "r.html").exists()


@pytest.mark.parametrize(("value", "text", "num"), [
    (0.000123456, "0.0001235", True), (3, "3", True), (None, "-", False), (True, "True", False),
    (float("nan"), "nan", True), ("x<y", "x&lt;y", False), (2.5e-7, "2.5e-07", True)])
def test_cell_format(value, text, num):
    assert format_cell(value) == (text, num)


def _result(values):
    """A validation result {file: {signal: rms}}."""
    return {"recordings": [{"file": f, "signals": {s: {"rms": r, "max": 2 * r, "nrmse": r / 10, "nrmse_fs": r / 20}
                                                    for s, r in sig.items()}} for f, sig in values.items()]}


def test_errors_table_before_and_after_tolerates_missing_signals():
    before = _result({"a.csv": {"force_N": 2.0, "psi_Wb": 0.004}, "b.csv": {"current_A": 0.0}})
    after = _result({"a.csv": {"force_N": 0.5}, "b.csv": {"current_A": 0.1}, "c.csv": {"psi_Wb": 0.001}})
    t = errors_table(before, after)
    assert t["columns"] == ["file", "signal", "rms before", "rms after", "ratio (after/before)"]
    rows = {(r[0], r[1]): r[2:] for r in t["rows"]}
    assert rows[("a.csv", "force_N")] == [2.0, 0.5, pytest.approx(0.25)]
    assert rows[("a.csv", "psi_Wb")] == [0.004, None, None]
    assert rows[("b.csv", "current_A")] == [0.0, 0.1, None]  # zero before: no ratio
    assert rows[("c.csv", "psi_Wb")] == [None, 0.001, None]
    assert [r[0] for r in t["rows"]] == ["a.csv", "a.csv", "b.csv", "c.csv"]


def test_errors_table_of_one_result_and_a_section(tmp_path, png):
    res = _result({"a.csv": {"force_N": 2.0}})
    res["figures"] = [str(png)]
    t = errors_table(res)
    assert t["columns"] == ["file", "signal", "rms", "max", "nrmse", "nrmse_fs"]
    assert t["rows"] == [["a.csv", "force_N", 2.0, 4.0, 0.2, 0.1]]
    sec = validation_section(res, "Validation", "text")
    out = write_html_report(tmp_path / "v.html", "v", [sec]).read_text()
    assert out.count("data:image/png;base64,") == 1 and re.search(r">a\.csv<", out)
