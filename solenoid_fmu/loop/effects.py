"""The effects' fits: each effect's parameters from the recordings or their residuals, by its own regression.

Each fit returns ``(section, note)``: the maps.json ``effects`` section of the effect (see
:mod:`solenoid_fmu.loop.tables`) and a note for the report (what it was fitted on). The fits:

``hysteresis``
    Play operator (:func:`solenoid_fmu.realtime.fit_play_to_series`) on the current the maps do
    not explain, ``i - i_f(Psi, x) - i_eddy`` along the measured flux of the slow (``flux``)
    recordings: rate-independent, so the slow triangles carry it cleanly. Where the plays alone vanish
    (the error an identified B(H) leaves in ``i_f`` is larger than the loops), a single-valued
    correction ``dh(Psi)`` is fitted beside them and dropped (:data:`HYSTERESIS_CORRECTION_NODES`); elsewhere
    the loop fits both and keeps the one that predicts the recordings neither saw
    (:func:`solenoid_fmu.loop.gates.hysteresis_chosen`).
``eddy``
    Ladder ``i_eddy = G e + sum_k G_k lowpass_tau_k(e)`` with ``e = dPsi/dt`` over a fixed grid of
    time constants (0.1 ms .. 10 ms), non-negative least squares on the ``eddy`` recordings; sections
    under 3 % of the total conductance are dropped.

    Both take the flux linkage itself from paper eq. 4 as the state along which they fit. When the
    model already has coil heating, that flux is the one of the heating-corrected recordings
    (:func:`heating_corrected`: the resistance measured before the run plus the fitted R(T) rise):
    with the header resistance alone it drifts by ``int (R(T) - R) i dt``, and the play operator or
    the ladder would be fitted to that drift (on the demo campaign, 0.4 K of warming in the 2 A
    triangles, the play operator then misses the current by 0.21 A RMS instead of 0.008 A).
``heating``
    ``C_th`` and, where runs that start warm cool measurably, ``R_th`` from the eq.-4 flux drift the coil
    heating leaves (:mod:`solenoid_fmu.loop.heating_fit`, which also corrects recordings for it).
``friction``
    Dahl friction in the force, ``F_fr -> +-F_c`` over the presliding displacement, linear in
    ``F_c`` for each presliding length of a grid (5 um .. 100 um); the best fit wins.

One fit per parameter: the eddy ladder's direct term ``G`` is the single conductance the maps
already carry (maps.json ``eddy.G_eddy_S``, fitted by :func:`solenoid_fmu.maps.fit_eddy`). The
ladder fits it again, jointly with its sections (so that they do not absorb the misfit of a value
fitted without them), and when the ladder is kept its refit *replaces* the maps' value: the fit's
note says so (``note["G_eddy_S"]``: the maps' value and the refit), and the improved maps'
``eddy.source`` names the refit (:func:`g_eddy_source`).
"""

from __future__ import annotations

import math

import numpy as np

from ..fmu import start_excess_K
from ..measure import armature_moves, flux_linkage
from ..realtime import HysteresisError, MapTables, PlayHysteresis, fit_play_to_series
from .heating_fit import heating_corrected
from .residuals import recording_name
from .signals import lowpass
from .tables import ImproveError

#: Time constants of the eddy-ladder regression [s].
LADDER_TAUS_S = (1e-4, 3e-4, 1e-3, 3e-3, 1e-2)
#: Nodes of the single-valued current correction fitted with the play operator, and then dropped, where
#: the plays alone vanish: a B(H) error leaves a single-valued i(Psi) residual that can be larger than the
#: loops (it then leaves nothing to non-negative play weights); the model keeps its maps' i_f and the plays.
#: Not always: a unipolar loop's own mean is not its centre, and the correction would take that part of the
#: hysteresis away from the plays (on true maps the flux error after the fit grows from 1/3 to 0.35); where both
#: fits exist, recordings neither was fitted on choose (:func:`solenoid_fmu.loop.gates.hysteresis_chosen`).
HYSTERESIS_CORRECTION_NODES = 7
#: Presliding lengths tried for friction [m].
PRESLIDING_M = (5e-6, 10e-6, 20e-6, 50e-6, 100e-6)


def _i_f(tables: MapTables, psi: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.array([tables.i_f_A(float(p), float(xx)) for p, xx in zip(psi, x, strict=True)])


def flux_data(rec, tables: MapTables, flux_of=flux_linkage):
    """(t, Psi, dPsi/dt, i, x) of a recording from paper eq. 4, or None if its flux is not absolute.

    A recording that starts energized has Psi anchored to the maps' flux at the first sample's
    current and position (the integration constant eq. 4 cannot give); one without any
    zero-current rest (no measured voltage offset) is left out (None).
    """
    fr = flux_of(rec)
    if not fr.offset_measured:
        return None
    t = np.asarray(rec.time_s, dtype=float)
    x = np.asarray(rec.positions_m(), dtype=float)
    psi = np.asarray(fr.psi_Wb, dtype=float)
    if not fr.starts_at_rest:
        psi = psi + tables.psi_of_current(float(fr.current_A[0]), float(x[0]))
    return t, psi, np.gradient(psi, t), np.asarray(rec.current_A, dtype=float), x


def _eddy_current(tables, effects, e, t) -> np.ndarray:
    G0 = tables.G_eddy_S or 0.0
    out = G0 * e
    lad = effects.get("eddy_ladder")
    if lad:
        for G, tau in zip(lad["G_S"], lad["tau_s"], strict=True):
            out = out + G * lowpass(e, t, tau)
    return out


def _hyst_current(effects, psi) -> np.ndarray:
    hy = effects.get("hysteresis")
    if not hy:
        return np.zeros_like(psi)
    shape = hy.get("shape")
    play = PlayHysteresis(hy["thresholds"], hy["weights"],
                          shape=None if not shape else (shape["b_nodes"], shape["g_nodes"]), b0=float(psi[0]))
    return play.run(psi)


def _without_heating(recordings: list, effects: dict, flux_of) -> list:
    """The recordings with the model's coil heating taken out of their voltage (module docstring), each run
    from its temperature above ambient (``flux_of.ambient_R_ohm``, a FluxCache's, when known); unchanged when
    the model has no heating."""
    heating = effects.get("heating")
    if not heating:
        return list(recordings)
    ambient = getattr(flux_of, "ambient_R_ohm", None)
    return [heating_corrected(r, heating, T_start_excess_K=start_excess_K(r.coil_resistance_ohm, ambient,
                                                                          heating["alpha_per_K"]))
            for r in recordings]


def _flux_series(recs: list, tables: MapTables, flux_of):
    """Each recording of ``recs`` with its :func:`flux_data` ``(t, psi, e, i, x)``, where it has them."""
    for rec in recs:
        data = flux_data(rec, tables, flux_of)
        if data is not None:
            yield rec, data


def _fit_series(recs: list, effects: dict, tables: MapTables, flux_of):
    """:func:`_flux_series` of the recordings a flux-fitted effect is fitted on: a recording with a resistance
    track (``flux_of.tracked``, a :class:`~solenoid_fmu.loop.residuals.FluxCache` that noted the campaign's
    tracks) with the flux integrated with it, the others with the model's heating taken out of their voltage
    (:func:`_without_heating`). Each recording once, in the order of ``recs``."""
    tracked = getattr(flux_of, "tracked", None)
    own = {id(r): tracked(r) for r in recs} if tracked is not None else {}
    plain = iter(_without_heating([r for r in recs if own.get(id(r)) is None], effects, flux_of))
    for rec in recs:
        flux = own.get(id(rec))
        if flux is None:
            yield from _flux_series([next(plain)], tables, flux_of)
        else:
            yield from _flux_series([rec], tables, lambda _r, flux=flux: flux)


# -- fits ----------------------------------------------------------------------------------------
def fit_hysteresis(tables, effects, recordings, flux_of=flux_linkage, correction: bool = False) -> tuple[dict, dict]:
    """Play-operator hysteresis from slow current-driven recordings with voltage; (section, note).

    ``correction``: fit the single-valued correction beside the plays (and drop it) from the start; without it,
    only where the plays alone vanish (module docstring; :func:`solenoid_fmu.loop.gates.hysteresis_chosen` fits
    both and keeps the one that predicts the recordings neither was fitted on better)."""
    recs = [r for r in recordings if r.kind == "flux" and r.voltage_V is not None]
    if not recs:
        recs = [r for r in recordings if r.kind in ("ramp", "eddy") and r.voltage_V is not None]
    if not recs:
        raise ImproveError("hysteresis: no current-driven recording with a voltage to fit on")
    recs, unpinned = pinned_first(recs, flux_of)
    bs, hs, used = [], [], []
    for rec, (t, psi, e, i, x) in _fit_series(recs, effects, tables, flux_of):
        h = i - _i_f(tables, psi, x) - _eddy_current(tables, effects, e, t)
        step = max(1, psi.size // 3000)  # rate-independent: a decimated series keeps the loops
        bs.append(psi[::step])
        hs.append(h[::step])
        used.append(rec)
    if not bs:
        raise ImproveError("hysteresis: not identifiable from these recordings: add a slow 'flux' recording "
                           "(triangles from zero current, with a zero-current rest for the voltage offset)")
    corrected = bool(correction)
    try:
        fit = fit_play_to_series(bs, hs, n_plays=12, n_shape=7, b0=0.0,
                                 n_correction=HYSTERESIS_CORRECTION_NODES if corrected else 0)
    except HysteresisError as exc:
        if corrected:
            raise ImproveError(f"hysteresis: {exc}") from None
        try:  # a single-valued error larger than the loops left nothing to the plays: take it out beside them
            fit = fit_play_to_series(bs, hs, n_plays=12, n_shape=7, b0=0.0, n_correction=HYSTERESIS_CORRECTION_NODES)
            corrected = True
        except HysteresisError as exc:
            raise ImproveError(f"hysteresis: {exc}") from None
    d = fit.play.to_dict()
    section = {"thresholds": d["thresholds"], "weights": d["weights"], "shape": d["shape"]}
    note = {"fitted_on": [recording_name(r) for r in used], "rms_A": fit.rms}
    if unpinned:
        note["left_out_not_pinned"] = unpinned
    if corrected:
        note["single_valued_correction"] = ("fitted beside the plays and dropped" if correction else
                                            "fitted beside the plays and dropped: without it the plays vanished "
                                            "(an i_f error larger than the loops)")
    return section, note


#: A heated flux recording is left out of the hysteresis fit where its resistance track leaves the flux at its peak
#: uncertain by more than this share (:func:`pinned_first`): half the loop half-width (2 % of the flux) from which
#: the identification counts a loop as hysteresis. The demo's 2 A triangle: 1.3-2 %; random-2 #123's least pinned
#: flux recording: 0.32 % (leaving that one out cost the loop its exact effects: a spurious eddy ladder).
DRIFT_REL = 0.01


def pinned_first(recs: list, flux_of) -> tuple[list, list]:
    """The recordings a hysteresis fit uses (their eq.-4 flux pinned within :data:`DRIFT_REL`) and the names left out.

    A recording whose resistance track leaves its flux uncertain (``flux_of.tracks``: the coil heats and its R at
    the start or its heating rate is not measured by its own data; uncertain at the peak by more than
    :data:`DRIFT_REL`) carries a drift that opens its loops towards their tips, which the play operator takes for
    hysteresis: on the demo campaign the 2 A triangle's made the shape factor rise at the top, and the model's
    force at the 2 A holds 1.1-1.2 % of full scale off where the bare model had 0.3 %. Left out where another
    recording (pinned, or without a track: no heating measured) remains; all kept otherwise."""
    tracks = getattr(flux_of, "tracks", None)
    if tracks is None:
        return recs, []
    bad = [r for r in recs if (t := tracks.track_for(r)) is not None
           and t.psi_peak_sigma_Wb > DRIFT_REL * abs(t.psi_peak_Wb)]
    if not bad or len(bad) == len(recs):
        return recs, []
    return [r for r in recs if all(r is not b for b in bad)], [recording_name(r) for r in bad]


def fit_eddy_ladder(tables, effects, recordings, flux_of=flux_linkage) -> tuple[dict, dict]:
    """Eddy-current ladder by NNLS over fixed time constants; (section, note).

    The note's ``G_eddy_S`` is ``{"maps": the maps' G_eddy [S] or None, "refit": G [S], "kept":
    ...}``: the ladder's direct term, which replaces the maps' value with the ladder (module
    docstring).
    """
    # lazy: scipy.optimize takes ~0.15 s to import and only this fit needs it (command-line start-up)
    from scipy.optimize import nnls

    recs = [r for r in recordings if r.kind == "eddy" and r.voltage_V is not None]
    if not recs:
        raise ImproveError("eddy: no 'eddy' recording (fast triangles) to fit the ladder on")
    rows, ys, used = [], [], []
    for rec, (t, psi, e, i, x) in _fit_series(recs, effects, tables, flux_of):
        y = i - _i_f(tables, psi, x) - _hyst_current(effects, psi)
        cols = [e] + [lowpass(e, t, tau) for tau in LADDER_TAUS_S]
        rows.append(np.column_stack(cols))
        ys.append(y)
        used.append(rec)
    if not rows:
        raise ImproveError("eddy: not identifiable from these recordings: add fast 'eddy' triangles with a "
                           "zero-current rest (for the voltage offset)")
    A, y = np.vstack(rows), np.concatenate(ys)
    scale = np.maximum(np.sqrt(np.mean(A**2, axis=0)), 1e-30)
    coef, _ = nnls(A / scale, y)
    coef = coef / scale
    G0, Gk = float(coef[0]), coef[1:]
    total = G0 + float(Gk.sum())
    keep = Gk > 0.03 * max(total, 1e-30)
    if not keep.any():
        raise ImproveError("eddy: no ladder section with a share above 3 % (a single G_eddy explains the data)")
    section = {"G_S": [float(g) for g in Gk[keep]], "tau_s": [float(tau) for tau, k in zip(LADDER_TAUS_S, keep,
                                                                                          strict=True) if k]}
    g_eddy = {"maps": tables.G_eddy_S, "refit": G0,
              "kept": "the refit: it replaces the maps' G_eddy when the ladder is kept (fitted with the ladder)"}
    return section, {"fitted_on": [recording_name(r) for r in used], "G_eddy_S": g_eddy}


def g_eddy_source(tables, note: dict) -> str:
    """maps.json ``eddy.source`` for the G_eddy a kept ladder brings (its fit's ``note``)."""
    old = tables.eddy.source or "unknown"
    was = note["G_eddy_S"]["maps"]
    was = "none" if was is None else f"{was:.6g} S"
    return (f"refit with the eddy ladder by improve on {', '.join(note['fitted_on'])} "
            f"(replaces the maps' G_eddy, {was}, from: {old})")


def _dahl(x: np.ndarray, presliding_m: float) -> np.ndarray:
    """Dahl friction state for F_c = 1 along positions ``x`` (same update as model.py)."""
    f = np.zeros_like(x)
    for k in range(1, x.size):
        dx = x[k] - x[k - 1]
        prev = f[k - 1]
        if dx != 0.0:
            target = 1.0 if dx > 0.0 else -1.0
            prev = target + (prev - target) * math.exp(-abs(dx) / presliding_m)
        f[k] = prev
    return f


def fit_friction(tables, effects, cases) -> tuple[dict, dict]:
    """Friction force and presliding length from the force residual where the armature moves (beyond its position
    sensor's noise: :func:`~solenoid_fmu.measure.armature_moves`; a fixed stroke's noisy column is no motion)."""
    moving = [c for c in cases if "force_N" in c.residuals and armature_moves(c.position_m)]
    if not moving:
        raise ImproveError("friction: no recording with force and a moving armature")
    best = None
    res = [c.residuals["force_N"] - np.mean(c.residuals["force_N"]) for c in moving]
    for p in PRESLIDING_M:
        phis = [_dahl(np.asarray(c.position_m, dtype=float), p) for c in moving]
        phis = [phi - phi.mean() for phi in phis]
        den = sum(float(phi @ phi) for phi in phis)
        if den <= 0:
            continue
        Fc = sum(float(phi @ r) for phi, r in zip(phis, res, strict=True)) / den
        sse = sum(float(np.sum((r - Fc * phi) ** 2)) for phi, r in zip(phis, res, strict=True))
        if best is None or sse < best[0]:
            best = (sse, Fc, p)
    if best is None or best[1] <= 0.0:
        raise ImproveError("friction: the force residual does not flip with the direction of motion")
    return {"force_N": float(best[1]), "presliding_m": float(best[2])}, {"fitted_on": [c.name for c in moving]}
