"""The measured curves the identification takes from recordings: absolute flux, grouped by stroke,
the hysteresis half-width that weights the fit, and the force-stroke curve of the report."""

from __future__ import annotations

import numpy as np

from ..errors import RecordingError
from ..measure import flux_linkage

__all__ = ["absolute_flux", "group_flux", "groups_of", "force_stroke_curve"]


def absolute_flux(recs) -> tuple[list, list[str]]:
    """The flux recordings whose eq.-4 flux is absolute (start at zero current, a rest for the
    voltage offset), and a reason for each one left out."""
    keep, reasons = [], []
    for rec in recs:
        fr = flux_linkage(rec)
        if not fr.starts_at_rest:
            reasons.append(f"{rec.label()}: starts energized ({fr.current_A[0]:.4g} A), its flux has an unknown "
                           "integration constant")
        elif not fr.offset_measured:
            reasons.append(f"{rec.label()}: no zero-current rest, the voltage offset of eq. 4 is unknown")
        else:
            keep.append(rec)
    return keep, reasons


def groups_of(recs) -> dict[int, list]:
    """Recordings grouped by stroke: {stroke in um (rounded): recordings}."""
    groups: dict[int, list] = {}
    for rec in recs:
        groups.setdefault(int(round(float(np.median(rec.positions_m())) * 1e6)), []).append(rec)
    return groups


def group_flux(recs) -> tuple[list, list[list]]:
    """Flux recordings grouped by stroke (1 um); the identification group first: the most
    recordings, then the highest peak current."""
    groups = groups_of(recs)
    ordered = sorted(groups.values(), key=lambda g: (-len(g), -max(float(np.max(r.current_A)) for r in g)))
    return ordered[0], ordered[1:]


def force_stroke_curve(rec, bin_m: float = 0.1e-3) -> dict:
    """Measured force vs stroke of a ``force_stroke`` recording, friction averaged out.

    Samples with the current on (above half its peak) and the armature moving are binned by
    position (``bin_m`` [m]); in each bin the mean force of the closing and of the opening pass
    are averaged (dry friction has opposite signs in the two passes). Returns ``x_m``, ``force_N``
    (bins seen in both directions) and ``i_A`` (median current while on).
    """
    x = rec.positions_m()
    i = rec.current_A
    F = rec.force_N
    on = i > 0.5 * np.max(i)
    t = rec.time_s
    k = max(3, int(round(0.02 / max(np.median(np.diff(t)), 1e-9))))
    xs = np.convolve(x, np.ones(k) / k, mode="same")
    v = np.gradient(xs, t)
    moving = np.abs(v) > 0.2 * np.percentile(np.abs(v[on]), 90) if on.any() else np.zeros_like(on)
    sel = on & moving
    if np.count_nonzero(sel) < 10:
        raise RecordingError(rec.label(), ["force_stroke recording: no moving samples with the current on"])
    edges = np.arange(x[sel].min(), x[sel].max() + bin_m, bin_m)
    idx = np.digitize(x, edges) - 1
    xc, fc = [], []
    for b in range(len(edges) - 1):
        inb = sel & (idx == b)
        up, down = inb & (v > 0), inb & (v < 0)
        if np.count_nonzero(up) >= 2 and np.count_nonzero(down) >= 2:
            xc.append(0.5 * (edges[b] + edges[b + 1]))
            fc.append(0.5 * (np.mean(F[up]) + np.mean(F[down])))
    if len(xc) < 2:
        raise RecordingError(rec.label(), ["force_stroke recording: fewer than two positions passed in both "
                                            "directions (a one-way stroke): friction cannot be averaged out"])
    return {"x_m": np.array(xc), "force_N": np.array(fc), "i_A": float(np.median(i[on]))}

