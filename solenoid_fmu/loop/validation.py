"""Validation: run the FMU on measured inputs and compare every output a recording has.

For each recording the FMU is driven by the recording's measured inputs
(:func:`solenoid_fmu.loop.residuals.cases_from_recordings`, which calls
:func:`solenoid_fmu.fmu.simulate_recording`): current-driven for ``flux``, ``force_stroke``,
``ramp`` and ``eddy``, voltage-driven for ``voltage_step``. The outputs compared:

============= =====================================================================================
signal        measured vs simulated
============= =====================================================================================
``force_N``   the measured force vs the FMU's F(Psi, x) (paper eq. 3), where the recording has force
``psi_Wb``    flux linkage from the measured voltage (paper eq. 4, offset removed) vs the FMU's Psi,
              for current-driven runs with a voltage column; both anchored to the model's Psi at
              the first sample (eq. 4 gives changes: a recording may start energized), and
              without any zero-current rest compared orthogonal to a linear trend (unknown offset)
``current_A`` the measured current vs the FMU's (paper eqs. 1-2), for voltage-driven runs
============= =====================================================================================

The metrics (``rms``, ``max``, ``nrmse``, ``nrmse_fs``) are defined in :mod:`solenoid_fmu.loop.metrics`,
the figures drawn by :mod:`solenoid_fmu.loop.plots`.

:func:`validate_model` runs the model in this process instead of the FMU (``improve``: the FMU is an output).

Forces are compared on the time base of the voltage and current that drive the model: :func:`validate`
measures the force channel's lead on the recordings (:mod:`solenoid_fmu.loop.force_timing`, with the maps
the FMU carries) and, where it is significant, compares the force on its channel's time base
(:func:`~solenoid_fmu.loop.residuals.residual_case`); :func:`validate_model` uses
the lead its ``flux_of`` carries (``improve`` measures it once per run). The result's ``force_lead_samples``
is the lead used [sample periods], ``force_timing`` (:func:`validate`) the measurement.

Output (:func:`validate_cases`, :func:`validate`; JSON as printed by ``solenoid-fmu validate --json``)::

    {"recordings": [{"file": "01_flux_0p50A.csv", "kind": "flux", "drive": "current",
                     "signals": {"psi_Wb": {"rms": ..., "max": ..., "nrmse": ..., "n": ...}}}, ...],
     "summary": {"psi_Wb": {"nrmse_mean": ..., "nrmse_max": ..., "n_recordings": ...}, ...},
     "figures": ["report/01_flux_0p50A_overlay.png", ...]}

Command line: ``solenoid-fmu validate build/NAME.fmu RECORDING.csv... [--report DIR] [--json]``.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import FmuInputError, RecordingError
from ..fileio import atomic_write_bytes, atomic_write_text
from ..fmu import simulate_model
from ..measure import Recording, flux_linkage, misspelt_in, read_recording, unipolar
from ..realtime import MapTables
from .force_timing import ForceTiming, timing_of_fmu
from .metrics import ValidationError, summarize, validate_cases
from .plots import overlay_png, residual_png
from .residuals import FluxCache, cases_from_recordings, recording_name


def _unique_stems(names: list[str]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for name in names:
        stem = Path(name).stem or "recording"
        n = seen.get(stem, 0) + 1
        seen[stem] = n
        out.append(stem if n == 1 else f"{stem}_{n}")
    return out


# -- the validation run -------------------------------------------------------------------------------
def _read_all(recordings) -> list:
    """Read every recording first, so a bad file fails before any simulation (all problems listed); those with a
    negative current mirrored (:func:`~solenoid_fmu.measure.unipolar`), bipolar ones refused."""
    recs, problems = [], []
    for item in recordings:
        if isinstance(item, Recording):
            recs.append(item)
            continue
        try:
            recs.append(read_recording(item))
        except RecordingError as exc:
            problems += exc.problems
    if problems:
        raise RecordingError("validate: recordings", problems)
    recs, _, bipolar = unipolar(recs)  # a rig's negative current mirrored (the model is odd in the current)
    if bipolar:
        raise RecordingError("validate: recordings", bipolar)
    return recs


def validate(fmu_path, recordings, *, report_dir=None, progress=None, flux_of=None) -> dict:
    """Run the FMU on each recording's measured inputs and compare every output it has.

    Parameters
    ----------
    fmu_path : path-like
        A solenoid-fmu FMU (``solenoid-fmu export``).
    recordings : list of path-like or solenoid_fmu.measure.Recording
        Recordings (format v1). All are read before the first simulation.
    report_dir : path-like, optional
        When given: ``<stem>_overlay.png`` and ``<stem>_residual.png`` per recording and
        ``validation.json`` (the returned dict) are written there (atomically).
    progress : callable, optional
        Called with each file name before it is simulated.
    flux_of : callable, optional
        ``flux_of(recording) -> FluxResult`` (default: a new :class:`~solenoid_fmu.loop.residuals.FluxCache`;
        one shared with other steps computes the eq.-4 flux once). A FluxCache also carries the force
        channel's lead measured here; another callable (e.g. :func:`solenoid_fmu.measure.flux_linkage`)
        compares the forces as sampled.

    Returns
    -------
    dict
        As :func:`validate_cases`, each recording entry also with ``path`` and ``figures``
        (``{"overlay": path, "residual": path}``, empty without ``report_dir``); ``figures`` at
        the top level lists every figure path in recording order (overlay, residual). A
        recording with nothing to compare (no force, no voltage in a current-driven run) gets
        empty ``signals`` and a ``note``. ``names_not_read``: header keys and columns kept but not read for
        looking like misspelt ones of recordings.md (:func:`solenoid_fmu.measure.misspelt_in`).

    Raises
    ------
    FmuInputError
        The FMU file does not exist or is not a solenoid-fmu FMU, or refused a recording.
    RecordingError
        A recording cannot be read or is malformed (every file's problems listed).
    ValidationError
        No recordings given.
    """
    fmu_path = Path(fmu_path)
    if not fmu_path.is_file():
        raise FmuInputError(f"{fmu_path}: FMU file not found")
    recs = _read_all(recordings)
    timing = ForceTiming(note="not measured: flux_of is no FluxCache, which would carry it")
    if flux_of is None:
        flux_of = FluxCache()
    if isinstance(flux_of, FluxCache):
        flux_of.note_ambient(recs)
        timing = timing_of_fmu(fmu_path, recs, flux_of)
    lead = float(getattr(flux_of, "force_lead_samples", 0.0))
    return _validate(str(fmu_path), recs, lambda rec: cases_from_recordings(fmu_path, [rec], progress=progress,
                                                                            flux_of=flux_of), report_dir,
                     extra={"force_lead_samples": lead, "force_timing": timing.as_dict(),
                            "names_not_read": misspelt_in(recs)})


def timed_cases(fmu_path, recordings, progress=None, not_read: list | None = None) -> list:
    """The residual cases of an FMU on ``recordings`` (:func:`cases_from_recordings`), the forces compared on
    the time base the recordings' force channel has (:func:`~solenoid_fmu.loop.force_timing.timing_of_fmu`):
    what ``diagnose`` works on, compared as :func:`validate` compares. ``not_read`` (a list), when given, receives
    the header keys and columns kept but not read for looking like misspelt ones (as :func:`validate`'s
    ``names_not_read``)."""
    recs = _read_all(recordings)
    if not_read is not None:
        not_read += misspelt_in(recs)
    flux_of = FluxCache()
    flux_of.note_ambient(recs)
    timing_of_fmu(fmu_path, recs, flux_of)
    return cases_from_recordings(fmu_path, recs, progress=progress, flux_of=flux_of)


def validate_model(tables: MapTables, recordings, *, label: str, report_dir=None, progress=None,
                   flux_of=flux_linkage, images: dict | None = None, memo=None) -> dict:
    """:func:`validate` with the real-time model run in this process on ``tables`` instead of an FMU.

    The FMU runs the same model on the same maps (:func:`solenoid_fmu.fmu.simulate_model`, whose agreement
    with the FMU is tested), so this is the validation of an FMU built from ``tables`` without reading it.

    Parameters
    ----------
    tables : MapTables
        The maps, with any ``effects`` section in their meta.
    recordings : list of path-like or Recording
    label : str
        What the result's ``"fmu"`` names (the FMU built from ``tables``).
    report_dir, progress, flux_of : see :func:`validate`
    images : dict, optional
        Receives the figures written to ``report_dir``, ``{str(path): PNG bytes}`` (a report embeds them from
        memory).
    memo : CaseMemo, optional
        Cases already simulated (:class:`~solenoid_fmu.loop.residuals.CaseMemo`): a recording (object) whose
        cases on ``tables`` (object) it holds is not simulated again.
    """
    def cases_of(rec):
        known = None if memo is None else memo.get(tables, rec)
        if known is not None:
            if progress:
                progress(recording_name(rec))
            return known
        return cases_from_recordings(None, [rec], progress=progress, flux_of=flux_of,
                                     simulate=lambda r, R: simulate_model(tables, r, R_ohm=R, ambient_R_ohm=ambient))

    ambient = getattr(flux_of, "ambient_R_ohm", None)

    return _validate(label, recordings, cases_of, report_dir, images,
                     extra={"force_lead_samples": float(getattr(flux_of, "force_lead_samples", 0.0))})


def _validate(label: str, recordings, cases_of, report_dir, images: dict | None = None,
              extra: dict | None = None) -> dict:
    """The validation of :func:`validate` and :func:`validate_model`; ``cases_of(rec)`` simulates one; ``extra``
    joins the result."""
    recordings = list(recordings)
    if not recordings:
        raise ValidationError("validate needs at least one recording")
    recs = _read_all(recordings)
    names = [r.path.name if r.path is not None else f"{r.kind}.csv" for r in recs]
    stems = _unique_stems(names)
    out_dir = None if report_dir is None else Path(report_dir)
    entries, figures = [], []
    for rec, name, stem in zip(recs, names, stems, strict=True):
        found = cases_of(rec)
        if not found:
            entry = {"file": name, "kind": rec.kind, "drive": "", "signals": {},
                     "note": "nothing to compare (no force; no voltage in a current-driven run)"}
            if rec.path is not None:
                entry["path"] = str(rec.path)
            entry["figures"] = {}
            entries.append(entry)
            continue
        case = found[0]
        entry = validate_cases([case])["recordings"][0]
        entry["file"] = name
        entry["figures"] = {}
        if out_dir is not None:
            for key, png in (("overlay", overlay_png(case)), ("residual", residual_png(case))):
                written = str(atomic_write_bytes(out_dir / f"{stem}_{key}.png", png))
                entry["figures"][key] = written
                figures.append(written)
                if images is not None:
                    images[written] = png
        entries.append(entry)
    result = {"fmu": label, "recordings": entries, "summary": summarize(entries), "figures": figures, **(extra or {})}
    if out_dir is not None:
        atomic_write_text(out_dir / "validation.json", json.dumps(result, indent=2) + "\n")
    return result
