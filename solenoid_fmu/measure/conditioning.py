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
from typing import NamedTuple

import numpy as np

from ..errors import RecordingError
from .format import Recording

__all__ = ["Conditioned", "condition", "noise_std", "armature_moves", "MOVE_NOISE_SIGMAS",
           "smooth", "rest_runs", "rest_level", "RestLevel",
           "offset_model", "plateaus", "hold_segments", "SETTLING_F", "DRIFT_SIGMAS"]


def noise_std(y: np.ndarray) -> float:
    """Robust white-noise standard deviation of a signal (MAD of second differences)."""
    if y.size < 5:
        return 0.0
    d2 = np.diff(y, 2)
    mad = np.median(np.abs(d2 - np.median(d2)))
    return float(1.4826 * mad / math.sqrt(6.0))


#: A position column whose spread (0.5 to 99.5 percentile) is within this many of its own noise sigmas (or 1 um)
#: is a fixed stroke read by a noisy sensor (:func:`armature_moves`).
MOVE_NOISE_SIGMAS = 10.0


def armature_moves(position_m) -> bool:
    """Whether a recording's position column [m] shows the armature moving (None: no column, a fixed stroke). A fixed
    stroke logged by a sensor with 2 um of noise spans 15 um over 20 000 samples: taken as moving, it cost every
    recording its resistance track and the identification its campaign (stop 52)."""
    if position_m is None:
        return False
    x = np.asarray(position_m, dtype=float)
    lo, hi = np.percentile(x, [0.5, 99.5])
    return bool(float(hi - lo) > max(1e-6, MOVE_NOISE_SIGMAS * noise_std(x)))


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


#: Time constants the settling fit of a rest phase tries, as multiples of the sample interval (log grid).
SETTLING_TAU_SAMPLES = np.geomspace(1.0, 1000.0, 31)
#: A richer model of a rest phase's voltage (a decay against a line, a line against a constant) is taken when it
#: lowers the sum of squares by more than this many residual variances (one extra parameter each: the 0.1 %
#: point of F(1, n) is about 11; the decay takes the best of the grid's time constants, hence the margin).
SETTLING_F = 12.0
#: Two rest phases' offsets differ significantly (a drift of the DAQ) beyond this many combined sigmas.
DRIFT_SIGMAS = 3.0


class RestLevel(NamedTuple):
    """What a rest phase says about the voltage offset (:func:`rest_level`)."""

    level_V: float       #: the offset the phase measures (settled or trending: its mean; settling: the asymptote)
    se_V: float          #: its standard error
    state: str           #: "flat", "trending" (a straight line beats a constant) or "settling" (a decay beats a line)
    slope_V_per_s: float  #: the straight line's slope
    slope_se_V_per_s: float


def rest_level(t: np.ndarray, u: np.ndarray) -> RestLevel:
    """The voltage offset a zero-current rest phase measures, from three models of its voltage ``u`` [V].

    A rest phase right after an excitation may still carry a voltage that decays (the current's tail under the
    rest threshold, R i and the flux it moves; eddy currents; a hysteresis creeping to remanence): its mean is
    not the offset. Models: a constant; a straight line
    (an offset that drifts); ``a + c exp(-(t - t[0]) / tau)`` (an induced voltage decaying to the offset
    ``a``; tau on the grid :data:`SETTLING_TAU_SAMPLES` in samples). Each richer model is taken when it
    lowers the sum of squares by more than :data:`SETTLING_F` residual variances (the decay against the
    line: "settling"; the line against the constant: "trending"; else "flat"). Flat or trending: the level is
    the 10 %-trimmed mean, its standard error the residual std / sqrt(n). Settling: the asymptote at the best
    tau, its standard error the fit's at that tau combined with the spread of the asymptote over the time
    constants within one chi^2 unit of the best (profile).
    """
    from scipy.stats import trim_mean  # heavy: see the module docstring

    n = u.size
    mean = float(trim_mean(u, 0.1)) if n else 0.0
    if n < 12:
        return RestLevel(mean, float(np.std(u)) / math.sqrt(max(n, 1)), "flat", 0.0, math.inf)
    du = u - np.mean(u)
    rss0 = float(du @ du)
    tc = t - float(np.mean(t))
    stt = max(float(tc @ tc), 1e-300)
    slope = float(tc @ du) / stt
    rss_lin = max(rss0 - slope * slope * stt, 0.0)
    fits = []  # (rss, asymptote, its unscaled variance at this tau)
    step = float(np.median(np.diff(t))) or 1.0
    for tau in SETTLING_TAU_SAMPLES * step:
        X = np.column_stack([np.ones(n), np.exp(-(t - t[0]) / tau)])
        coef, *_ = np.linalg.lstsq(X, u, rcond=None)
        fits.append((float(np.sum((X @ coef - u) ** 2)), float(coef[0]), float(np.linalg.pinv(X.T @ X)[0, 0])))
    best = min(fits, key=lambda f: f[0])
    s2_exp, s2_lin = best[0] / (n - 3), rss_lin / (n - 2)
    slope_se = math.sqrt(s2_lin / stt)
    if rss_lin - best[0] > SETTLING_F * s2_exp:
        spread = max(abs(f[1] - best[1]) for f in fits if f[0] <= best[0] + s2_exp)
        return RestLevel(best[1], math.hypot(math.sqrt(max(best[2] * s2_exp, 0.0)), spread), "settling",
                         slope, slope_se)
    if rss0 - rss_lin > SETTLING_F * s2_lin:
        return RestLevel(mean, math.sqrt(s2_lin / n), "trending", slope, slope_se)
    return RestLevel(mean, math.sqrt(rss0 / (n - 1) / n), "flat", slope, slope_se)


def offset_model(t, u, head, tail):
    """Voltage offset (a, b, t0, n, se): U_off(t) = a + b (t - t0) [V], from the ``n`` (0-2) rest phases used;
    ``se`` [V] the larger standard error of the phases' levels.

    U alone (not U - R i): with i = 0 in the rest phases, R i only adds the current noise times R.
    Each phase's level comes from :func:`rest_level`. A flat or trending phase measures the offset, a
    settling one extrapolates it: where one phase measures, a settling one is not used. With two phases a
    drift is taken only when their levels differ by more than :data:`DRIFT_SIGMAS` combined standard errors,
    and a trending phase whose own slope disagrees with that drift (by as many sigmas) is an induced
    voltage, not a drift: it is treated as settling. Without a drift the offset is the inverse-variance mean
    of the phases, constant. A lone trending phase (nothing to tell a drift from a decay) gives its mean, uncertain
    by at least half its own change (|slope| x its duration / 2).
    """
    found = []
    for sl in (head, tail):
        if sl is not None and sl.stop - sl.start > 0:
            rl = rest_level(t[sl], u[sl])
            if math.isfinite(rl.level_V):
                found.append((float(np.median(t[sl])), rl.level_V, max(rl.se_V, 1e-15), rl, float(np.ptp(t[sl]))))
    measuring = [f for f in found if f[3].state != "settling"]
    if len(measuring) == 2:
        (t0, a0, s0, *_), (t1, a1, s1, *_) = measuring
        b, b_se = (a1 - a0) / (t1 - t0), math.hypot(s0, s1) / abs(t1 - t0)
        agree = [f for f in measuring if f[3].state != "trending"
                 or abs(f[3].slope_V_per_s - b) <= DRIFT_SIGMAS * math.hypot(f[3].slope_se_V_per_s, b_se)]
        measuring = agree or measuring[:1]
    used = measuring or found
    if not used:
        return 0.0, 0.0, float(t[0]), 0, math.inf
    if len(used) == 1:
        tm, level, se, rl, width = used[0]
        if rl.state == "trending":  # no other rest to tell a drift from a decay: uncertain by its own change
            se = math.hypot(se, 0.5 * abs(rl.slope_V_per_s) * width)
        return level, 0.0, tm, 1, se
    (t0, a0, s0, *_), (t1, a1, s1, *_) = used
    if abs(a1 - a0) > DRIFT_SIGMAS * math.hypot(s0, s1):
        return a0, (a1 - a0) / (t1 - t0), t0, 2, max(s0, s1)
    w0, w1 = 1.0 / s0 ** 2, 1.0 / s1 ** 2
    # the reported se stays the larger of the two (as with a drift): downstream it decides whether the eq.-4
    # flux's trend is known (the loop compares flux residuals orthogonal to a trend where it is not)
    return (w0 * a0 + w1 * a1) / (w0 + w1), 0.0, t0, 2, max(s0, s1)


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
    Offset: the level U settles to in the zero-current rest phases at the start and at the end (each
    at least 10 ms; of the end phase only its second half; :func:`rest_level`: the 10 %-trimmed mean, or
    the asymptote of a decaying exponential where an induced voltage still decays); with both, linear
    drift between them only when they differ significantly (:func:`offset_model`). Rest:
    ``|i| < max(5 sigma_i, 0.2 % of the peak)``. A mean current in the rest phases is removed as a
    current-sensor offset only when it exceeds five standard errors.
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
