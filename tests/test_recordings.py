"""Tests of solenoid_fmu.measure: the CSV format v1 (strict reader, exact writer) and eq. 4.

Every malformed file is written here, in tmp_path, with the line the problem is on known by
construction. The flux tests use synthetic recordings made from a known Psi(i) curve.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from solenoid_fmu.cli import main
from solenoid_fmu.errors import RecordingError
from solenoid_fmu.measure import (
    KINDS,
    Recording,
    commutation_curve,
    flux_linkage,
    make_recording,
    read_recording,
    reader,
    validate_recording,
    write_recording,
)
from solenoid_fmu.measure import format as R

# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------

GOOD_HEADER = [
    "# recording: 1",
    "# kind: flux",
    "# solenoid: PS45",
    "# position_mm: 1.0",
    "# coil_resistance_ohm: 12.05",
]
GOOD_COLUMNS = "time_s,voltage_V,current_A"
GOOD_ROWS = ["0.0000,0.0013,0.0001", "0.0002,0.0041,0.0003", "0.0004,0.0050,0.0005", "0.0006,0.0061,0.0007"]


def write_lines(tmp_path: Path, lines: list[str], name: str = "rec.csv") -> Path:
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def good_lines(header=None, columns=None, rows=None) -> list[str]:
    return list(GOOD_HEADER if header is None else header) + [columns or GOOD_COLUMNS] + list(
        GOOD_ROWS if rows is None else rows)


def problems_at(problems: list[str], path: Path, line: int) -> list[str]:
    return [p for p in problems if p.startswith(f"{path}:{line}: ")]


def assert_problem(path: Path, line: int, *words: str) -> list[str]:
    """The file has a problem on ``line`` whose message holds every word; read_recording refuses it."""
    problems = validate_recording(path)
    here = problems_at(problems, path, line)
    assert here, f"no problem reported on line {line}: {problems}"
    assert any(all(w.lower() in p.lower() for w in words) for p in here), here
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    assert info.value.problems == problems
    assert str(path) in str(info.value)
    return problems


def psi_true_Wb(i_A):
    """A saturating flux-linkage curve of a solenoid at fixed stroke [Wb]."""
    return 0.12 * np.tanh(np.asarray(i_A) / 0.8) + 0.01 * np.asarray(i_A)


def triangle_current(peaks_A, rate_A_per_s=1.0, fs_Hz=5000.0, rest_s=0.5, pause_s=0.3):
    """Triangles 0 -> peak -> 0 at the given rate, with rests at both ends and pauses between."""
    knots_t, knots_i = [0.0, rest_s], [0.0, 0.0]
    t = rest_s
    for k, peak in enumerate(peaks_A):
        t += peak / rate_A_per_s
        knots_t.append(t)
        knots_i.append(peak)
        t += peak / rate_A_per_s
        knots_t.append(t)
        knots_i.append(0.0)
        t += pause_s if k < len(peaks_A) - 1 else rest_s
        knots_t.append(t)
        knots_i.append(0.0)
    t_s = np.arange(0.0, knots_t[-1], 1.0 / fs_Hz)
    return t_s, np.interp(t_s, knots_t, knots_i)


def synthetic(t_s, i_A, psi_Wb, *, kind="flux", R_ohm=12.05, header_R=True, offset_V=5e-3, drift_V_per_s=0.0,
              i_offset_A=0.0, seed=1, position_m=1e-3, force=False):
    """U = R i + dPsi/dt + offset + 1 mV noise; measured i = i + offset + 0.5 mA noise."""
    rng = np.random.default_rng(seed)
    u = R_ohm * i_A + np.gradient(psi_Wb, t_s) + offset_V + drift_V_per_s * t_s
    u = u + rng.normal(0, 1e-3, t_s.size)
    i_meas = i_A + i_offset_A + rng.normal(0, 0.5e-3, t_s.size)
    return make_recording(kind, "PS45", t_s, i_meas, voltage_V=u, position_m=position_m,
                          force_N=20.0 * i_A**2 if force else None,
                          coil_resistance_ohm=R_ohm if header_R else None, sample_rate_Hz=5000.0)


def play(i_A, r_A):
    """Rate-independent play (backlash) operator of width r: a simple hysteresis."""
    out = np.empty_like(i_A)
    state = 0.0
    for k, value in enumerate(i_A):
        state = min(max(state, value - r_A), value + r_A)
        out[k] = state
    return out


@pytest.fixture(scope="module")
def flux_rec():
    t, i = triangle_current([1.5])
    return synthetic(t, i, psi_true_Wb(i))


# ---------------------------------------------------------------------------------------------
# reader: one malformed file per problem
# ---------------------------------------------------------------------------------------------


def test_good_file_reads_in_SI(tmp_path):
    path = write_lines(tmp_path, good_lines())
    assert validate_recording(path) == []
    rec = read_recording(path)
    assert rec.kind == "flux" and rec.solenoid == "PS45" and rec.path == path
    assert list(rec.header) == ["recording", "kind", "solenoid", "position_mm", "coil_resistance_ohm"]
    assert rec.header_position_m == 1.0e-3
    assert rec.coil_resistance_ohm == 12.05
    assert rec.coil_temperature_C is None and rec.sample_rate_Hz is None and rec.notes is None
    np.testing.assert_array_equal(rec.time_s, [0.0, 0.0002, 0.0004, 0.0006])
    np.testing.assert_array_equal(rec.current_A, [0.0001, 0.0003, 0.0005, 0.0007])
    assert rec.force_N is None and rec.position_m is None
    np.testing.assert_array_equal(rec.positions_m(), np.full(4, 1e-3))
    assert not rec.time_s.flags.writeable  # immutable recording


def test_position_column_mm_to_m_and_extra_columns_kept(tmp_path):
    rows = ["0.0,1.0,2.5,10.0,7", "0.1,1.5,2.25,11.5,8", "0.2,2.0,2.0,12.0,9"]
    path = write_lines(tmp_path, good_lines(header=GOOD_HEADER[:3] + ["# kind_note: x"],
                                            columns="time_s,current_A,position_mm,force_N,temp_C", rows=rows))
    path.write_text(path.read_text().replace("kind: flux", "kind: force_stroke"))
    rec = read_recording(path)
    np.testing.assert_array_equal(rec.position_m, [2.5e-3, 2.25e-3, 2.0e-3])
    np.testing.assert_array_equal(rec.positions_m(), rec.position_m)
    assert list(rec.extra) == ["temp_C"]
    np.testing.assert_array_equal(rec.extra["temp_C"], [7.0, 8.0, 9.0])
    assert rec.header["kind_note"] == "x"


def test_crlf_and_bom_are_read(tmp_path):
    path = tmp_path / "win.csv"
    path.write_bytes(("\ufeff" + "\r\n".join(good_lines()) + "\r\n").encode("utf-8"))
    rec = read_recording(path)
    assert rec.header["recording"] == "1" and len(rec) == 4


def test_missing_recording_header(tmp_path):
    path = write_lines(tmp_path, good_lines(header=GOOD_HEADER[1:]))
    assert_problem(path, 1, "missing header key 'recording'")


def test_other_format_version(tmp_path):
    header = ["# kind: flux", "# recording: 2"] + GOOD_HEADER[2:]
    path = write_lines(tmp_path, good_lines(header=header))
    assert_problem(path, 2, "unsupported format version", "2")


@pytest.mark.parametrize("key", ["kind", "solenoid"])
def test_missing_required_header_key(tmp_path, key):
    header = [h for h in GOOD_HEADER if not h.startswith(f"# {key}:")]
    path = write_lines(tmp_path, good_lines(header=header))
    assert_problem(path, 1, f"missing header key '{key}'")


def test_unknown_kind(tmp_path):
    header = list(GOOD_HEADER)
    header[1] = "# kind: fluxx"
    path = write_lines(tmp_path, good_lines(header=header))
    assert_problem(path, 2, "unknown kind", "fluxx")


def test_position_missing_for_fixed_stroke_kind(tmp_path):
    header = [h for h in GOOD_HEADER if "position_mm" not in h]
    path = write_lines(tmp_path, good_lines(header=header))
    problems = assert_problem(path, len(header) + 1, "fixed-stroke", "position_mm")
    assert len(problems) == 1
    # a position_mm column instead of the header is fine
    rows = [r + ",1.0" for r in GOOD_ROWS]
    lines = good_lines(header=header, columns=GOOD_COLUMNS + ",position_mm", rows=rows)
    ok = write_lines(tmp_path, lines, "ok.csv")
    assert validate_recording(ok) == []


def test_missing_columns_the_kind_needs(tmp_path):
    header = list(GOOD_HEADER)
    header[1] = "# kind: ramp"  # ramp needs force_N
    path = write_lines(tmp_path, good_lines(header=header))
    assert_problem(path, len(header) + 1, "needs column", "force_N")


def test_position_column_in_metres_is_refused(tmp_path):
    rows = [r + ",0.001" for r in GOOD_ROWS]
    path = write_lines(tmp_path, good_lines(columns=GOOD_COLUMNS + ",position_m", rows=rows))
    assert_problem(path, len(GOOD_HEADER) + 1, "position_m", "millimetres")


def test_missing_time_column(tmp_path):
    rows = [r.split(",", 1)[1] for r in GOOD_ROWS]
    path = write_lines(tmp_path, good_lines(columns="voltage_V,current_A", rows=rows))
    assert_problem(path, len(GOOD_HEADER) + 1, "missing column", "time_s")


def test_empty_cell(tmp_path):
    rows = list(GOOD_ROWS)
    rows[2] = "0.0004,,0.0005"
    path = write_lines(tmp_path, good_lines(rows=rows))
    problems = assert_problem(path, len(GOOD_HEADER) + 4, "empty cell", "voltage_V")
    assert len(problems) == 1


@pytest.mark.parametrize("token", ["nan", "NaN", "inf", "-inf", "Infinity"])
def test_nan_and_inf(tmp_path, token):
    rows = list(GOOD_ROWS)
    rows[1] = f"0.0002,0.0041,{token}"
    path = write_lines(tmp_path, good_lines(rows=rows))
    assert_problem(path, len(GOOD_HEADER) + 3, token, "current_A", "not allowed")


def test_overflowing_number(tmp_path):
    rows = list(GOOD_ROWS)
    rows[3] = "0.0006,1e999,0.0007"
    path = write_lines(tmp_path, good_lines(rows=rows))
    assert_problem(path, len(GOOD_HEADER) + 5, "out of range", "voltage_V")


@pytest.mark.parametrize("cell", ["abc", "1.2.3", "0x10", "5 V", "--1"])
def test_non_numeric_cell(tmp_path, cell):
    rows = list(GOOD_ROWS)
    rows[0] = f"0.0000,{cell},0.0001"
    path = write_lines(tmp_path, good_lines(rows=rows))
    assert_problem(path, len(GOOD_HEADER) + 2, "non-numeric", "voltage_V")


def test_time_going_backwards_and_duplicate(tmp_path):
    rows = ["0.0000,0,0", "0.0002,0,0", "0.0001,0,0", "0.0003,0,0", "0.0003,0,0", "0.0004,0,0"]
    path = write_lines(tmp_path, good_lines(rows=rows))
    first = len(GOOD_HEADER) + 2
    assert_problem(path, first + 2, "time goes backwards")
    problems = assert_problem(path, first + 4, "duplicate time", f"line {first + 3}")
    assert len(problems) == 2


def test_semicolon_delimiter_and_decimal_comma(tmp_path):
    rows = [r.replace(",", ";").replace(".", ",") for r in GOOD_ROWS]
    path = write_lines(tmp_path, good_lines(columns=GOOD_COLUMNS.replace(",", ";"), rows=rows))
    col_line = len(GOOD_HEADER) + 1
    assert_problem(path, col_line, "wrong delimiter", "';'")
    problems = assert_problem(path, col_line + 1, "decimal comma", "0,0000")
    assert len(problems) == 2  # not one problem per row


def test_decimal_comma_with_comma_delimiter(tmp_path):
    rows = list(GOOD_ROWS)
    rows[1] = "0,0002,0,0041,0,0003"
    path = write_lines(tmp_path, good_lines(rows=rows))
    assert_problem(path, len(GOOD_HEADER) + 3, "ragged row", "6 field", "decimal comma")


def test_ragged_row(tmp_path):
    rows = list(GOOD_ROWS)
    rows[2] = "0.0004,0.0050"
    path = write_lines(tmp_path, good_lines(rows=rows))
    assert_problem(path, len(GOOD_HEADER) + 4, "ragged row", "2 field", "has 3")


def test_blank_line_and_header_after_data(tmp_path):
    rows = list(GOOD_ROWS)
    rows[1:1] = ["", "# notes: late"]
    path = write_lines(tmp_path, good_lines(rows=rows))
    assert_problem(path, len(GOOD_HEADER) + 3, "blank line")
    assert_problem(path, len(GOOD_HEADER) + 4, "header line after the column line")


def test_malformed_and_duplicate_header_lines(tmp_path):
    header = GOOD_HEADER + ["#notes: no space", "# kind: flux", "# coil_temperature_C: warm"]
    path = write_lines(tmp_path, good_lines(header=header))
    n = len(GOOD_HEADER)
    assert_problem(path, n + 1, "must read '# key: value'")
    assert_problem(path, n + 2, "duplicate header key 'kind'", "line 2")
    assert_problem(path, n + 3, "coil_temperature_C", "not a number")


@pytest.mark.parametrize("value", ["12,05", "12 ohm", "-3", "0"])
def test_bad_resistance_header_value(tmp_path, value):
    header = list(GOOD_HEADER)
    header[4] = f"# coil_resistance_ohm: {value}"
    path = write_lines(tmp_path, good_lines(header=header))
    assert_problem(path, 5, "coil_resistance_ohm")


def test_no_column_line_and_no_rows(tmp_path):
    only_header = write_lines(tmp_path, GOOD_HEADER, "h.csv")
    assert_problem(only_header, len(GOOD_HEADER), "no column line")
    no_rows = write_lines(tmp_path, good_lines(rows=[]), "n.csv")
    assert_problem(no_rows, len(GOOD_HEADER) + 1, "no data rows")
    numbers_first = write_lines(tmp_path, GOOD_HEADER + GOOD_ROWS, "d.csv")
    assert_problem(numbers_first, len(GOOD_HEADER) + 1, "no column line", "numbers")
    empty = write_lines(tmp_path, [], "e.csv")
    assert_problem(empty, 1, "empty file")


def test_missing_file_is_a_problem_not_a_traceback(tmp_path):
    path = tmp_path / "absent.csv"
    problems = validate_recording(path)
    assert len(problems) == 1 and str(path) in problems[0] and "cannot read" in problems[0]
    with pytest.raises(RecordingError):
        read_recording(path)


def test_every_problem_listed_together(tmp_path):
    header = [h for h in GOOD_HEADER if "solenoid" not in h]
    rows = ["0.0,1,nan", "0.1,,2", "0.1,3,4"]
    path = write_lines(tmp_path, good_lines(header=header, rows=rows))
    problems = validate_recording(path)
    first = len(header) + 2
    lines = sorted(int(p.split(":")[1]) for p in problems)
    assert lines == [1, first, first + 1, first + 2]


def test_thousands_of_bad_lines_are_capped(tmp_path):
    rows = [f"{k * 1e-3!r},1.0,{'x' if k % 2 else '0.5'}" for k in range(5001)]
    path = write_lines(tmp_path, good_lines(rows=rows))
    problems = validate_recording(path)
    n_bad = 2500
    assert len(problems) == reader.MAX_LISTED_PROBLEMS + 1
    assert problems[-1].startswith(f"{path}: ... and {n_bad - reader.MAX_LISTED_PROBLEMS} more")
    first = len(GOOD_HEADER) + 2
    assert problems[0].startswith(f"{path}:{first + 1}: non-numeric cell 'x' in column current_A")
    last_line = first + 4999
    assert f"up to line {last_line}" in problems[-1]


# ---------------------------------------------------------------------------------------------
# recording objects and the writer
# ---------------------------------------------------------------------------------------------


def test_recording_object_is_checked_on_construction():
    t = np.array([0.0, 1.0, 2.0])
    with pytest.raises(RecordingError) as info:
        make_recording("ramp", "PS45", t, t, voltage_V=t)  # no force_N, no position
    text = str(info.value)
    assert "force_N" in text and "fixed-stroke" in text
    with pytest.raises(RecordingError, match="strictly increasing"):
        make_recording("flux", "PS45", [0.0, 1.0, 1.0], t, voltage_V=t, position_m=1e-3)
    with pytest.raises(RecordingError, match="non-finite"):
        make_recording("flux", "PS45", t, [0.0, np.nan, 1.0], voltage_V=t, position_m=1e-3)
    with pytest.raises(RecordingError, match="unknown kind"):
        make_recording("flux2", "PS45", t, t, voltage_V=t, position_m=1e-3)
    with pytest.raises(RecordingError, match="header 'kind' is 'eddy'"):
        Recording(kind="flux", solenoid="PS45", header={"kind": "eddy", "position_mm": "1"}, time_s=t,
                  current_A=t, voltage_V=t, force_N=None, position_m=None, extra={})
    with pytest.raises(RecordingError, match="needs column"):
        make_recording("force_stroke", "PS45", t, t, force_N=t, position_m=1e-3)  # stroke must move: column
    with pytest.raises(RecordingError, match="coil_resistance_ohm"):
        make_recording("flux", "PS45", t, t, voltage_V=t, position_m=1e-3, coil_resistance_ohm=0.0)


def test_write_read_roundtrip_and_mm_at_the_boundary(tmp_path):
    t = np.linspace(0.0, 1.0, 11)
    rec = make_recording("force_stroke", "PS45 #17", t, 0.1 * t, force_N=3.0 * t, position_m=1e-3 * (0.5 + t),
                         coil_temperature_C=22.5, notes="sweep 0.5..1.5 mm", extra={"temp_C": 20 + t})
    path = write_recording(tmp_path / "fs.csv", rec)
    text = path.read_text()
    assert "time_s,current_A,position_mm,force_N,temp_C" in text
    assert "\n0.0,0.0,0.5,0.0,20.0\n" in text  # millimetres in the file
    back = read_recording(path)
    assert back == rec
    assert back.position_m[3] == 1e-3 * (0.5 + t[3])
    assert back.notes == "sweep 0.5..1.5 mm" and back.coil_temperature_C == 22.5


def test_write_is_atomic(tmp_path, monkeypatch, flux_rec):
    path = tmp_path / "rec.csv"
    write_recording(path, flux_rec)
    before = path.read_bytes()

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    other = make_recording("flux", "OTHER", [0.0, 1.0], [0.0, 1.0], voltage_V=[0.0, 1.0], position_m=2e-3)
    with pytest.raises(OSError, match="disk full"):
        write_recording(path, other)
    assert path.read_bytes() == before  # the old file is intact
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.csv"]  # no temporary file left


def test_write_with_digits_keeps_files_small_and_refuses_collapsed_time(tmp_path, flux_rec):
    full = write_recording(tmp_path / "full.csv", flux_rec)
    small = write_recording(tmp_path / "small.csv", flux_rec, digits=7)
    assert small.stat().st_size < 0.8 * full.stat().st_size
    back = read_recording(small)
    np.testing.assert_allclose(back.voltage_V, flux_rec.voltage_V, rtol=1e-6, atol=1e-12)
    rec = make_recording("flux", "PS45", [1.0, 1.0 + 1e-9], [0.0, 0.0], voltage_V=[0.0, 0.0], position_m=1e-3)
    with pytest.raises(RecordingError, match="use more digits"):
        write_recording(tmp_path / "bad.csv", rec, digits=6)
    assert not (tmp_path / "bad.csv").exists()


# property: any valid recording written and read back is identical ---------------------------

_finite = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e12, max_value=1e12)
_tiny_or_any = st.one_of(_finite, st.floats(min_value=-1e-300, max_value=1e-300, allow_nan=False))
_text = st.text(st.characters(blacklist_categories=("Cs", "Cc", "Zl", "Zp")), max_size=20).map(str.strip)
_name = st.from_regex(r"[A-Za-z][A-Za-z0-9_]{0,12}", fullmatch=True)


@st.composite
def recordings(draw):
    n = draw(st.integers(min_value=2, max_value=40))
    t0 = draw(st.floats(min_value=-1e3, max_value=1e3))
    # uneven sampling, but no gap the reader refuses (> 1000 sample periods: an acquisition that stopped)
    base = draw(st.floats(min_value=1e-6, max_value=1.0))
    steps = base * np.array(draw(st.lists(st.floats(min_value=0.1, max_value=10.0), min_size=n - 1, max_size=n - 1)))
    time_s = t0 + np.concatenate(([0.0], np.cumsum(steps)))
    if np.any(np.diff(time_s) <= 0):  # rounding at large |t0| can merge steps; keep strictly increasing
        time_s = t0 + np.arange(n, dtype=float)

    def column():
        return np.array(draw(st.lists(_tiny_or_any, min_size=n, max_size=n)))

    kind = draw(st.sampled_from(KINDS))
    need = R.REQUIRED_COLUMNS[kind]
    voltage = column() if "voltage_V" in need or draw(st.booleans()) else None
    force = column() if "force_N" in need or draw(st.booleans()) else None
    position_col = column() * 1e-3 if "position_mm" in need or draw(st.booleans()) else None
    header = {}
    if kind != "force_stroke" and (position_col is None or draw(st.booleans())):
        header["position_mm"] = repr(draw(_finite))
    if draw(st.booleans()):
        header["coil_resistance_ohm"] = repr(draw(st.floats(min_value=1e-3, max_value=1e4)))
    if draw(st.booleans()):
        header["notes"] = draw(_text)
    for key in draw(st.lists(_name, max_size=3, unique=True)):
        if key not in ("recording", "kind", "solenoid", "position_mm", "coil_resistance_ohm",
                       "coil_temperature_C", "sample_rate_Hz", "notes"):
            header[key] = draw(_text)
    extra = {}
    for key in draw(st.lists(_name, max_size=2, unique=True)):
        if key not in R.KNOWN_COLUMNS:
            extra[key] = column()
    solenoid = draw(_text.filter(bool))
    return Recording(kind=kind, solenoid=solenoid, header=header, time_s=time_s, current_A=column(),
                     voltage_V=voltage, force_N=force, position_m=position_col, extra=extra)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rec=recordings())
def test_property_write_then_read_is_identical(rec):
    with tempfile.TemporaryDirectory() as tmp:
        path = write_recording(Path(tmp) / "r.csv", rec)
        assert validate_recording(path) == []
        back = read_recording(path)
    assert back == rec
    assert back.header == rec.header and list(back.header) == list(rec.header)
    if rec.position_m is not None:
        assert np.array_equal(back.position_m, rec.position_m)


# ---------------------------------------------------------------------------------------------
# flux linkage from voltage (paper eq. 4)
# ---------------------------------------------------------------------------------------------


def max_rel_error(res, psi_fn=psi_true_Wb, peak_A=1.5):
    return float(np.max(np.abs(res.commutation_psi_Wb - psi_fn(res.commutation_i_A))) / psi_fn(peak_A))


def test_flux_recovers_psi_of_i_within_half_percent(flux_rec):
    res = flux_linkage(flux_rec)
    assert res.resistance_source == "header" and res.R_ohm == 12.05
    assert res.commutation_i_A[0] == 0.0 and res.commutation_i_A[-1] == pytest.approx(1.5, abs=3e-3)
    assert res.commutation_i_A.size == 101
    assert max_rel_error(res) < 5e-3
    assert res.offset_V == pytest.approx(5e-3, abs=2e-4)
    assert abs(res.offset_drift_V_per_s) < 1e-4
    assert res.psi_at_peak_Wb == pytest.approx(psi_true_Wb(1.5), rel=5e-3)
    assert res.peak_current_A == pytest.approx(1.5, abs=3e-3)
    # no hysteresis in the truth: the branches coincide within the noise
    assert res.hysteresis_width_Wb < 5e-3 * psi_true_Wb(1.5)
    assert res.psi_Wb.shape == flux_rec.time_s.shape and res.psi_Wb[0] == 0.0


def test_without_offset_removal_the_integral_would_drift(flux_rec):
    res = flux_linkage(flux_rec)
    # the 5 mV offset over the 4 s recording would add 20 mWb: the removal is what keeps it small
    assert abs(res.psi_Wb[-1]) < 1e-3
    assert np.trapezoid(np.full_like(flux_rec.time_s, 5e-3), flux_rec.time_s) > 0.015


def test_offset_drift_between_start_and_end_rest_is_removed():
    t, i = triangle_current([1.5])
    rec = synthetic(t, i, psi_true_Wb(i), drift_V_per_s=2e-3)
    res = flux_linkage(rec)
    assert res.offset_drift_V_per_s == pytest.approx(2e-3, abs=1e-4)
    assert max_rel_error(res) < 5e-3


def test_current_sensor_offset_is_removed():
    t, i = triangle_current([1.5])
    rec = synthetic(t, i, psi_true_Wb(i), i_offset_A=2e-3)
    res = flux_linkage(rec)
    assert res.current_offset_A == pytest.approx(2e-3, abs=1e-4)
    assert max_rel_error(res) < 5e-3
    assert any("current-sensor offset" in note for note in res.notes)


def test_resistance_from_closure_when_header_has_none():
    t, i = triangle_current([1.5])
    rec = synthetic(t, i, psi_true_Wb(i), header_R=False, R_ohm=11.3)
    res = flux_linkage(rec)
    assert res.resistance_source == "estimated" and res.resistance_method == "closure"
    assert res.R_ohm == pytest.approx(11.3, rel=1e-2)
    assert max_rel_error(res) < 5e-3


def test_resistance_from_plateau_within_one_percent():
    fs = 5000.0
    t = np.arange(0.0, 1.5, 1.0 / fs)
    i = np.interp(t, [0.0, 0.3, 0.45, 0.95, 1.1, 1.5], [0.0, 0.0, 1.5, 1.5, 0.0, 0.0])  # 10 A/s ramp, hold
    lagged = np.zeros_like(i)  # eddy currents: Psi lags the static curve by 5 ms
    static = psi_true_Wb(i)
    a = (1.0 / fs) / 5e-3
    for k in range(1, i.size):
        lagged[k] = lagged[k - 1] + a * (static[k] - lagged[k - 1])
    rec = synthetic(t, i, lagged, kind="ramp", R_ohm=13.1, header_R=False, force=True)
    res = flux_linkage(rec)
    assert res.resistance_method == "plateau" and res.resistance_source == "estimated"
    assert res.R_ohm == pytest.approx(13.1, rel=1e-2)
    assert res.psi_at_peak_Wb == pytest.approx(psi_true_Wb(1.5), rel=5e-3)
    given = flux_linkage(rec, R_ohm=13.0)
    assert given.resistance_source == "given" and given.R_ohm == 13.0


def test_branch_split_two_peaks():
    t, i = triangle_current([1.0, 1.5])
    rec = synthetic(t, i, psi_true_Wb(i))
    res = flux_linkage(rec)
    assert [b.direction for b in res.branches] == ["ascending", "descending"] * 2
    assert [b.peak_A for b in res.branches] == pytest.approx([1.0, 1.0, 1.5, 1.5], abs=3e-3)
    for b in res.branches:
        i_start, i_end = float(np.mean(b.i_A[:25])), float(np.mean(b.i_A[-25:]))
        low, high = (i_start, i_end) if b.direction == "ascending" else (i_end, i_start)
        assert low < 0.02 and high == pytest.approx(b.peak_A, abs=0.02)
        np.testing.assert_array_equal(b.i_A, res.current_A[b.start:b.stop])
    asc2 = res.branches[2]
    assert t[asc2.start] > t[res.branches[1].stop - 1]  # the second triangle starts after the first
    assert max_rel_error(res) < 5e-3


def test_hysteresis_width_of_a_play_loop():
    r_A = 0.02
    t, i = triangle_current([1.5])
    rec = synthetic(t, i, psi_true_Wb(play(i, r_A)))
    res = flux_linkage(rec)
    # on the loop, descending Psi(i) = f(i + r) and ascending f(max(i - r, 0)): width at i
    grid = res.commutation_i_A
    top = 1.5 - 2 * r_A
    width = psi_true_Wb(np.minimum(grid + r_A, 1.5 - r_A)) - psi_true_Wb(np.maximum(grid - r_A, 0.0))
    width = np.where(grid <= top, width, psi_true_Wb(1.5 - r_A) - psi_true_Wb(np.maximum(grid - r_A, 0.0)))
    assert res.hysteresis_width_Wb == pytest.approx(np.max(width), rel=0.1)
    assert res.hysteresis_mean_width_Wb == pytest.approx(np.mean(width), rel=0.1)
    assert res.hysteresis_width_Wb > 10 * flux_linkage(synthetic(t, i, psi_true_Wb(i))).hysteresis_width_Wb


def test_flux_refuses_what_it_cannot_do():
    t = np.linspace(0.0, 1.0, 101)
    force_only = make_recording("force_stroke", "PS45", t, np.ones_like(t), force_N=t,
                                position_m=np.full_like(t, 1e-3))
    with pytest.raises(RecordingError, match="no voltage_V"):
        flux_linkage(force_only)
    # half a triangle, no rest at the end, no plateau, no header R: R cannot be found
    t, i = triangle_current([1.5])
    half = t < 1.5
    rec = synthetic(t[half], i[half], psi_true_Wb(i[half]), header_R=False)
    with pytest.raises(RecordingError, match="no coil resistance"):
        flux_linkage(rec)
    with pytest.raises(RecordingError, match="must be > 0"):
        flux_linkage(rec, R_ohm=-1.0)


def test_commutation_curve_merges_recordings_at_one_stroke():
    recs = []
    for seed, peak in enumerate([1.0, 1.5]):
        t, i = triangle_current([peak])
        recs.append(synthetic(t, i, psi_true_Wb(i), seed=seed))
    cc = commutation_curve(recs, n_points=61)
    assert cc.position_m == 1e-3
    assert cc.peak_currents_A == pytest.approx([1.0, 1.5], abs=3e-3)
    assert np.max(np.abs(cc.psi_Wb - psi_true_Wb(cc.i_A))) < 5e-3 * psi_true_Wb(1.5)
    assert cc.i_A[-1] == pytest.approx(1.5, abs=3e-3)
    assert set(cc.n_sources[cc.i_A < 0.95].tolist()) == {2}
    assert set(cc.n_sources[cc.i_A > 1.05].tolist()) == {1}


def test_commutation_curve_refuses_mixed_recordings():
    t, i = triangle_current([1.0])
    a = synthetic(t, i, psi_true_Wb(i))
    b = synthetic(t, i, psi_true_Wb(i), position_m=1.5e-3)
    with pytest.raises(RecordingError, match="different strokes"):
        commutation_curve([a, b])
    ramp = make_recording("eddy", "PS45", t, i, voltage_V=i, position_m=1e-3)
    with pytest.raises(RecordingError, match="need 'flux'"):
        commutation_curve([a, ramp])
    with pytest.raises(RecordingError, match="no recordings"):
        commutation_curve([])


# ---------------------------------------------------------------------------------------------
# command line, in process
# ---------------------------------------------------------------------------------------------


def test_cli_flux_json(tmp_path, capsys, flux_rec):
    path = write_recording(tmp_path / "flux.csv", flux_rec)
    assert main(["flux", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("resistance_ohm", "resistance_source", "offset_V", "psi_at_peak_Wb", "peak_current_A",
                "hysteresis_width_Wb"):
        assert key in out
    # by default the R(t) track: R at the start within its uncertainty of the (true) header value
    assert out["resistance_method"] == "track" and out["resistance_source"] == "estimated"
    assert abs(out["resistance_ohm"] - 12.05) <= 3 * out["resistance_sigma_ohm"] + 1e-4
    assert out["resistance_end_ohm"] is not None and out["kappa_per_J"] is not None
    assert out["offset_V"] == pytest.approx(5e-3, abs=2e-4)
    assert out["psi_at_peak_Wb"] == pytest.approx(psi_true_Wb(1.5), rel=5e-3)
    assert out["peak_current_A"] == pytest.approx(1.5, abs=3e-3)
    assert 0.0 <= out["hysteresis_width_Wb"] < 5e-3 * psi_true_Wb(1.5)
    assert main(["flux", str(path), "--json", "--constant-resistance"]) == 0  # one R: the header's, as before
    out = json.loads(capsys.readouterr().out)
    assert out["resistance_ohm"] == 12.05 and out["resistance_source"] == "header"
    assert out["resistance_end_ohm"] is None and out["resistance_pinned"] is None


def test_cli_flux_text_and_plot(tmp_path, capsys):
    t, i = triangle_current([1.5])
    path = write_recording(tmp_path / "flux.csv", synthetic(t, i, psi_true_Wb(i), header_R=False))
    png = tmp_path / "flux.png"
    assert main(["flux", str(path), "--plot", str(png), "--constant-resistance"]) == 0
    out = capsys.readouterr().out
    assert "estimated from flux closure" in out
    r_line = next(line for line in out.splitlines() if line.startswith("resistance used:"))
    assert float(r_line.split()[2]) == pytest.approx(12.05, rel=1e-2)
    assert "offset removed: 5.0" in out or "offset removed: 4.9" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000


def test_cli_check_recording(tmp_path, capsys):
    good = write_lines(tmp_path, good_lines(), "good.csv")
    rows = list(GOOD_ROWS)
    rows[1] = "0.0002,abc,0.0003"
    bad = write_lines(tmp_path, good_lines(rows=rows), "bad.csv")
    assert main(["check-recording", str(good)]) == 0
    assert f"{good}: ok" in capsys.readouterr().out
    assert main(["check-recording", str(good), str(bad)]) == 1
    out = capsys.readouterr().out
    assert f"{bad}:{len(GOOD_HEADER) + 3}: non-numeric cell 'abc' in column voltage_V" in out


def test_cli_flux_on_a_broken_file_exits_1_with_the_problem(tmp_path, capsys):
    rows = list(GOOD_ROWS)
    rows[0] = "0.0000,,0.0001"
    bad = write_lines(tmp_path, good_lines(rows=rows))
    assert main(["flux", str(bad)]) == 1
    err = capsys.readouterr().err
    assert f"{bad}:{len(GOOD_HEADER) + 2}: empty cell in column voltage_V" in err
    assert "Traceback" not in err


def test_mm_conversion_is_exact():
    for x_m in [1e-3, 2.5e-3, 0.1 + 0.2, 1e-12, 3.3e-3, -0.0, 7.0]:
        assert R.mm_text_to_m(R.m_to_mm_text(x_m)) == x_m
    assert R.mm_text_to_m("1.5") == 0.0015 and R.mm_text_to_m("2E1") == 0.02
    assert math.isclose(R.mm_text_to_m("0.333"), 0.333e-3, rel_tol=0, abs_tol=0)
