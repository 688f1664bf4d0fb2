"""Close the loop: add the effect the diagnosis names to the real-time model, fit it, keep it if it pays.

The loop (issue 7), on a campaign of recordings and an FMU built from characteristic maps:

1. simulate every recording with the current model and diagnose the residual
   (:mod:`solenoid_fmu.diagnose`);
2. take the best-ranked candidate that the model can add and has not tried, scoring at least
   :data:`TRY_THRESHOLD` (0.1; the verdict threshold of ``diagnose`` is 0.25, but here the held-out
   gate of step 3 decides), while the residual is significant (``hysteresis``,
   ``eddy`` as an eddy-current ladder, ``heating``, ``friction``; ``material`` and ``sensor`` are
   not model effects: a wrong B(H) is fixed by ``identify``, a sensor by calibration);
3. fit its parameters on the *fit* part of the recordings (:func:`split_recordings`) by the
   effect's own regression (below), simulate all recordings with it and keep it only if the
   error on the *validation* part falls by at least ``min_gain`` (default 10 %). A one- or
   two-parameter effect (heating, friction) whose evidence sits in a few recordings, all of them
   in the fit part, cannot pass that; it is fitted on all recordings and kept if it cuts the error
   over all of them by ``min_gain`` while the fit-part estimate does not make the validation part
   worse (by more than a tenth of ``min_gain``; the diagnosis has already cross-validated its
   signature);
4. repeat while an effect still pays, up to ``max_effects``. An effect rejected in step 3 is
   tried again after another effect was kept (the other one may have masked it: a large eddy
   residual spoils the heating fit until the ladder is in the model).

Campaigns from any rig: the fit/validation split and the diagnosis's cross-validation folds go
by the size of the excitations, not by file names; the flux of a recording that starts energized
is compared as a change from the model's flux at its first sample; the gate's error is the
full-scale NRMSE per kind (:func:`_error`), so that no single recording can swing it.

The effect sub-models live in ``model.py`` (their equations are in
:meth:`solenoid_fmu.model.SolenoidModel._step_fx`); the improved FMU carries them as switchable
sub-models with parameters, from the ``effects`` section of its maps.json. The fits:

``hysteresis``
    Play operator (:func:`solenoid_fmu.hysteresis.fit_play_to_series`) on the current the maps do
    not explain, ``i - i_f(Psi, x) - i_eddy`` along the measured flux of the slow (``flux``)
    recordings: rate-independent, so the slow triangles carry it cleanly.
``eddy``
    Ladder ``i_eddy = G e + sum_k G_k lowpass_tau_k(e)`` with ``e = dPsi/dt`` over a fixed grid of
    time constants (0.1 ms .. 10 ms), non-negative least squares on the ``eddy`` recordings; sections
    under 3 % of the total conductance are dropped.
``heating``
    With the resistance measured before a run, coil heating leaves the eq.-4 flux drifting by
    ``int (R(T) - R) i dt``; with ``C_th dT/dt = R i^2`` (cooling is negligible within a
    recording) the drift is ``(alpha R^2 / C_th) int i int i^2``: linear in ``1 / C_th``, fitted by
    least squares on the flux residual (``R_th`` is not identifiable from short recordings and
    keeps its default, ``alpha`` is copper's unless the maps say otherwise).
``friction``
    Dahl friction in the force, ``F_fr -> +-F_c`` over the presliding displacement, linear in
    ``F_c`` for each presliding length of a grid (5 um .. 100 um); the best fit wins.

The reported before/after errors come from the FMUs themselves (fmpy), per recording and signal.
"""

from __future__ import annotations

import json
import math
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import SolenoidError
from ..realtime import COPPER_ALPHA_PER_K, HysteresisError
from ..realtime import model as _model
from .diagnose import detrend, lowpass

#: Effects ``improve`` can add, by the names ``diagnose`` uses, and their maps.json section.
ADDABLE = {"hysteresis": "hysteresis", "eddy": "eddy_ladder", "heating": "heating", "friction": "friction"}
DEFAULT_MAX_EFFECTS = 4
DEFAULT_MIN_GAIN = 0.10
#: Diagnosis score from which an addable effect is *tried* (fitted and judged on the validation
#: recordings) even when it does not clear the verdict threshold: the held-out gate decides.
TRY_THRESHOLD = 0.1
#: Time constants of the eddy-ladder regression [s].
LADDER_TAUS_S = (1e-4, 3e-4, 1e-3, 3e-3, 1e-2)
#: Effects with one or two fitted parameters (see the gate in :func:`improve_tables`).
FEW_PARAMETERS = ("heating", "friction")
#: Presliding lengths tried for friction [m].
PRESLIDING_M = (5e-6, 10e-6, 20e-6, 50e-6, 100e-6)


class ImproveError(SolenoidError):
    """The improvement loop cannot run (no recordings, an FMU without maps, ...)."""


@dataclass
class Step:
    """One tried effect: its parameters and the validation error before and after (normalized)."""

    effect: str
    accepted: bool
    params: dict = field(default_factory=dict)
    heldout_before: float = math.nan
    heldout_after: float = math.nan
    note: str = ""

    def as_dict(self) -> dict:
        return {"effect": self.effect, "accepted": self.accepted, "params": self.params,
                "heldout_error_before": self.heldout_before, "heldout_error_after": self.heldout_after,
                "note": self.note}


class Improvement(NamedTuple):
    """Outcome of :func:`improve_tables`: the model's maps with the kept effects, every tried
    :class:`Step`, the diagnosis of each round (dicts), the residual cases of the first and
    the final model (in-process simulations of all recordings), and for every addable effect the
    campaign cannot identify, what to add (:func:`not_identifiable`)."""

    tables: _model.MapTables
    steps: list
    diagnoses: list
    cases_before: list
    cases_after: list
    not_identifiable: dict = {}


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
    from .diagnose import conditioned_position

    x = conditioned_position(np.asarray(rec.positions_m(), dtype=float))
    span = float(np.ptp(x))
    if span <= 0.0:
        return False
    k = int(np.argmax(np.abs(x - x[0])))
    return float(np.max(np.abs(x[k:] - x[k]))) > 0.05 * span


def not_identifiable(recordings) -> dict:
    """Addable effects the campaign cannot identify, each with what to add (see README).

    ``hysteresis``: a current-driven ``flux`` (or ``ramp`` / ``eddy``) recording with voltage that
    starts at zero current and rests there (absolute eq.-4 flux); ``eddy``: an ``eddy`` recording
    with voltage and a zero-current rest; ``heating``: a recording with voltage, the resistance
    measured before the run (header ``coil_resistance_ohm``) and the current held for >= 0.2 s;
    ``friction``: a ``force_stroke`` recording in which the armature moves there and back.
    """
    from ..measure import flux_linkage

    def absolute(rec):
        if rec.voltage_V is None:
            return False
        fr = flux_linkage(rec)
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


# -- tables with effects -------------------------------------------------------------------------
def tables_from_fmu(fmu_path) -> tuple[_model.MapTables, dict]:
    """The maps an FMU carries (resources/maps.npz + maps.json) and the raw maps.json dict."""
    fmu_path = Path(fmu_path)
    if not fmu_path.is_file():
        raise ImproveError(f"{fmu_path}: FMU file not found")
    try:
        with zipfile.ZipFile(fmu_path) as zf, tempfile.TemporaryDirectory(prefix="solenoid_improve_") as tmp:
            for name in ("maps.npz", "maps.json"):
                Path(tmp, name).write_bytes(zf.read(f"resources/{name}"))
            tab = _model.load_tables(tmp)
            meta = json.loads(Path(tmp, "maps.json").read_text(encoding="utf-8"))
    except (KeyError, zipfile.BadZipFile, OSError) as exc:
        raise ImproveError(f"{fmu_path}: not a solenoid-fmu FMU with maps in resources/ ({exc})") from None
    except _model.ModelMapsError as exc:
        raise ImproveError(f"{fmu_path}: {exc}") from None
    tab.where = str(fmu_path)
    return tab, meta


def with_effects(tables: _model.MapTables, effects: dict, G_eddy_S: float | None = None) -> _model.MapTables:
    """A copy of ``tables`` whose maps.json meta carries ``effects`` (and ``G_eddy_S`` [S] if given)."""
    meta = json.loads(json.dumps(tables.meta))
    meta["effects"] = effects
    if G_eddy_S is not None:
        meta.setdefault("eddy", {})
        meta["eddy"] = dict(meta["eddy"] or {}, G_eddy_S=float(G_eddy_S))
    t = tables.tables()
    psi = np.arange(tables.n_psi) * tables.dpsi_Wb
    return _model.MapTables(psi, t["x_m"], t["i_f_A"], t["force_N"], extrapolated=tables.extrapolated, meta=meta,
                            where=tables.where, i_fem_max_A=tables.i_fem_max_A)


# -- recordings ----------------------------------------------------------------------------------
def _excitation_size(rec) -> tuple[float, float]:
    """(peak |current| [A] to 2 %, 95th percentile of |di/dt| [A/s]): how large an excitation is."""
    i = np.asarray(rec.current_A, dtype=float)
    t = np.asarray(rec.time_s, dtype=float)
    peak = float(np.max(np.abs(i))) if i.size else 0.0
    k = max(1, int(round(1e-3 / max(float(np.median(np.diff(t))), 1e-12)))) if t.size > 1 else 1
    if t.size > 2 * k:
        rate = float(np.percentile(np.abs(i[k:] - i[:-k]) / (t[k:] - t[:-k]), 95))
    else:
        rate = 0.0
    return (round(math.log(peak), 1) if peak > 0 else -math.inf, rate)


def split_recordings(recordings) -> tuple[list, list]:
    """Fit / validation split: per kind, from the largest excitation down, alternately fit and validate.

    "Largest" is judged from the data, not from file names (other rigs name files anyhow): the
    peak current (to about 10 %), then the rate of change of the current. The largest excitation
    of a kind is fitted; a kind with a single recording is only validated on. Ties keep the
    order of the file names.
    """
    by_kind: dict = {}
    for rec in recordings:
        by_kind.setdefault(rec.kind, []).append(rec)
    fit, val = [], []
    for recs in by_kind.values():
        recs = sorted(recs, key=lambda r: str(r.path or ""))
        recs = sorted(recs, key=_excitation_size, reverse=True)
        if len(recs) == 1:
            val.extend(recs)
            continue
        for k, rec in enumerate(recs):
            (fit if k % 2 == 0 else val).append(rec)
    return fit, val


def _name(rec) -> str:
    return rec.path.name if rec.path is not None else rec.kind


def _i_f(tables: _model.MapTables, psi: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.array([tables.i_f_A(float(p), float(xx)) for p, xx in zip(psi, x, strict=True)])


def _flux_data(rec, tables: _model.MapTables):
    """(t, Psi, dPsi/dt, i, x) of a recording from paper eq. 4, or None if its flux is not absolute.

    A recording that starts energized has Psi anchored to the maps' flux at the first sample's
    current and position (the integration constant eq. 4 cannot give); one without any
    zero-current rest (no measured voltage offset) is left out (None).
    """
    from ..measure import flux_linkage

    fr = flux_linkage(rec)
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
    from ..realtime import PlayHysteresis

    hy = effects.get("hysteresis")
    if not hy:
        return np.zeros_like(psi)
    shape = hy.get("shape")
    play = PlayHysteresis(hy["thresholds"], hy["weights"],
                          shape=None if not shape else (shape["b_nodes"], shape["g_nodes"]), b0=float(psi[0]))
    return play.run(psi)


# -- fits ----------------------------------------------------------------------------------------
def fit_hysteresis(tables, effects, recordings) -> tuple[dict, dict]:
    """Play-operator hysteresis from slow current-driven recordings with voltage; (section, note)."""
    from ..realtime import fit_play_to_series

    recs = [r for r in recordings if r.kind == "flux" and r.voltage_V is not None]
    if not recs:
        recs = [r for r in recordings if r.kind in ("ramp", "eddy") and r.voltage_V is not None]
    if not recs:
        raise ImproveError("hysteresis: no current-driven recording with a voltage to fit on")
    bs, hs, used = [], [], []
    for rec in recs:
        data = _flux_data(rec, tables)
        if data is None:
            continue
        t, psi, e, i, x = data
        h = i - _i_f(tables, psi, x) - _eddy_current(tables, effects, e, t)
        step = max(1, psi.size // 3000)  # rate-independent: a decimated series keeps the loops
        bs.append(psi[::step])
        hs.append(h[::step])
        used.append(rec)
    if not bs:
        raise ImproveError("hysteresis: not identifiable from these recordings: add a slow 'flux' recording "
                           "(triangles from zero current, with a zero-current rest for the voltage offset)")
    try:
        fit = fit_play_to_series(bs, hs, n_plays=12, n_shape=7, b0=0.0)
    except HysteresisError as exc:
        raise ImproveError(f"hysteresis: {exc}") from None
    d = fit.play.to_dict()
    section = {"thresholds": d["thresholds"], "weights": d["weights"], "shape": d["shape"]}
    return section, {"fitted_on": [_name(r) for r in used], "rms_A": fit.rms}


def fit_eddy_ladder(tables, effects, recordings) -> tuple[dict, dict]:
    """Eddy-current ladder by NNLS over fixed time constants; (section, note with the new G_eddy)."""
    from scipy.optimize import nnls

    recs = [r for r in recordings if r.kind == "eddy" and r.voltage_V is not None]
    if not recs:
        raise ImproveError("eddy: no 'eddy' recording (fast triangles) to fit the ladder on")
    rows, ys, used = [], [], []
    for rec in recs:
        data = _flux_data(rec, tables)
        if data is None:
            continue
        t, psi, e, i, x = data
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
    return section, {"fitted_on": [_name(r) for r in used], "G_eddy_S": G0}


def fit_heating(tables, effects, cases) -> tuple[dict, dict]:
    """``C_th`` from the eq.-4 flux residual of current-driven recordings (see module docstring)."""
    alpha = float(((tables.meta.get("coil") or {}).get("temperature_coefficient_per_K")) or COPPER_ALPHA_PER_K)
    num = den = 0.0
    used = []
    for c in cases:
        r = c.residuals.get("psi_Wb")
        if r is None:
            continue
        t, i, R = c.time_s, c.current_A, c.resistance_ohm
        dt = np.diff(t)
        energy = np.concatenate([[0.0], np.cumsum(dt * i[1:] ** 2)])  # int i^2 dt
        phi = alpha * R * R * np.concatenate([[0.0], np.cumsum(dt * i[1:] * energy[1:])])
        if "psi_Wb" in c.detrended:
            phi = detrend(phi, t)
        num += float(phi @ r)
        den += float(phi @ phi)
        used.append(c.name)
    if den <= 0.0 or num <= 0.0:
        raise ImproveError("heating: the flux residual does not drift with the dissipated energy")
    C_th = den / num
    return ({"C_th_J_per_K": C_th, "R_th_K_per_W": 1.0, "alpha_per_K": alpha},
            {"fitted_on": used})


def heating_corrected(rec, heating: dict, R_ohm: float | None = None):
    """The recording with the coil heating's resistive voltage removed (for a heating-free eq.-4 flux).

    With the heating sub-model's parameters (``C_th_J_per_K``, ``R_th_K_per_W``, ``alpha_per_K``) the
    temperature rise along the recording is integrated from the measured current,
    ``C_th dT/dt = R (1 + alpha T) i^2 - T / R_th``, and ``R alpha T i`` is subtracted from the voltage,
    so that paper eq. 4 with the resistance measured before the run gives the flux of a coil at constant
    temperature. ``R_ohm`` [ohm] defaults to the header's resistance. Returns a new Recording (same
    kind, header noted); recordings without a voltage are returned unchanged.
    """
    from dataclasses import replace

    if rec.voltage_V is None:
        return rec
    R = float(R_ohm if R_ohm is not None else rec.coil_resistance_ohm)
    C, Rth, alpha = heating["C_th_J_per_K"], heating["R_th_K_per_W"], heating["alpha_per_K"]
    t = np.asarray(rec.time_s, dtype=float)
    i = np.asarray(rec.current_A, dtype=float)
    T = np.zeros_like(t)
    for k in range(1, t.size):
        Tk = T[k - 1]
        T[k] = Tk + (t[k] - t[k - 1]) * (R * (1.0 + alpha * Tk) * i[k] ** 2 - Tk / Rth) / C
    header = dict(rec.header)
    note = f"voltage corrected for coil heating (C_th {C:.4g} J/K)"
    header["notes"] = f"{header['notes']}; {note}" if header.get("notes") else note
    return replace(rec, voltage_V=np.asarray(rec.voltage_V, dtype=float) - R * alpha * T * i, header=header)


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
    """Friction force and presliding length from the force residual where the armature moves."""
    moving = [c for c in cases if "force_N" in c.residuals and np.ptp(c.position_m) > 0]
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


# -- the loop ------------------------------------------------------------------------------------
def _cases(tables, recordings, progress=None):
    from ..fmu import simulate_model
    from .diagnose import cases_from_recordings

    return cases_from_recordings(None, recordings, progress=progress and (lambda n: progress(f"simulating {n}")),
                                 simulate=lambda r, R: simulate_model(tables, r, R_ohm=R))


def _error(cases, names) -> float:
    """Mean over recordings in ``names`` and their signals of the squared full-scale NRMSE.

    Each residual's RMS is divided by the signal's full scale for the recording's kind and capped
    at 1 (:func:`solenoid_fmu.validate.full_scales`, computed over all ``cases``), so that no
    single recording whose signal hardly changes can dominate the gate.
    """
    from .validate import full_scales, nrmse_fs

    fs = full_scales(cases)
    vals = []
    for c in cases:
        if c.name not in names:
            continue
        for sig, r in c.residuals.items():
            r = np.asarray(r, dtype=float)
            rms = float(np.sqrt(np.mean(r[np.isfinite(r)] ** 2))) if np.isfinite(r).any() else None
            v = nrmse_fs(rms, fs[(c.kind, sig)])
            vals.append(1.0 if v is None else v * v)
    return float(np.mean(vals)) if vals else 0.0


def _fit_effect(pick: str, tables, effects: dict, recs: list, cases: list) -> tuple[dict, dict, float | None]:
    """Fit ``pick`` on ``recs`` (their residual ``cases``): (section, note, new G_eddy or None)."""
    if pick == "hysteresis":
        section, note = fit_hysteresis(tables, effects, recs)
        return section, note, None
    if pick == "eddy":
        section, note = fit_eddy_ladder(tables, effects, recs)
        return section, note, note["G_eddy_S"]
    if pick == "heating":
        section, note = fit_heating(tables, effects, cases)
        return section, note, None
    section, note = fit_friction(tables, effects, cases)
    return section, note, None


def improve_tables(tables, recordings, *, max_effects: int = DEFAULT_MAX_EFFECTS, min_gain: float = DEFAULT_MIN_GAIN,
                   threshold: float | None = None, progress=None) -> Improvement:
    """Run the loop on in-process simulations (see the module docstring).

    Parameters
    ----------
    tables : MapTables
        The model's maps (an ``effects`` section already present is kept and built on).
    recordings : list of Recording
    max_effects : int
        Upper limit of effects added.
    min_gain : float
        Relative fall of the validation error an effect must bring to be kept.
    threshold : float, optional
        Diagnosis threshold (default :data:`solenoid_fmu.diagnose.DEFAULT_THRESHOLD`).
    """
    from .diagnose import DEFAULT_MIN_NRMS, DEFAULT_THRESHOLD, diagnose

    if not recordings:
        raise ImproveError("improve needs at least one recording")
    threshold = DEFAULT_THRESHOLD if threshold is None else threshold
    try_threshold = min(threshold, TRY_THRESHOLD)
    say = progress or (lambda msg: None)
    fit_recs, val_recs = split_recordings(recordings)
    val_names = {_name(r) for r in val_recs}
    fit_names = {_name(r) for r in fit_recs}
    effects = dict(tables.meta.get("effects") or {})
    steps: list[Step] = []
    diagnoses = []
    tried: set = set()
    missing = not_identifiable(recordings)
    for effect, what in missing.items():
        say(f"{effect}: not identifiable from these recordings: {what}")
    cases = cases0 = _cases(tables, recordings, say)
    while sum(s.accepted for s in steps) < max_effects:
        d = diagnose(cases, threshold=threshold)
        diagnoses.append(d.as_dict())
        significant = any(v >= DEFAULT_MIN_NRMS for v in d.residual_nrms.values())
        pick = next((c.effect for c in d.ranking if c.score >= try_threshold and c.effect in ADDABLE
                     and c.effect not in tried and significant), None)
        if pick is None and significant:  # one recording's large residual may drown the others' evidence
            d = diagnose(cases, threshold=threshold, balanced=True)
            diagnoses.append(dict(d.as_dict(), balanced=True))
            pick = next((c.effect for c in d.ranking if c.score >= try_threshold and c.effect in ADDABLE
                         and c.effect not in tried), None)
        if pick is None:
            say("no further effect clears the diagnosis threshold")
            break
        tried.add(pick)
        if pick in missing:
            steps.append(Step(pick, False, note=f"not identifiable from these recordings: {missing[pick]}"))
            say(f"{pick} is named by the diagnosis but not identifiable from these recordings: {missing[pick]}")
            continue
        say(f"adding {pick} (diagnosis score {next(c.score for c in d.ranking if c.effect == pick):.3f})")
        try:
            section, note, G_new = _fit_effect(pick, tables, effects, fit_recs,
                                               [c for c in cases if c.name in fit_names])
        except ImproveError as exc:
            steps.append(Step(pick, False, note=str(exc)))
            say(f"  not added: {exc}")
            continue
        trial_fx = dict(effects, **{ADDABLE[pick]: section})
        trial = with_effects(tables, trial_fx, G_eddy_S=G_new)
        trial_cases = _cases(trial, recordings, say)
        before, after = _error(cases, val_names), _error(trial_cases, val_names)
        ok = after < (1.0 - min_gain) * before
        if not ok and pick in FEW_PARAMETERS:
            # a one- or two-parameter effect whose evidence sits in a few recordings: one fold may be
            # too weak to estimate it. Fitted on all recordings, it must cut the error over all of them
            # by min_gain, and the fit-part estimate must not make the validation recordings worse.
            try:
                section_all, note_all, G_all = _fit_effect(pick, tables, effects, recordings, cases)
            except ImproveError:
                section_all = None
            if section_all is not None:
                all_names = val_names | fit_names
                trial_all_fx = dict(effects, **{ADDABLE[pick]: section_all})
                trial_all = with_effects(tables, trial_all_fx, G_eddy_S=G_all)
                cases_all = _cases(trial_all, recordings, say)
                b_all, a_all = _error(cases, all_names), _error(cases_all, all_names)
                val_ok = after <= (1.0 + 0.1 * min_gain) * before  # not worse beyond a tenth of the gain asked for
                if a_all < (1.0 - min_gain) * b_all and val_ok:
                    note = dict(note_all, judged=f"in-sample on all recordings (few parameters; held out "
                                                 f"{after:.3g} vs {before:.3g}: the validation part holds too "
                                                 "little of its evidence)")
                    ok, before, after = True, b_all, a_all
                    section, trial_fx, trial, trial_cases = section_all, trial_all_fx, trial_all, cases_all
        steps.append(Step(pick, ok, params=section, heldout_before=before, heldout_after=after,
                          note=json.dumps(note)))
        say(f"  validation error {before:.3g} -> {after:.3g}: {'kept' if ok else 'rejected'}")
        if ok:
            effects, tables, cases = trial_fx, trial, trial_cases
            # an effect rejected before may have been masked by the one just added: it may be tried again
            tried = {s.effect for s in steps if s.accepted}
    return Improvement(tables, steps, diagnoses, cases0, cases, missing)


def write_maps_dir(tables: _model.MapTables, fmu_path, dest_dir) -> Path:
    """Write the improved maps directory (the FMU's maps.npz, maps.json with the effects)."""
    from ..fileio import atomic_write_bytes, atomic_write_text

    dest_dir = Path(dest_dir)
    dest_dir.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(fmu_path) as zf:
        atomic_write_bytes(dest_dir / "maps.npz", zf.read("resources/maps.npz"))
    atomic_write_text(dest_dir / "maps.json", json.dumps(tables.meta, indent=1, sort_keys=True) + "\n")
    return dest_dir


def improve(fmu_path, recordings, out_fmu, *, report_dir=None, max_effects: int = DEFAULT_MAX_EFFECTS,
            min_gain: float = DEFAULT_MIN_GAIN, threshold: float | None = None, progress=None,
            before_report_dir=None) -> dict:
    """Add the effects the residual asks for; build the improved FMU; report before and after.

    Parameters
    ----------
    fmu_path : path-like
        The FMU to improve (solenoid-fmu export; its maps travel inside it).
    recordings : list of path-like or Recording
    out_fmu : path-like
        The improved FMU to write (its maps directory is written beside it, ``<stem>.maps/``).
    report_dir : path-like, optional
        Validation figures of the improved FMU and ``improve.json``.
    before_report_dir : path-like, optional
        Validation figures of the FMU before improvement.

    Returns
    -------
    dict
        ``{"effects_added": [...], "steps": [...], "fmu": ..., "improved_fmu": ..., "maps": ...,
        "recordings": [{"file", "split", "signals": {signal: {"before", "after", "before_nrmse",
        "after_nrmse", "before_nrmse_fs", "after_nrmse_fs"}}}], "before": validation dict, "after":
        validation dict}``; before/after are RMS errors in the signal's unit from the FMUs (fmpy),
        ``*_nrmse`` by the recording's range, ``*_nrmse_fs`` by the full scale per kind.
    """
    from ..fmu import build_fmu
    from ..measure import Recording, read_recording
    from .validate import validate

    say = progress or (lambda msg: None)
    recs = [r if isinstance(r, Recording) else read_recording(r) for r in recordings]
    if not recs:
        raise ImproveError("improve needs at least one recording")
    tables, _ = tables_from_fmu(fmu_path)
    improved, steps, diagnoses, _, _, missing = improve_tables(tables, recs, max_effects=max_effects, min_gain=min_gain,
                                                      threshold=threshold, progress=say)
    out_fmu = Path(out_fmu)
    maps_dir = write_maps_dir(improved, fmu_path, out_fmu.with_suffix(".maps"))
    say(f"building {out_fmu}")
    build_fmu(maps_dir, out_fmu)
    say("validating the FMU before and after")
    before = validate(fmu_path, recs, report_dir=before_report_dir)
    after = validate(out_fmu, recs, report_dir=report_dir)
    fit_recs, _ = split_recordings(recs)
    fit_names = {_name(r) for r in fit_recs}
    rows = []
    after_by = {r["file"]: r for r in after["recordings"]}
    for rb in before["recordings"]:
        ra = after_by.get(rb["file"], {"signals": {}})
        sig = {}
        for name, m in rb["signals"].items():
            a = ra["signals"].get(name, {})
            sig[name] = {"before": m.get("rms"), "after": a.get("rms"), "before_nrmse": m.get("nrmse"),
                         "after_nrmse": a.get("nrmse"), "before_nrmse_fs": m.get("nrmse_fs"),
                         "after_nrmse_fs": a.get("nrmse_fs")}
        rows.append({"file": rb["file"], "split": "fit" if rb["file"] in fit_names else "validate", "signals": sig})
    result = {"fmu": str(fmu_path), "improved_fmu": str(out_fmu), "maps": str(maps_dir),
              "effects_added": [s.effect for s in steps if s.accepted], "steps": [s.as_dict() for s in steps],
              "not_identifiable": missing,
              "diagnoses": diagnoses, "recordings": rows, "before": before, "after": after}
    if report_dir is not None:
        from ..fileio import atomic_write_text

        Path(report_dir).mkdir(parents=True, exist_ok=True)
        atomic_write_text(Path(report_dir) / "improve.json", json.dumps(jsonable(result), indent=1) + "\n")
    return result


def jsonable(obj):
    if isinstance(obj, dict):
        return {k: jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, np.generic):
        return jsonable(obj.item())
    return obj


# -- command line --------------------------------------------------------------------------------
def add_cli(sub) -> None:
    """Register ``solenoid-fmu improve``."""
    p = sub.add_parser("improve", help="add the diagnosed effects to the model, fit, validate, export")
    p.add_argument("fmu", help="the FMU to improve (solenoid-fmu export)")
    p.add_argument("recordings", nargs="+", help="recording CSV files (format v1)")
    p.add_argument("-o", "--output", required=True, help="the improved FMU to write")
    p.add_argument("--report", help="directory for figures and improve.json")
    p.add_argument("--max-effects", type=int, default=DEFAULT_MAX_EFFECTS)
    p.add_argument("--min-gain", type=float, default=DEFAULT_MIN_GAIN,
                   help="relative fall of the validation error an effect must bring (default 0.1)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cli)


def _cli(args) -> int:
    import sys

    def progress(msg):
        print(msg, file=sys.stderr, flush=True)

    from ..fileio import refuse_overwriting_inputs

    refuse_overwriting_inputs(args.output, [args.fmu, *args.recordings])
    if args.report is not None:
        from ..fileio import require_directory

        refuse_overwriting_inputs(require_directory(args.report, "--report"), [args.fmu, *args.recordings], written=[])
    res = improve(args.fmu, args.recordings, args.output, report_dir=args.report, max_effects=args.max_effects,
                  min_gain=args.min_gain, progress=progress)
    if args.json:
        out = {k: res[k] for k in ("effects_added", "steps", "recordings", "fmu", "improved_fmu", "not_identifiable")}
        print(json.dumps(jsonable(out)))
        return 0
    print(f"effects added: {', '.join(res['effects_added']) or 'none'}")
    for effect, what in res["not_identifiable"].items():
        print(f"{effect}: not identifiable from these recordings: {what}")
    print(f"{'file':<28} {'split':<9} {'signal':<10} {'rms before':>12} {'rms after':>12} {'ratio':>7}")
    for row in res["recordings"]:
        for sig, m in row["signals"].items():
            b, a = m["before"], m["after"]
            ratio = a / b if b and a is not None else math.nan
            print(f"{row['file']:<28} {row['split']:<9} {sig:<10} {b:12.4g} {a:12.4g} {ratio:7.3f}")
    print(f"wrote {res['improved_fmu']}")
    return 0


__all__ = ["ADDABLE", "ImproveError", "Improvement", "Step", "fit_eddy_ladder", "fit_friction", "fit_heating",
           "fit_hysteresis", "heating_corrected", "improve", "improve_tables", "not_identifiable", "split_recordings",
           "tables_from_fmu", "with_effects", "write_maps_dir"]
