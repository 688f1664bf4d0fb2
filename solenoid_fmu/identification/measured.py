"""The measured curves the identification takes from recordings: absolute flux, grouped by stroke,
the hysteresis half-width that weights the fit, and the force-stroke curve of the report."""

from __future__ import annotations

import numpy as np

from ..errors import RecordingError
from ..measure import flux_linkage

__all__ = ["absolute_flux", "group_flux", "groups_of", "force_stroke_curve", "force_stroke_passes", "friction_offset"]


def absolute_flux(recs) -> tuple[list, list[str]]:
    """The flux recordings whose eq.-4 flux is absolute (start at zero current, a rest for the
    voltage offset), and a reason for each one left out (also one without a resistance to integrate eq. 4 with:
    no header R, no plateau, not back at its start)."""
    keep, reasons = [], []
    for rec in recs:
        try:  # without a header R, the recording's own track (what the flags below read does not depend on R)
            fr = flux_linkage(rec, resistance="track" if rec.coil_resistance_ohm is None else None)
        except RecordingError as exc:
            reasons.append(f"{rec.label()}: {'; '.join(exc.problems)}")
            continue
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


def force_stroke_passes(rec, bin_m: float = 0.1e-3) -> dict:
    """Measured force of a ``force_stroke`` recording binned by position, per direction of motion.

    Samples with the current on (above half its peak) and the armature moving are binned by position
    (``bin_m`` [m]). Returns ``x_m`` (bin centres [m]), ``up_N`` and ``down_N`` (mean force [N] of the
    opening pass, x rising, and of the closing pass in each bin; NaN where that pass has fewer than two
    samples) and ``i_A`` (median current while on [A]).
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
    nb = len(edges) - 1
    up, down = np.full(nb, np.nan), np.full(nb, np.nan)
    for b in range(nb):
        inb = sel & (idx == b)
        for out, mask in ((up, inb & (v > 0)), (down, inb & (v < 0))):
            if np.count_nonzero(mask) >= 2:
                out[b] = np.mean(F[mask])
    return {"x_m": 0.5 * (edges[:-1] + edges[1:]), "up_N": up, "down_N": down, "i_A": float(np.median(i[on]))}


def friction_offset(passes: list[dict]) -> tuple[float, float] | None:
    """The campaign's friction in the force strokes from the bins passed both ways: (d, sigma) [N].

    ``d`` is the mean over those bins, of every stroke in ``passes`` (:func:`force_stroke_passes`), of half the
    opening pass's force minus the closing pass's: dry friction adds ``+d`` to the measured force while the
    gap opens and ``-d`` while it closes, whatever the current. ``sigma`` is the bins' scatter of that half
    difference (position-dependent friction and noise). None with fewer than three such bins.
    """
    half = np.concatenate([0.5 * (p["up_N"] - p["down_N"]) for p in passes]) if passes else np.array([])
    half = half[np.isfinite(half)]
    if half.size < 3:
        return None
    return float(np.mean(half)), float(np.std(half, ddof=1))


def force_stroke_curve(rec, bin_m: float = 0.1e-3, friction: tuple[float, float] | None = None,
                       passes: dict | None = None) -> dict:
    """Measured force vs stroke of a ``force_stroke`` recording, friction taken out.

    In each position bin passed in both directions the mean force of the closing and of the opening
    pass are averaged (dry friction has opposite signs in the two passes; :func:`force_stroke_passes`).
    A one-way stroke (fewer than two bins passed both ways) is used only with the campaign's
    ``friction`` (d, sigma) [N] (:func:`friction_offset`): its pass is shifted by ``-d`` (opening) or
    ``+d`` (closing). Returns ``x_m``, ``force_N``, ``i_A`` (median current while on) and
    ``friction_sigma_N`` (``sigma`` for a one-way stroke, 0 otherwise). ``passes``: the recording's
    :func:`force_stroke_passes` at ``bin_m``, where the caller has them already.
    """
    p = force_stroke_passes(rec, bin_m) if passes is None else passes
    both = np.isfinite(p["up_N"]) & np.isfinite(p["down_N"])
    if np.count_nonzero(both) >= 2:
        return {"x_m": p["x_m"][both], "force_N": 0.5 * (p["up_N"] + p["down_N"])[both], "i_A": p["i_A"],
                "friction_sigma_N": 0.0}
    passes = [(np.isfinite(p["up_N"]), p["up_N"], -1.0), (np.isfinite(p["down_N"]), p["down_N"], 1.0)]
    seen, F, sign = max(passes, key=lambda q: np.count_nonzero(q[0]))
    if friction is None or np.count_nonzero(seen) < 2:
        why = ("and the campaign has no stroke passed both ways to measure the friction" if friction is None
               else "and fewer than two positions in one direction either")
        raise RecordingError(rec.label(), ["force_stroke recording: fewer than two positions passed in both "
                                            f"directions (a one-way stroke), {why}: friction cannot be taken out"])
    d, sigma = friction
    return {"x_m": p["x_m"][seen], "force_N": F[seen] + sign * d, "i_A": p["i_A"], "friction_sigma_N": sigma}
