"""The coil resistance of each recording's header, checked and completed from the campaign's own data.

The header's ``coil_resistance_ohm`` (measured 4-wire before the run, recordings.md) is what the eq.-4 flux
and the model's simulations of a recording start from. A rig can get it wrong for every recording alike (the
voltage taken across leads, connectors or the shunt too) or leave it out (the key is optional).
:func:`headers_from_data` mends both once for the whole chain (the pipeline's step 1), from one fit of the
campaign's resistance tracks (:func:`~.resistance_campaign.campaign_resistance`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np

from ..errors import RecordingError
from .conditioning import armature_moves, condition
from .format import FILL_KEY, SHIFT_KEY, Recording
from .resistance import HEADER_SIGMA_REL, resistance_track
from .resistance_campaign import campaign_resistance
from .resistance_equations import cumtrapz

__all__ = ["OFFSET_KINDS", "SHIFT_KEY", "FILL_KEY", "ESTIMATED_KEYS", "REMANENCE_REL", "HeaderFix", "headers_from_data",
           "start_R_from_rests"]

#: The kinds the campaign's header offset and the missing headers are estimated from (those the identification
#: fits the resistance tracks on: current-driven at a fixed stroke, with voltage).
OFFSET_KINDS = ("flux", "ramp", "eddy")
#: Header keys that mark ``coil_resistance_ohm`` as an estimate, not a measurement.
ESTIMATED_KEYS = (SHIFT_KEY, FILL_KEY)
#: Flux left at zero current after an excitation (remanence), allowed for as 1-sigma relative to the recording's
#: flux at its peak (:func:`start_R_from_rests`; an air gap keeps a solenoid's remanence far below this).
REMANENCE_REL = 0.05


class HeaderFix(NamedTuple):
    """What :func:`headers_from_data` did: the recordings (in the order given), the note on a common offset
    (None: none found), a line per header filled in and a line per recording left without one."""

    recordings: list
    shifted: str | None
    filled: list
    unfilled: list


def headers_from_data(recordings: list[Recording]) -> HeaderFix:
    """The recordings with their header resistances mended from the campaign's resistance tracks.

    * Every header off by one offset (:func:`~.resistance_campaign.common_header_offset`, estimated on the
      :data:`OFFSET_KINDS` recordings): each ``coil_resistance_ohm`` shifted by it (:data:`SHIFT_KEY`). A voltage
      step simulated with the 3-ohm shunt left in its measured voltage drew 25 % too much current.
    * A recording without ``coil_resistance_ohm``: R at the start as its own data pin it (its track, the
      campaign's fit or, for a voltage step, its own), written where that is as good as a header
      (1-sigma below the header's :data:`~.resistance.HEADER_SIGMA_REL`) with :data:`FILL_KEY`. Without it the
      model would simulate that run with the coil at 20 degC and the loop could not place its start temperature.
      Recordings whose data do not pin R are left as they are and named.

    Estimated headers are marked (:data:`ESTIMATED_KEYS`): the identification integrates eq. 4 with the tracks
    where any header is an estimate (a shifted header is the offset's estimate, 0.002 % off on DC03 #402, and a flux
    recording of 8 s at 0.6 A then drifts by 0.4 %; F came out 2.28 % off the truth with them, 1.41 % with the
    tracks)."""
    fixed = [r for r in recordings if r.kind in OFFSET_KINDS and r.voltage_V is not None]
    try:
        camp = campaign_resistance(fixed) if fixed else None
    except RecordingError:
        camp = None
    off = None if camp is None else camp.header_offset
    out, filled, unfilled = [], [], []
    for rec in recordings:
        hdr = rec.coil_resistance_ohm
        if hdr is not None and off is not None:
            rec = _with_header(rec, hdr + off["ohm"], SHIFT_KEY, off["ohm"])
        elif hdr is None and rec.voltage_V is not None:
            rec = _filled(rec, camp, filled, unfilled)
        out.append(rec)
    shifted = None if off is None else (
        f"every header's coil_resistance_ohm taken {off['ohm']:+.4g} +- {off['sigma_ohm']:.2g} ohm off: the "
        f"{off['recordings']} recordings that pin their own R all miss their headers by it (the voltage taken "
        "across more than the coil: leads, connectors, a shunt; or the header's meter off)")
    return HeaderFix(out, shifted, filled, unfilled)


def _with_header(rec: Recording, R_ohm: float, key: str, value: float) -> Recording:
    return dataclasses.replace(rec, header={**rec.header, "coil_resistance_ohm": f"{R_ohm:.10g}", key: f"{value:.6g}"})


def _filled(rec: Recording, camp, filled: list, unfilled: list) -> Recording:
    """``rec`` with R at the start from its track (the campaign's, else its own) where that pins it as well as a
    header would; a line on ``filled`` or ``unfilled``."""
    tr = None if camp is None else camp.track_for(rec)
    moves = armature_moves(rec.position_m)
    try:
        if tr is not None:
            R0, sigma, how = tr.R0_ohm, tr.R0_sigma_ohm, ", ".join(tr.constraints)
        elif not moves:
            tr = resistance_track(rec)
            R0, sigma, how = tr.R0_ohm, tr.R0_sigma_ohm, ", ".join(tr.constraints)
        else:
            kappa = (0.0, 0.0) if camp is None else (camp.kappa_per_J, camp.kappa_sigma_per_J)
            R0, sigma = start_R_from_rests(rec, *kappa)
            how = "the flux back at zero with the current, the campaign's heating rate"
    except RecordingError as exc:
        unfilled.append(f"{rec.label()}: no coil_resistance_ohm, and none from its data ({'; '.join(exc.problems)})")
        return rec
    if not sigma < HEADER_SIGMA_REL * R0:
        unfilled.append(f"{rec.label()}: no coil_resistance_ohm, and its data pin R at the start to "
                        f"+-{100 * sigma / R0:.2g} % only")
        return rec
    filled.append(f"{rec.label()}: coil_resistance_ohm {R0:.5g} +- {sigma:.2g} ohm from its data ({how})")
    return _with_header(rec, R0, FILL_KEY, sigma)


def start_R_from_rests(rec: Recording, kappa_per_J: float = 0.0, kappa_sigma_per_J: float = 0.0) -> tuple[float, float]:
    """R at the start [ohm] and its 1-sigma [ohm] of a recording whose current starts and ends at rest, from its flux
    coming back: ``Psi(end) - Psi(0)`` is the remanence (a solenoid without a magnet has no flux at zero current,
    wherever the armature is; allowed for as :data:`REMANENCE_REL` of the flux at the peak), eq. 4 with
    ``R(t) = R0 (1 + kappa E(t))`` (``kappa_per_J``: the campaign's heating rate, E the Joule energy). The one
    equation of :mod:`.resistance` that holds while the armature moves (a force stroke: neither plateaus nor
    closure do). Raises RecordingError where the current does not start and end at rest."""
    c = condition(rec)
    if c.head is None or c.tail is None:
        raise RecordingError(rec.label(), ["the current does not start and end at rest: the flux's return cannot "
                                           "pin R"])
    A = cumtrapz(c.uc, c.t)
    B0 = cumtrapz(c.ic, c.t)
    R0 = float(A[-1] / B0[-1])
    E = cumtrapz(R0 * c.ic ** 2, c.t)
    for _ in range(3):  # the Joule energy with the track of the last estimate
        B1 = cumtrapz(E * c.ic, c.t)
        R0 = float(A[-1] / (B0[-1] + kappa_per_J * B1[-1]))
        E = cumtrapz(R0 * (1.0 + kappa_per_J * E) * c.ic ** 2, c.t)
    se = c.offset_se_V * float(c.t[-1] - c.t[0])
    if not (math.isfinite(R0) and R0 > 0.0 and math.isfinite(se)):
        raise RecordingError(rec.label(), [f"the flux's return gives no R (R0 {R0!r} ohm, voltage offset's standard "
                                           f"error {c.offset_se_V!r} V)"])
    psi_peak = float(np.max(A - R0 * (B0 + kappa_per_J * B1)))
    sigma_psi = math.sqrt((REMANENCE_REL * psi_peak) ** 2 + se ** 2 + (kappa_sigma_per_J * R0 * B1[-1]) ** 2)
    return R0, sigma_psi / float(B0[-1] + kappa_per_J * B1[-1])
