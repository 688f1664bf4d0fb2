"""Test-rig recordings: the CSV format v1, and the flux linkage from voltage and current (paper eq. 4).

The format is specified in ``shared/recordings.md``: header lines ``# key: value`` (format version,
kind, solenoid, stroke ...), one column line whose names carry their units, then one sample per
line, comma-delimited, decimal point, strictly increasing time. Millimetres appear only in the
file (header ``position_mm``, column ``position_mm``); a :class:`Recording` holds SI arrays.

Reading is strict: :func:`validate_recording` returns every problem as ``"file:line: message"``
and :func:`read_recording` raises :class:`~solenoid_fmu.errors.RecordingError` with all of them,
so a broken file never yields a half-read recording. :func:`write_recording` writes atomically
(temporary file + rename) and round-trips exactly (shortest ``repr`` of every float).

:func:`flux_linkage` integrates ``Psi(t) = int (U - R i) dt`` (paper eq. 4) with what real data
needs: the coil resistance from the header or estimated (plateaus, else flux closure), removal of
the voltage offset seen in the zero-current rest phases (with linear drift when there is a rest
phase at both ends), the split of triangular excitations into ascending and descending branches,
and the commutation curve (mean of the two branches, the paper's initial curve) with the
hysteresis width. :func:`commutation_curve` merges several ``flux`` recordings at one stroke.
"""

from __future__ import annotations

import argparse
import io
import json
import math
import re
import sys
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path

import numpy as np

from ..errors import RecordingError
from ..fileio import atomic_write_text

__all__ = [
    "KINDS",
    "FIXED_STROKE_KINDS",
    "Recording",
    "make_recording",
    "mm_text_to_m",
    "read_recording",
    "validate_recording",
    "write_recording",
    "FluxBranch",
    "FluxResult",
    "flux_linkage",
    "CommutationCurve",
    "commutation_curve",
    "plot_flux",
    "add_cli",
]

#: Recording kinds of the test campaign (``shared/recordings.md``).
KINDS = ("flux", "force_stroke", "ramp", "eddy", "voltage_step")

#: Kinds recorded at a fixed stroke: they need header ``position_mm`` or a ``position_mm`` column.
FIXED_STROKE_KINDS = ("flux", "ramp", "eddy", "voltage_step")

#: The format version this module reads and writes.
FORMAT_VERSION = "1"

#: File columns every kind needs, in the canonical column order of the writer.
_REQUIRED_COLUMNS = {
    "flux": ("time_s", "voltage_V", "current_A"),
    "force_stroke": ("time_s", "current_A", "position_mm", "force_N"),
    "ramp": ("time_s", "voltage_V", "current_A", "force_N"),
    "eddy": ("time_s", "voltage_V", "current_A"),
    "voltage_step": ("time_s", "voltage_V", "current_A", "force_N"),
}
_KNOWN_COLUMNS = ("time_s", "voltage_V", "current_A", "position_mm", "force_N")
_REQUIRED_HEADER = ("recording", "kind", "solenoid")

#: Row-level problems listed before the rest is summarised as "... and N more".
MAX_LISTED_PROBLEMS = 20
#: A time step larger than this many median sample periods is a gap in the acquisition (an error).
MAX_GAP_PERIODS = 1000

_KEY_RE = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
_NUM_RE = re.compile(r"[ \t]*[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?[ \t]*\Z", re.ASCII)
_NONFINITE_RE = re.compile(r"[ \t]*[+-]?(?:nan|inf|infinity)[ \t]*\Z", re.IGNORECASE)
_DECIMAL_COMMA_RE = re.compile(r"[ \t]*[+-]?\d+,\d+(?:[eE][+-]?\d+)?[ \t]*\Z", re.ASCII)
# characters a valid data block can contain; anything else sends the parse to the diagnosing path
_NOT_NUMERIC_TEXT_RE = re.compile(r"[^0-9.,+\-eE \t\n]")


# --------------------------------------------------------------------------------------------
# The Recording object
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Recording:
    """One test-rig recording in SI units (format v1; mm only in the file).

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    solenoid : str
        Solenoid type or serial number (header ``solenoid``).
    header : dict of str to str
        Every header key and its raw string value, in file order. ``recording``, ``kind`` and
        ``solenoid`` are inserted (at the front) when missing and must agree with the fields.
    time_s : array-like, shape (n,)
        Sample times [s], finite and strictly increasing, n >= 2.
    current_A : array-like, shape (n,)
        Coil current [A].
    voltage_V : array-like, shape (n,), or None
        Coil voltage [V] (column ``voltage_V``).
    force_N : array-like, shape (n,), or None
        Armature force [N] (column ``force_N``), positive when pulling towards the pole.
    position_m : array-like, shape (n,), or None
        Per-sample working gap x [m] from the ``position_mm`` column, else None.
    extra : dict of str to array-like, shape (n,)
        Unknown extra columns, kept by their file column name (numbers, unit as in the name).
    path : pathlib.Path or None
        The file the recording was read from (not part of equality).

    Notes
    -----
    The arrays are stored as read-only float64 copies; equality (``==``) compares every field
    except ``path`` exactly. Construction checks the same rules as the file reader and raises
    :class:`~solenoid_fmu.errors.RecordingError` listing every problem.
    """

    kind: str
    solenoid: str
    header: dict[str, str]
    time_s: np.ndarray
    current_A: np.ndarray
    voltage_V: np.ndarray | None
    force_N: np.ndarray | None
    position_m: np.ndarray | None
    extra: dict[str, np.ndarray]
    path: Path | None = None

    def __post_init__(self):
        problems: list[str] = []
        what = f"Recording(kind={self.kind!r}, solenoid={self.solenoid!r})"
        arrays = {}
        for name in ("time_s", "current_A", "voltage_V", "force_N", "position_m"):
            value = getattr(self, name)
            if value is None and name not in ("time_s", "current_A"):
                arrays[name] = None
                continue
            arr = _as_readonly_1d(value, name, problems)
            arrays[name] = arr
        extra = {}
        if not isinstance(self.extra, dict):
            problems.append(f"extra must be a dict of column name -> array, not {type(self.extra).__name__}")
        else:
            for name, value in self.extra.items():
                extra[name] = _as_readonly_1d(value, f"extra[{name!r}]", problems)
        header = _normalized_header(self.kind, self.solenoid, self.header, problems)
        path = None if self.path is None else Path(self.path)
        for name, arr in arrays.items():
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "extra", extra)
        object.__setattr__(self, "header", header)
        object.__setattr__(self, "path", path)
        if not problems:
            problems += _semantic_problems(self)
        if problems:
            raise RecordingError(what, problems)

    # equality: exact, arrays included, path excluded -----------------------------------------
    def __eq__(self, other):
        if not isinstance(other, Recording):
            return NotImplemented
        if (self.kind, self.solenoid, self.header) != (other.kind, other.solenoid, other.header):
            return False
        if list(self.extra) != list(other.extra):
            return False
        pairs = [(getattr(self, n), getattr(other, n))
                 for n in ("time_s", "current_A", "voltage_V", "force_N", "position_m")]
        pairs += [(self.extra[k], other.extra[k]) for k in self.extra]
        for a, b in pairs:
            if (a is None) != (b is None):
                return False
            if a is not None and not np.array_equal(a, b):
                return False
        return True

    __hash__ = None  # mutable-looking arrays inside: not hashable

    def __len__(self) -> int:
        """Number of samples."""
        return int(self.time_s.size)

    # header accessors -------------------------------------------------------------------------
    def _header_float(self, key: str) -> float | None:
        value = self.header.get(key)
        if value is None or value.strip() == "":
            return None
        return float(value)

    @property
    def header_position_m(self) -> float | None:
        """Working gap x [m] from header ``position_mm``, or None when the header has none."""
        value = self._header_float("position_mm")
        return None if value is None else mm_text_to_m(self.header["position_mm"])

    @property
    def coil_resistance_ohm(self) -> float | None:
        """Coil resistance [ohm] measured before the run (header ``coil_resistance_ohm``), or None."""
        return self._header_float("coil_resistance_ohm")

    @property
    def coil_temperature_C(self) -> float | None:
        """Coil temperature [degC] at the resistance measurement (header), or None."""
        return self._header_float("coil_temperature_C")

    @property
    def sample_rate_Hz(self) -> float | None:
        """Nominal sample rate [Hz] from the header (the time column is what counts), or None."""
        return self._header_float("sample_rate_Hz")

    @property
    def notes(self) -> str | None:
        """Free-text header ``notes``, or None."""
        return self.header.get("notes")

    def positions_m(self) -> np.ndarray:
        """Working gap x [m] per sample, shape (n,).

        The ``position_mm`` column when present, else the header ``position_mm`` repeated.

        Raises
        ------
        RecordingError
            When the recording has neither.
        """
        if self.position_m is not None:
            return self.position_m
        x_m = self.header_position_m
        if x_m is None:
            raise RecordingError(self._where(),
                                 ["no position: neither header 'position_mm' nor a position_mm column"])
        return np.full(self.time_s.shape, x_m)

    def _where(self) -> str:
        return str(self.path) if self.path is not None else f"{self.kind} recording of {self.solenoid}"


def _as_readonly_1d(value, name: str, problems: list[str]) -> np.ndarray | None:
    """A read-only float64 copy of a 1-D array, or None with a problem appended."""
    try:
        arr = np.array(value, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        problems.append(f"{name}: not an array of numbers ({exc})")
        return None
    if arr.ndim != 1:
        problems.append(f"{name}: must be 1-D, got shape {arr.shape}")
        return None
    arr.flags.writeable = False
    return arr


def _normalized_header(kind, solenoid, header, problems: list[str]) -> dict[str, str]:
    """Header dict with ``recording``, ``kind``, ``solenoid`` present and consistent."""
    if not isinstance(header, dict):
        problems.append(f"header must be a dict of str -> str, not {type(header).__name__}")
        return {}
    wanted = {"recording": FORMAT_VERSION, "kind": kind, "solenoid": solenoid}
    front = {k: v for k, v in wanted.items() if k not in header}
    out = dict(front)
    for key, value in header.items():
        if not isinstance(key, str) or not isinstance(value, str):
            problems.append(f"header {key!r}: keys and values must be str, got {type(value).__name__}")
            continue
        if key in wanted and value.strip() != wanted[key]:
            problems.append(f"header {key!r} is {value!r} but the recording says {wanted[key]!r}")
        out[key] = value
    return out


def _semantic_problems(rec: Recording) -> list[str]:
    """Everything the format demands of a recording object (header, columns, arrays)."""
    problems: list[str] = []  # (an unknown kind is reported with the header, which holds rec.kind)
    if not isinstance(rec.solenoid, str) or not rec.solenoid.strip() or "\n" in rec.solenoid:
        problems.append(f"solenoid must be a non-empty one-line string, got {rec.solenoid!r}")
    for key, value in rec.header.items():
        if not _KEY_RE.match(key):
            problems.append(f"header key {key!r} is not a name (letters, digits, '_')")
        if "\n" in value or "\r" in value:
            problems.append(f"header {key!r}: value spans several lines")
        elif value != value.strip():
            problems.append(f"header {key!r}: value {value!r} has surrounding blanks")
    problems += [message for _, message in _header_value_problems(rec.header)]
    n = rec.time_s.size
    if n < 2:
        problems.append(f"a recording needs at least 2 samples, got {n}")
    columns = {"time_s": rec.time_s, "current_A": rec.current_A, "voltage_V": rec.voltage_V,
               "force_N": rec.force_N, "position_m": rec.position_m}
    columns.update({f"extra[{k!r}]": v for k, v in rec.extra.items()})
    for name, arr in columns.items():
        if arr is None:
            continue
        if arr.size != n:
            problems.append(f"{name} has {arr.size} samples, time_s has {n}")
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            problems.append(f"{name}: {bad.size} non-finite value(s), first at sample {bad[0]}")
    if n >= 2 and np.all(np.isfinite(rec.time_s)):
        bad = np.flatnonzero(np.diff(rec.time_s) <= 0)
        if bad.size:
            problems.append(f"time_s not strictly increasing at sample {bad[0] + 1} "
                            f"({bad.size} place(s))")
    for name in rec.extra:
        if (not isinstance(name, str) or not name.strip() or name != name.strip() or name in _KNOWN_COLUMNS
                or name == "position_m" or name.startswith("#") or any(c in name for c in ",\n\r")):
            problems.append(f"extra column name {name!r} is not usable "
                            "(empty, blanks around, a known column, starts with '#', or has ',')")
    if rec.kind in KINDS:
        have = {"time_s", "current_A"}
        have |= {c for c, a in (("voltage_V", rec.voltage_V), ("force_N", rec.force_N),
                                ("position_mm", rec.position_m)) if a is not None}
        missing = [c for c in _REQUIRED_COLUMNS[rec.kind] if c not in have]
        if missing:
            problems.append(f"kind {rec.kind!r} needs column(s) {', '.join(missing)}")
        if rec.kind in FIXED_STROKE_KINDS and rec.position_m is None and "position_mm" not in rec.header:
            problems.append(f"kind {rec.kind!r} is a fixed-stroke test: give header 'position_mm' "
                            "or a position_mm column")
    return problems


def _header_value_problems(header: dict[str, str]) -> list[tuple[str, str]]:
    """Problems with the values of the known header keys, as (key, message), without line numbers."""
    problems = []
    version = header.get("recording")
    if version is not None and version.strip() != FORMAT_VERSION:
        problems.append(("recording", f"unsupported format version 'recording: {version}' "
                                      f"(this reader knows {FORMAT_VERSION})"))
    kind = header.get("kind")
    if kind is not None and kind.strip() not in KINDS:
        problems.append(("kind", f"unknown kind {kind!r} (known: {', '.join(KINDS)})"))
    if "solenoid" in header and not header["solenoid"].strip():
        problems.append(("solenoid", "header 'solenoid' is empty"))
    limits = {"position_mm": (None, "finite"), "coil_resistance_ohm": (0.0, "> 0"),
              "coil_temperature_C": (-273.15, "> -273.15"), "sample_rate_Hz": (0.0, "> 0")}
    for key, (low, rule) in limits.items():
        if key not in header:
            continue
        text = header[key]
        if not _NUM_RE.match(text):
            problems.append((key, f"header {key!r}: {text!r} is not a number (decimal point, no unit)"))
            continue
        value = float(text)
        if not math.isfinite(value) or (low is not None and value <= low):
            problems.append((key, f"header {key!r}: {text!r} must be {rule}"))
    return problems


def make_recording(kind: str, solenoid: str, time_s, current_A, *, voltage_V=None, force_N=None,
                   position_m=None, coil_resistance_ohm: float | None = None,
                   coil_temperature_C: float | None = None, sample_rate_Hz: float | None = None,
                   notes: str | None = None, extra: dict | None = None, header: dict | None = None
                   ) -> Recording:
    """Build a :class:`Recording` from SI arrays and numbers (for the virtual rig and tests).

    Parameters
    ----------
    kind, solenoid : str
        Recording kind (one of :data:`KINDS`) and solenoid name.
    time_s, current_A : array-like, shape (n,)
        Sample times [s] (strictly increasing) and coil current [A].
    voltage_V, force_N : array-like, shape (n,), optional
        Coil voltage [V] and force [N].
    position_m : float or array-like, shape (n,), optional
        Working gap x [m]: a float goes into the header as ``position_mm``, an array becomes the
        ``position_mm`` column.
    coil_resistance_ohm, coil_temperature_C, sample_rate_Hz : float, optional
        Header values [ohm], [degC], [Hz], written with ``repr`` (exact).
    notes : str, optional
        Free text for header ``notes`` (one line).
    extra : dict, optional
        Extra columns by file name.
    header : dict, optional
        Further header keys (str -> str), placed after the ones above.

    Returns
    -------
    Recording
    """
    head = {"recording": FORMAT_VERSION, "kind": kind, "solenoid": solenoid}
    column_position = None
    if position_m is not None:
        if np.ndim(position_m) == 0:
            head["position_mm"] = _m_to_mm_text(float(position_m))
        else:
            column_position = position_m
    for key, value in (("coil_resistance_ohm", coil_resistance_ohm),
                       ("coil_temperature_C", coil_temperature_C), ("sample_rate_Hz", sample_rate_Hz)):
        if value is not None:
            head[key] = repr(float(value))
    if notes is not None:
        head["notes"] = str(notes).strip()
    head.update(header or {})
    return Recording(kind=kind, solenoid=solenoid, header=head, time_s=time_s, current_A=current_A,
                     voltage_V=voltage_V, force_N=force_N, position_m=column_position,
                     extra=dict(extra or {}))


# --------------------------------------------------------------------------------------------
# Reading and validating
# --------------------------------------------------------------------------------------------


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
    probs = _Problems(where)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        return [f"{where}: cannot read: {exc.strerror or exc}"], None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        return [f"{where}:{line}: not UTF-8 text (byte {exc.start})"], None
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    while lines and not lines[-1].strip():  # trailing blank lines (and the final newline)
        lines.pop()
    if not lines:
        probs.add(1, "empty file: no header and no column line")
        return probs.listing(), None

    # header -------------------------------------------------------------------------------
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
        if not sep or not _KEY_RE.match(key):
            probs.add(lineno, f"header line must read '# key: value', got {line[:60]!r}")
            continue
        if key in header:
            probs.add(lineno, f"duplicate header key {key!r} (first on line {header_line[key]})")
            continue
        header[key] = value.strip()
        header_line[key] = lineno
    if idx >= len(lines):
        probs.add(len(lines), "no column line after the header (expected e.g. 'time_s,voltage_V,current_A')")
        _check_header(header, header_line, probs, None, set())
        return probs.listing(), None

    # column line ----------------------------------------------------------------------------
    col_lineno = idx + 1
    col_line = lines[idx]
    data = lines[idx + 1:]
    first_data = idx + 2  # line number of data[0]
    delimiter_ok = True
    names = [c.strip() for c in col_line.split(",")]
    if len(names) == 1:
        for bad in (";", "\t", "|"):
            if bad in col_line:
                probs.add(col_lineno, f"wrong delimiter {bad!r} in the column line (the format uses ',')")
                delimiter_ok = False
                break
        if not delimiter_ok:
            for j, dline in enumerate(data):
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
        if names and all(_NUM_RE.match(n) for n in names):
            probs.add(col_lineno, "no column line: this line holds numbers; "
                                  "the names (time_s, ...) must come first")
        elif "time_s" not in seen or "current_A" not in seen:
            missing = [c for c in ("time_s", "current_A") if c not in seen]
            probs.add(col_lineno, f"missing column(s) {', '.join(missing)} "
                                  "(every recording has time_s and current_A)")
    columns = set(names) if delimiter_ok else set()
    _check_header(header, header_line, probs, col_lineno, columns)

    # data -----------------------------------------------------------------------------------
    values = None
    if delimiter_ok:
        if not data:
            probs.add(col_lineno, "no data rows after the column line")
        else:
            values = _parse_data(data, first_data, names, probs)
            if values is not None and values.shape[0] < 2:
                probs.add(first_data, "a recording needs at least 2 samples")
    if probs or values is None:
        return probs.listing(), None

    cols = {name: values[:, k] for k, name in enumerate(names)}
    extra = {name: cols[name] for name in names if name not in _KNOWN_COLUMNS}
    position_m = None
    if "position_mm" in cols:  # from the text: a decimal shift, exact (see mm_text_to_m)
        k = names.index("position_mm")
        position_m = _mm_column_to_m([line.split(",")[k] for line in data])
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
    for key in _REQUIRED_HEADER:
        if key not in header:
            hint = " (format version, '# recording: 1')" if key == "recording" else ""
            probs.add(1, f"missing header key {key!r}{hint}")
    for key, message in _header_value_problems(header):
        probs.add(header_line.get(key, 1), message)
    kind = header.get("kind", "").strip()
    if col_lineno is None or kind not in KINDS or not columns:
        return
    missing = [c for c in _REQUIRED_COLUMNS[kind] if c not in columns]
    missing = [c for c in missing if c not in ("time_s", "current_A")]  # reported with the column line
    if missing:
        probs.add(col_lineno, f"kind {kind!r} needs column(s) {', '.join(missing)} "
                              f"(found: {', '.join(sorted(columns))})")
    if kind in FIXED_STROKE_KINDS and "position_mm" not in header and "position_mm" not in columns:
        probs.add(col_lineno, f"kind {kind!r} is a fixed-stroke test: the stroke is missing "
                              "(give header '# position_mm: ...' or a position_mm column)")


def _parse_data(data: list[str], first_line: int, names: list[str], probs: _Problems) -> np.ndarray | None:
    """Parse the data rows into an (n, m) float array, or report every problem and return None."""
    m = len(names)
    block = "\n".join(data)
    if not _NOT_NUMERIC_TEXT_RE.search(block) and all(line.strip() for line in data):
        try:
            values = np.loadtxt(io.StringIO(block), delimiter=",", dtype=np.float64, ndmin=2,
                                comments=None, quotechar=None)
        except ValueError:
            values = None
        if values is not None and values.shape == (len(data), m):
            _check_values(values, data, first_line, names, probs)
            return None if probs else values
    return _diagnose_rows(data, first_line, names, probs)


def _check_values(values: np.ndarray, data: list[str], first_line: int, names: list[str],
                  probs: _Problems) -> None:
    """Out-of-range numbers and the time order on already parsed rows."""
    bad_rows, bad_cols = np.nonzero(~np.isfinite(values))
    for r, c in zip(bad_rows.tolist(), bad_cols.tolist(), strict=True):
        cell = data[r].split(",")[c].strip()
        probs.add_row(first_line + r,
                      f"number {cell!r} in column {names[c]} is out of range (overflows to inf)")
    if "time_s" in names:
        t = values[:, names.index("time_s")]
        _check_time(t, np.arange(t.size), first_line, probs)


def _check_time(t: np.ndarray, rows: np.ndarray, first_line: int, probs: _Problems) -> None:
    """Strictly increasing time; ``rows`` are the row indices the finite times ``t`` belong to."""
    ok = np.isfinite(t)
    t, rows = t[ok], rows[ok]
    for k in np.flatnonzero(np.diff(t) <= 0).tolist():
        prev, cur = t[k], t[k + 1]
        why = "duplicate time" if cur == prev else "time goes backwards"
        probs.add_row(first_line + int(rows[k + 1]),
                      f"{why}: time_s {cur!r} after {prev!r} on line {first_line + int(rows[k])} "
                      "(time must be strictly increasing)")
    dt = np.diff(t)
    if dt.size >= 2:
        period = float(np.median(dt))
        for k in np.flatnonzero(dt > MAX_GAP_PERIODS * period).tolist()[:MAX_LISTED_PROBLEMS]:
            probs.add_row(first_line + int(rows[k + 1]),
                          f"time gap of {float(dt[k])!r} s before this sample, more than {MAX_GAP_PERIODS} sample "
                          f"periods ({period:.6g} s): split the recording where the acquisition stopped")


def _diagnose_rows(data: list[str], first_line: int, names: list[str], probs: _Problems) -> None:
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
            if _NUM_RE.match(cell):
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
    if t_col is not None:
        _check_time(times, np.arange(times.size), first_line, probs)
    if probs:
        return None
    # valid after all (only the fast-path screen was too strict): parse the checked cells
    return np.array([[float(c) for c in line.split(",")] for line in data], dtype=np.float64)


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------


def mm_text_to_m(text: str) -> float:
    """A millimetre number from a file to metres, rounded once: ``float(Decimal(text) / 1000)``.

    Shifting the decimal exponent (rather than dividing the parsed float by 1000) makes the
    conversion exact to the last bit and lets :func:`_m_to_mm_text` invert it exactly.
    """
    return float(Decimal(text.strip()).scaleb(-3))


def _mm_column_to_m(cells: list[str]) -> np.ndarray:
    """Vectorised :func:`mm_text_to_m` for a column of already validated number texts [m]."""
    stripped = [c.strip() for c in cells]
    plain = [c + "e-3" if "e" not in c and "E" not in c else None for c in stripped]
    if all(p is not None for p in plain):
        return np.array(plain, dtype=np.float64)
    return np.array([mm_text_to_m(c) for c in stripped], dtype=np.float64)


def _m_to_mm_text(x_m: float) -> str:
    """The millimetre text of ``x_m`` that :func:`mm_text_to_m` reads back exactly (repr shifted)."""
    d = Decimal(repr(float(x_m))).scaleb(3)
    text = format(d, "f") if d == 0 or Decimal("1e-6") <= abs(d) < Decimal("1e9") else str(d)
    return text if "." in text or "E" in text else text + ".0"


def _float_texts(values: np.ndarray, digits: int | None) -> list[str]:
    if digits is None:
        return [repr(v) for v in values.tolist()]
    return [f"{v:.{digits}g}" for v in values.tolist()]


def write_recording(path, rec: Recording, *, digits: int | None = None, columns=None) -> Path:
    """Write a recording file (format v1) atomically: a temporary file, then a rename.

    Parameters
    ----------
    path : str or pathlib.Path
        Destination; its directory must exist. An existing file is replaced only once the new
        one is complete.
    rec : Recording
        The recording (already checked on construction).
    digits : int, optional
        Significant digits per number (``%.{digits}g``) to keep files small. By default every
        float is written with its shortest exact ``repr``, so reading the file back gives an
        identical :class:`Recording` (positions: ``float(mm) / 1000`` gives back ``position_m``).
    columns : sequence of str, optional
        Column order: a permutation of the columns the recording holds (the format allows any
        order); default ``time_s, voltage_V, current_A, position_mm, force_N, extra...``.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    RecordingError
        If rounding to ``digits`` would make the time column non-increasing.
    """
    path = Path(path)
    if not isinstance(rec, Recording):
        raise TypeError(f"write_recording needs a Recording, got {type(rec).__name__}")
    if digits is not None and not (isinstance(digits, int) and 1 <= digits <= 17):
        raise RecordingError(str(path), [f"digits must be an int in 1..17, got {digits!r}"])
    cols: list[tuple[str, list[str]]] = [("time_s", _float_texts(rec.time_s, digits))]
    if rec.voltage_V is not None:
        cols.append(("voltage_V", _float_texts(rec.voltage_V, digits)))
    cols.append(("current_A", _float_texts(rec.current_A, digits)))
    if rec.position_m is not None:
        if digits is None:
            mm = [_m_to_mm_text(v) for v in rec.position_m.tolist()]
        else:
            mm = _float_texts(rec.position_m * 1000.0, digits)
        cols.append(("position_mm", mm))
    if rec.force_N is not None:
        cols.append(("force_N", _float_texts(rec.force_N, digits)))
    cols += [(name, _float_texts(arr, digits)) for name, arr in rec.extra.items()]
    time_texts = cols[0][1]
    if columns is not None:
        by_name = dict(cols)
        if sorted(columns) != sorted(by_name):
            raise RecordingError(str(path), [f"columns {list(columns)} are not an order of the recording's "
                                             f"columns {list(by_name)}"])
        cols = [(name, by_name[name]) for name in columns]
    if digits is not None:
        t = np.array([float(s) for s in time_texts])
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            raise RecordingError(str(path), [
                f"with {digits} digits the time of samples {bad[0]} and {bad[0] + 1} "
                f"becomes equal ({time_texts[bad[0]]}); use more digits"])
    out = io.StringIO()
    for key, value in rec.header.items():
        out.write(f"# {key}: {value}\n" if value else f"# {key}:\n")
    out.write(",".join(name for name, _ in cols) + "\n")
    out.write("\n".join(map(",".join, zip(*(c for _, c in cols), strict=True))))
    out.write("\n")
    _atomic_write_text(path, out.getvalue())
    return path


def _atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (see :mod:`solenoid_fmu.fileio`)."""
    atomic_write_text(path, text)


# --------------------------------------------------------------------------------------------
# Flux linkage from voltage and current (paper eq. 4)
# --------------------------------------------------------------------------------------------


@dataclass
class FluxBranch:
    """One monotone half of a triangular excitation.

    Attributes
    ----------
    direction : str
        ``"ascending"`` (current rising to the peak) or ``"descending"`` (falling from it).
    peak_A : float
        Current at the peak this branch belongs to [A].
    i_A : numpy.ndarray, shape (m,)
        Measured current of the branch samples [A], in time order.
    psi_Wb : numpy.ndarray, shape (m,)
        Flux linkage of the same samples [Wb].
    start, stop : int
        Sample index range ``[start, stop)`` in the recording.
    """

    direction: str
    peak_A: float
    i_A: np.ndarray
    psi_Wb: np.ndarray
    start: int
    stop: int


@dataclass
class FluxResult:
    """Flux linkage of one recording (paper eq. 4) and what follows from it.

    Attributes
    ----------
    time_s, current_A : numpy.ndarray, shape (n,)
        The recording's time [s] and current [A] (less the current offset, if one was removed).
    psi_Wb : numpy.ndarray, shape (n,)
        Flux linkage per sample [Wb], zero at the first sample.
    resistance_ohm : float
        Coil resistance used [ohm].
    resistance_source : str
        ``"header"`` (coil_resistance_ohm), ``"given"`` (argument) or ``"estimated"``.
    resistance_method : str
        How it was obtained: ``"header"``, ``"given"``, ``"plateau"`` (U/i where the current
        holds still) or ``"closure"`` (Psi back to its start value); see :func:`flux_linkage`.
    offset_V : float
        Mean voltage offset removed over the recording [V].
    offset_drift_V_per_s : float
        Linear drift of that offset [V/s] (0 unless there are rest phases at both ends).
    current_offset_A : float
        Current-sensor offset removed [A] (0 unless significant in the rest phases).
    branches : list of FluxBranch
        Ascending and descending branch per current peak, in time order.
    peak_current_A : float
        Highest current of the excitation [A].
    psi_at_peak_Wb : float
        Flux linkage at the highest current peak [Wb].
    commutation_i_A, commutation_psi_Wb : numpy.ndarray, shape (k,)
        Commutation curve Psi(i): mean of ascending and descending branch, averaged over the
        peaks that reach each current level [A], [Wb]. Empty without a peak.
    hysteresis_width_Wb : float
        Largest Psi difference between descending and ascending branch at equal current [Wb]
        (NaN without a peak).
    hysteresis_mean_width_Wb : float
        Mean of that difference over the current grid [Wb].
    notes : list of str
        Warnings (no rest phase, resistance from closure, ...).
    starts_at_rest : bool
        The current is zero (within the rest threshold) at the first sample. Only then is
        ``psi_Wb`` (zero at the first sample) an absolute flux linkage of a demagnetized coil;
        otherwise it is the flux *change* since the first sample, with an unknown integration
        constant Psi(0).
    offset_measured : bool
        A zero-current rest phase at the start or end gave the voltage offset. Without one, the
        integral drifts by (unknown offset) x t and only its part orthogonal to a linear trend
        carries information.
    offset_uncertainty_Wb : float
        What the voltage offset's own uncertainty can make of the flux by the end of the
        recording [Wb]: the standard error of the rest phases' mean voltage times the duration
        (infinite without a usable rest). Flux differences smaller than this, growing linearly
        with time, are not measured.
    """

    time_s: np.ndarray
    current_A: np.ndarray
    psi_Wb: np.ndarray
    resistance_ohm: float
    resistance_source: str
    resistance_method: str
    offset_V: float
    offset_drift_V_per_s: float
    current_offset_A: float
    branches: list[FluxBranch]
    peak_current_A: float
    psi_at_peak_Wb: float
    commutation_i_A: np.ndarray
    commutation_psi_Wb: np.ndarray
    hysteresis_width_Wb: float
    hysteresis_mean_width_Wb: float
    notes: list[str] = field(default_factory=list)
    starts_at_rest: bool = True
    offset_measured: bool = True
    offset_uncertainty_Wb: float = 0.0

    def summary(self) -> dict:
        """The CLI's JSON object: numbers in SI, NaN as None."""
        def num(v):
            return None if v is None or not math.isfinite(v) else float(v)
        return {
            "resistance_ohm": num(self.resistance_ohm),
            "resistance_source": self.resistance_source,
            "resistance_method": self.resistance_method,
            "offset_V": num(self.offset_V),
            "offset_drift_V_per_s": num(self.offset_drift_V_per_s),
            "current_offset_A": num(self.current_offset_A),
            "psi_at_peak_Wb": num(self.psi_at_peak_Wb),
            "peak_current_A": num(self.peak_current_A),
            "hysteresis_width_Wb": num(self.hysteresis_width_Wb),
            "hysteresis_mean_width_Wb": num(self.hysteresis_mean_width_Wb),
            "n_peaks": len(self.branches) // 2,
            "notes": list(self.notes),
            "starts_at_rest": self.starts_at_rest,
            "offset_measured": self.offset_measured,
            "offset_uncertainty_Wb": num(self.offset_uncertainty_Wb),
        }


def _noise_std(y: np.ndarray) -> float:
    """Robust white-noise standard deviation of a signal (MAD of second differences)."""
    if y.size < 5:
        return 0.0
    d2 = np.diff(y, 2)
    mad = np.median(np.abs(d2 - np.median(d2)))
    return float(1.4826 * mad / math.sqrt(6.0))


def _smooth(y: np.ndarray, k: int) -> np.ndarray:
    from scipy.ndimage import uniform_filter1d

    return y if k <= 1 else uniform_filter1d(y, size=k, mode="nearest")


def _rest_runs(i_s: np.ndarray, thr_A: float, min_len: int) -> tuple[slice | None, slice | None]:
    """Zero-current rest phases at the start and end.

    The start phase loses its last 5 % (the excitation begins); of the end phase only the second
    half is kept, so that induced voltages still decaying after the excitation (eddy currents)
    do not bias the offset.
    """
    active = np.abs(i_s) > thr_A
    if not active.any():
        return None, None
    first = int(np.argmax(active))
    last = int(active.size - 1 - np.argmax(active[::-1]))
    head = tail = None
    if first >= min_len:
        head = slice(0, first - max(1, first // 20))
    n_tail = active.size - 1 - last
    if n_tail >= min_len:
        tail = slice(last + 1 + max(1, n_tail // 2), active.size)
    return head, tail


def _stationary(u: np.ndarray, u_scale: float) -> bool:
    """True when the two halves of a rest phase's voltage agree within 5 standard errors or within
    0.1 % of the recording's largest voltage ``u_scale`` [V] (a slow offset drift of the DAQ).

    A rest phase right after an excitation may still carry an induced voltage that decays (eddy
    currents, a hysteresis creeping to remanence): such a phase does not give the offset.
    """
    n = u.size // 2
    if n < 4:
        return True
    a, b = u[:n], u[-n:]
    se = math.sqrt((float(np.var(a)) + float(np.var(b))) / n)
    return abs(float(np.mean(a)) - float(np.mean(b))) <= max(5.0 * se, 1e-3 * u_scale, 1e-12)


def _offset_model(t, u, head, tail):
    """Voltage offset (a, b, t0, n, se): U_off(t) = a + b (t - t0), from 10 %-trimmed means of U [V]
    over the ``n`` (0-2) rest phases used; ``se`` [V] the larger standard error of those means.

    U alone (not U - R i): with i = 0 in the rest phases, R i only adds the current noise times R.
    A rest phase whose voltage is still settling (:func:`_stationary`) is not used.
    """
    from scipy.stats import trim_mean

    anchors = []
    se = 0.0
    for sl in (head, tail):
        if sl is not None and sl.stop - sl.start > 0 and _stationary(u[sl], float(np.max(np.abs(u)))):
            anchors.append((float(np.median(t[sl])), float(trim_mean(u[sl], 0.1))))
            se = max(se, float(np.std(u[sl])) / math.sqrt(sl.stop - sl.start))
    if not anchors:
        return 0.0, 0.0, float(t[0]), 0, math.inf
    if len(anchors) == 1:
        return anchors[0][1], 0.0, anchors[0][0], 1, se
    (t0, a0), (t1, a1) = anchors
    return a0, (a1 - a0) / (t1 - t0), t0, 2, se


def _plateaus(i_s: np.ndarray, sigma_s: float, i_max: float, min_len: int) -> np.ndarray:
    """Boolean mask of settled samples on non-zero current plateaus (second half of each run)."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    band = max(10.0 * sigma_s, 1e-3 * i_max)
    span = maximum_filter1d(i_s, min_len, mode="nearest") - minimum_filter1d(i_s, min_len, mode="nearest")
    still = (span < band) & (np.abs(i_s) > 0.1 * i_max)
    mask = np.zeros_like(still)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], still.astype(np.int8), [0]))))
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        if stop - start >= min_len:
            mask[(start + stop) // 2: stop] = True
    return mask


def flux_linkage(rec: Recording, resistance_ohm: float | None = None, *, n_points: int = 101) -> FluxResult:
    """Flux linkage Psi(t) from voltage and current, and Psi(i) of triangular excitations.

    Parameters
    ----------
    rec : Recording
        A recording with a ``voltage_V`` column (any kind; ``flux`` and ``eddy`` have triangles).
    resistance_ohm : float, optional
        Coil resistance [ohm]; overrides the header.
    n_points : int
        Points of the current grid of the commutation curve (0 to the highest peak).

    Returns
    -------
    FluxResult

    Raises
    ------
    RecordingError
        No voltage column; no resistance in the header and none can be estimated.

    Notes
    -----
    Paper eq. (4): ``Psi(t) = int_0^t (U - R i - U_off) dt`` by cumulative trapezoid.

    * Resistance: the argument, else header ``coil_resistance_ohm``, else estimated by least
      squares ``R = sum(u i) / sum(i^2)`` over the settled second half of every current plateau
      (|i| > 10 % of the peak, held for >= 50 ms); without a plateau, from flux closure: the R
      that makes Psi at the end equal Psi at the start (needs a closed excitation, assumes no
      remanence is left).
    * Offset: the 10 %-trimmed mean of U over the zero-current rest phases at the start and at
      the end (each at least 10 ms; of the end phase only its second half, after induced
      voltages have decayed); with both, linear drift between them; with none, no offset is
      removed (a note says so). Rest: ``|i| < max(5 sigma_i, 0.2 % of the peak)``. A mean
      current in the rest phases is removed as a current-sensor offset only when it exceeds five
      standard errors (otherwise it would only add noise times R to the integral).
    * Branches: peaks of the (lightly smoothed) current with a prominence of at least 20 % of the
      highest current; each peak gives an ascending branch (from the preceding valley) and a
      descending one (to the next valley). On each branch Psi is averaged in current bins and
      interpolated onto the grid; the commutation curve is the mean of the two branches,
      averaged over the peaks reaching each level. Only positive current peaks are analysed.
    """
    if rec.voltage_V is None:
        raise RecordingError(rec._where(), ["no voltage_V column: the flux linkage needs the coil voltage"])
    if n_points < 3:
        raise RecordingError(rec._where(), [f"n_points must be >= 3, got {n_points}"])
    t = rec.time_s
    u = rec.voltage_V
    i = rec.current_A
    n = t.size
    notes: list[str] = []
    dt = float(np.median(np.diff(t)))
    k_smooth = max(1, int(round(1e-3 / dt)))
    i_s = _smooth(i, k_smooth)
    sigma_i = _noise_std(i)
    i_max = float(np.max(np.abs(i_s)))
    if i_max <= 0:
        raise RecordingError(rec._where(), ["the current is zero throughout: no flux to compute"])
    thr = max(5.0 * sigma_i, 2e-3 * i_max)
    min_rest = max(10, int(round(10e-3 / dt)))
    head, tail = _rest_runs(i_s, thr, min_rest)
    if head is None and tail is None:
        notes.append("no zero-current rest phase at the start or end: no voltage offset removed")

    if resistance_ohm is not None:
        if not (math.isfinite(resistance_ohm) and resistance_ohm > 0):
            raise RecordingError(rec._where(), [f"resistance must be > 0 ohm, got {resistance_ohm!r}"])
        R, method = float(resistance_ohm), "given"
    elif rec.coil_resistance_ohm is not None:
        R, method = rec.coil_resistance_ohm, "header"
    else:
        R, method = None, None

    # voltage offset (with drift) from the rest phases; current-sensor offset only if significant
    a, b, t0, n_anchors, offset_se = _offset_model(t, u, head, tail)
    if n_anchors == 0 and (head is not None or tail is not None):
        notes.append("the zero-current rest phases still carry a settling induced voltage: no voltage offset "
                     "removed")
    offset = a + b * (t - t0)
    uc = u - offset
    i_off = 0.0
    rest = np.concatenate([np.arange(n)[sl] for sl in (head, tail) if sl is not None] or [np.empty(0, int)])
    if rest.size >= 2:
        mean_rest = float(np.mean(i[rest]))
        stderr = max(float(np.std(i[rest])), 1e-9) / math.sqrt(rest.size)
        if abs(mean_rest) > 5.0 * stderr:
            i_off = mean_rest
            notes.append(f"current-sensor offset of {i_off * 1e3:.3f} mA in the rest phases removed")
    ic = i - i_off

    if R is None:
        k_plateau = max(5, 2 * k_smooth)
        plateau = _plateaus(_smooth(ic, k_plateau), sigma_i / math.sqrt(k_plateau), i_max,
                            max(20, int(round(50e-3 / dt))))
        closed = abs(float(i_s[-1] - i_s[0])) <= thr
        R_est = math.nan
        if plateau.any():
            R_est = float(np.sum(uc[plateau] * ic[plateau]) / np.sum(ic[plateau] ** 2))
            method = "plateau"
        elif closed:
            q_A_s = float(np.trapezoid(ic, t))
            if abs(q_A_s) > 1e-12:
                R_est = float(np.trapezoid(uc, t)) / q_A_s
                method = "closure"
                notes.append("resistance from flux closure (assumes Psi returns to its start value)")
        if method is None or not (math.isfinite(R_est) and R_est > 0):
            raise RecordingError(rec._where(), [
                "no coil resistance: the header has no coil_resistance_ohm, the current has no plateau "
                "to estimate it from, and the excitation does not return to its start "
                "(give --resistance-ohm or add '# coil_resistance_ohm: ...')"])
        R = R_est

    from scipy.integrate import cumulative_trapezoid

    psi = cumulative_trapezoid(uc - R * ic, t, initial=0.0)
    offset_mean = float(np.trapezoid(offset, t) / (t[-1] - t[0]))
    i, i_s = ic, i_s - i_off

    if rec.position_m is not None and float(np.ptp(rec.position_m)) > 1e-6:
        notes.append(f"the armature moves by {float(np.ptp(rec.position_m)) * 1e3:.4g} mm during the recording: Psi "
                     "changes with the position too, so the branches and the 'hysteresis width' include motion "
                     "and are not a property of the steel")
    if abs(float(i_s[0])) > thr:
        notes.append(f"the recording starts energized ({float(i_s[0]):.4g} A): Psi is the change since the "
                     "first sample (its integration constant Psi(0) is not measured)")
    branches = _split_branches(i, i_s, psi, thr, k_smooth)
    grid = np.linspace(0.0, max((br.peak_A for br in branches), default=0.0), n_points)
    mean_curves, widths = peak_curves(branches, grid)
    if mean_curves:
        stack = np.vstack(mean_curves)
        with np.errstate(invalid="ignore"):
            count = np.sum(np.isfinite(stack), axis=0)
            merged = np.where(count > 0, np.nansum(stack, axis=0) / np.maximum(count, 1), np.nan)
        keep = np.isfinite(merged)
        com_i, com_psi = grid[keep], merged[keep]
        all_w = np.concatenate([w[np.isfinite(w)] for w in widths])
        width_max = float(np.max(np.abs(all_w))) if all_w.size else math.nan
        width_mean = float(np.mean(np.abs(all_w))) if all_w.size else math.nan
        top = max(range(len(branches)), key=lambda j: branches[j].peak_A)
        p = branches[top].stop - 1 if branches[top].direction == "ascending" else branches[top].start
        lo, hi = max(0, p - k_smooth), min(n, p + k_smooth + 1)
        psi_peak = float(np.mean(psi[lo:hi]))
        peak_A = branches[top].peak_A
    else:
        com_i = com_psi = np.empty(0)
        width_max = width_mean = math.nan
        p = int(np.argmax(i_s))
        psi_peak, peak_A = float(psi[p]), float(i_s[p])
        notes.append("no current peak found: no branches, commutation curve or hysteresis width")
    return FluxResult(time_s=t, current_A=i, psi_Wb=psi, resistance_ohm=float(R),
                      resistance_source=method if method in ("header", "given") else "estimated",
                      resistance_method=method,
                      offset_V=offset_mean, offset_drift_V_per_s=float(b),
                      current_offset_A=i_off, branches=branches,
                      peak_current_A=float(peak_A), psi_at_peak_Wb=psi_peak, commutation_i_A=com_i,
                      commutation_psi_Wb=com_psi, hysteresis_width_Wb=width_max,
                      hysteresis_mean_width_Wb=width_mean, notes=notes,
                      starts_at_rest=bool(abs(float(i_s[0])) <= thr),
                      offset_measured=n_anchors > 0, offset_uncertainty_Wb=offset_se * float(t[-1] - t[0]))


def _split_branches(i, i_s, psi, thr, k) -> list[FluxBranch]:
    """Ascending and descending branch for every positive current peak."""
    from scipy.signal import find_peaks

    i_top = float(np.max(i_s))
    if i_top <= 0:
        return []
    peaks, _ = find_peaks(i_s, prominence=0.2 * i_top)
    n = i.size
    # each peak refined to the highest smoothed sample within +-k; two peaks that refine onto each
    # other (or cross) count once, so that every valley between two peaks is a non-empty range
    refined = sorted({max(0, p - k) + int(np.argmax(i_s[max(0, p - k):min(n, p + k + 1)])) for p in peaks.tolist()})
    branches: list[FluxBranch] = []
    for j, p in enumerate(refined):
        lo, hi = max(0, p - k), min(n, p + k + 1)
        peak_A = float(np.max(i[lo:hi]))
        left = 0 if j == 0 else refined[j - 1] + int(np.argmin(i_s[refined[j - 1]:p]))
        right = n - 1 if j == len(refined) - 1 else p + int(np.argmin(i_s[p:refined[j + 1]]))
        # leave the flat valley out: the branch starts where the current leaves the valley level
        low_left = np.flatnonzero(i_s[left:p] <= i_s[left] + thr)
        start = left + (int(low_left[-1]) if low_left.size else 0)
        low_right = np.flatnonzero(i_s[p:right + 1] <= i_s[right] + thr)
        stop = p + (int(low_right[0]) if low_right.size else right - p) + 1
        branches.append(FluxBranch("ascending", peak_A, i[start:p + 1].copy(), psi[start:p + 1].copy(),
                                   start, p + 1))
        branches.append(FluxBranch("descending", peak_A, i[p:stop].copy(), psi[p:stop].copy(), p, stop))
    return branches


def _branch_on_grid(i_A: np.ndarray, psi_Wb: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Psi of one branch on the current grid: bin means, linear interpolation; NaN off the branch."""
    out = np.full(grid.shape, np.nan)
    if i_A.size < 2:
        return out
    step = grid[1] - grid[0]
    edges_lo = float(np.min(i_A))
    nbins = max(1, int(math.ceil((float(np.max(i_A)) - edges_lo) / (0.5 * step))))
    idx = np.minimum(((i_A - edges_lo) / (0.5 * step)).astype(np.int64), nbins - 1)
    cnt = np.bincount(idx, minlength=nbins)
    used = cnt > 0
    mi = np.bincount(idx, weights=i_A, minlength=nbins)[used] / cnt[used]
    mp = np.bincount(idx, weights=psi_Wb, minlength=nbins)[used] / cnt[used]
    order = np.argsort(mi, kind="stable")
    mi, mp = mi[order], mp[order]
    lo_i, hi_i = float(np.min(i_A)), float(np.max(i_A))
    inside = (grid >= lo_i - 0.5 * step) & (grid <= hi_i + 0.5 * step)
    if mi.size == 1:
        out[inside] = mp[0]
        return out
    x = grid[inside]
    y = np.interp(x, mi, mp)
    below, above = x < mi[0], x > mi[-1]  # linear extrapolation, at most about one step
    y[below] = mp[0] + (x[below] - mi[0]) * (mp[1] - mp[0]) / (mi[1] - mi[0])
    y[above] = mp[-1] + (x[above] - mi[-1]) * (mp[-1] - mp[-2]) / (mi[-1] - mi[-2])
    out[inside] = y
    return out


def peak_curves(branches: list[FluxBranch], grid: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per peak: mean of its two branches on ``grid`` and the width (descending - ascending)."""
    means, widths = [], []
    if grid.size < 2 or grid[-1] <= 0:
        return means, widths
    for asc, desc in zip(branches[::2], branches[1::2], strict=True):
        pa = _branch_on_grid(asc.i_A, asc.psi_Wb, grid)
        pd = _branch_on_grid(desc.i_A, desc.psi_Wb, grid)
        means.append(0.5 * (pa + pd))
        widths.append(pd - pa)
    return means, widths


@dataclass
class CommutationCurve:
    """Measured commutation curve Psi(i) at one stroke, merged from several ``flux`` recordings.

    Attributes
    ----------
    i_A : numpy.ndarray, shape (k,)
        Current grid [A] (points covered by at least one recording).
    psi_Wb : numpy.ndarray, shape (k,)
        Mean of ascending and descending branch, averaged over the peaks reaching each level [Wb].
    n_sources : numpy.ndarray of int, shape (k,)
        How many peaks (over all recordings) contribute at each current.
    position_m : float
        The common working gap x [m].
    peak_currents_A : list of float
        The peaks of the merged excitations [A].
    results : list of FluxResult
        The per-recording flux results.
    """

    i_A: np.ndarray
    psi_Wb: np.ndarray
    n_sources: np.ndarray
    position_m: float
    peak_currents_A: list[float]
    results: list[FluxResult]


def commutation_curve(recordings: list[Recording], n_points: int = 101,
                      resistance_ohm: float | None = None) -> CommutationCurve:
    """Merge ``flux`` recordings at one stroke (different peaks) into one measured Psi(i) curve.

    Parameters
    ----------
    recordings : list of Recording
        ``flux`` recordings of one solenoid at one working gap (within 1 um).
    n_points : int
        Points of the current grid from 0 to the highest peak.
    resistance_ohm : float, optional
        Coil resistance [ohm] for every recording (default: each one's header, else estimated).

    Returns
    -------
    CommutationCurve

    Raises
    ------
    RecordingError
        No recordings, a kind other than ``flux``, different solenoids or strokes, no peak, a
        recording that starts energized or has no zero-current rest (its eq.-4 flux is not absolute).

    Notes
    -----
    Each current level is the average of the branch means of all peaks (of all recordings)
    that reach it, so low levels use every recording and high levels only the high peaks.
    """
    if not recordings:
        raise RecordingError("commutation_curve", ["no recordings given"])
    problems = []
    positions = []
    for rec in recordings:
        if rec.kind != "flux":
            problems.append(f"{rec._where()}: kind {rec.kind!r}, commutation curves need 'flux' recordings")
            continue
        x = rec.positions_m()
        if float(np.ptp(x)) > 1e-6:
            problems.append(f"{rec._where()}: the stroke moves by {np.ptp(x) * 1e3:.4f} mm "
                            "during the recording")
        positions.append(float(np.median(x)))
    names = {rec.solenoid for rec in recordings}
    if len(names) > 1:
        problems.append(f"recordings of different solenoids: {', '.join(sorted(names))}")
    if positions and max(positions) - min(positions) > 1e-6:
        problems.append("recordings at different strokes: "
                        + ", ".join(f"{x * 1e3:.4f} mm" for x in positions))
    if problems:
        raise RecordingError("commutation_curve", problems)
    results = [flux_linkage(rec, resistance_ohm, n_points=n_points) for rec in recordings]
    for rec, res in zip(recordings, results, strict=True):
        if not res.starts_at_rest:
            problems.append(f"{rec._where()}: starts energized ({res.current_A[0]:.4g} A): its flux is only known "
                            "up to the integration constant Psi(0); a flux recording must start at zero current")
        elif not res.offset_measured:
            problems.append(f"{rec._where()}: no zero-current rest at the start or end: the voltage offset of "
                            "eq. 4 cannot be measured (add a rest of >= 10 ms)")
    if problems:
        raise RecordingError("commutation_curve", problems)
    branches = [br for res in results for br in res.branches]
    if not branches:
        raise RecordingError("commutation_curve", ["no current peak in any recording"])
    grid = np.linspace(0.0, max(br.peak_A for br in branches), n_points)
    means, _ = peak_curves(branches, grid)
    stack = np.vstack(means)
    count = np.sum(np.isfinite(stack), axis=0)
    keep = count > 0
    merged = np.nansum(stack[:, keep], axis=0) / count[keep]
    return CommutationCurve(i_A=grid[keep], psi_Wb=merged, n_sources=count[keep].astype(np.int64),
                            position_m=float(np.median(positions)),
                            peak_currents_A=[br.peak_A for br in branches[::2]], results=results)


def plot_flux(result: FluxResult, path, title: str | None = None) -> Path:
    """Draw Psi(i): ascending and descending branches and the commutation curve, to a PNG.

    Parameters
    ----------
    result : FluxResult
        From :func:`flux_linkage`.
    path : str or pathlib.Path
        Image file to write (format from the suffix).
    title : str, optional
        Figure title.

    Returns
    -------
    pathlib.Path
    """
    from matplotlib.figure import Figure  # no pyplot: no global backend state

    path = Path(path)
    fig = Figure(figsize=(6.4, 4.8), layout="constrained")
    ax = fig.add_subplot()
    if result.branches:
        for br in result.branches:
            up = br.direction == "ascending"
            ax.plot(br.i_A, br.psi_Wb * 1e3, lw=0.8, color="tab:red" if up else "tab:blue",
                    label=f"{br.direction} (peak {br.peak_A:.2f} A)")
    else:
        ax.plot(result.current_A, result.psi_Wb * 1e3, lw=0.8, color="tab:gray", label="Psi(i)")
    if result.commutation_i_A.size:
        ax.plot(result.commutation_i_A, result.commutation_psi_Wb * 1e3, color="black", lw=1.6,
                label="commutation curve (branch mean)")
    ax.set_xlabel("current i [A]")
    ax.set_ylabel("flux linkage Psi [mWb]")
    ax.grid(True, alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    if len(handles) > 8:  # many peaks: one legend entry per kind of line
        wanted = {}
        for h, lab in zip(handles, labels, strict=True):
            wanted.setdefault(lab.split(" (")[0], h)
        handles, labels = list(wanted.values()), list(wanted)
    ax.legend(handles, labels, fontsize="small")
    ax.set_title(title or f"R = {result.resistance_ohm:.4g} ohm ({result.resistance_method})")
    fig.savefig(path, dpi=120)
    return path


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------


def add_cli(subparsers) -> None:
    """Register ``flux`` and ``check-recording``."""
    p = subparsers.add_parser(
        "flux", help="flux linkage Psi(i) from a recording's voltage and current (paper eq. 4)",
        description="Integrate Psi = int (U - R i) dt, remove the voltage offset, split the triangles "
                    "into branches; print R, offset, Psi at the peak and the hysteresis width.")
    p.add_argument("recording", type=Path, help="recording CSV (format v1) with a voltage_V column")
    p.add_argument("--plot", type=Path, metavar="PNG", help="draw Psi(i) branches and the commutation curve")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.add_argument("--resistance-ohm", type=float, metavar="R",
                   help="coil resistance [ohm] (overrides the header)")
    p.set_defaults(func=_cmd_flux)
    c = subparsers.add_parser("check-recording", help="validate recording files; print every problem",
                              description="Check recording CSV files against format v1; "
                                          "exit 1 if any problem.")
    c.add_argument("files", nargs="+", type=Path, metavar="FILE")
    c.set_defaults(func=_cmd_check)


def _cmd_flux(args: argparse.Namespace) -> int:
    if args.plot is not None:  # what matplotlib writes: a PNG, never over the recording
        from ..fileio import refuse_overwriting_inputs, require_directory

        if args.plot.suffix.lower() != ".png":
            args.plot = args.plot.with_name(args.plot.name + ".png")
        require_directory(args.plot.parent, "--plot")
        refuse_overwriting_inputs(args.plot, [args.recording])
    rec = read_recording(args.recording)
    res = flux_linkage(rec, args.resistance_ohm)
    if args.plot is not None:
        plot_flux(res, args.plot, title=f"{args.recording.name}: Psi(i)")
    if args.json:
        out = {"file": str(args.recording), **res.summary()}
        print(json.dumps(out))
        return 0
    x = rec.positions_m()
    print(f"recording: {args.recording} (kind {rec.kind}, solenoid {rec.solenoid}, "
          f"x = {np.mean(x) * 1e3:.3f} mm, {len(rec)} samples)")
    origin = {"header": "from the header", "given": "given", "plateau": "estimated from current plateaus",
              "closure": "estimated from flux closure"}[res.resistance_method]
    print(f"resistance used: {res.resistance_ohm:.4f} ohm ({origin})")
    print(f"offset removed: {res.offset_V * 1e3:.3f} mV (drift {res.offset_drift_V_per_s * 1e3:.4f} mV/s)")
    print(f"peak current: {res.peak_current_A:.4f} A")
    print(f"Psi at peak: {res.psi_at_peak_Wb * 1e3:.4f} mWb")
    if math.isfinite(res.hysteresis_width_Wb):
        print(f"hysteresis width: max {res.hysteresis_width_Wb * 1e3:.4f} mWb, "
              f"mean {res.hysteresis_mean_width_Wb * 1e3:.4f} mWb ({len(res.branches) // 2} peak(s))")
    else:
        print("hysteresis width: n/a (no current peak)")
    for note in res.notes:
        print(f"note: {note}")
    if args.plot is not None:
        print(f"plot: {args.plot}")
    return 0


def _cmd_check(args: argparse.Namespace) -> int:
    status = 0
    for path in args.files:
        problems = validate_recording(path)
        if problems:
            status = 1
            for line in problems:
                print(line)
        else:
            print(f"{path}: ok")
    sys.stdout.flush()
    return status
