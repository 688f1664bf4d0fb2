"""Writing recording files (format v1): atomic, and exact to the last bit by default."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..errors import RecordingError
from ..fileio import atomic_write_text
from .format import Recording, m_to_mm_text

__all__ = ["write_recording"]


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
            mm = [m_to_mm_text(v) for v in rec.position_m.tolist()]
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
    atomic_write_text(path, out.getvalue())
    return path
