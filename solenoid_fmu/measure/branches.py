"""Branches of triangular excitations: ascending and descending halves per current peak, on a grid.

Used by :func:`solenoid_fmu.measure.flux_linkage` (commutation curve and hysteresis width of one
recording) and by the identification (the hysteresis width weights the fit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["FluxBranch", "split_branches", "branch_on_grid", "peak_curves"]


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


#: A current peak counts when the current falls by this share of the recording's top current on both sides.
PEAK_PROMINENCE = 0.2


def _one_per_top(peaks: list[int], i_s: np.ndarray, dip: float) -> list[int]:
    """Peaks (sample indices, increasing) with those on one top merged: two neighbours between which the
    current ``i_s`` [A] does not fall by ``dip`` [A] below the lower of them are one peak, the higher one (the
    first of equals). ``find_peaks`` gives each of two equal samples on a hold at the top the full prominence
    (it measures a peak against a strictly higher one): a quantized current held at its top gave two peaks
    a few samples apart and a branch pair of two samples between them."""
    kept: list[int] = []
    for p in peaks:
        if kept and float(np.min(i_s[kept[-1]:p + 1])) > min(i_s[kept[-1]], i_s[p]) - dip:
            if i_s[p] > i_s[kept[-1]]:
                kept[-1] = p
            continue
        kept.append(p)
    return kept


def split_branches(i, i_s, psi, thr, k) -> list[FluxBranch]:
    """Ascending and descending branch for every positive current peak."""
    from scipy.signal import find_peaks  # heavy (about 0.8 s): loaded on first use

    i_top = float(np.max(i_s))
    if i_top <= 0:
        return []
    peaks, _ = find_peaks(i_s, prominence=PEAK_PROMINENCE * i_top)
    n = i.size
    # each peak refined to the highest smoothed sample within +-k; two peaks that refine onto each
    # other (or cross) count once, so that every valley between two peaks is a non-empty range
    refined = sorted({max(0, p - k) + int(np.argmax(i_s[max(0, p - k):min(n, p + k + 1)])) for p in peaks.tolist()})
    refined = _one_per_top(refined, i_s, PEAK_PROMINENCE * i_top)
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


def branch_on_grid(i_A: np.ndarray, psi_Wb: np.ndarray, grid: np.ndarray) -> np.ndarray:
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
        pa = branch_on_grid(asc.i_A, asc.psi_Wb, grid)
        pd = branch_on_grid(desc.i_A, desc.psi_Wb, grid)
        means.append(0.5 * (pa + pd))
        widths.append(pd - pa)
    return means, widths

