"""Which recordings fit and which judge: the fit/validation split and the cross-validation folds.

Both go by the size of the excitations, not by file names (other rigs name files anyhow): within
each kind, the recordings are ordered from the largest excitation down (:func:`largest_first_key`,
by :func:`excitation_size`) and dealt out alternately.

* :func:`split_recordings` (``improve``'s gate): per kind, the largest excitation is fitted, the
  next validated on, and so on; a kind with a single recording is only validated on.
* :func:`cv_folds` (``diagnose``'s two-fold cross-validation): one toggle running across the kinds
  (in sorted order), so that both folds hold recordings of every kind and size; a single
  recording is cut into 20 alternating blocks in time.
"""

from __future__ import annotations

import math

import numpy as np


def excitation_size(time_s, current_A) -> tuple[float, float]:
    """How large an excitation is: (ln of the peak |current| [A] rounded to 0.1, i.e. to about 10 %;
    95th percentile of |di/dt| over 1 ms [A/s]). Compared as a tuple: the peak, then the rate."""
    i = np.asarray(current_A, dtype=float)
    t = np.asarray(time_s, dtype=float)
    peak = float(np.max(np.abs(i))) if i.size else 0.0
    k = max(1, int(round(1e-3 / max(float(np.median(np.diff(t))), 1e-12)))) if t.size > 1 else 1
    if t.size > 2 * k:
        rate = float(np.percentile(np.abs(i[k:] - i[:-k]) / (t[k:] - t[:-k]), 95))
    else:
        rate = 0.0
    return (round(math.log(peak), 1) if peak > 0 else -math.inf, rate)


def largest_first_key(time_s, current_A, name: str) -> tuple:
    """Sort key of a recording that puts the largest :func:`excitation_size` first, ties in the
    order of ``name``."""
    peak, rate = excitation_size(time_s, current_A)
    return (-peak, -rate, name)


def _by_kind(items) -> dict:
    """kind -> indices of ``items`` of that kind."""
    out: dict = {}
    for k, item in enumerate(items):
        out.setdefault(item.kind, []).append(k)
    return out


def split_recordings(recordings) -> tuple[list, list]:
    """Fit / validation split: per kind, from the largest excitation down, alternately fit and validate.

    "Largest" is judged from the data (:func:`excitation_size`): the peak current (to about 10 %),
    then the rate of change of the current. The largest excitation of a kind is fitted; a kind
    with a single recording is only validated on. Ties keep the order of the file paths.
    """
    fit, val = [], []
    recordings = list(recordings)
    for ks in _by_kind(recordings).values():
        recs = sorted((recordings[k] for k in ks),
                      key=lambda r: largest_first_key(r.time_s, r.current_A, str(r.path or "")))
        if len(recs) == 1:
            val.extend(recs)
            continue
        for k, rec in enumerate(recs):
            (fit if k % 2 == 0 else val).append(rec)
    return fit, val


def cv_folds(cases) -> list[tuple[list, list]]:
    """Two folds of (case index, sample mask) for cross-validation (``[(train, test), (test, train)]``).

    Whole recordings go to one fold or the other: within each kind, from the largest excitation
    down (:func:`largest_first_key`, ties by name), alternately (one toggle running across kinds in
    sorted order), so that both folds hold recordings of every kind and size whatever the files
    are called. A single recording is cut into 20 alternating blocks in time.
    """
    if len(cases) >= 2:
        by_kind = _by_kind(cases)
        a, b = [], []
        toggle = 0
        for kind in sorted(by_kind):
            for k in sorted(by_kind[kind], key=lambda k: largest_first_key(cases[k].time_s, cases[k].current_A,
                                                                             cases[k].name)):
                (a if toggle == 0 else b).append((k, np.ones(len(cases[k].time_s), bool)))
                toggle ^= 1
        return [(a, b), (b, a)]
    n = len(cases[0].time_s)
    half = (np.arange(n) * 20 // max(n, 1)) % 2 == 0  # 20 alternating blocks: both folds span the run
    return [([(0, half)], [(0, ~half)]), ([(0, ~half)], [(0, half)])]
