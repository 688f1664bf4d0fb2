"""Conditioning of a recording's voltage and current before paper eq. 4: noise, rests, offsets, plateaus.

Shared by :func:`solenoid_fmu.measure.flux_linkage` and the resistance track
(:mod:`solenoid_fmu.measure.resistance`): :func:`condition` finds the zero-current rest phases,
removes the voltage offset (with drift) seen there and a significant current-sensor offset, and
returns the corrected signals with the thresholds it used.

SciPy's submodules are imported where they are used (see :mod:`solenoid_fmu.measure.flux`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import RecordingError
from .format import Recording

__all__ = ["Conditioned", "condition", "noise_std", "smooth", "rest_runs", "stationary", "offset_model",
           "plateaus", "hold_segments"]


def noise_std(y: np.ndarray) -> float:
    """Robust white-noise standard deviation of a signal (MAD of second differences)."""
    if y.size < 5:
        return 0.0
    d2 = np.diff(y, 2)
    mad = np.median(np.abs(d2 - np.median(d2)))
    return float(1.4826 * mad / math.sqrt(6.0))


def smooth(y: np.ndarray, k: int) -> np.ndarray:
    """Moving mean over ``k`` samples (edges: nearest); ``y`` itself for ``k <= 1``."""
    from scipy.ndimage import uniform_filter1d  # heavy: see the module docstring

    return y if k <= 1 else uniform_filter1d(y, size=k, mode="nearest")


def rest_runs(i_s: np.ndarray, thr_A: float, min_len: int) -> tuple[slice | None, slice | None]:
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


def stationary(u: np.ndarray, u_scale: float) -> bool:
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


def offset_model(t, u, head, tail):
    """Voltage offset (a, b, t0, n, se): U_off(t) = a + b (t - t0), from 10 %-trimmed means of U [V]
    over the ``n`` (0-2) rest phases used; ``se`` [V] the larger standard error of those means.

    U alone (not U - R i): with i = 0 in the rest phases, R i only adds the current noise times R.
    A rest phase whose voltage is still settling (:func:`stationary`) is not used.
    """
    from scipy.stats import trim_mean  # heavy: see the module docstring

    anchors = []
    se = 0.0
    for sl in (head, tail):
        if sl is not None and sl.stop - sl.start > 0 and stationary(u[sl], float(np.max(np.abs(u)))):
            anchors.append((float(np.median(t[sl])), float(trim_mean(u[sl], 0.1))))
            se = max(se, float(np.std(u[sl])) / math.sqrt(sl.stop - sl.start))
    if not anchors:
        return 0.0, 0.0, float(t[0]), 0, math.inf
    if len(anchors) == 1:
        return anchors[0][1], 0.0, anchors[0][0], 1, se
    (t0, a0), (t1, a1) = anchors
    return a0, (a1 - a0) / (t1 - t0), t0, 2, se


def plateaus(i_s: np.ndarray, sigma_s: float, i_max: float, min_len: int) -> np.ndarray:
    """Boolean mask of settled samples on non-zero current plateaus (second half of each run)."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d  # heavy: see the module docstring

    band = max(10.0 * sigma_s, 1e-3 * i_max)
    span = maximum_filter1d(i_s, min_len, mode="nearest") - minimum_filter1d(i_s, min_len, mode="nearest")
    still = (span < band) & (np.abs(i_s) > 0.1 * i_max)
    mask = np.zeros_like(still)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], still.astype(np.int8), [0]))))
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        if stop - start >= min_len:
            mask[(start + stop) // 2: stop] = True
    return mask


@dataclass
class Conditioned:
    """A recording's signals ready for eq. 4 (see :func:`condition`).

    Attributes
    ----------
    t : numpy.ndarray, shape (n,)
        Time [s].
    uc, ic : numpy.ndarray, shape (n,)
        Voltage less its offset model [V]; current less the current-sensor offset [A].
    i_s : numpy.ndarray, shape (n,)
        Current smoothed over about 1 ms [A] (current offset *not* removed).
    offset : numpy.ndarray, shape (n,)
        The voltage offset model per sample [V].
    drift_V_per_s, offset_se_V, current_offset_A : float
        Offset drift [V/s], the standard error of the offset [V] (inf: not measured), the
        current-sensor offset removed [A].
    n_anchors : int
        Rest phases that gave the offset (0-2).
    head, tail : slice or None
        The zero-current rest phases at the start and end.
    dt, sigma_i, i_max, thr : float
        Median sample interval [s], current noise [A], largest smoothed current [A], rest threshold [A].
    k_smooth : int
        Samples of the 1-ms smoothing.
    notes : list of str
        What was (not) removed, in plain English.
    """

    t: np.ndarray
    uc: np.ndarray
    ic: np.ndarray
    i_s: np.ndarray
    offset: np.ndarray
    drift_V_per_s: float
    offset_se_V: float
    current_offset_A: float
    n_anchors: int
    head: slice | None
    tail: slice | None
    dt: float
    sigma_i: float
    i_max: float
    thr: float
    k_smooth: int
    notes: list[str] = field(default_factory=list)

    def plateau_mask(self) -> np.ndarray:
        """Settled samples of the current plateaus (|i| > 10 % of the peak, held >= 50 ms)."""
        k_plateau = max(5, 2 * self.k_smooth)
        return plateaus(smooth(self.ic, k_plateau), self.sigma_i / math.sqrt(k_plateau), self.i_max,
                        max(20, int(round(50e-3 / self.dt))))


def condition(rec: Recording) -> Conditioned:
    """Rest phases, voltage offset (with drift) and current offset of a recording with voltage.

    Raises
    ------
    RecordingError
        No voltage column, or the current is zero throughout.

    Notes
    -----
    Offset: the 10 %-trimmed mean of U over the zero-current rest phases at the start and at the
    end (each at least 10 ms; of the end phase only its second half); with both, linear drift
    between them. Rest: ``|i| < max(5 sigma_i, 0.2 % of the peak)``. A mean current in the rest
    phases is removed as a current-sensor offset only when it exceeds five standard errors.
    """
    if rec.voltage_V is None:
        raise RecordingError(rec.label(), ["no voltage_V column: the flux linkage needs the coil voltage"])
    t = rec.time_s
    u = rec.voltage_V
    i = rec.current_A
    n = t.size
    notes: list[str] = []
    dt = float(np.median(np.diff(t)))
    k_smooth = max(1, int(round(1e-3 / dt)))
    i_s = smooth(i, k_smooth)
    sigma_i = noise_std(i)
    i_max = float(np.max(np.abs(i_s)))
    if i_max <= 0:
        raise RecordingError(rec.label(), ["the current is zero throughout: no flux to compute"])
    thr = max(5.0 * sigma_i, 2e-3 * i_max)
    min_rest = max(10, int(round(10e-3 / dt)))
    head, tail = rest_runs(i_s, thr, min_rest)
    if head is None and tail is None:
        notes.append("no zero-current rest phase at the start or end: no voltage offset removed")
    a, b, t0, n_anchors, offset_se = offset_model(t, u, head, tail)
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
    return Conditioned(t=t, uc=uc, ic=i - i_off, i_s=i_s, offset=offset, drift_V_per_s=float(b),
                       offset_se_V=offset_se, current_offset_A=i_off, n_anchors=n_anchors, head=head, tail=tail,
                       dt=dt, sigma_i=sigma_i, i_max=i_max, thr=thr, k_smooth=k_smooth, notes=notes)


def hold_segments(rec: Recording) -> list[slice]:
    """The settled current holds of a recording with voltage: one slice per plateau (the second half of
    each run where |i| > 10 % of the peak holds still for >= 50 ms, :meth:`Conditioned.plateau_mask`),
    in time order. There dPsi/dt = 0: no eddy current, and U = R i."""
    mask = condition(rec).plateau_mask()
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(np.int8), [0]))))
    return [slice(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]
