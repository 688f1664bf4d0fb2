"""Close the loop: add the effect the diagnosis names to the real-time model, fit it, keep it if it pays.

The loop, on a campaign of recordings and the characteristic maps of a model (or the FMU that carries them):

1. simulate every recording with the current model and diagnose the residual
   (:mod:`solenoid_fmu.loop.diagnosis`);
2. take the best-ranked candidate that the model can add and has not tried, scoring at least
   :data:`TRY_THRESHOLD` (0.1; the verdict threshold of ``diagnose`` is 0.25, but here the held-out
   gate of step 3 decides) pooled over the signals or on one of them (:func:`_try_score`), while
   the residual is significant (``hysteresis``,
   ``eddy`` as an eddy-current ladder, ``heating``, ``friction``; ``material`` and ``sensor`` are
   not model effects: a wrong B(H) is fixed by ``identify``, a sensor by calibration);
3. fit its parameters on the *fit* part of the recordings
   (:func:`solenoid_fmu.loop.split.split_recordings`) by the effect's own regression
   (:mod:`solenoid_fmu.loop.effects`), simulate all recordings with it and keep it only if the
   error on the *validation* part falls by at least ``min_gain`` (default 10 %). A one- or
   two-parameter effect (heating, friction) whose evidence sits in a few recordings, all of them
   in the fit part, cannot pass that; it is fitted on all recordings and kept if it cuts the error
   over all of them by ``min_gain`` while the fit-part estimate does not make the validation part
   worse (by more than a tenth of ``min_gain``; the diagnosis has already cross-validated its
   signature);
4. repeat while an effect still pays, up to ``max_effects``. An effect rejected in step 3 is
   tried again after another effect was kept (the other one may have masked it: a large eddy
   residual spoils the heating fit until the ladder is in the model).

Before step 1, coil heating is looked for where the flux residual cannot show it: a heating rate the
campaign's resistance tracks measure significantly (:mod:`solenoid_fmu.loop.heating_evidence`) is
added with ``C_th = alpha / kappa`` and kept unless the validation error grows by ``min_gain`` or more
(the margin an effect must gain to be kept); it is measured, not fitted to the residual, so it need not
pay there (random-0's campaign: +1.2 % of the squared error with C_th 332 J/K against the truth's 300). Then C_th is
fitted on the flux residual of all recordings, and that value replaces the tracks' where it cuts the
error over all recordings by more than a tenth of ``min_gain`` (a drift large enough to measure it);
once more at the end when hysteresis or an eddy ladder was added meanwhile (their part of the residual
is then modelled).

When coil heating is kept, the effects kept before it that were fitted along the eq.-4 flux
(hysteresis, eddy ladder: :data:`FLUX_FITTED`) were fitted to a flux that carried the heating's drift
(the resistance measured before the run, while the coil warmed); they are fitted again along the
heating-corrected flux (:func:`solenoid_fmu.loop.effects.heating_corrected`), then the heating itself
on the residual the corrected effects leave, and each refit replaces the earlier fit if it lowers the
validation error (steps marked ``refit``; :func:`_refit_after_heating`).

Campaigns from any rig: the fit/validation split and the diagnosis's cross-validation folds go
by the size of the excitations, not by file names (one ordering, :mod:`solenoid_fmu.loop.split`);
the flux of a recording that starts energized is compared as a change from the model's flux at
its first sample; the gate's error is the full-scale NRMSE per kind (:func:`_error`), so that no
single recording can swing it.

The maps gain their effect sections in :mod:`solenoid_fmu.loop.tables` (in memory). A kept eddy ladder
brings its own refit of the maps' single eddy conductance, which replaces the maps' value: the
step's note (``G_eddy_S``: the maps' value and the refit) and the improved maps' ``eddy.source``
say so (see :mod:`solenoid_fmu.loop.effects`). Each recording's eq.-4 flux is computed once per
run (:class:`solenoid_fmu.loop.residuals.FluxCache`).

The reported before/after errors, per recording and signal, come from the model run in this process on the
maps the FMUs carry (the FMU runs the same model; :func:`solenoid_fmu.loop.validate_model`): the improved FMU
is an output only, nothing the run writes is read back.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import MapsError
from ..fileio import atomic_write_text, check_output_name, jsonable
from ..fmu import build_fmu, simulate_model
from ..maps import CharacteristicMaps, maps_tables, save_maps
from ..measure import Recording, flux_linkage, read_recording
from ..realtime import MapTables
from .diagnosis import DEFAULT_MIN_NRMS, DEFAULT_THRESHOLD, diagnose
from .effects import fit_eddy_ladder, fit_friction, fit_heating, fit_hysteresis, g_eddy_source
from .heating_evidence import heating_from_resistance
from .identifiability import not_identifiable
from .metrics import full_scales, nrmse_fs
from .residuals import FluxCache, cases_from_recordings, recording_name
from .split import split_recordings
from .tables import ADDABLE, ImproveError, maps_from_fmu, with_effects, with_maps_meta
from .validation import validate_model

DEFAULT_MAX_EFFECTS = 4
DEFAULT_MIN_GAIN = 0.10
#: Diagnosis score from which an addable effect is *tried* (fitted and judged on the validation
#: recordings) even when it does not clear the verdict threshold: the held-out gate decides.
TRY_THRESHOLD = 0.1
#: Effects with one or two fitted parameters (see the gate in :func:`improve_tables`).
FEW_PARAMETERS = ("heating", "friction")
#: Effects fitted along the measured eq.-4 flux, refitted when heating is kept (module docstring).
FLUX_FITTED = ("hysteresis", "eddy")


@dataclass
class Step:
    """One tried effect: its parameters and the validation error before and after (normalized)."""

    effect: str
    accepted: bool
    params: dict = field(default_factory=dict)
    heldout_before: float = math.nan
    heldout_after: float = math.nan
    note: str = ""
    #: True for a refit of an effect already kept (its parameters replace the earlier ones).
    refit: bool = False

    def as_dict(self) -> dict:
        return {"effect": self.effect, "accepted": self.accepted, "params": self.params,
                "heldout_error_before": self.heldout_before, "heldout_error_after": self.heldout_after,
                "note": self.note, "refit": self.refit}


class Improvement(NamedTuple):
    """Outcome of :func:`improve_tables`: the model's maps with the kept effects, every tried
    :class:`Step`, the diagnosis of each round (dicts), the residual cases of the first and
    the final model (in-process simulations of all recordings), and for every addable effect the
    campaign cannot identify, what to add (:func:`solenoid_fmu.loop.identifiability.not_identifiable`)."""

    tables: MapTables
    steps: list
    diagnoses: list
    cases_before: list
    cases_after: list
    not_identifiable: dict = {}


# -- the loop ------------------------------------------------------------------------------------
def _cases(tables, recordings, progress=None, flux_of=flux_linkage):
    return cases_from_recordings(None, recordings, progress=progress and (lambda n: progress(f"simulating {n}")),
                                 simulate=lambda r, R: simulate_model(tables, r, R_ohm=R), flux_of=flux_of)


def _error(cases, names) -> float:
    """Mean over recordings in ``names`` and their signals of the squared full-scale NRMSE.

    Each residual's RMS is divided by the signal's full scale for the recording's kind and capped
    at 1 (:func:`solenoid_fmu.loop.metrics.full_scales`, computed over all ``cases``), so that no
    single recording whose signal hardly changes can dominate the gate.
    """
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


def _fit_effect(pick: str, tables, effects: dict, recs: list, cases: list, flux_of) -> tuple[dict, dict, dict]:
    """Fit ``pick`` on ``recs`` (their residual ``cases``): (section, note, replaced), ``replaced``
    the keywords of :func:`with_effects` for the maps' values the effect replaces (the eddy
    ladder's refit of G_eddy with its source; ``{}`` for the others)."""
    if pick == "hysteresis":
        section, note = fit_hysteresis(tables, effects, recs, flux_of)
        return section, note, {}
    if pick == "eddy":
        section, note = fit_eddy_ladder(tables, effects, recs, flux_of)
        return section, note, {"G_eddy_S": note["G_eddy_S"]["refit"], "G_eddy_source": g_eddy_source(tables, note)}
    if pick == "heating":
        section, note = fit_heating(tables, effects, cases)
        return section, note, {}
    section, note = fit_friction(tables, effects, cases)
    return section, note, {}


def improve_tables(tables, recordings, *, max_effects: int = DEFAULT_MAX_EFFECTS, min_gain: float = DEFAULT_MIN_GAIN,
                   threshold: float | None = None, progress=None, flux_of=None) -> Improvement:
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
        Diagnosis threshold (default :data:`solenoid_fmu.loop.diagnosis.DEFAULT_THRESHOLD`).
    flux_of : FluxCache, optional
        The eq.-4 flux of the recordings (default: a new :class:`~solenoid_fmu.loop.residuals.FluxCache`,
        so that each recording's flux is computed once in the run).
    """
    if not recordings:
        raise ImproveError("improve needs at least one recording")
    threshold = DEFAULT_THRESHOLD if threshold is None else threshold
    say = progress or (lambda msg: None)
    fit_recs, val_recs = split_recordings(recordings)
    flux_of = FluxCache() if flux_of is None else flux_of  # one eq.-4 flux per recording for the whole run
    run = _Run(recordings, fit_recs, {recording_name(r) for r in fit_recs}, {recording_name(r) for r in val_recs},
               flux_of, say)
    effects = tables.effects.as_dict()
    steps: list[Step] = []
    diagnoses: list = []
    tried: set = set()
    missing = not_identifiable(recordings, flux_of)
    for effect, what in missing.items():
        say(f"{effect}: not identifiable from these recordings: {what}")
    cases = cases0 = _cases(tables, recordings, say, flux_of)
    heat = None if "heating" in effects else heating_from_resistance(recordings, tables)
    if heat is not None:
        effects, tables, cases = _add_measured_heating(run, heat, effects, tables, cases, steps, min_gain)
        tried.add("heating")
    while len(_kept(steps)) < max_effects:
        pick, d = _pick(cases, threshold, tried, diagnoses)
        if pick is None:
            say("no further effect clears the diagnosis threshold")
            break
        tried.add(pick)
        if pick in missing:
            steps.append(Step(pick, False, note=f"not identifiable from these recordings: {missing[pick]}"))
            say(f"{pick} is named by the diagnosis but not identifiable from these recordings: {missing[pick]}")
            continue
        cand = next(c for c in d.ranking if c.effect == pick)
        best_signal = max(cand.per_signal, key=cand.per_signal.get, default=None)
        say(f"adding {pick} (diagnosis score {cand.score:.3f}"
            + (f"; {best_signal} {cand.per_signal[best_signal]:.3f})" if best_signal else ")"))
        kept = _try_effect(run, pick, effects, tables, cases, steps, min_gain)
        if kept is not None:
            (effects, tables, cases), note = kept
            if pick == "heating":
                effects, tables, cases = _refit_after_heating(run, effects, tables, cases, steps,
                                                              heat_on_all="judged" in note)
            # an effect rejected before may have been masked by the one just added: it may be tried again
            tried = set(_kept(steps))
    if heat is not None and steps[0].accepted and any(s.accepted and not s.refit and s.effect in FLUX_FITTED
                                                      for s in steps[1:]):
        # the heating from the tracks was refitted on the flux residual before the effects fitted along the
        # flux were in: once more now that their part of the residual is modelled
        effects, tables, cases = _refit_after_heating(run, effects, tables, cases, steps, heat_on_all=True,
                                                      heating_first=True, min_fall=0.1 * min_gain)
    return Improvement(tables, steps, diagnoses, cases0, cases, missing)


def _add_measured_heating(run, heat: tuple, effects: dict, tables, cases: list, steps: list, min_gain: float):
    """Add the heating the resistance tracks measure (module docstring); the (effects, tables, cases) after."""
    section, note = heat
    run.say(f"heating from the resistance tracks: kappa {note['sigmas']:.1f} sigma above zero, "
            f"C_th = {section['C_th_J_per_K']:.4g} J/K")
    trial_fx = dict(effects, heating=section)
    trial = with_effects(tables, trial_fx)
    trial_cases = _cases(trial, run.recordings, run.say, run.flux_of)
    before, after = _error(cases, run.val_names), _error(trial_cases, run.val_names)
    ok = after <= (1.0 + min_gain) * before  # measured: kept unless rejected by the margin
    steps.append(Step("heating", ok, params=section, heldout_before=before, heldout_after=after,
                      note=json.dumps(dict(note, judged="resistance evidence; kept unless the validation error "
                                                        "grows by min_gain or more"))))
    run.say(f"  validation error {before:.3g} -> {after:.3g}: {'kept' if ok else 'rejected'}")
    if not ok:
        return effects, tables, cases
    return _refit_after_heating(run, trial_fx, trial, trial_cases, steps, heat_on_all=True, heating_first=True,
                                min_fall=0.1 * min_gain)


def _pick(cases: list, threshold: float, tried: set, diagnoses: list):
    """The next effect to try (None: none) and the diagnosis that names it; appends the diagnoses made.

    While the residual is significant, the best-ranked addable effect not yet tried whose :func:`_try_score`
    reaches :data:`TRY_THRESHOLD` (or the diagnosis threshold if lower); if there is none, the same on the
    balanced diagnosis (one recording's large residual may drown the others' evidence)."""
    try_threshold = min(threshold, TRY_THRESHOLD)
    d = diagnose(cases, threshold=threshold)
    diagnoses.append(d.as_dict())
    if not any(v >= DEFAULT_MIN_NRMS for v in d.residual_nrms.values()):
        return None, d
    pick = next((c.effect for c in d.ranking if _try_score(c) >= try_threshold and c.effect in ADDABLE
                 and c.effect not in tried), None)
    if pick is None:
        d = diagnose(cases, threshold=threshold, balanced=True)
        diagnoses.append(dict(d.as_dict(), balanced=True))
        pick = next((c.effect for c in d.ranking if _try_score(c) >= try_threshold and c.effect in ADDABLE
                     and c.effect not in tried), None)
    return pick, d


def _try_effect(run, pick: str, effects: dict, tables, cases: list, steps: list, min_gain: float):
    """Fit ``pick`` and judge it (module docstring, step 3); appends its :class:`Step`. When it is kept, the
    (effects, tables, cases) with it and the fit's note; else None."""
    try:
        section, note, replaced = _fit_effect(pick, tables, effects, run.fit_recs,
                                              [c for c in cases if c.name in run.fit_names], run.flux_of)
    except ImproveError as exc:
        steps.append(Step(pick, False, note=str(exc)))
        run.say(f"  not added: {exc}")
        return None
    trial_fx = dict(effects, **{ADDABLE[pick]: section})
    trial = with_effects(tables, trial_fx, **replaced)
    trial_cases = _cases(trial, run.recordings, run.say, run.flux_of)
    before, after = _error(cases, run.val_names), _error(trial_cases, run.val_names)
    ok = after < (1.0 - min_gain) * before
    if not ok and pick in FEW_PARAMETERS:
        on_all = _judged_on_all(run, pick, effects, tables, cases, (before, after), min_gain)
        if on_all is not None:
            ok = True
            section, note, (trial_fx, trial, trial_cases), (before, after) = on_all
    steps.append(Step(pick, ok, params=section, heldout_before=before, heldout_after=after, note=json.dumps(note)))
    run.say(f"  validation error {before:.3g} -> {after:.3g}: {'kept' if ok else 'rejected'}")
    return ((trial_fx, trial, trial_cases), note) if ok else None


def _judged_on_all(run, pick: str, effects: dict, tables, cases: list, held_out: tuple, min_gain: float):
    """The gate of a one- or two-parameter effect whose evidence sits in a few recordings (one fold may be too
    weak to estimate it): fitted on all recordings, it must cut the error over all of them by ``min_gain``,
    and the fit-part estimate (``held_out``: its validation errors before, after) must not make the
    validation recordings worse beyond a tenth of that. (section, note, trial, errors) if it passes, else None.
    """
    try:
        section, note, replaced = _fit_effect(pick, tables, effects, run.recordings, cases, run.flux_of)
    except ImproveError:
        return None
    before, after = held_out
    all_names = run.val_names | run.fit_names
    trial_fx = dict(effects, **{ADDABLE[pick]: section})
    trial = with_effects(tables, trial_fx, **replaced)
    trial_cases = _cases(trial, run.recordings, run.say, run.flux_of)
    b_all, a_all = _error(cases, all_names), _error(trial_cases, all_names)
    if not (a_all < (1.0 - min_gain) * b_all and after <= (1.0 + 0.1 * min_gain) * before):
        return None
    note = dict(note, judged=f"in-sample on all recordings (few parameters; held out {after:.3g} vs {before:.3g}: "
                             "the validation part holds too little of its evidence)")
    return section, note, (trial_fx, trial, trial_cases), (b_all, a_all)


def _try_score(c) -> float:
    """Diagnosis score from which a candidate is tried: its pooled score or its best signal's.

    The pooled score is the share of *all* signals' residual energy an effect explains; an effect that
    acts on one signal (eddy currents on the flux) is diluted by another signal's residual from another
    cause (the force's), by as much as the signals' normalizations happen to weigh. The share of the one
    signal it explains is evidence on its own; the held-out gate decides either way."""
    return max([c.score, *c.per_signal.values()])


def _kept(steps: list) -> list:
    """The effects kept, in the order they were added (a refit adds none)."""
    return list(dict.fromkeys(s.effect for s in steps if s.accepted))


class _Run(NamedTuple):
    """What the refits need of the loop's run: the recordings, their split, the flux cache, the progress."""

    recordings: list
    fit_recs: list
    fit_names: set
    val_names: set
    flux_of: object
    say: object


def _refit_after_heating(run: _Run, effects: dict, tables, cases: list, steps: list, heat_on_all: bool,
                         heating_first: bool = False, min_fall: float = 0.0):
    """Heating was just kept: fit again what was fitted against the heating's drift (module docstring).

    First the flux-fitted effects kept before it (:data:`FLUX_FITTED`), along the heating-corrected flux;
    if one of them changed, the heating itself, on the residual the model without heating leaves now (its
    first fit saw the misfit of an effect fitted to the drifting flux), and if that refit is kept, the
    flux-fitted ones once more along the newly corrected flux. Each refit replaces the earlier fit if the
    validation error falls (the heating's, when it was judged on all recordings: the error over all of
    them). Appends a ``refit`` :class:`Step` per try; returns the (effects, tables, cases) after them.

    ``heating_first``: the heating was just added from the resistance tracks (nothing fitted along the
    flux yet): only the heating is refitted on the flux residual, and it replaces the tracks' value if the
    error falls by more than the fraction ``min_fall`` (where the drift within the recordings is large
    enough to measure C_th better than the tracks do).
    """
    def refit(effect: str) -> bool:
        nonlocal effects, tables, cases
        on_all = effect == "heating" and heat_on_all
        recs = run.recordings if on_all else run.fit_recs
        judged = run.val_names | run.fit_names if on_all else run.val_names
        run.say(f"refitting {effect}" + ("" if effect == "heating" else " along the heating-corrected flux"))
        try:
            if effect == "heating":  # fitted on the residual of the model without it
                base_fx = {k: v for k, v in effects.items() if k != ADDABLE["heating"]}
                base = with_effects(tables, base_fx)
                base_cases = _cases(base, recs, None, run.flux_of)
                section, note, replaced = _fit_effect(effect, base, base_fx, recs, base_cases, run.flux_of)
            else:
                names = {recording_name(r) for r in recs}
                section, note, replaced = _fit_effect(effect, tables, effects, recs,
                                                      [c for c in cases if c.name in names], run.flux_of)
        except ImproveError as exc:
            steps.append(Step(effect, False, note=f"refit: {exc}", refit=True))
            run.say(f"  refit failed, the earlier fit stays: {exc}")
            return False
        trial_fx = dict(effects, **{ADDABLE[effect]: section})
        trial = with_effects(tables, trial_fx, **replaced)
        trial_cases = _cases(trial, run.recordings, run.say, run.flux_of)
        before, after = _error(cases, judged), _error(trial_cases, judged)
        ok = after < (1.0 - min_fall) * before
        why = "on the residual of the model without heating" if effect == "heating" else \
            "along the heating-corrected flux"
        steps.append(Step(effect, ok, params=section, heldout_before=before, heldout_after=after,
                          note=json.dumps(dict(note, refit=why)), refit=True))
        run.say(f"  {'validation' if not on_all else 'all-recordings'} error {before:.3g} -> {after:.3g}: "
                f"{'refit kept' if ok else 'earlier fit kept'}")
        if ok:
            effects, tables, cases = trial_fx, trial, trial_cases
        return ok

    if heating_first:
        refit("heating")
        return effects, tables, cases
    flux_fitted = [e for e in FLUX_FITTED if ADDABLE[e] in effects]
    if [refit(e) for e in flux_fitted].count(True) and refit("heating"):
        for e in flux_fitted:
            refit(e)
    return effects, tables, cases


@dataclass(frozen=True)
class ImproveResult:
    """Outcome of :func:`improve`: the improved model in memory, what was tried, the errors before and after.

    Attributes
    ----------
    maps : CharacteristicMaps
        The improved maps (maps.json ``effects``; a kept eddy ladder's refit ``eddy``).
    tables : MapTables
        The same maps as the real-time model's tables.
    steps : list of Step
        Every effect tried, in order.
    diagnoses : list of dict
        The diagnosis of each round.
    not_identifiable : dict
        Effect -> what to add to the campaign to identify it.
    recordings : list of dict
        Per recording: ``file``, ``split`` and per signal the errors ``before``/``after`` (RMS, the signal's
        unit), ``*_nrmse`` (by the recording's range), ``*_nrmse_fs`` (by the full scale per kind).
    before, after : dict
        The validations of the model before and after (:func:`solenoid_fmu.loop.validate_model`).
    source : str
        The model improved (the FMU's path, or the maps' name).
    improved_fmu, maps_dir : pathlib.Path or None
        The improved FMU and its maps directory (``<stem>.maps/``), when one was written.
    images : dict
        The validation figures written (``report_dir``, ``before_report_dir``) as ``{str(path): PNG bytes}``.
    """

    maps: CharacteristicMaps
    tables: MapTables
    steps: list
    diagnoses: list
    not_identifiable: dict
    recordings: list
    before: dict
    after: dict
    source: str
    improved_fmu: Path | None = None
    maps_dir: Path | None = None
    images: dict = field(default_factory=dict, repr=False)

    @property
    def effects_added(self) -> list:
        """The effects kept, in the order they were added."""
        return _kept(self.steps)

    def as_dict(self) -> dict:
        """The JSON form (``improve.json``): ``effects_added``, ``steps``, ``fmu``, ``improved_fmu``, ``maps``,
        ``not_identifiable``, ``diagnoses``, ``recordings``, ``before``, ``after``."""
        return {"fmu": self.source, "improved_fmu": None if self.improved_fmu is None else str(self.improved_fmu),
                "maps": None if self.maps_dir is None else str(self.maps_dir),
                "effects_added": self.effects_added, "steps": [s.as_dict() for s in self.steps],
                "not_identifiable": self.not_identifiable, "diagnoses": self.diagnoses, "recordings": self.recordings,
                "before": self.before, "after": self.after}


def improve(model, recordings, out_fmu=None, *, report_dir=None, max_effects: int = DEFAULT_MAX_EFFECTS,
            min_gain: float = DEFAULT_MIN_GAIN, threshold: float | None = None, progress=None,
            before_report_dir=None, source: str | None = None) -> ImproveResult:
    """Add the effects the residual asks for; report before and after; build the improved FMU if asked.

    Everything runs in memory: the model is simulated in this process (:func:`validate_model`; the FMU
    runs the same model on the same maps), and the improved FMU and its maps are outputs only.

    Parameters
    ----------
    model : path-like or CharacteristicMaps
        The FMU to improve (solenoid-fmu export; its maps are read out of it once), or the maps.
    recordings : list of path-like or Recording
    out_fmu : path-like, optional
        The improved FMU to write (its maps directory is written beside it, ``<stem>.maps/``).
    report_dir : path-like, optional
        Validation figures of the improved model and ``improve.json``.
    before_report_dir : path-like, optional
        Validation figures of the model before improvement.
    source : str, optional
        How the result names the model improved (``ImproveResult.source``, ``improve.json`` ``"fmu"``);
        default the FMU's path, or the maps' name (the pipeline: the FMU it built from them).

    Returns
    -------
    ImproveResult
        ``as_dict()`` is the JSON form (``improve.json``).
    """
    say = progress or (lambda msg: None)
    if out_fmu is not None:
        out_fmu = check_output_name(out_fmu)  # before any simulation
    recs = [r if isinstance(r, Recording) else read_recording(r) for r in recordings]
    if not recs:
        raise ImproveError("improve needs at least one recording")
    if isinstance(model, CharacteristicMaps):
        maps, source = model, source or model.name
    else:
        maps, source = maps_from_fmu(model), source or str(model)
    try:
        tables = maps_tables(maps, where=source)
    except MapsError as exc:
        raise ImproveError(str(exc)) from None
    flux_of = FluxCache()
    found = improve_tables(tables, recs, max_effects=max_effects, min_gain=min_gain, threshold=threshold,
                           progress=say, flux_of=flux_of)
    improved = with_maps_meta(maps, found.tables)
    improved_tables = maps_tables(improved, where=source)
    maps_dir = None
    if out_fmu is not None:
        maps_dir = save_maps(improved, out_fmu.with_suffix(".maps"))
        say(f"building {out_fmu}")
        build_fmu(improved, out_fmu)
    say("validating the model before and after")
    images: dict = {}
    before = validate_model(tables, recs, label=source, report_dir=before_report_dir, flux_of=flux_of, images=images)
    after = validate_model(improved_tables, recs, label=str(out_fmu or improved.name), report_dir=report_dir,
                           flux_of=flux_of, images=images)
    result = ImproveResult(improved, improved_tables, found.steps, found.diagnoses, found.not_identifiable,
                           _error_rows(recs, before, after), before, after, source, out_fmu, maps_dir, images)
    if report_dir is not None:
        Path(report_dir).mkdir(parents=True, exist_ok=True)
        atomic_write_text(Path(report_dir) / "improve.json", json.dumps(jsonable(result.as_dict()), indent=1) + "\n")
    return result


def _error_rows(recs: list, before: dict, after: dict) -> list:
    """Per recording (``file``, fit or validation ``split``) and signal: the errors before and after."""
    fit_recs, _ = split_recordings(recs)
    fit_names = {recording_name(r) for r in fit_recs}
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
    return rows


def effects_summary_lines(result: dict) -> list[str]:
    """The first lines the ``improve`` and ``pipeline`` commands print: effects added, then each effect
    that was not identifiable from the recordings and why (``result``: their summary dict)."""
    lines = [f"effects added: {', '.join(result['effects_added']) or 'none'}"]
    lines += [f"{effect}: not identifiable from these recordings: {what}"
              for effect, what in result["not_identifiable"].items()]
    return lines
