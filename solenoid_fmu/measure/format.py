"""Test-rig recordings, format v1: the :class:`Recording` object and the rules of the format.

The format is specified in ``shared/recordings.md``: header lines ``# key: value`` (format version,
kind, solenoid, stroke ...), one column line whose names carry their units, then one sample per
line, comma-delimited, decimal point, strictly increasing time. Millimetres appear only in the
file (header ``position_mm``, column ``position_mm``); a :class:`Recording` holds SI arrays.

This module holds what the object and the file share: the kinds, the columns each kind needs, the
header keys and their value rules (:func:`header_value_problems`), the exact millimetre texts
(:func:`mm_text_to_m`, :func:`m_to_mm_text`). Construction checks the same rules as the file
reader (:mod:`solenoid_fmu.measure.reader`) and raises
:class:`~solenoid_fmu.errors.RecordingError` listing every problem.
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path

import numpy as np

from ..errors import RecordingError

__all__ = [
    "KINDS",
    "FIXED_STROKE_KINDS",
    "FORMAT_VERSION",
    "REQUIRED_COLUMNS",
    "KNOWN_COLUMNS",
    "REQUIRED_HEADER",
    "KNOWN_HEADER",
    "SHIFT_KEY",
    "FILL_KEY",
    "near_miss",
    "misspelt_names",
    "misspelt_in",
    "KEY_RE",
    "NUM_RE",
    "Recording",
    "make_recording",
    "header_value_problems",
    "mm_text_to_m",
    "mm_column_to_m",
    "m_to_mm_text",
]

#: Recording kinds of the test campaign (``shared/recordings.md``).
KINDS = ("flux", "force_stroke", "ramp", "eddy", "voltage_step")

#: Kinds recorded at a fixed stroke: they need header ``position_mm`` or a ``position_mm`` column.
FIXED_STROKE_KINDS = ("flux", "ramp", "eddy", "voltage_step")

#: The format version this module reads and writes.
FORMAT_VERSION = "1"

#: File columns every kind needs, in the canonical column order of the writer.
REQUIRED_COLUMNS = {
    "flux": ("time_s", "voltage_V", "current_A"),
    "force_stroke": ("time_s", "current_A", "position_mm", "force_N"),
    "ramp": ("time_s", "voltage_V", "current_A", "force_N"),
    "eddy": ("time_s", "voltage_V", "current_A"),
    "voltage_step": ("time_s", "voltage_V", "current_A", "force_N"),
}
KNOWN_COLUMNS = ("time_s", "voltage_V", "current_A", "position_mm", "force_N")
REQUIRED_HEADER = ("recording", "kind", "solenoid")
#: Every header key of ``recordings.md``; other keys are kept and not read (a rig may add its own).
KNOWN_HEADER = REQUIRED_HEADER + ("position_mm", "coil_resistance_ohm", "coil_temperature_C", "sample_rate_Hz",
                                  "notes")
#: The header key this project writes where ``coil_resistance_ohm`` was shifted (:mod:`.headers`): the offset [ohm].
SHIFT_KEY = "coil_resistance_shift_ohm"
#: The header key this project writes where ``coil_resistance_ohm`` was missing and taken from the recording's own
#: data: the estimate's 1-sigma [ohm].
FILL_KEY = "coil_resistance_estimated_sigma_ohm"
#: How alike (difflib's ratio, case ignored) an unknown header key or column name must be to a known one to be taken
#: for its misspelling: 'coil_resistance_Ohm', 'coil_resistence_ohm', 'position_MM', 'forceN' are; 'operator',
#: 'coil_resistance_estimated_sigma_ohm' (the pipeline's own key, 0.70) and 'temperature_C' (0.76) are not.
NEAR_MISS_RATIO = 0.85


def near_miss(name: str, known) -> str | None:
    """The known name that ``name`` (not itself known) looks like a misspelling of, or None."""
    if name in known:
        return None
    folded = {k.lower(): k for k in known}
    if name.lower() in folded:
        return folded[name.lower()]
    hit = difflib.get_close_matches(name.lower(), list(folded), n=1, cutoff=NEAR_MISS_RATIO)
    return folded[hit[0]] if hit else None


def misspelt_names(header_keys, columns=()) -> list[str]:
    """Why each unknown header key or column name that looks like a misspelt known one is not read, e.g.
    "header 'coil_resistance_Ohm' is not read (recordings.md has 'coil_resistance_ohm')". Such a name is kept and
    ignored as any other unknown one (the file stays readable as the rig wrote it); a caller says so where the known
    name's absence matters (a missing header resistance, a missing stroke)."""
    out = []
    for what, names, known in (("header", header_keys, KNOWN_HEADER), ("column", columns, KNOWN_COLUMNS)):
        for name in names:
            hit = None if name in (SHIFT_KEY, FILL_KEY) else near_miss(name, known)
            if hit is not None:
                out.append(f"{what} {name!r} is not read (recordings.md has {hit!r})")
    return out


def misspelt_in(recordings) -> list[str]:
    """:func:`misspelt_names` of each recording, as "FILE: header 'X' is not read (...)"."""
    return [f"{Path(r.path).name if r.path is not None else r.kind}: {line}" for r in recordings
            for line in misspelt_names(r.header, r.extra)]


KEY_RE = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
NUM_RE = re.compile(r"[ \t]*[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?[ \t]*\Z", re.ASCII)


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
            raise RecordingError(self.label(),
                                 ["no position: neither header 'position_mm' nor a position_mm column"])
        return np.full(self.time_s.shape, x_m)

    def label(self) -> str:
        """How messages name this recording: its file, else its kind and solenoid."""
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
        if not KEY_RE.match(key):
            problems.append(f"header key {key!r} is not a name (letters, digits, '_')")
        if "\n" in value or "\r" in value:
            problems.append(f"header {key!r}: value spans several lines")
        elif value != value.strip():
            problems.append(f"header {key!r}: value {value!r} has surrounding blanks")
    problems += [message for _, message in header_value_problems(rec.header)]
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
        if (not isinstance(name, str) or not name.strip() or name != name.strip() or name in KNOWN_COLUMNS
                or name == "position_m" or name.startswith("#") or any(c in name for c in ",\n\r")):
            problems.append(f"extra column name {name!r} is not usable "
                            "(empty, blanks around, a known column, starts with '#', or has ',')")
    if rec.kind in KINDS:
        have = {"time_s", "current_A"}
        have |= {c for c, a in (("voltage_V", rec.voltage_V), ("force_N", rec.force_N),
                                ("position_mm", rec.position_m)) if a is not None}
        missing = [c for c in REQUIRED_COLUMNS[rec.kind] if c not in have]
        if missing:
            problems.append(f"kind {rec.kind!r} needs column(s) {', '.join(missing)}")
        if rec.kind in FIXED_STROKE_KINDS and rec.position_m is None and "position_mm" not in rec.header:
            problems.append(f"kind {rec.kind!r} is a fixed-stroke test: give header 'position_mm' "
                            "or a position_mm column")
    return problems


def header_value_problems(header: dict[str, str]) -> list[tuple[str, str]]:
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
        if not NUM_RE.match(text):
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
            head["position_mm"] = m_to_mm_text(float(position_m))
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
# Millimetre texts (exact)
# --------------------------------------------------------------------------------------------


def mm_text_to_m(text: str) -> float:
    """A millimetre number from a file to metres, rounded once: ``float(Decimal(text) / 1000)``.

    Shifting the decimal exponent (rather than dividing the parsed float by 1000) makes the
    conversion exact to the last bit and lets :func:`m_to_mm_text` invert it exactly.
    """
    return float(Decimal(text.strip()).scaleb(-3))


def mm_column_to_m(cells: list[str]) -> np.ndarray:
    """Vectorised :func:`mm_text_to_m` for a column of already validated number texts [m]."""
    stripped = [c.strip() for c in cells]
    plain = [c + "e-3" if "e" not in c and "E" not in c else None for c in stripped]
    if all(p is not None for p in plain):
        return np.array(plain, dtype=np.float64)
    return np.array([mm_text_to_m(c) for c in stripped], dtype=np.float64)


def m_to_mm_text(x_m: float) -> str:
    """The millimetre text of ``x_m`` that :func:`mm_text_to_m` reads back exactly (repr shifted)."""
    d = Decimal(repr(float(x_m))).scaleb(3)
    text = format(d, "f") if d == 0 or Decimal("1e-6") <= abs(d) < Decimal("1e9") else str(d)
    return text if "." in text or "E" in text else text + ".0"
