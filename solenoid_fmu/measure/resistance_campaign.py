"""One heating rate for a campaign's recordings (same coil), R at the start per recording: joint least squares
of the equations of :mod:`.resistance` (model and equations there), and each recording's track from it.

A recording whose loops the joint rate leaves open while its own track closes them keeps its own: a coil warm
from the campaign also cools, and warms within a recording at a lower rate than one started cold.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import RecordingError
from .conditioning import armature_moves
from .format import Recording
from .resistance import (
    CLOSURE_FACTOR,
    HEADER_SIGMA_REL,
    KAPPA_PRIOR_PER_J,
    ResistanceTrack,
    closure_problems,
    own_fit,
    track_alone,
    track_of_fit,
)
from .resistance_equations import TAU_MODEL_S, data_block, equations, scale_of, solve_wls

__all__ = ["CampaignResistance", "campaign_resistance", "common_header_offset"]


@dataclass
class CampaignResistance:
    """Resistance tracks of a campaign with one heating rate ``kappa`` (see :func:`campaign_resistance`).

    Attributes
    ----------
    kappa_per_J, kappa_sigma_per_J : float
        The joint heating rate ``alpha / C_th`` [1/J] and its 1-sigma.
    tracks : dict of str to ResistanceTrack
        Per recording label.
    skipped : dict of str to str
        Recordings left out of the joint fit, and why.
    not_pinned : list of str
        ``"<file>: <why>"`` for every track that is not pinned.
    problems : list of str
        Recordings whose loops do not close even with the best track (:func:`closure_problems`).
    """

    kappa_per_J: float
    kappa_sigma_per_J: float
    tracks: dict[str, ResistanceTrack]
    skipped: dict[str, str]
    not_pinned: list[str]
    problems: list[str]
    #: True: a recording without a track uses its header's resistance (:meth:`restricted`).
    header_elsewhere: bool = False
    #: The offset every header was shifted by as the prior of its recording's R0 (:func:`common_header_offset`):
    #: ``{"ohm", "sigma_ohm", "recordings"}``, or None (the headers as written).
    header_offset: dict | None = None
    #: (recording, key in ``tracks``) of the recordings fitted: recordings in memory without a file share a
    #: label, so their keys carry their place in the list (``"flux recording of PS45 (#2)"``).
    members: tuple = field(default=(), repr=False, compare=False)

    def track_for(self, rec: Recording) -> ResistanceTrack | None:
        """The track of ``rec`` (the recording object given, else by label), or None."""
        for member, key in self.members:
            if member is rec:
                return self.tracks.get(key)
        return self.tracks.get(rec.label())

    def restricted(self, labels) -> CampaignResistance:
        """These tracks only (by recording label); every other recording keeps its header's resistance."""
        keep = set(labels)
        return dataclasses.replace(self, tracks={k: v for k, v in self.tracks.items() if k in keep},
                                   not_pinned=[w for w in self.not_pinned if w.split(": ", 1)[0] in keep],
                                   header_elsewhere=True)

    def summary(self) -> dict:
        """JSON-able: kappa, per-recording tracks, what is skipped, not pinned, inconsistent."""
        return {"kappa_per_J": float(self.kappa_per_J), "kappa_sigma_per_J": float(self.kappa_sigma_per_J),
                "recordings": [tr.summary() for tr in self.tracks.values()], "skipped": dict(self.skipped),
                "not_pinned": list(self.not_pinned), "problems": list(self.problems),
                "header_offset": self.header_offset}


def campaign_resistance(recordings: list[Recording], *, header_sigma_rel: float = HEADER_SIGMA_REL,
                        header_offset: dict | None = None) -> CampaignResistance:
    """One heating rate ``kappa`` for a campaign (same coil), R0 per recording, by joint least squares.

    Parameters
    ----------
    recordings : list of Recording
        Any kinds; those with voltage at a fixed stroke take part (a moving armature changes Psi at
        constant current, so neither plateaus nor closure hold).
    header_sigma_rel : float
        Relative 1-sigma of each header R as the prior of its R0 [1].
    header_offset : dict, optional
        Shift every header R by ``ohm`` (1-sigma ``sigma_ohm``, added to the header's) as the prior of its R0;
        default: by :func:`common_header_offset` of a first fit where it finds one, else none.

    Returns
    -------
    CampaignResistance

    Notes
    -----
    Each recording's equations are first fitted alone; their noise scale (``sqrt(chi^2/dof)``, at
    least 1) weights its equations in the joint fit, so that one recording's model error does not
    set the weights of the others. The joint fit is done twice, the Joule energy recomputed with
    the tracks of the first. A recording whose loops the joint kappa leaves open while its own track closes
    them keeps its own track (:func:`_own_where_joint_fails`), and the joint fit is repeated without it (once).
    """
    keys = _unique_labels(recordings)
    fits, skipped, alone = _own_fits(recordings, keys, header_sigma_rel, header_offset)
    if not fits:
        raise RecordingError("campaign_resistance", ["no recording with voltage at a fixed stroke"]
                             + [f"{k}: {v}" for k, v in skipped.items()])
    own = {}
    for _ in range(2):  # the joint kappa again without the recordings that need their own
        theta, cov, tracks = _joint_tracks(fits, recordings, keys)
        moved = _own_where_joint_fails(fits, recordings, keys, tracks, alone)
        own.update(moved)
        if not moved or len(moved) == len(fits):
            break
        fits = [f for f in fits if _key_of(f[0].rec, recordings, keys) not in moved]
    tracks.update(own)
    m = len(fits)
    not_pinned = [f"{lab}: {tr.why_not_pinned}" for lab, tr in tracks.items() if not tr.pinned]
    durations = [float(f[0].cond.t[-1] - f[0].cond.t[0]) for f in fits]
    kappa_sigma = math.hypot(math.sqrt(cov[m, m]), theta[m] * float(np.median(durations)) / (2.0 * TAU_MODEL_S))
    camp = CampaignResistance(kappa_per_J=float(theta[m]), kappa_sigma_per_J=float(kappa_sigma),
                              tracks=tracks, skipped=skipped, not_pinned=not_pinned,
                              problems=closure_problems(list(tracks.values())),
                              members=tuple(zip(recordings, keys, strict=True)), header_offset=header_offset)
    if header_offset is None and (offset := common_header_offset(camp)) is not None:
        return campaign_resistance(recordings, header_sigma_rel=header_sigma_rel, header_offset=offset)
    return camp


#: :func:`common_header_offset` asks for at least this many recordings whose own data pin their R at the start.
MIN_OFFSET_RECORDINGS = 2


def common_header_offset(camp: CampaignResistance) -> dict | None:
    """The offset [ohm] by which every header resistance misses the data, where the recordings whose own data pin
    their R at the start (its sigma under half the header's) all agree on one beyond the header's own uncertainty:
    the voltage is taken across more than the coil (leads, connectors, a shunt in the voltage path) or the header's
    meter is off. Such a rig's headers are wrong for the recordings that cannot tell as well, which rested on
    theirs: a single-triangle flux recording of a campaign whose voltage included the 3-ohm shunt came out 4.2 times
    its true flux at the peak while every recording with plateaus or closing cycles pinned 15.09 against the
    headers' 12.09 ohm. ``{"ohm": mean offset, "sigma_ohm": its scatter over the recordings or its standard
    error, whichever is larger, "recordings": how many}``, or None: fewer than :data:`MIN_OFFSET_RECORDINGS`, an
    offset within twice the header's uncertainty, or one of them more than the header's uncertainty (or three of
    its own sigmas) from the mean (stale headers of a coil warming during the campaign differ one by one)."""
    d, s, h = [], [], []
    for tr in camp.tracks.values():
        hdr = tr.header_R_ohm
        if hdr is not None and tr.R0_sigma_ohm < 0.5 * HEADER_SIGMA_REL * hdr:
            d.append(tr.R0_ohm - hdr)
            s.append(max(tr.R0_sigma_ohm, 1e-12))
            h.append(HEADER_SIGMA_REL * hdr)
    if len(d) < MIN_OFFSET_RECORDINGS:
        return None
    d, s, h = np.array(d), np.array(s), np.array(h)
    w = 1.0 / s**2
    mean = float(np.sum(w * d) / np.sum(w))
    if abs(mean) <= 2.0 * float(np.median(h)) or np.any(np.abs(d - mean) > np.maximum(h, 3.0 * s)):
        return None
    sigma = max(float(np.std(d)), float(1.0 / np.sqrt(np.sum(w))))
    return {"ohm": mean, "sigma_ohm": sigma, "recordings": int(d.size)}


def _key_of(rec: Recording, recordings: list[Recording], keys: list[str]) -> str:
    """The key (unique label) of ``rec`` in ``recordings``."""
    return keys[next(k for k, r in enumerate(recordings) if r is rec)]


def _own_where_joint_fails(fits: list, recordings: list[Recording], keys: list[str], tracks: dict,
                           alone: dict) -> dict:
    """Own tracks (kappa from the recording alone: its fit ``alone[key]`` from :func:`_own_fits`, the track
    :func:`~.resistance.resistance_track` gives) of the recordings whose loops the
    campaign's one kappa leaves open (closure residual over :data:`CLOSURE_FACTOR` times the noise) while
    their own track closes them (pinned or not: its uncertainty goes on with it).

    One ``kappa`` holds for a coil heated from ambient. A coil already warm from the campaign also cools,
    ``(T - T_amb) / R_th``, and the rate at which it warms within a recording (seconds) is then lower: on fresh
    DC03 #130 (heating + hysteresis) a flux recording started 3.6 % above the cold R warmed at 0.55 times the
    rate of one started cold; the joint kappa left its loops open by 2.4 mWb RMS (0.28 from the noise), its own
    closed them to 0.08."""
    out = {}
    for eq, _sc, _theta in fits:
        key = _key_of(eq.rec, recordings, keys)
        tr = tracks[key]
        if not (math.isfinite(tr.closure_rms_Wb) and tr.closure_rms_Wb > CLOSURE_FACTOR * tr.closure_noise_Wb):
            continue
        mine = track_alone(alone[key])
        if mine.closure_rms_Wb <= CLOSURE_FACTOR * mine.closure_noise_Wb:
            mine.notes.append(f"the campaign's one heating rate left this recording's loops open by "
                              f"{tr.closure_rms_Wb * 1e3:.3g} mWb RMS ({tr.closure_noise_Wb * 1e3:.3g} from the "
                              f"noise); its own track closes them ({mine.closure_rms_Wb * 1e3:.3g} mWb, kappa "
                              f"{mine.kappa_per_J:.3g} /J against the campaign's {tr.kappa_per_J:.3g}): a coil "
                              f"warm from the campaign also cools")
            out[key] = mine
    return out


def _joint_tracks(fits: list, recordings: list[Recording], keys: list[str]) -> tuple[np.ndarray, np.ndarray, dict]:
    """The joint fit of :func:`campaign_resistance` (one kappa) and each recording's track from it."""
    m = len(fits)
    theta, cov = _joint_fit(fits)
    chi2, n_eq = 0.0, 0
    for j, (eq, sc, _t) in enumerate(fits):
        r = (eq.g @ np.array([theta[j], theta[m] * eq.R_ref]) - eq.y) / (eq.sigma * sc)
        chi2 += float(r @ r)
        n_eq += r.size
    dof = n_eq - (m + 1)
    s2 = max(1.0, chi2 / dof) if dof > 0 else 1.0
    cov = cov * s2
    tracks = {}
    for j, (eq, sc, _t) in enumerate(fits):
        T = np.array([[1.0, 0.0], [0.0, eq.R_ref]])
        idx = [j, m]
        cj = T @ cov[np.ix_(idx, idx)] @ T.T
        tracks[_key_of(eq.rec, recordings, keys)] = track_of_fit(eq, np.array([theta[j], theta[m] * eq.R_ref]), cj, sc,
                                                                 "campaign", ["campaign kappa"])
    return theta, cov, tracks


def _unique_labels(recordings: list[Recording]) -> list[str]:
    """Each recording's ``label()``, with ``" (#k)"`` (its place in the list, from 1) where labels repeat."""
    labels = [rec.label() for rec in recordings]
    return [lab if labels.count(lab) == 1 else f"{lab} (#{k + 1})" for k, lab in enumerate(labels)]


def _own_fits(recordings: list[Recording], keys: list[str], header_sigma_rel: float,
              header_offset: dict | None = None) -> tuple[list, dict, dict]:
    """Each recording with voltage at a fixed stroke fitted alone: ``[equations, noise scale (>= 1), theta]``
    per recording (the joint fit replaces the equations), the recordings skipped with why, and each fit as
    :func:`~.resistance.own_fit` gave it (both by ``keys``); each header shifted by ``header_offset`` when given
    (:func:`campaign_resistance`)."""
    fits, skipped, alone = [], {}, {}
    for rec, key in zip(recordings, keys, strict=True):
        if rec.voltage_V is None:
            skipped[key] = "no voltage column"
            continue
        if armature_moves(rec.position_m):
            skipped[key] = "the armature moves: Psi changes at constant current"
            continue
        R_prior, rel = None, header_sigma_rel
        if header_offset is not None and rec.coil_resistance_ohm is not None:
            R_prior = rec.coil_resistance_ohm + header_offset["ohm"]
            rel = math.hypot(header_sigma_rel * rec.coil_resistance_ohm, header_offset["sigma_ohm"]) / R_prior
        try:
            alone[key] = eq, theta, _cov, _chi2, _dof = own_fit(rec, R_prior, 0.0, KAPPA_PRIOR_PER_J, rel,
                                                                "header R (shifted)")
        except RecordingError as exc:
            skipped[key] = "; ".join(exc.problems) if hasattr(exc, "problems") else str(exc)
            continue
        fits.append([eq, 1.0, theta])
    _campaign_prior(fits, alone, keys, recordings)
    for f in fits:
        ns = scale_of(*alone[_key_of(f[0].rec, recordings, keys)][3:])
        f[1] = max(1.0, ns) if math.isfinite(ns) else 1.0
    return fits, skipped, alone


def _campaign_prior(fits: list, alone: dict, keys: list[str], recordings: list[Recording]) -> None:
    """Refit, in place, each recording without a header R whose own data pin its R at the start worse than a header
    would, with the campaign's R as the prior: the same coil, so the median of the R0s that are pinned (headers and
    data), +- their range and a header's uncertainty. Its rough prior of its own (the mean U/i, :func:`~.resistance_
    equations.prepare`) can be far off: 17.2 against 12.1 ohm on a fast eddy trapezoid of AISI 1008 #116."""
    sure = [float(th[0]) for _eq, th, cov, _c, _d in alone.values()
            if math.sqrt(max(cov[0, 0], 0.0)) < HEADER_SIGMA_REL * th[0]]
    if not sure:
        return
    R_mid = float(np.median(sure))
    sigma = math.hypot(HEADER_SIGMA_REL * R_mid, max(sure) - min(sure))
    for f in fits:
        eq, th = f[0], f[2]
        key = _key_of(eq.rec, recordings, keys)
        cov = alone[key][2]
        if eq.rec.coil_resistance_ohm is None and not math.sqrt(max(cov[0, 0], 0.0)) < HEADER_SIGMA_REL * th[0]:
            alone[key] = fit = own_fit(eq.rec, R_mid, 0.0, KAPPA_PRIOR_PER_J, sigma / R_mid,
                                       "campaign's R (no header R)")
            f[0], f[2] = fit[0], fit[1]


def _joint_fit(fits: list) -> tuple[np.ndarray, np.ndarray]:
    """The joint least squares of :func:`campaign_resistance` (R0 per recording, one kappa), done twice with
    the Joule energy recomputed from the first's tracks (``fits`` updated in place): estimate and (JtJ)^-1."""
    m = len(fits)
    for _ in range(2):
        rows, rhs = [], []
        for j, (eq, sc, _theta) in enumerate(fits):
            Jd, rd = data_block(eq, sc)
            block = np.zeros((Jd.shape[0], m + 1))
            block[:, j] = Jd[:, 0]
            block[:, m] = Jd[:, 1] * eq.R_ref
            rows.append(block)
            rhs.append(rd)
            prior = np.zeros((1, m + 1))
            prior[0, j] = 1.0 / eq.R_prior_sigma
            rows.append(prior)
            rhs.append(np.array([eq.R_prior / eq.R_prior_sigma]))
        prior = np.zeros((1, m + 1))
        prior[0, m] = 1.0 / KAPPA_PRIOR_PER_J
        rows.append(prior)
        rhs.append(np.zeros(1))
        theta, cov = solve_wls(list(zip(rows, rhs, strict=True)), m + 1)
        for j, f in enumerate(fits):
            eq = f[0]
            R_t = theta[j] + theta[m] * eq.R_ref * eq.energy_J
            f[0] = equations(eq.rec, eq.cond, R_t, eq.R_prior, eq.R_prior_sigma, eq.R_prior_source)
            f[2] = theta
    return theta, cov
