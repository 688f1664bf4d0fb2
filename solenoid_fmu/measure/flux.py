"""Flux linkage from voltage and current (paper eq. 4), and the commutation curve of several recordings.

:func:`flux_linkage` integrates ``Psi(t) = int (U - R i) dt`` (paper eq. 4) with what real data
needs: the coil resistance from the header or estimated (plateaus, else flux closure), removal of
the voltage offset seen in the zero-current rest phases (with linear drift when there is a rest
phase at both ends), the split of triangular excitations into ascending and descending branches
(:mod:`solenoid_fmu.measure.branches`), and the commutation curve (mean of the two branches, the
paper's initial curve) with the hysteresis width. :func:`commutation_curve` merges several
``flux`` recordings at one stroke.

SciPy's submodules are imported where they are used: each takes 0.2-0.8 s to load, and reading or
writing a recording (the rig, the FMU's input) needs none of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import RecordingError
from .branches import FluxBranch, peak_curves, split_branches
from .conditioning import armature_moves, condition
from .format import Recording
from .polarity import polarity_problem
from .resistance import ResistanceTrack, resistance_track
from .resistance_campaign import CampaignResistance, campaign_resistance

__all__ = ["FluxResult", "flux_linkage", "CommutationCurve", "commutation_curve"]


@dataclass
class FluxResult:
    """Flux linkage of one recording (paper eq. 4) and what follows from it.

    Attributes
    ----------
    time_s, current_A : numpy.ndarray, shape (n,)
        The recording's time [s] and current [A] (less the current offset, if one was removed).
    psi_Wb : numpy.ndarray, shape (n,)
        Flux linkage per sample [Wb], zero at the first sample.
    R_ohm : float
        Coil resistance used [ohm].
    resistance_source : str
        ``"header"`` (coil_resistance_ohm), ``"given"`` (argument) or ``"estimated"`` (also the track).
    resistance_method : str
        How it was obtained: ``"header"``, ``"given"``, ``"plateau"`` (U/i where the current
        holds still), ``"closure"`` (Psi back to its start value) or ``"track"`` (R(t) of
        :attr:`track`); see :func:`flux_linkage`.
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
    track : ResistanceTrack or None
        The resistance track R(t) integrated with (``resistance="track"`` or a given track;
        :mod:`solenoid_fmu.measure.resistance`), else None (one R throughout). With a track
        ``R_ohm`` is R at the first sample.
    head_rest_samples : int
        Samples of the zero-current rest phase at the start (0 without one, see :func:`flux_linkage`'s
        Notes): there the flux is constant and only the sensors' noise moves the current, so a comparison
        anchors the flux on their mean rather than on the first sample alone.
    """

    time_s: np.ndarray
    current_A: np.ndarray
    psi_Wb: np.ndarray
    R_ohm: float
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
    track: ResistanceTrack | None = None
    head_rest_samples: int = 0

    def summary(self) -> dict:
        """The CLI's JSON object: numbers in SI, NaN as None."""
        def num(v):
            return None if v is None or not math.isfinite(v) else float(v)
        return {
            "resistance_ohm": num(self.R_ohm),
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
            "head_rest_samples": self.head_rest_samples,
            **self._track_summary(num),
        }

    def _track_summary(self, num) -> dict:
        """The resistance track's keys (None without a track): R at start and end, kappa, sigmas, pinned."""
        tr = self.track
        keys = ("resistance_sigma_ohm", "resistance_end_ohm", "resistance_end_sigma_ohm", "kappa_per_J",
                "kappa_sigma_per_J", "psi_at_peak_sigma_Wb")
        if tr is None:
            return {**dict.fromkeys(keys), "resistance_pinned": None, "resistance_constraints": [],
                    "header_resistance_disagrees": None, "header_resistance_overruled": None,
                    "resistance_why_not_pinned": ""}
        vals = (tr.R0_sigma_ohm, tr.R_end_ohm, tr.R_end_sigma_ohm, tr.kappa_per_J, tr.kappa_sigma_per_J,
                tr.psi_peak_sigma_Wb)
        return {**{k: num(v) for k, v in zip(keys, vals, strict=True)}, "resistance_pinned": tr.pinned,
                "resistance_constraints": list(tr.constraints), "header_resistance_disagrees": tr.header_disagrees,
                "header_resistance_overruled": tr.header_overruled, "resistance_why_not_pinned": tr.why_not_pinned}


def flux_linkage(rec: Recording, R_ohm: float | None = None, *, n_points: int = 101,
                 resistance: str | ResistanceTrack | None = None) -> FluxResult:
    """Flux linkage Psi(t) from voltage and current, and Psi(i) of triangular excitations.

    Parameters
    ----------
    rec : Recording
        A recording with a ``voltage_V`` column (any kind; ``flux`` and ``eddy`` have triangles).
    R_ohm : float, optional
        Coil resistance [ohm]; overrides the header.
    n_points : int
        Points of the current grid of the commutation curve (0 to the highest peak).
    resistance : {None, "track"} or ResistanceTrack
        None (default): one R throughout (argument, header, else estimated; see Notes). ``"track"``:
        integrate with R(t) estimated from this recording
        (:func:`~solenoid_fmu.measure.resistance_track`, ``R_ohm`` or the header as its prior); a
        :class:`~solenoid_fmu.measure.ResistanceTrack` (e.g. from
        :func:`~solenoid_fmu.measure.campaign_resistance`): integrate with that one.

    Returns
    -------
    FluxResult

    Raises
    ------
    RecordingError
        No voltage column; no resistance in the header and none can be estimated; a current that is not positive
        (negative throughout: take it :func:`~.polarity.mirrored`; bipolar: :func:`~.polarity.polarity_problem`).

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
    problems = _input_problems(rec, n_points)
    if problems:
        raise RecordingError(rec.label(), problems)
    c = condition(rec)
    t = c.t
    notes = list(c.notes)
    track = _track_of(rec, resistance, R_ohm, t.size)
    R, method = _constant_resistance(rec, c, R_ohm, notes, estimate=track is None)

    from scipy.integrate import cumulative_trapezoid  # heavy: see the module docstring

    if track is not None:
        R, method = track.R0_ohm, "track"
        notes += track.notes
        if not track.pinned:
            notes.append(f"resistance track not pinned: {track.why_not_pinned}")
    psi = cumulative_trapezoid(c.uc - (R * c.ic if track is None else track.R_t_ohm * c.ic), t, initial=0.0)
    i, i_s = c.ic, c.i_s - c.current_offset_A
    notes += _context_notes(rec, i_s, c.thr)
    branches = split_branches(i, i_s, psi, c.thr, c.k_smooth)
    curve = _commutation(branches, psi, i_s, n_points, c.k_smooth, notes)
    return FluxResult(time_s=t, current_A=i, psi_Wb=psi, R_ohm=float(R), resistance_method=method,
                      resistance_source=method if method in ("header", "given") else "estimated",
                      offset_V=float(np.trapezoid(c.offset, t) / (t[-1] - t[0])),
                      offset_drift_V_per_s=float(c.drift_V_per_s), current_offset_A=c.current_offset_A,
                      branches=branches, **curve, notes=notes, starts_at_rest=bool(abs(float(i_s[0])) <= c.thr),
                      offset_measured=c.n_anchors > 0, offset_uncertainty_Wb=c.offset_se_V * float(t[-1] - t[0]),
                      track=track, head_rest_samples=_head_rest(c))


def _input_problems(rec: Recording, n_points: int) -> list[str]:
    """Why :func:`flux_linkage` cannot take ``rec``: no voltage, too few grid points, a current that is not one-
    signed positive (:func:`~.polarity.polarity_problem`); empty when it can."""
    problems = [] if rec.voltage_V is not None else ["no voltage_V column: the flux linkage needs the coil voltage"]
    if n_points < 3:
        problems.append(f"n_points must be >= 3, got {n_points}")
    why = polarity_problem(rec)
    return problems + ([why] if why is not None else [])


def _head_rest(c) -> int:
    """Leading samples at rest (the smoothed current within the rest threshold, less the last 5 %, at least 3;
    unlike the offset's rest phase, of any duration): 0 when the recording does not start at rest."""
    active = np.abs(c.i_s) > c.thr
    first = int(np.argmax(active)) if active.any() else 0
    n = first - max(1, first // 20)
    return n if n >= 3 else 0


def _track_of(rec: Recording, resistance, R_ohm: float | None, n: int) -> ResistanceTrack | None:
    """The resistance track :func:`flux_linkage` integrates with (its ``resistance`` argument), or None."""
    if isinstance(resistance, ResistanceTrack):
        if resistance.label != rec.label() or resistance.R_t_ohm.size != n:
            raise RecordingError(rec.label(), [f"the resistance track is of {resistance.label} "
                                               f"({resistance.R_t_ohm.size} samples), not of this recording"])
        return resistance
    if resistance == "track":
        return resistance_track(rec, R_ohm)
    if resistance is not None:
        raise RecordingError(rec.label(), [f"resistance must be None, 'track' or a ResistanceTrack, "
                                           f"got {resistance!r}"])
    return None


def _constant_resistance(rec: Recording, c, R_ohm: float | None, notes: list, *, estimate: bool) -> tuple:
    """(R [ohm], method) of one resistance throughout: given, the header's, else (``estimate``) from the
    current plateaus or the flux closure (:func:`flux_linkage`'s Notes); (None, None) without one."""
    if R_ohm is not None:
        if not (math.isfinite(R_ohm) and R_ohm > 0):
            raise RecordingError(rec.label(), [f"resistance must be > 0 ohm, got {R_ohm!r}"])
        return float(R_ohm), "given"
    if rec.coil_resistance_ohm is not None:
        return rec.coil_resistance_ohm, "header"
    if not estimate:
        return None, None
    t, uc, ic = c.t, c.uc, c.ic
    plateau = c.plateau_mask()
    closed = abs(float(c.i_s[-1] - c.i_s[0])) <= c.thr
    R_est, method = math.nan, None
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
        raise RecordingError(rec.label(), [
            "no coil resistance: the header has no coil_resistance_ohm, the current has no plateau "
            "to estimate it from, and the excitation does not return to its start "
            "(give --resistance-ohm or add '# coil_resistance_ohm: ...')"])
    return R_est, method


def _context_notes(rec: Recording, i_s: np.ndarray, thr: float) -> list[str]:
    """Notes on what the flux of this recording is not: a moving armature, a start under current."""
    notes = []
    if armature_moves(rec.position_m):
        notes.append(f"the armature moves by {float(np.ptp(rec.position_m)) * 1e3:.4g} mm during the recording: Psi "
                     "changes with the position too, so the branches and the 'hysteresis width' include motion "
                     "and are not a property of the steel")
    if abs(float(i_s[0])) > thr:
        notes.append(f"the recording starts energized ({float(i_s[0]):.4g} A): Psi is the change since the "
                     "first sample (its integration constant Psi(0) is not measured)")
    return notes


def _commutation(branches: list, psi: np.ndarray, i_s: np.ndarray, n_points: int, k_smooth: int,
                 notes: list) -> dict:
    """:class:`FluxResult`'s commutation curve on its current grid, largest and mean hysteresis width, the
    highest peak and Psi there, from the branches: the mean of the branches' peak curves, averaged over the
    peaks reaching each level (:func:`flux_linkage`'s Notes)."""
    grid = np.linspace(0.0, max((br.peak_A for br in branches), default=0.0), n_points)
    mean_curves, widths = peak_curves(branches, grid)
    if not mean_curves:
        p = int(np.argmax(i_s))
        notes.append("no current peak found: no branches, commutation curve or hysteresis width")
        return _curve(np.empty(0), np.empty(0), math.nan, math.nan, float(psi[p]), float(i_s[p]))
    stack = np.vstack(mean_curves)
    with np.errstate(invalid="ignore"):
        count = np.sum(np.isfinite(stack), axis=0)
        merged = np.where(count > 0, np.nansum(stack, axis=0) / np.maximum(count, 1), np.nan)
    keep = np.isfinite(merged)
    all_w = np.concatenate([w[np.isfinite(w)] for w in widths])
    width_max = float(np.max(np.abs(all_w))) if all_w.size else math.nan
    width_mean = float(np.mean(np.abs(all_w))) if all_w.size else math.nan
    top = max(range(len(branches)), key=lambda j: branches[j].peak_A)
    p = branches[top].stop - 1 if branches[top].direction == "ascending" else branches[top].start
    lo, hi = max(0, p - k_smooth), min(psi.size, p + k_smooth + 1)
    return _curve(grid[keep], merged[keep], width_max, width_mean, float(np.mean(psi[lo:hi])), branches[top].peak_A)


def _curve(i_A, psi_Wb, width_max, width_mean, psi_peak, peak_A) -> dict:
    return {"commutation_i_A": i_A, "commutation_psi_Wb": psi_Wb, "hysteresis_width_Wb": width_max,
            "hysteresis_mean_width_Wb": width_mean, "psi_at_peak_Wb": psi_peak, "peak_current_A": float(peak_A)}


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
    resistance : CampaignResistance or None
        The resistance tracks the flux was integrated with (None: one R per recording).
    """

    i_A: np.ndarray
    psi_Wb: np.ndarray
    n_sources: np.ndarray
    position_m: float
    peak_currents_A: list[float]
    results: list[FluxResult]
    resistance: CampaignResistance | None = None


def commutation_curve(recordings: list[Recording], n_points: int = 101,
                      R_ohm: float | None = None, *,
                      resistance: str | CampaignResistance | None = None) -> CommutationCurve:
    """Merge ``flux`` recordings at one stroke (different peaks) into one measured Psi(i) curve.

    Parameters
    ----------
    recordings : list of Recording
        ``flux`` recordings of one solenoid at one working gap (within 1 um).
    n_points : int
        Points of the current grid from 0 to the highest peak.
    R_ohm : float, optional
        Coil resistance [ohm] for every recording (default: each one's header, else estimated).
    resistance : {None, "track"} or CampaignResistance
        None: one R per recording (as ``R_ohm``). ``"track"``: R(t) per recording with one heating
        rate fitted jointly over these recordings (:func:`~solenoid_fmu.measure.campaign_resistance`);
        a :class:`~solenoid_fmu.measure.CampaignResistance` (e.g. of the whole campaign, so that
        ramps and voltage steps help pin kappa): its track of each recording.

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
    positions = _common_stroke(recordings)
    camp = _campaign_of(recordings, resistance)
    problems = []
    results = [flux_linkage(rec, R_ohm, n_points=n_points,
                            resistance=None if camp is None else camp.track_for(rec)) for rec in recordings]
    for rec, res in zip(recordings, results, strict=True):
        if not res.starts_at_rest:
            problems.append(f"{rec.label()}: starts energized ({res.current_A[0]:.4g} A): its flux is only known "
                            "up to the integration constant Psi(0); a flux recording must start at zero current")
        elif not res.offset_measured:
            problems.append(f"{rec.label()}: no zero-current rest at the start or end: the voltage offset of "
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
                            peak_currents_A=[br.peak_A for br in branches[::2]], results=results,
                            resistance=camp)


def _common_stroke(recordings: list[Recording]) -> list[float]:
    """The median stroke of each recording [m], checked: ``flux`` recordings of one solenoid at one fixed stroke
    (else :class:`RecordingError`)."""
    problems = []
    positions = []
    for rec in recordings:
        if rec.kind != "flux":
            problems.append(f"{rec.label()}: kind {rec.kind!r}, commutation curves need 'flux' recordings")
            continue
        x = rec.positions_m()
        if armature_moves(x):
            problems.append(f"{rec.label()}: the stroke moves by {np.ptp(x) * 1e3:.4f} mm "
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
    return positions


def _campaign_of(recordings: list[Recording], resistance) -> CampaignResistance | None:
    """The resistance tracks :func:`commutation_curve` uses (None: one R per recording), with a track for every
    recording (else :class:`RecordingError`)."""
    camp = None
    if isinstance(resistance, CampaignResistance):
        camp = resistance
    elif resistance == "track":
        camp = campaign_resistance(recordings)
    elif resistance is not None:
        raise RecordingError("commutation_curve", [f"resistance must be None, 'track' or a CampaignResistance, "
                                                   f"got {resistance!r}"])
    if camp is not None and not camp.header_elsewhere:
        missing = [rec.label() for rec in recordings if camp.track_for(rec) is None]
        if missing:
            why = {lab: camp.skipped.get(lab, "not in the campaign fit") for lab in missing}
            raise RecordingError("commutation_curve", [f"{lab}: no resistance track ({w})" for lab, w in why.items()])
    return camp
