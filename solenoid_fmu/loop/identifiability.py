"""Which effects a campaign can identify: the recordings each addable effect's fit needs."""

from __future__ import annotations

import numpy as np

from ..measure import flux_linkage
from .signals import conditioned_position


def _holds_current(rec, min_s: float = 0.2) -> bool:
    """The current stays above half its peak for at least ``min_s`` [s] in total."""
    i = np.abs(np.asarray(rec.current_A, dtype=float))
    t = np.asarray(rec.time_s, dtype=float)
    if i.size < 2 or float(np.max(i)) <= 0.0:
        return False
    on = i[1:] > 0.5 * float(np.max(i))
    return float(np.sum(np.diff(t)[on])) >= min_s


def _reverses(rec) -> bool:
    """The armature moves there and back within the recording (by more than 5 % of its span)."""
    x = conditioned_position(np.asarray(rec.positions_m(), dtype=float))
    span = float(np.ptp(x))
    if span <= 0.0:
        return False
    k = int(np.argmax(np.abs(x - x[0])))
    return float(np.max(np.abs(x[k:] - x[k]))) > 0.05 * span


def not_identifiable(recordings, flux_of=flux_linkage) -> dict:
    """Addable effects the campaign cannot identify, each with what to add (see README).

    ``hysteresis``: a current-driven ``flux`` (or ``ramp`` / ``eddy``) recording with voltage that
    starts at zero current and rests there (absolute eq.-4 flux); ``eddy``: an ``eddy`` recording
    with voltage and a zero-current rest; ``heating``: a recording with voltage, the resistance
    measured before the run (header ``coil_resistance_ohm``) and the current held for >= 0.2 s;
    ``friction``: a ``force_stroke`` recording in which the armature moves there and back.
    """
    def absolute(rec):
        if rec.voltage_V is None:
            return False
        fr = flux_of(rec)
        return fr.starts_at_rest and fr.offset_measured

    volt = [r for r in recordings if r.voltage_V is not None and r.kind != "voltage_step"]
    out = {}
    if not any(absolute(r) for r in volt if r.kind in ("flux", "ramp", "eddy")):
        out["hysteresis"] = ("add a slow 'flux' recording with voltage: triangles from zero current with a "
                             "zero-current rest (for the voltage offset)")
    if not any(absolute(r) for r in volt if r.kind == "eddy"):
        out["eddy"] = "add fast 'eddy' triangles (several rates) with voltage and a zero-current rest"
    if not any(r.coil_resistance_ohm is not None and _holds_current(r) for r in volt):
        out["heating"] = ("add a recording with voltage, the coil resistance measured before the run "
                          "(# coil_resistance_ohm) and the current held for a while (a ramp with a hold, or a "
                          "force stroke with voltage)")
    if not any(r.kind == "force_stroke" and r.force_N is not None and _reverses(r) for r in recordings):
        out["friction"] = "add a 'force_stroke' recording in which the carriage moves the armature there and back"
    return out
