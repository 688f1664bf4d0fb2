"""Close the loop: add the effect the diagnosis names to the real-time model, fit it, keep it if it pays.

The loop, on a campaign of recordings and the characteristic maps of a model (or the FMU that carries them):

1. simulate every recording with the current model and diagnose the residual
   (:mod:`solenoid_fmu.loop.diagnosis`);
2. take the best-ranked candidate that the model can add and has not tried, scoring at least
   :data:`TRY_THRESHOLD` (0.1; the verdict threshold of ``diagnose`` is 0.25, but here the held-out
   gate of step 3 decides) pooled over the signals or on one of them (:func:`~solenoid_fmu.loop.gates.try_score`), while
   the residual is significant (the eddy ladder from :data:`~solenoid_fmu.loop.gates.TRY_THRESHOLD_WITH_EVIDENCE`,
   0.05, where the maps' eddy fit measured an eddy current: ``eddy_measured``, by default maps.json
   ``eddy.measured``) (``hysteresis``,
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
pay there (random-0's campaign: +1.2 % of the squared error with C_th 332 J/K against the truth's 300). Then C_th
(and R_th where runs that start warm cool measurably: :mod:`solenoid_fmu.loop.heating_fit`) is fitted on the flux
residual of all recordings, and that value replaces the tracks' where it cuts the error over all recordings by
more than a tenth of ``min_gain`` (a drift large enough to measure it); once more at the end when hysteresis or
an eddy ladder was added meanwhile (their part of the residual is then modelled), jointly with them: they are
fitted again along the flux the new heating corrects before the trial is judged.

Where the tracks measure the heating, the effects fitted along the eq.-4 flux (hysteresis, eddy ladder) are fitted
on each recording's flux integrated with its own track (:meth:`~solenoid_fmu.loop.residuals.FluxCache.tracked`,
measured on the recording, whatever the model's heating), the recordings without one on the heating-corrected flux:
the model's heating, 20 % off in C_th, left a five-cycle triangle at 1.8 A drifting by 9 % (stop 48, random-8).

Every run starts at its coil temperature above ambient: the run's resistance over the campaign's coldest
(``FluxCache.ambient_R_ohm``, :func:`~solenoid_fmu.loop.residuals.ambient_resistance`), which the model's
heating cools from through R_th (``T_start_excess_K``).

When coil heating is kept, the effects kept before it that were fitted along the eq.-4 flux
(hysteresis, eddy ladder: :data:`FLUX_FITTED`) were fitted to a flux that carried the heating's drift
(the resistance measured before the run, while the coil warmed); they are fitted again along the
heating-corrected flux (:func:`solenoid_fmu.loop.heating_fit.heating_corrected`), then the heating itself
on the residual the corrected effects leave, and each refit replaces the earlier fit if it lowers the
validation error (steps marked ``refit``; :func:`~solenoid_fmu.loop.gates.refit_after_heating`).

Campaigns from any rig: the fit/validation split and the diagnosis's cross-validation folds go
by the size of the excitations, not by file names (one ordering, :mod:`solenoid_fmu.loop.split`);
the flux of a recording that starts energized is compared as a change from the model's flux at
its first sample; the gate's error is the full-scale NRMSE per kind
(:func:`~solenoid_fmu.loop.gates.gate_error`), so that no single recording can swing it.

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
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

from ..errors import MapsError
from ..fileio import atomic_write_text, check_output_name, jsonable
from ..fmu import build_fmu
from ..maps import CharacteristicMaps, maps_tables, save_maps
from ..measure import ESTIMATED_KEYS, Recording, headers_from_data, misspelt_in, read_unipolar
from ..realtime import MapTables
from .diagnosis import DEFAULT_THRESHOLD
from .force_timing import ForceTiming, measure_force_timing
from .gates import (
    FEW_PARAMETERS,
    FLUX_FITTED,
    TRY_THRESHOLD,
    TRY_THRESHOLD_WITH_EVIDENCE,
    LoopRun,
    Step,
    add_measured_heating,
    evidence_of,
    gate_error,
    kept_effects,
    pick_effect,
    refit_after_heating,
    simulate_cases,
    try_effect,
    try_score,
)
from .heating_evidence import campaign_tracks, heating_from_resistance, heats
from .identifiability import not_identifiable
from .residuals import CaseMemo, FluxCache, recording_name
from .split import split_recordings
from .tables import ImproveError, maps_from_fmu, simulates_alike, with_maps_meta
from .validation import validate_model

__all__ = ["DEFAULT_MAX_EFFECTS", "DEFAULT_MIN_GAIN", "TRY_THRESHOLD", "FEW_PARAMETERS", "FLUX_FITTED", "Step",
           "Improvement", "improve_tables", "ImproveResult", "improve", "effects_summary_lines"]

DEFAULT_MAX_EFFECTS = 4
DEFAULT_MIN_GAIN = 0.10


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
    force_timing: ForceTiming = ForceTiming()


#: The loop's simulation and gate error under their names before the steps had their own module (tests use them).
_cases, _error = simulate_cases, gate_error


# -- the loop --------------------------------------------------------------------------------------
def improve_tables(tables, recordings, *, max_effects: int = DEFAULT_MAX_EFFECTS, min_gain: float = DEFAULT_MIN_GAIN,
                   threshold: float | None = None, progress=None, flux_of=None, memo=None,
                   eddy_measured: bool | None = None) -> Improvement:
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
    memo : CaseMemo, optional
        Receives the cases of ``tables`` itself (:func:`improve` validates it on them).
    eddy_measured : bool, optional
        The maps' eddy fit measured an eddy current (:attr:`solenoid_fmu.maps.EddyFit.measurable`, the pipeline's
        step 4): the eddy ladder is tried from :data:`~.gates.TRY_THRESHOLD_WITH_EVIDENCE`. Default: what the
        maps say (maps.json ``eddy.measured``, written by :func:`solenoid_fmu.maps.with_fitted_eddy`; not said
        counts as not measured).
    """
    if not recordings:
        raise ImproveError("improve needs at least one recording")
    threshold = DEFAULT_THRESHOLD if threshold is None else threshold
    evidence = evidence_of(tables, eddy_measured)
    say = progress or (lambda msg: None)
    fit_recs, val_recs = split_recordings(recordings)
    flux_of = FluxCache() if flux_of is None else flux_of  # one eq.-4 flux per recording for the whole run
    run = LoopRun(recordings, fit_recs, {recording_name(r) for r in fit_recs}, {recording_name(r) for r in val_recs},
               flux_of, say)
    effects = tables.effects.as_dict()
    steps: list[Step] = []
    diagnoses: list = []
    tried: set = set()
    missing = not_identifiable(recordings, flux_of)
    for effect, what in missing.items():
        say(f"{effect}: not identifiable from these recordings: {what}")
    timing, camp = _channels(tables, recordings, flux_of, say)
    cases = cases0 = simulate_cases(tables, recordings, say, flux_of, memo)
    heat = None if "heating" in effects else heating_from_resistance(recordings, tables, camp)
    if heat is not None:
        effects, tables, cases = add_measured_heating(run, heat, effects, tables, cases, steps, min_gain)
        tried.add("heating")
    while len(kept_effects(steps)) < max_effects:
        pick, d = pick_effect(cases, threshold, tried, diagnoses, evidence)
        if pick is None:
            say("no further effect clears the diagnosis threshold")
            break
        tried.add(pick)
        if pick in missing:
            steps.append(Step(pick, False, note=f"not identifiable from these recordings: {missing[pick]}"))
            say(f"{pick} is named by the diagnosis but not identifiable from these recordings: {missing[pick]}")
            continue
        say(_adding(next(c for c in d.ranking if c.effect == pick), evidence))
        kept = try_effect(run, pick, effects, tables, cases, steps, min_gain)
        if kept is not None:
            (effects, tables, cases), note = kept
            if pick == "heating":
                effects, tables, cases = refit_after_heating(run, effects, tables, cases, steps,
                                                              heat_on_all="judged" in note)
            # an effect rejected before may have been masked by the one just added: it may be tried again
            tried = set(kept_effects(steps))
    if heat is not None and steps[0].accepted and any(s.accepted and not s.refit and s.effect in FLUX_FITTED
                                                      for s in steps[1:]):
        # the heating from the tracks was refitted on the flux residual before the effects fitted along the
        # flux were in: once more now that their part of the residual is modelled, and those effects with it
        effects, tables, cases = refit_after_heating(run, effects, tables, cases, steps, heat_on_all=True,
                                                      heating_first=True, min_fall=0.1 * min_gain, joint=True)
    return Improvement(tables, steps, diagnoses, cases0, cases, missing, timing)


def _channels(tables, recordings, flux_of, say) -> tuple:
    """What the run measures of the recordings before it simulates them: (the force channel's timing, the campaign's
    resistance tracks or None, :func:`~.heating_evidence.campaign_tracks`). A :class:`FluxCache` ``flux_of`` keeps
    them: the simulations compare the forces with that timing and start a heated coil at its temperature above
    ambient, and where the tracks measure the heating the flux-fitted effects are fitted on their flux."""
    camp = campaign_tracks(recordings)
    if not isinstance(flux_of, FluxCache):
        return ForceTiming(note="not measured: the run's flux_of is no FluxCache, which would carry it"), camp
    flux_of.note_ambient(recordings)
    timing = measure_force_timing(tables, recordings, flux_of)
    flux_of.force_lead_samples = timing.used_lead_samples
    say(timing.note)
    if heats(camp):
        flux_of.note_tracks(camp)
    return timing, camp


def _adding(cand, evidence: frozenset) -> str:
    """The progress line of the effect about to be tried (a diagnosis :class:`~.diagnosis.Candidate`): its score,
    its best signal's, and why an eddy ladder under :data:`TRY_THRESHOLD` is tried."""
    best = max(cand.per_signal, key=cand.per_signal.get, default=None)
    why = (f"; tried from {TRY_THRESHOLD_WITH_EVIDENCE:g}: the maps' eddy fit measured an eddy current"
           if cand.effect == "eddy" and "eddy" in evidence and try_score(cand) < TRY_THRESHOLD else "")
    return (f"adding {cand.effect} (diagnosis score {cand.score:.3f}"
            + (f"; {best} {cand.per_signal[best]:.3f}" if best else "") + why + ")")


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
    force_timing : ForceTiming
        The force channel's lead over the voltage and current the forces were compared with
        (:mod:`solenoid_fmu.loop.force_timing`).
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
    force_timing: ForceTiming = ForceTiming()

    @property
    def effects_added(self) -> list:
        """The effects kept, in the order they were added."""
        return kept_effects(self.steps)

    def as_dict(self) -> dict:
        """The JSON form (``improve.json``): ``effects_added``, ``steps``, ``fmu``, ``improved_fmu``, ``maps``,
        ``not_identifiable``, ``diagnoses``, ``recordings``, ``before``, ``after``, ``force_timing``."""
        return {"fmu": self.source, "improved_fmu": None if self.improved_fmu is None else str(self.improved_fmu),
                "maps": None if self.maps_dir is None else str(self.maps_dir),
                "effects_added": self.effects_added, "steps": [s.as_dict() for s in self.steps],
                "not_identifiable": self.not_identifiable, "diagnoses": self.diagnoses, "recordings": self.recordings,
                "before": self.before, "after": self.after, "force_timing": self.force_timing.as_dict()}


def improve(model, recordings, out_fmu=None, *, report_dir=None, max_effects: int = DEFAULT_MAX_EFFECTS,
            min_gain: float = DEFAULT_MIN_GAIN, threshold: float | None = None, progress=None,
            before_report_dir=None, source: str | None = None, eddy_measured: bool | None = None) -> ImproveResult:
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
    eddy_measured : bool, optional
        The maps' G_eddy comes from a fit that measured an eddy current (see :func:`improve_tables`; default: what
        the maps say, maps.json ``eddy.measured``).

    Returns
    -------
    ImproveResult
        ``as_dict()`` is the JSON form (``improve.json``).
    """
    say = progress or (lambda msg: None)
    if out_fmu is not None:
        out_fmu = check_output_name(out_fmu)  # before any simulation
    recs, turned, left = read_unipolar(recordings)  # a rig's negative current mirrored, bipolar ones left out
    if not recs:
        raise ImproveError("improve needs at least one recording" + "".join(f"; left out {w}" for w in left))
    read_here = not any(isinstance(item, Recording) for item in recordings)  # else the caller read them and said so
    for line in turned + [f"left out {w}" for w in left] + (misspelt_in(recs) if read_here else []):
        say(line)
    if any(r.voltage_V is not None and r.coil_resistance_ohm is None for r in recs) and \
            not any(k in r.header for r in recs for k in ESTIMATED_KEYS):  # else done (the pipeline's step 1)
        recs, _, filled, missing = headers_from_data(recs)
        for line in filled + missing:
            say(line)
    if isinstance(model, CharacteristicMaps):
        maps, source = model, source or model.name
    else:
        maps, source = maps_from_fmu(model), source or str(model)
    try:
        tables = maps_tables(maps, where=source)
    except MapsError as exc:
        raise ImproveError(str(exc)) from None
    flux_of = FluxCache()
    memo = CaseMemo()  # the loop's first simulation of the model is its validation before
    found = improve_tables(tables, recs, max_effects=max_effects, min_gain=min_gain, threshold=threshold,
                           progress=say, flux_of=flux_of, memo=memo, eddy_measured=eddy_measured)
    improved = with_maps_meta(maps, found.tables)
    improved_tables = maps_tables(improved, where=source)
    if simulates_alike(improved_tables, found.tables):  # the loop simulated the improved maps last: its cases
        memo.put_all(improved_tables, recs, found.cases_after)
    maps_dir = None
    if out_fmu is not None:
        maps_dir = save_maps(improved, out_fmu.with_suffix(".maps"))
        say(f"building {out_fmu}")
        build_fmu(improved, out_fmu)
    say("validating the model before and after")
    images: dict = {}
    before = validate_model(tables, recs, label=source, report_dir=before_report_dir, flux_of=flux_of, images=images,
                            memo=memo)
    after = validate_model(improved_tables, recs, label=str(out_fmu or improved.name), report_dir=report_dir,
                           flux_of=flux_of, images=images, memo=memo)
    result = ImproveResult(improved, improved_tables, found.steps, found.diagnoses, found.not_identifiable,
                           _error_rows(recs, before, after), before, after, source, out_fmu, maps_dir, images,
                           found.force_timing)
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
