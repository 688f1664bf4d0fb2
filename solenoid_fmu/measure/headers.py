"""The coil resistance of each recording's header, checked and completed from the campaign's own data.

The header's ``coil_resistance_ohm`` (measured 4-wire before the run, recordings.md) is what the eq.-4 flux
and the model's simulations of a recording start from. A rig can get it wrong for every recording alike (the
voltage taken across leads, connectors or the shunt too) or leave it out (the key is optional).
:func:`headers_from_data` mends both once for the whole chain (the pipeline's step 1), from one fit of the
campaign's resistance tracks (:func:`~.resistance_campaign.campaign_resistance`).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

from ..errors import RecordingError
from .format import Recording
from .resistance import HEADER_SIGMA_REL, resistance_track
from .resistance_campaign import campaign_resistance

__all__ = ["OFFSET_KINDS", "SHIFT_KEY", "FILL_KEY", "ESTIMATED_KEYS", "HeaderFix", "headers_from_data"]

#: The kinds the campaign's header offset and the missing headers are estimated from (those the identification
#: fits the resistance tracks on: current-driven at a fixed stroke, with voltage).
OFFSET_KINDS = ("flux", "ramp", "eddy")
#: The header key written where ``coil_resistance_ohm`` was shifted: the offset [ohm].
SHIFT_KEY = "coil_resistance_shift_ohm"
#: The header key written where ``coil_resistance_ohm`` was missing and taken from the recording's own data:
#: the estimate's 1-sigma [ohm].
FILL_KEY = "coil_resistance_estimated_sigma_ohm"
#: Header keys that mark ``coil_resistance_ohm`` as an estimate, not a measurement.
ESTIMATED_KEYS = (SHIFT_KEY, FILL_KEY)


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
    if tr is None and (rec.position_m is None or float(rec.position_m.max() - rec.position_m.min()) <= 1e-6):
        try:
            tr = resistance_track(rec)
        except RecordingError as exc:
            unfilled.append(f"{rec.label()}: no coil_resistance_ohm, and none from its data ({exc})")
            return rec
    if tr is None:
        unfilled.append(f"{rec.label()}: no coil_resistance_ohm, and the armature moves (no track)")
        return rec
    if not tr.R0_sigma_ohm < HEADER_SIGMA_REL * tr.R0_ohm:
        unfilled.append(f"{rec.label()}: no coil_resistance_ohm, and its data pin R at the start to "
                        f"+-{100 * tr.R0_sigma_ohm / tr.R0_ohm:.2g} % only")
        return rec
    filled.append(f"{rec.label()}: coil_resistance_ohm {tr.R0_ohm:.5g} +- {tr.R0_sigma_ohm:.2g} ohm from its data "
                  f"({', '.join(tr.constraints)})")
    return _with_header(rec, tr.R0_ohm, FILL_KEY, tr.R0_sigma_ohm)
