r"""What a campaign tells about the steel: measured operating points with their uncertainty.

Every recording that carries the steel's magnetization is used, not one stroke:

- **Flux** (``flux`` recordings starting at rest with a measured voltage offset): at each stroke, the
  commutation curve (mean of ascending and descending branch, paper sec. 4) at ``n_currents`` currents, of
  each recording's first ascent (after the rig's demagnetization) and the descent from its highest peak
  (:func:`virgin_and_top`). Before the branches are averaged the rate-dependent part of the loops is taken
  out: eddy currents add ``G dPsi/dt`` to the current (paper eq. 2), so the recordings' loops are split into a
  rate-independent half-width (hysteresis) and ``G`` by least squares over all loops (:func:`eddy_split`); the
  branch mean is then taken in ``i - G dPsi/dt``, where it is unbiased, and only the rate-independent half-
  width counts as the mean's uncertainty.
- **Force** (``force_stroke`` recordings at constant current): friction averaged out between the
  closing and the opening pass (:func:`~.measured.force_stroke_curve`), sampled at
  :data:`FORCE_POSITIONS` positions. A one-way stroke (energized from one stop to the other) is shifted by
  the friction the two-way strokes of the campaign show, with their scatter in its uncertainty. The force
  does not depend on the coil resistance, so it is immune to coil heating.
- **Holds** (``ramp`` and ``voltage_step`` recordings at a fixed stroke with voltage,
  :func:`hold_points`): where the current holds still, dPsi/dt = 0, so there is no eddy current and the
  current is the magnetizing one; Psi by eq. 4 up to the hold and, with a force column, the holding force
  give static points, often at currents above the flux recordings' peaks (a ramp to the rated current).
- **Hysteresis**: force strokes and holds sit on the virgin ascent; :mod:`.virgin_side` takes their points to
  the branch mean's current.
- **Coil heating** (:func:`resistance_choice`): one heating rate ``kappa`` for the campaign's coil, from
  the ``flux`` recordings and the other current-driven recordings at a fixed stroke (``ramp``,
  ``eddy``). Unipolar triangles of a hysteretic steel do not close (the remanence is unknown), so in
  them R at the start and kappa trade off within the header resistance's uncertainty; a ramp's
  current hold (Psi constant while the current is held) gives R(t) itself and pins kappa for them.

Uncertainty of a point (1 sigma, absolute): a relative floor (:data:`PSI_FLOOR_REL`,
:data:`FORCE_FLOOR_REL`, of the value or of a fifth of the recording's largest value, whichever
is larger), and for flux the bias of the branch mean of a rate-independent loop, second order in
its current half-width h: ``|Psi''| h^2 / 2``, plus a share of the half-width w: all of it below
:data:`LOOP_NEAR_ORIGIN` h (the loops are unipolar: the descending branch ends at the remanence, so
the mean there is biased to first order), falling as 1/i above, to :data:`LOOP_ASYMMETRY` w (the first,
virgin ascent is not symmetric to the descending branch: on Preisach truths the first pass's mean lay
within 0.36 w of the curve above 0.1 of the peak, :func:`virgin_and_top`).

Units: SI (A, m, Wb, N).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..errors import RecordingError
from ..measure import (
    ESTIMATED_KEYS,
    HEADER_OFF_SIGMAS,
    campaign_resistance,
    commutation_curve,
    flux_linkage,
    hold_segments,
    peak_curves,
)
from .measured import force_stroke_curve, force_stroke_passes, friction_offset, groups_of

__all__ = ["MeasuredPoint", "PSI_FLOOR_REL", "FORCE_FLOOR_REL", "LOOP_ASYMMETRY", "FORCE_POSITIONS",
           "flux_points", "flux_sigma", "force_points", "hold_points", "HOLD_KINDS", "eddy_split", "resistance_choice",
           "KAPPA_SIGNIFICANT", "EDDY_RATE_SPREAD", "LOOP_NEAR_ORIGIN", "HEADER_OFF_SIGMAS", "MAJOR_LOOP_SHARE",
           "corrected_curve", "corrected_curve_of", "hysteresis_half_width", "virgin_and_top"]

#: Relative 1-sigma floor of a measured flux point (noise, offsets, the resistance's uncertainty).
PSI_FLOOR_REL = 2e-3
#: Relative 1-sigma floor of a measured force point (load cell, friction not quite symmetric).
FORCE_FLOOR_REL = 4e-3
#: Share of the rate-independent loop half-width counted as the branch mean's first-order bias.
LOOP_ASYMMETRY = 0.3
#: The coil counts as heating when the campaign's kappa exceeds this many of its sigmas.
KAPPA_SIGNIFICANT = 3.0
#: Current rates must differ by this factor among the loops to tell eddy currents from hysteresis.
EDDY_RATE_SPREAD = 2.0
#: A recording's loops count for the commutation curve when its highest peak reaches this share of the
#: stroke's highest peak (:func:`virgin_and_top`: the descent from a low peak can lie below the curve).
MAJOR_LOOP_SHARE = 0.75
#: Below this many loop half-widths (in current) the branch mean is no estimate of the curve at all
#: (the descending branch ends at the remanence): there the whole half-width counts as its uncertainty.
#: (5: the error of :func:`virgin_and_top`'s mean stayed within 1.1 sigma on nine Preisach densities; 3 let it
#: reach 1.8 sigma at 0.15-0.3 A, ``tests/test_virgin_and_top.py``.)
LOOP_NEAR_ORIGIN = 5.0
#: Kinds of recordings whose current holds give static points (:func:`hold_points`).
HOLD_KINDS = ("ramp", "voltage_step")
#: Positions taken from each force-stroke curve (evenly over the range passed both ways).
FORCE_POSITIONS = 3
#: Fewest points of a stroke's commutation curve (on its 101-point grid) for it to give flux points.
MIN_CURVE_POINTS = 5


@dataclass(frozen=True)
class MeasuredPoint:
    """One measured operating point: ``kind`` ``"psi"`` [Wb] or ``"force"`` [N] at (i_A, x_m),
    ``value`` and ``sigma`` (1-sigma, same unit), ``group`` (held-out unit: a stroke, a current
    band or a force recording) and ``source`` (file names)."""

    kind: str
    i_A: float
    x_m: float
    value: float
    sigma: float
    group: str
    source: str


def _branch_pairs(results):
    """(ascending, descending) branch pairs of every peak of every flux result."""
    out = []
    for res in results:
        br = res.branches
        for k in range(0, len(br) - 1, 2):
            if br[k].direction == "ascending" and br[k + 1].direction == "descending":
                out.append((res, br[k], br[k + 1]))
    return out


def eddy_split(results) -> tuple[float, str]:
    """Eddy conductance G [S] of the current-driven loops: a loop's current width at equal flux is
    ``2 h(Psi) + G (|dPsi/dt|_asc + |dPsi/dt|_desc)`` (paper eq. 2); with h(Psi) a smooth function
    of the flux (a cubic in Psi / Psi_peak), G follows by least squares over all loops of all
    recordings (slow ``flux`` and fast ``eddy`` triangles).

    G and h can only be told apart by loops run at different current rates (at one rate the flux
    rate at a given flux is the same in every loop): with rates within a factor
    :data:`EDDY_RATE_SPREAD`, G is 0 and the whole loop counts as hysteresis. Returns G (>= 0) and a
    note in words.
    """
    rows, rhs, rates_A = [], [], []
    for res, up, down in _branch_pairs(results):
        t, psi, i = res.time_s, res.psi_Wb, res.current_A
        s_up, s_dn = slice(up.start, up.stop), slice(down.start, down.stop)
        if up.stop - up.start < 8 or down.stop - down.start < 8:
            continue
        p_up, p_dn = psi[s_up], psi[s_dn]
        top = float(max(p_up.max(), p_dn.max()))
        if top <= 0:
            continue
        grid = np.linspace(0.15 * top, 0.85 * top, 12)
        rate_up = np.gradient(p_up, t[s_up])
        rate_dn = np.gradient(p_dn, t[s_dn])
        o_up, o_dn = np.argsort(p_up), np.argsort(p_dn)
        i_up = np.interp(grid, p_up[o_up], i[s_up][o_up])
        i_dn = np.interp(grid, p_dn[o_dn], i[s_dn][o_dn])
        r_up = np.interp(grid, p_up[o_up], np.abs(rate_up)[o_up])
        r_dn = np.interp(grid, p_dn[o_dn], np.abs(rate_dn)[o_dn])
        rates_A.append(float(np.median(np.abs(np.gradient(i[s_up], t[s_up])))))
        z = grid / top
        for zk, w, r in zip(z, i_up - i_dn, r_up + r_dn, strict=True):
            rows.append([r, 1.0, zk, zk**2, zk**3])
            rhs.append(w)
    if len(rows) < 8:
        return 0.0, "eddy loops: too few branches to separate rate-dependent loops"
    if max(rates_A) < EDDY_RATE_SPREAD * max(min(rates_A), 1e-12):
        return 0.0, (f"eddy loops: current rates {min(rates_A):.3g}-{max(rates_A):.3g} A/s too alike to tell eddy "
                     "currents from hysteresis: the whole loop width counts as hysteresis")
    sol, *_ = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)
    G = max(float(sol[0]), 0.0)
    return G, (f"eddy loops: G = {G * 1e3:.3g} mS from {len(rows)} loop widths at {min(rates_A):.3g}-"
               f"{max(rates_A):.3g} A/s (taken out of the current before the branch mean)")


def flux_points(recs, n_currents: int, choose, eddy_recs=(),
                heat_recs=()) -> tuple[list[MeasuredPoint], list[str], dict]:
    """Measured commutation-curve points at every stroke (see the module docstring).

    ``choose(i_A, psi_Wb, n)`` picks the currents (:func:`~.fit.choose_currents`); ``eddy_recs``
    (fast triangles from rest) only help to tell eddy loops from hysteresis; ``heat_recs`` (other
    current-driven recordings at a fixed stroke: ramps, eddy triangles) only help to measure the coil's
    heating. Returns the points, notes and per-stroke details (``curves``: commutation curves for the
    report; ``left_out``: the strokes whose branches give no curve, :data:`MIN_CURVE_POINTS`).
    """
    groups = groups_of(recs)
    extra = [r for r in heat_recs if all(r is not q for q in recs)]
    camp, heated, notes = resistance_choice([*recs, *extra])
    ccs = {key: commutation_curve(g, resistance=camp if heated else None) for key, g in groups.items()}
    all_results = [r for cc in ccs.values() for r in cc.results]
    for rec in eddy_recs:
        fr = flux_linkage(rec, resistance=camp.track_for(rec) if heated and camp.track_for(rec) else None)
        if fr.starts_at_rest and fr.offset_measured:
            all_results.append(fr)
    G, note = eddy_split(all_results)
    notes.append(note)
    points: list[MeasuredPoint] = []
    details, left_out = {}, []
    # with several strokes fewer currents each: the strokes pin the curve together (FEM cost ~ points)
    n_each = n_currents if len(ccs) == 1 else max(5, -(-2 * n_currents // (len(ccs) + 1)))
    for key, cc in sorted(ccs.items()):
        com_i, com_psi, half = corrected_curve(cc, G)
        x = cc.position_m
        names = ",".join(sorted({r.path.name if r.path else r.label() for r in groups[key]}))
        if com_i.size < MIN_CURVE_POINTS:
            left_out.append(f"flux: left out {names} at {x * 1e3:.3f} mm: its branches give {com_i.size} point(s) "
                            f"of a commutation curve, fewer than {MIN_CURVE_POINTS}")
            notes.append(left_out[-1])
            continue
        i_sel, psi_sel = choose(com_i, com_psi, n_each)
        half_w = np.interp(i_sel, com_i, half)
        sigma = flux_sigma(com_i, com_psi, half, i_sel, _track_sigma_rel(cc, camp) if heated else 0.0)
        for i, p, s in zip(i_sel, psi_sel, sigma, strict=True):
            points.append(MeasuredPoint("psi", float(i), x, float(p), float(s), f"flux@{x * 1e3:.3f}mm", names))
        details[key] = {"cc": cc, "i_A": i_sel, "psi_Wb": psi_sel, "sigma_Wb": sigma, "half_width_Wb": half_w}
    if len(ccs) == 1:  # one stroke: hold out current bands instead
        n = len(points)
        band = np.minimum((np.arange(n) * 3) // max(n, 1), 2)
        points = [MeasuredPoint(p.kind, p.i_A, p.x_m, p.value, p.sigma, f"{p.group}/band{b}", p.source)
                  for p, b in zip(points, band, strict=True)]
    return points, notes, {"G_eddy_S": G, "strokes": details, "resistance": camp.summary(), "heated": heated,
                             "camp": camp, "left_out": left_out}


def flux_sigma(com_i, com_psi, half, i_sel, track_rel: float = 0.0) -> np.ndarray:
    """1-sigma [Wb] of commutation-curve points at currents ``i_sel`` [A] (see the module docstring): the
    floor, the resistance tracks' relative ``track_rel`` and the loop's bias, from the curve ``com_i`` [A],
    ``com_psi`` [Wb] and its loop half-width ``half`` [Wb]."""
    psi_sel = np.interp(i_sel, com_i, com_psi)
    half_w = np.interp(i_sel, com_i, half)
    slope = np.gradient(com_psi, com_i)
    curv = np.gradient(slope, com_i)
    d1 = np.maximum(np.interp(i_sel, com_i, slope), 1e-12)
    d2 = np.abs(np.interp(i_sel, com_i, curv))
    h_i = half_w / d1
    peak = float(np.max(np.abs(com_psi)))
    floor = PSI_FLOOR_REL * np.maximum(np.abs(psi_sel), 0.2 * peak)
    near = np.clip(LOOP_NEAR_ORIGIN * h_i / np.maximum(i_sel, 1e-12), LOOP_ASYMMETRY, 1.0)
    bias = 0.5 * d2 * h_i**2 + near * half_w
    return np.sqrt(floor**2 + (track_rel * np.abs(psi_sel)) ** 2 + bias**2)


def resistance_choice(recs) -> tuple:
    """The campaign's resistance tracks (:func:`~solenoid_fmu.measure.campaign_resistance`, one kappa for
    all of ``recs``: the flux recordings and the other current-driven ones at a fixed stroke) and whether
    the eq.-4 flux must use them: the coil heats measurably (kappa above :data:`KAPPA_SIGNIFICANT`
    sigmas), a header resistance disagrees with the data beyond the header's own uncertainty, or a
    recording's own data pin its R more than :data:`HEADER_OFF_SIGMAS` of their sigmas from its header, or every
    header misses the data by one offset (:func:`~solenoid_fmu.measure.resistance_campaign.common_header_offset`),
    or a recording has no header resistance (its track then, the data's own R). Else the header resistance
    (measured before each run) is the better value: a single-cycle recording's track rests on it anyway,
    and its loop need not close (the remanence of a hysteretic steel is several per cent of the peak flux).
    Returns (campaign tracks, heated, notes)."""
    camp = campaign_resistance(recs)
    why = []
    if (o := camp.header_offset) is not None:  # every track then, the headers shifted (common_header_offset)
        why.append(f"every header resistance misses the data by {o['ohm']:+.4g} +- {o['sigma_ohm']:.2g} ohm "
                   f"({o['recordings']} recordings pin their own R: the voltage taken across more than the coil, or "
                   "the header's meter off), so every header is taken shifted by it")
    if camp.header_offset is None and any(k in r.header for r in recs for k in ESTIMATED_KEYS):  # the pipeline's
        why.append("header resistances were shifted by the campaign's common offset or filled in from the "
                   "recordings' data (headers_from_data): estimates, not measurements")
    if camp.kappa_per_J > KAPPA_SIGNIFICANT * camp.kappa_sigma_per_J:
        why.append(f"the coil heats (kappa = {camp.kappa_per_J:.3g} +- {camp.kappa_sigma_per_J:.2g} 1/J)")
    why += [f"{tr.label}: header resistance disagrees with the data (R0 = {tr.R0_ohm:.5g} +- "
            f"{tr.R0_sigma_ohm:.2g} ohm)" for tr in camp.tracks.values() if tr.header_disagrees]
    why += [f"{tr.label}: its own data pin R at the start to {tr.R0_ohm:.6g} +- {tr.R0_sigma_ohm:.2g} ohm, "
            f"{tr.header_off_sigmas:.0f} sigma from the header's {tr.header_R_ohm:.6g} ohm"
            for tr in camp.tracks.values() if tr.header_overruled]
    why += [f"{tr.label}: no header resistance (R at the start {tr.R0_ohm:.6g} +- {tr.R0_sigma_ohm:.2g} ohm from its "
            "data)" for tr in camp.tracks.values() if tr.header_R_ohm is None]
    heated = bool(why)
    off = [key for key, tr in camp.tracks.items() if tr.header_disagrees or tr.header_overruled or
           tr.header_R_ohm is None]
    if heated and len(why) == len(off):  # no heating: only those recordings' headers are at odds with their data
        camp = camp.restricted(off)
        notes = [f"resistance: R(t) tracks used for eq. 4 in {len(off)} recording(s) because {'; '.join(why)}; "
                 "the others keep their header's resistance"]
    else:
        notes = ([f"resistance: R(t) tracks used for eq. 4 because {'; '.join(why)}"] if heated else
                 ["resistance: the header resistances hold (no measurable heating, no header at odds with the "
                  "data)"])
    if heated:
        notes += [f"resistance not pinned: {w}" for w in camp.not_pinned]
        notes += [f"resistance: {w}" for w in camp.problems]
    return camp, heated, notes


def _track_sigma_rel(cc, camp) -> float:
    """Relative flux uncertainty the resistance tracks leave in a stroke's commutation curve: the
    recordings' relative Psi-at-peak sigmas, averaged over the recordings (independent tracks)."""
    rel = []
    for res in cc.results:  # a recording on its header's resistance counts with the floor alone
        tr = res.track
        rel.append(tr.psi_peak_sigma_Wb / abs(tr.psi_peak_Wb) if tr is not None and tr.psi_peak_Wb else 0.0)
    if not rel:
        return 0.0
    return float(np.sqrt(np.mean(np.square(rel))) / np.sqrt(len(rel)))


def corrected_curve(cc, G_S: float, n: int = 101) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Commutation curve (i [A], Psi [Wb]) and rate-independent loop half-width [Wb] of ``cc``'s
    branches with the eddy current ``G dPsi/dt`` taken out of the current: :func:`corrected_curve_of`
    its flux results ``cc.results``."""
    return corrected_curve_of(cc.results, G_S, n)


def corrected_curve_of(results, G_S: float, n: int = 101) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`corrected_curve` of flux results (each with ``psi_Wb``, ``time_s`` and ``branches``).

    Per recording the mean of its first ascent and the descent from its highest peak
    (:func:`virgin_and_top`), averaged over the recordings whose highest peak reaches
    :data:`MAJOR_LOOP_SHARE` of the highest."""
    pairs = []
    for res in results:
        rate = np.gradient(res.psi_Wb, res.time_s)
        pairs.append([dataclasses.replace(br, i_A=br.i_A - G_S * rate[br.start:br.stop]) for br in res.branches])
    top = max(b.peak_A for br in pairs for b in br)
    grid = np.linspace(0.0, top, n)
    kept = [virgin_and_top(br, grid) for br in pairs if max(b.peak_A for b in br) >= MAJOR_LOOP_SHARE * top]
    stack, wst = np.vstack([m for m, _ in kept]), np.vstack([w for _, w in kept])
    count = np.sum(np.isfinite(stack), axis=0)
    keep = count > 0
    with np.errstate(all="ignore"):
        psi = np.nansum(stack[:, keep], axis=0) / count[keep]
        half = 0.5 * np.abs(np.nanmean(wst[:, keep], axis=0))
    half = np.where(np.isfinite(half), half, 0.0)
    return grid[keep], psi, half


def hysteresis_half_width(cc, i_A) -> np.ndarray:
    """Half the rate-independent loop width [Wb] of a commutation curve's branches at currents ``i_A`` [A]:
    how far the branch mean may sit from the magnetization curve the FEM computes. The same loops as the
    joint fit's points (:func:`corrected_curve` without an eddy current: each recording's first ascent
    and the descent from its highest peak)."""
    com_i, _, half = corrected_curve(cc, 0.0)
    return np.interp(i_A, com_i, half)


def virgin_and_top(branches, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Branch mean and width (descending - ascending) [Wb] on ``grid`` of one recording's unipolar loops:
    at each level the first ascent through it and the descent from the recording's highest peak.

    After the rig's demagnetization the first ascent through a level is the virgin curve (below the
    magnetization curve), also where it passes an earlier, lower peak (wiping out); the descent from a
    peak well into saturation lies above the curve. A later ascent starts at the remanence the loop
    before left (above the virgin curve), and the descent from a low peak can lie below the curve: the
    mean of every loop is biased up at low field, the mean of a small loop down near its peak. On
    quasi-static Preisach truths (Lorentzian and Gaussian densities, peak at 5-30 % and spread 10-40 % of
    the saturation flux, major half-width 1-3 % of the rated current; a 1.5 A loop at 2 mm) the mean of
    the first loop lay within 0.36 of its half-width (1.7 % of the flux) of the curve from 0.15 A up, the
    mean of two loops 2-11 % above it. Without hysteresis every pass has the same mean."""
    means, widths = peak_curves(branches, grid)
    ascents = [m - 0.5 * w for m, w in zip(means, widths, strict=True)]  # the ascending branch on the grid
    virgin = np.full(grid.shape, np.nan)
    reached = -np.inf
    for asc, branch in zip(ascents, branches[::2], strict=True):
        new = (grid > reached) & np.isfinite(asc)
        virgin[new] = asc[new]
        reached = max(reached, float(branch.peak_A))
    peaks = [b.peak_A for b in branches[::2]]
    k = int(np.argmax(peaks))
    descent = ascents[k] + widths[k]
    return 0.5 * (virgin + descent), descent - virgin


def force_points(recs) -> tuple[list[MeasuredPoint], list[str]]:
    """Force points from ``force_stroke`` recordings (friction averaged; see the module docstring).

    A one-way stroke is shifted by the friction the campaign's two-way strokes show
    (:func:`~.measured.friction_offset`), whose scatter is added to its points' 1-sigma; without a two-way
    stroke it is left out with a note."""
    points, notes, passes = [], [], {}
    for k, rec in enumerate(recs):
        try:
            passes[k] = force_stroke_passes(rec)
        except RecordingError:
            pass  # named below, where force_stroke_curve raises the same error
    friction = friction_offset(list(passes.values()))
    for k, rec in enumerate(recs):
        try:
            fc = force_stroke_curve(rec, friction=friction, passes=passes.get(k))
        except RecordingError as exc:
            notes.append(f"force: left out {exc}")
            continue
        x, F = fc["x_m"], fc["force_N"]
        xs = np.linspace(x.min(), x.max(), FORCE_POSITIONS + 2)[1:-1]
        Fs = np.interp(xs, x, F)
        Fmax = float(np.max(np.abs(F)))
        sig = np.hypot(FORCE_FLOOR_REL * np.maximum(np.abs(Fs), 0.2 * Fmax), fc["friction_sigma_N"])
        name = rec.path.name if rec.path else rec.label()
        if fc["friction_sigma_N"] > 0.0:
            notes.append(f"force: one-way stroke {name} at {fc['i_A']:.3g} A used with the friction the two-way "
                         f"strokes show, {friction[0]:+.3g} +- {friction[1]:.2g} N while the gap opens")
        for xv, fv, sv in zip(xs, Fs, sig, strict=True):
            points.append(MeasuredPoint("force", fc["i_A"], float(xv), float(fv), float(sv), f"force:{name}", name))
    return points, notes


def hold_points(recs, camp=None, heated: bool = False, remanence_Wb: float = 0.0
                ) -> tuple[list[MeasuredPoint], list[str]]:
    """Static points at the current holds of ``recs`` (``ramp``, ``voltage_step``: one stroke, with voltage).

    At a settled hold (:func:`~solenoid_fmu.measure.hold_segments`) dPsi/dt = 0: no eddy current, the
    current is the magnetizing one and the point lies at the tip of the recording's loop (on the
    commutation curve; on a hysteretic steel on the virgin ascent, :mod:`.virgin_side`). Psi [Wb]: the
    mean of eq. 4 over the hold, integrated from the rest before it
    (with the campaign's R(t) track where the coil heats, ``heated``, else the header's R), with the
    resistance the hold itself shows (U = R i there: a slope of Psi over the hold is the error of the R
    used, and corrects Psi by that error times the charge int i dt), 1-sigma from :data:`PSI_FLOOR_REL`,
    the track's own uncertainty, the hold's resistance uncertainty, the voltage noise integrated up to the
    hold (a random walk), the offset's error and ``remanence_Wb`` (the unknown remanence the integral starts from: the
    flux recordings' loop width; 0 for a steel without hysteresis). Force [N] (with a force column):
    the mean holding force, 1-sigma :data:`FORCE_FLOOR_REL`. Recordings that do not start at rest with a
    measured voltage offset, or have no hold, are left out with a note. Group: ``hold:<file>``.
    """
    points, notes = [], []
    for rec in recs:
        name = rec.path.name if rec.path else rec.label()
        if rec.voltage_V is None:
            continue
        track = camp.track_for(rec) if heated and camp is not None else None
        try:
            fr = flux_linkage(rec, resistance=track)
            segs = hold_segments(rec)
        except RecordingError as exc:
            notes.append(f"hold: left out {name}: {exc}")
            continue
        if not (fr.starts_at_rest and fr.offset_measured):
            notes.append(f"hold: left out {name}: it does not start at rest with a measured voltage offset")
            continue
        x = float(np.median(rec.positions_m()))
        track_rel = 0.0
        if fr.track is not None and fr.track.psi_peak_Wb:
            track_rel = fr.track.psi_peak_sigma_Wb / abs(fr.track.psi_peak_Wb)
        n0 = len(points)
        t, ic = fr.time_s, fr.current_A
        charge = np.concatenate([[0.0], np.cumsum(0.5 * (ic[1:] + ic[:-1]) * np.diff(t))])  # int i dt [A s]
        for sl in segs:
            i = float(np.mean(ic[sl]))
            if i <= 0.0 or sl.stop - sl.start < 4:
                continue
            # the resistance at the hold: there U = R i, so a slope of Psi is the error of the R used
            (slope, _), cov = np.polyfit(t[sl] - t[sl].mean(), fr.psi_Wb[sl], 1, cov=True)
            dR, dR_sigma = slope / i, float(np.sqrt(max(cov[0, 0], 0.0))) / i
            q = float(np.mean(charge[sl]))
            psi = float(np.mean(fr.psi_Wb[sl])) - dR * q
            # the voltage noise integrated up to the hold (a random walk) and the offset's own error
            u = rec.voltage_V[sl]
            u_noise = float(np.std(np.diff(u))) / np.sqrt(2.0)
            t_hold = float(np.mean(t[sl]) - t[0])
            walk = u_noise * np.sqrt(float(np.median(np.diff(t))) * t_hold)
            offset = fr.offset_uncertainty_Wb * t_hold / max(float(t[-1] - t[0]), 1e-12)
            sig = float(np.sqrt((PSI_FLOOR_REL * psi) ** 2 + (track_rel * psi) ** 2 + remanence_Wb**2
                                + (dR_sigma * q) ** 2 + walk**2 + offset**2))
            points.append(MeasuredPoint("psi", i, x, psi, sig, f"hold:{name}", name))
            if rec.force_N is not None:
                F = float(np.mean(rec.force_N[sl]))
                points.append(MeasuredPoint("force", i, x, F, FORCE_FLOOR_REL * abs(F), f"hold:{name}", name))
        if len(points) == n0:
            notes.append(f"hold: left out {name}: no settled current hold")
    return points, notes
