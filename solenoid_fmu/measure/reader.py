"""Reading recording files (format v1) strictly: every problem with its line, or a :class:`Recording`.

:func:`validate_recording` returns every problem as ``"file:line: message"`` and
:func:`read_recording` raises :class:`~solenoid_fmu.errors.RecordingError` with all of them, so a
broken file never yields a half-read recording. The rules of the format are in
:mod:`solenoid_fmu.measure.format`.
"""

from __future__ import annotations

import io
import itertools
import math
import os
import re
from pathlib import Path

import numpy as np

from ..errors import RecordingError
from .format import (
    FIXED_STROKE_KINDS,
    KEY_RE,
    KINDS,
    KNOWN_COLUMNS,
    NUM_RE,
    REQUIRED_COLUMNS,
    REQUIRED_HEADER,
    Recording,
    header_value_problems,
    mm_column_to_m,
    near_miss,
)

__all__ = ["MAX_LISTED_PROBLEMS", "MAX_GAP_PERIODS", "MAX_RECORDING_BYTES", "MIN_TIME_STEP_S", "read_recording",
           "validate_recording"]

#: Row-level problems listed before the rest is summarised as "... and N more".
MAX_LISTED_PROBLEMS = 20
#: A time step larger than this many median sample periods is a gap in the acquisition (an error).
MAX_GAP_PERIODS = 1000
#: Largest recording file [bytes] read (100 MB: ~2.5 million samples of 5 columns, two minutes at 20 kHz). The
#: file is read in blocks of CHUNK_BYTES, so reading peaks at about 2.5 x the file size (the float64 columns and
#: their copies in the Recording) over the interpreter; larger files are refused before they are read.
MAX_RECORDING_BYTES = 100_000_000
#: Size of the blocks of data rows parsed at a time [bytes].
CHUNK_BYTES = 1 << 22
#: Shortest time step [s] accepted (1 GHz): shorter ones are no acquisition and overflow rates (dU/dt, 1/dt).
MIN_TIME_STEP_S = 1e-9


_NONFINITE_RE = re.compile(r"[ \t]*[+-]?(?:nan|inf|infinity)[ \t]*\Z", re.IGNORECASE)
_DECIMAL_COMMA_RE = re.compile(r"[ \t]*[+-]?\d+,\d+(?:[eE][+-]?\d+)?[ \t]*\Z", re.ASCII)
# characters a valid data block can contain; anything else sends the parse to the diagnosing path
_NOT_NUMERIC_TEXT_RE = re.compile(r"[^0-9.,+\-eE \t\n]")


class _Problems:
    """Collects ``file:line: message`` problems; data-row problems are capped when listed."""

    def __init__(self, where: str):
        self.where = where
        self.items: list[tuple[int, str]] = []
        self.row_items: list[tuple[int, str]] = []
        self.row_count = 0
        self.last_row_line = 0

    def add(self, line: int, message: str):
        self.items.append((line, f"{self.where}:{line}: {message}"))

    def add_row(self, line: int, message: str):
        self.row_count += 1
        self.last_row_line = max(self.last_row_line, line)
        if len(self.row_items) < MAX_LISTED_PROBLEMS:
            self.row_items.append((line, f"{self.where}:{line}: {message}"))

    def listing(self) -> list[str]:
        out = [text for _, text in sorted(self.items + self.row_items, key=lambda item: item[0])]
        more = self.row_count - len(self.row_items)
        if more > 0:
            out.append(f"{self.where}: ... and {more} more problem(s) in the data rows "
                       f"(up to line {self.last_row_line})")
        return out

    def __bool__(self) -> bool:
        return bool(self.items) or self.row_count > 0


def validate_recording(path) -> list[str]:
    """Every problem of a recording file, as ``"file:line: message"`` strings.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file (format v1).

    Returns
    -------
    list of str
        Empty when the file is a valid recording. Data-row problems beyond
        :data:`MAX_LISTED_PROBLEMS` are summarised in one ``"... and N more"`` line.
    """
    problems, _ = _parse(Path(path))
    return problems


def read_recording(path) -> Recording:
    """Read a recording file (format v1) into a :class:`Recording` in SI units.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.

    Returns
    -------
    Recording
        Positions converted from mm to m (``x_m = x_mm / 1000``).

    Raises
    ------
    RecordingError
        Listing every problem as ``"file:line: message"`` (see :func:`validate_recording`).

    Notes
    -----
    Speed: the header and column line are parsed line by line; the data block is first screened
    as a whole (one regex scan for characters a number cannot contain, no blank lines) and then
    parsed in C by :func:`numpy.loadtxt` (about 0.2 s for 100k lines of 5 columns). Only when that
    fast path fails is every line checked cell by cell, to report each problem with its line.
    """
    path = Path(path)
    problems, rec = _parse(path)
    if problems:
        raise RecordingError(str(path), problems)
    return rec


def _parse(path: Path) -> tuple[list[str], Recording | None]:
    """Parse and check a file; returns (problems, recording or None)."""
    where = str(path)
    try:
        with open(path, "rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            if size > MAX_RECORDING_BYTES:
                return [f"{where}: {size / 1e6:.0f} MB, more than the {MAX_RECORDING_BYTES / 1e6:.0f} MB a recording "
                        "may have (split it into several recordings)"], None
            return _parse_open(fh, where, path)
    except OSError as exc:
        return [f"{where}: cannot read: {exc.strerror or exc}"], None


class _NotUtf8(Exception):
    def __init__(self, line: int, byte: int):
        self.line, self.byte = line, byte


def _decode(raw: bytes, first_line: int, offset: int, bom: bool = False) -> list[str]:
    """Lines of a block of whole lines (``\r\n`` and ``\r`` read as ``\n``)."""
    try:
        text = raw.decode("utf-8-sig" if bom else "utf-8")
    except UnicodeDecodeError as exc:
        raise _NotUtf8(first_line + raw[: exc.start].count(b"\n"), offset + exc.start) from None
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    if lines and lines[-1] == "" and raw.endswith((b"\n", b"\r")):
        lines.pop()
    return lines


def _head_and_chunks(fh):
    """The lines up to the column line (the first that is neither blank nor '#'), and a generator of
    (data lines, line number of the first) blocks of about CHUNK_BYTES; blank lines at the end of the
    file are dropped (as trailing newlines)."""
    head, offset = [], 0
    while True:
        raw = fh.readline()
        if not raw:
            break
        line = _decode(raw, len(head) + 1, offset, bom=offset == 0)
        offset += len(raw)
        head.extend(line or [""])
        if head and head[-1].strip() and not head[-1].startswith("#"):
            break

    def chunks():
        nonlocal offset
        line_no, held = len(head) + 1, []
        while True:
            raws = fh.readlines(CHUNK_BYTES)
            if not raws:
                return
            raw = b"".join(raws)
            lines = held + _decode(raw, line_no + len(held), offset)
            offset += len(raw)
            keep = len(lines)
            while keep and not lines[keep - 1].strip():
                keep -= 1
            held = lines[keep:]
            if keep:
                yield lines[:keep], line_no
            line_no += keep

    return head, chunks()


def _parse_open(fh, where: str, path: Path) -> tuple[list[str], Recording | None]:
    probs = _Problems(where)
    try:
        lines, chunks = _head_and_chunks(fh)
        return _parse_lines(lines, chunks, where, path, probs)
    except _NotUtf8 as exc:
        return [f"{where}:{exc.line}: not UTF-8 text (byte {exc.byte})"], None


def _parse_lines(lines: list[str], chunks, where: str, path: Path, probs: _Problems):
    """Check the head (header and column line) and the data blocks of ``chunks``."""
    if not (lines and lines[-1].strip() and not lines[-1].startswith("#")):  # no column line: the whole file
        while lines and not lines[-1].strip():  # trailing blank lines (and the final newline)
            lines.pop()
    if not lines:
        probs.add(1, "empty file: no header and no column line")
        return probs.listing(), None

    header, header_line, idx = _read_header(lines, probs)
    if idx >= len(lines):
        probs.add(len(lines), "no column line after the header (expected e.g. 'time_s,voltage_V,current_A')")
        _check_header(header, header_line, probs, None, set())
        return probs.listing(), None

    # column line ----------------------------------------------------------------------------
    col_lineno = idx + 1
    col_line = lines[idx]
    first_data = idx + 2  # line number of the first data row
    first_chunk = next(chunks, ([], first_data))[0]
    names, delimiter_ok = _read_columns(col_line, col_lineno, first_chunk, first_data, probs)
    columns = set(names) if delimiter_ok else set()
    _check_header(header, header_line, probs, col_lineno, columns)

    # data -----------------------------------------------------------------------------------
    if not delimiter_ok or (not first_chunk and probs):
        return probs.listing(), None
    if not first_chunk:
        probs.add(col_lineno, "no data rows after the column line")
        return probs.listing(), None
    return _read_data(names, header, first_chunk, first_data, chunks, where, path, probs)


def _read_header(lines: list[str], probs: _Problems) -> tuple[dict[str, str], dict[str, int], int]:
    """The header lines at the start of ``lines``: key -> value, key -> line number, and the index of the first
    line after them."""
    header: dict[str, str] = {}
    header_line: dict[str, int] = {}
    idx = 0
    while idx < len(lines) and (lines[idx].startswith("#") or not lines[idx].strip()):
        line = lines[idx]
        lineno = idx + 1
        idx += 1
        if not line.strip():
            probs.add(lineno, "blank line in the header")
            continue
        key, sep, value = line[2:].partition(":") if line.startswith("# ") else ("", "", "")
        key = key.strip()
        if not sep or not KEY_RE.match(key):
            probs.add(lineno, f"header line must read '# key: value', got {line[:60]!r}")
            continue
        if key in header:
            probs.add(lineno, f"duplicate header key {key!r} (first on line {header_line[key]})")
            continue
        header[key] = value.strip()
        header_line[key] = lineno
    return header, header_line, idx


def _read_columns(col_line: str, col_lineno: int, first_chunk: list[str], first_data: int,
                  probs: _Problems) -> tuple[list[str], bool]:
    """The column names of the column line, checked, and whether its delimiter is the format's (else a wrong
    delimiter, and a decimal comma in the first data rows, are listed)."""
    delimiter_ok = True
    names = [c.strip() for c in col_line.split(",")]
    if len(names) == 1:
        for bad in (";", "\t", "|"):
            if bad in col_line:
                probs.add(col_lineno, f"wrong delimiter {bad!r} in the column line (the format uses ',')")
                delimiter_ok = False
                break
        if not delimiter_ok:
            for j, dline in enumerate(first_chunk):
                cells = dline.split(bad)
                commas = [c for c in cells if _DECIMAL_COMMA_RE.match(c)]
                if commas:
                    probs.add(first_data + j, f"decimal comma in {commas[0].strip()!r} (the format uses '.')")
                    break
    if delimiter_ok:
        seen: dict[str, int] = {}
        for k, name in enumerate(names):
            if not name:
                probs.add(col_lineno, f"column {k + 1} has no name")
            elif name in seen:
                probs.add(col_lineno, f"duplicate column {name!r} (columns {seen[name] + 1} and {k + 1})")
            else:
                seen[name] = k
                if name == "position_m":
                    probs.add(col_lineno, "column 'position_m': positions are in millimetres in files "
                                          "(name the column position_mm)")
        if names and all(NUM_RE.match(n) for n in names):
            probs.add(col_lineno, "no column line: this line holds numbers; "
                                  "the names (time_s, ...) must come first")
        elif "time_s" not in seen or "current_A" not in seen:
            missing = [c for c in ("time_s", "current_A") if c not in seen]
            probs.add(col_lineno, f"missing column(s) {', '.join(missing)} "
                                  "(every recording has time_s and current_A)" + _found_instead(missing, seen))
    return names, delimiter_ok


def _read_data(names: list[str], header: dict[str, str], first_chunk: list[str], first_data: int, chunks,
               where: str, path: Path, probs: _Problems):
    """The data rows of the first block and of the further ``chunks``, checked; the recording (or the problems)."""
    t_col = names.index("time_s") if "time_s" in names else None
    k_pos = names.index("position_mm") if "position_mm" in names else None
    parts: list[np.ndarray] = []
    times: list[np.ndarray] = []
    positions: list[np.ndarray] = []
    n_rows = 0
    for data, first_line in itertools.chain([(first_chunk, first_data)], chunks):
        values, t = _parse_data(data, first_line, names, probs)
        n_rows += len(data)
        times.append(t if t is not None else np.full(len(data), np.nan))
        if values is not None and not probs:
            parts.append(values)
            if k_pos is not None:  # from the text: a decimal shift, exact (see mm_text_to_m)
                positions.append(mm_column_to_m([line.split(",")[k_pos] for line in data]))
        else:
            parts, positions = [], []  # a problem: only the listing is wanted from here on
    if t_col is not None:
        _check_time(np.concatenate(times), np.arange(n_rows), first_data, probs)
    del times
    if n_rows < 2:
        probs.add(first_data, "a recording needs at least 2 samples")
    if probs:
        return probs.listing(), None
    cols = {}
    for k, name in enumerate(names):  # one column at a time: the blocks and one column in memory
        cols[name] = np.concatenate([v[:, k] for v in parts])
    del parts
    extra = {name: cols[name] for name in names if name not in KNOWN_COLUMNS}
    position_m = np.concatenate(positions) if k_pos is not None else None
    try:
        rec = Recording(kind=header["kind"], solenoid=header["solenoid"], header=header,
                        time_s=cols["time_s"], current_A=cols["current_A"],
                        voltage_V=cols.get("voltage_V"), force_N=cols.get("force_N"),
                        position_m=position_m,
                        extra=extra, path=path)
    except RecordingError as exc:  # defensive: the checks above should have caught it
        return [f"{where}: {p}" for p in exc.problems], None
    return [], rec


def _check_header(header: dict[str, str], header_line: dict[str, int], probs: _Problems,
                  col_lineno: int | None, columns: set[str]) -> None:
    """Header problems with line numbers (missing keys are reported on line 1)."""
    for key in REQUIRED_HEADER:
        if key not in header:
            hint = " (format version, '# recording: 1')" if key == "recording" else ""
            probs.add(1, f"missing header key {key!r}{hint}" + _found_instead([key], header))
    for key, message in header_value_problems(header):
        probs.add(header_line.get(key, 1), message)
    kind = header.get("kind", "").strip()
    if col_lineno is None or kind not in KINDS or not columns:
        return
    missing = [c for c in REQUIRED_COLUMNS[kind] if c not in columns]
    missing = [c for c in missing if c not in ("time_s", "current_A")]  # reported with the column line
    if missing:
        probs.add(col_lineno, f"kind {kind!r} needs column(s) {', '.join(missing)} "
                              f"(found: {', '.join(sorted(columns))})" + _found_instead(missing, columns))
    if kind in FIXED_STROKE_KINDS and "position_mm" not in header and "position_mm" not in columns:
        probs.add(col_lineno, f"kind {kind!r} is a fixed-stroke test: the stroke is missing "
                              "(give header '# position_mm: ...' or a position_mm column)"
                  + _found_instead(["position_mm"], [*header, *columns]))


def _found_instead(missing, present) -> str:
    """"; 'X' found: a misspelling?" for the names in ``present`` that look like a misspelt one of ``missing``
    (:func:`~.format.near_miss`), else ""."""
    hits = [p for p in present if near_miss(p, missing) is not None]
    return f"; {', '.join(repr(h) for h in hits)} found: a misspelling?" if hits else ""


def _parse_data(data: list[str], first_line: int, names: list[str],
                probs: _Problems) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Parse a block of data rows into an (n, m) float array (or None, every problem reported) and its
    time column (NaN where a row is unusable; None without a time column). The time order is checked
    by the caller over all blocks."""
    m = len(names)
    t_col = names.index("time_s") if "time_s" in names else None
    block = "\n".join(data)
    if not _NOT_NUMERIC_TEXT_RE.search(block) and all(line.strip() for line in data):
        try:
            values = np.loadtxt(io.StringIO(block), delimiter=",", dtype=np.float64, ndmin=2,
                                comments=None, quotechar=None)
        except ValueError:
            values = None
        del block
        if values is not None and values.shape == (len(data), m):
            _check_values(values, data, first_line, names, probs)
            return values, (None if t_col is None else values[:, t_col])
    return _diagnose_rows(data, first_line, names, probs)


def _check_values(values: np.ndarray, data: list[str], first_line: int, names: list[str],
                  probs: _Problems) -> None:
    """Out-of-range numbers on already parsed rows."""
    bad_rows, bad_cols = np.nonzero(~np.isfinite(values))
    for r, c in zip(bad_rows.tolist(), bad_cols.tolist(), strict=True):
        cell = data[r].split(",")[c].strip()
        probs.add_row(first_line + r,
                      f"number {cell!r} in column {names[c]} is out of range (overflows to inf)")


def _check_time(t: np.ndarray, rows: np.ndarray, first_line: int, probs: _Problems) -> None:
    """Strictly increasing time; ``rows`` are the row indices the finite times ``t`` belong to."""
    ok = np.isfinite(t)
    t, rows = t[ok], rows[ok]
    for k in np.flatnonzero(np.diff(t) <= 0).tolist():
        prev, cur = float(t[k]), float(t[k + 1])  # Python floats: no np.float64(...) in the message
        why = "duplicate time" if cur == prev else "time goes backwards"
        probs.add_row(first_line + int(rows[k + 1]),
                      f"{why}: time_s {cur!r} after {prev!r} on line {first_line + int(rows[k])} "
                      "(time must be strictly increasing)")
    dt = np.diff(t)
    for k in np.flatnonzero((dt > 0) & (dt < MIN_TIME_STEP_S)).tolist()[:MAX_LISTED_PROBLEMS]:
        probs.add_row(first_line + int(rows[k + 1]),
                      f"time step of {float(dt[k])!r} s before this sample is below {MIN_TIME_STEP_S:g} s "
                      "(a sample rate above 1 GHz): not an acquisition this format holds")
    if dt.size >= 2:
        period = float(np.median(dt))
        for k in np.flatnonzero(dt > MAX_GAP_PERIODS * period).tolist()[:MAX_LISTED_PROBLEMS]:
            probs.add_row(first_line + int(rows[k + 1]),
                          f"time gap of {float(dt[k])!r} s before this sample, more than {MAX_GAP_PERIODS} sample "
                          f"periods ({period:.6g} s): split the recording where the acquisition stopped")


def _diagnose_rows(data: list[str], first_line: int, names: list[str],
                   probs: _Problems) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The slow path: check every row and cell, report each problem with its line."""
    m = len(names)
    t_col = names.index("time_s") if "time_s" in names else None
    times = np.full(len(data), np.nan)
    for r, line in enumerate(data):
        lineno = first_line + r
        if not line.strip():
            probs.add_row(lineno, "blank line in the data (one sample per line)")
            continue
        if line.startswith("#"):
            probs.add_row(lineno, "header line after the column line (headers come first)")
            continue
        cells = line.split(",")
        if len(cells) != m:
            hint = ""
            if len(cells) > m:
                hint = " (decimal comma? the format uses '.')"
            elif ";" in line or "\t" in line:
                hint = " (wrong delimiter? the format uses ',')"
            probs.add_row(lineno, f"ragged row: {len(cells)} field(s), the column line has {m}{hint}")
            continue
        for c, cell in enumerate(cells):
            if NUM_RE.match(cell):
                if c == t_col:
                    times[r] = float(cell)
                if not math.isfinite(float(cell)):
                    probs.add_row(lineno, f"number {cell.strip()!r} in column {names[c]} is out of range "
                                          "(overflows to inf)")
                continue
            if not cell.strip():
                probs.add_row(lineno, f"empty cell in column {names[c]}")
            elif _NONFINITE_RE.match(cell):
                probs.add_row(lineno, f"{cell.strip()!r} in column {names[c]} (nan/inf are not allowed)")
            else:
                probs.add_row(lineno, f"non-numeric cell {cell.strip()[:30]!r} in column {names[c]}")
    t_out = times if t_col is not None else None
    if probs:
        return None, t_out
    # valid after all (only the fast-path screen was too strict): parse the checked cells
    return np.array([[float(c) for c in line.split(",")] for line in data], dtype=np.float64), t_out

