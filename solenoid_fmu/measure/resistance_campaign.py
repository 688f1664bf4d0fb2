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

__all__ = ["CampaignResistance", "campaign_resistance", "common_header_offset", "headers_shifted"]


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


#: The kinds :func:`headers_shifted` estimates the campaign's header offset from (those the identification fits the
#: resistance tracks on: current-driven at a fixed stroke, with voltage).
OFFSET_KINDS = ("flux", "ramp", "eddy")
#: The header key :func:`headers_shifted` writes: the offset [ohm] the header's ``coil_resistance_ohm`` was shifted by.
SHIFT_KEY = "coil_resistance_shift_ohm"


def headers_shifted(recordings: list[Recording]) -> tuple[list[Recording], str | None]:
    """The recordings with every header ``coil_resistance_ohm`` shifted by the campaign's
    :func:`common_header_offset` (estimated on its :data:`OFFSET_KINDS` recordings) and a note saying so; unchanged
    and None where there is none (or nothing to estimate it from). For the whole chain at once (the pipeline's
    step 1): the eq.-4 flux of every analysis and the model's simulations with the header's R then agree with the
    data; a voltage step simulated with the 3-ohm shunt left in its measured voltage drew 25 % too much current.
    The shifted header carries :data:`SHIFT_KEY` (the identification then integrates eq. 4 with the tracks, not
    with these headers: they are the offset's estimate, 0.002 % off on DC03 #402, and a flux recording of 8 s
    at 0.6 A then drifts by 0.4 %; F came out 2.28 % off the truth with them, 1.41 % with the tracks)."""
    fixed = [r for r in recordings if r.kind in OFFSET_KINDS and r.voltage_V is not None]
    try:
        off = campaign_resistance(fixed).header_offset if fixed else None
    except RecordingError:
        return list(recordings), None
    if off is None:
        return list(recordings), None
    out = []
    for rec in recordings:
        hdr = rec.coil_resistance_ohm
        if hdr is not None:
            header = {**rec.header, "coil_resistance_ohm": f"{hdr + off['ohm']:.10g}", SHIFT_KEY: f"{off['ohm']:.6g}"}
            rec = dataclasses.replace(rec, header=header)
        out.append(rec)
    return out, (f"every header's coil_resistance_ohm taken {off['ohm']:+.4g} +- {off['sigma_ohm']:.2g} ohm off: "
                 f"the {off['recordings']} recordings that pin their own R all miss their headers by it (the "
                 "voltage taken across more than the coil: leads, connectors, a shunt; or the header's meter off)")


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
        if rec.position_m is not None and float(np.ptp(rec.position_m)) > 1e-6:
            skipped[key] = "the armature moves: Psi changes at constant current"
            continue
        R_prior, rel = None, header_sigma_rel
        if header_offset is not None and rec.coil_resistance_ohm is not None:
            R_prior = rec.coil_resistance_ohm + header_offset["ohm"]
            rel = math.hypot(header_sigma_rel * rec.coil_resistance_ohm, header_offset["sigma_ohm"]) / R_prior
        try:
            alone[key] = eq, theta, cov, chi2, dof = own_fit(rec, R_prior, 0.0, KAPPA_PRIOR_PER_J, rel)
        except RecordingError as exc:
            skipped[key] = "; ".join(exc.problems) if hasattr(exc, "problems") else str(exc)
            continue
        ns = scale_of(chi2, dof)
        fits.append([eq, max(1.0, ns) if math.isfinite(ns) else 1.0, theta])
    return fits, skipped, alone


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
            if eq.R_prior is not None:
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
            f[0] = equations(eq.rec, eq.cond, R_t, eq.R_prior, eq.R_prior_sigma)
            f[2] = theta
    return theta, cov
