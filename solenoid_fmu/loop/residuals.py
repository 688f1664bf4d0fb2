"""Residual cases: run a simulator on each recording's measured inputs and keep measured minus simulated.

A :class:`ResidualCase` holds one recording's residuals and the quantities the diagnosis's
signatures are built from; :func:`cases_from_recordings` makes them with the FMU (fmpy) or an
in-process simulator, :func:`residual_case` for one recording (how the eq.-4 flux is compared).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..fmu import DRIVE_BY_KIND, simulate_recording
from ..measure import Recording, flux_linkage, read_recording
from .force_timing import retimed, shifted
from .signals import conditioned_position, detrend

#: A flux residual is compared orthogonal to a linear trend when the eq.-4 offset's uncertainty
#: times the duration exceeds this share of the recording's largest |flux|.
OFFSET_UNCERTAINTY_SHARE = 1e-3


@dataclass
class ResidualCase:
    """One recording's residuals and the quantities the signatures are built from (SI).

    Parameters
    ----------
    name : str
        The recording's file name (for reports).
    time_s : ndarray, shape (n,)
    psi_Wb : ndarray, shape (n,)
        Flux linkage along the run (simulated, or from eq. 4).
    current_A : ndarray, shape (n,)
        Coil current (measured).
    position_m : ndarray, shape (n,)
        Armature gap per sample.
    R_ohm : float
        Coil resistance used for the i^2 R heating signature.
    residuals : dict of str -> ndarray
        Measured minus simulated, per signal name (``current_A``, ``voltage_V``, ``force_N``,
        ``psi_Wb``).
    measured : dict of str -> ndarray
        The measured signals with the same keys (for the sensor signature and normalization).
    kind : str
        The recording kind (``flux``, ``force_stroke``, ...); "" when not from a recording.
    drive : str
        How the FMU was driven (``"current"`` or ``"voltage"``); "" when not from a recording.
    path : str
        The recording's full path; "" when not from a file.
    detrended : tuple of str
        Signals whose residual is only known up to a linear trend ``a + b t`` and was projected
        orthogonal to it (``psi_Wb`` of a recording without a zero-current rest: eq. 4 cannot
        measure its voltage offset); their features are projected the same way.
    ambient_R_ohm : float or None
        The campaign's coldest resistance [ohm] (:func:`ambient_resistance`), the coil at ambient: with
        ``R_ohm`` it gives the temperature the run starts above ambient
        (:func:`solenoid_fmu.fmu.simulate.start_excess_K`); None
        when not known.
    """

    name: str
    time_s: np.ndarray
    psi_Wb: np.ndarray
    current_A: np.ndarray
    position_m: np.ndarray
    R_ohm: float
    residuals: dict
    measured: dict
    kind: str = ""
    drive: str = ""
    path: str = ""
    detrended: tuple = ()
    ambient_R_ohm: float | None = None


def ambient_resistance(recordings, flux_of) -> float | None:
    """The campaign's coldest coil resistance [ohm]: the least of the resistances its runs start from (the
    eq.-4 resistance of a current-driven recording with a voltage, else the header's); None without any.

    Taken for the coil at ambient: a campaign begins with a cold coil, and a run that starts warmer (its
    resistance above this one) starts with the heat the runs before it left
    (:func:`solenoid_fmu.fmu.simulate.start_excess_K`)."""
    found = []
    for rec in recordings:
        if rec.voltage_V is not None and rec.kind != "voltage_step":
            found.append(float(flux_of(rec).R_ohm))
        elif rec.coil_resistance_ohm:
            found.append(float(rec.coil_resistance_ohm))
    return min(found) if found else None


class FluxCache:
    """The eq.-4 flux (:func:`solenoid_fmu.measure.flux_linkage`) of each recording, computed once.

    Call it like ``flux_linkage(rec)``; results are kept per recording object while the cache
    lives (``improve`` keeps one per run: the flux of a recording does not change between its
    simulations, the identifiability check and the fits).

    It also carries the other thing the run measured of the recordings' channels: ``force_lead_samples``,
    the force channel's lead over the voltage and current [sample periods] (0 unless the loop measured a
    significant one, :mod:`solenoid_fmu.loop.force_timing`), with which :func:`cases_from_recordings`
    compares every simulated force on the force channel's time base (:func:`residual_case`), and
    ``ambient_R_ohm``, the campaign's coldest resistance (None until :meth:`note_ambient`), from which a
    model with coil heating starts each run at its temperature above ambient
    (:func:`solenoid_fmu.fmu.simulate.heating_start`).

    ``tracks`` (None until :meth:`note_tracks`): the campaign's resistance tracks where they measure the coil
    heating; :meth:`tracked` gives the eq.-4 flux with a recording's own R(t), which the loop's flux-fitted effects
    are fitted on (:mod:`solenoid_fmu.loop.effects`).
    """

    def __init__(self):
        self._by_id: dict = {}
        self._tracked_by_id: dict = {}
        self.force_lead_samples = 0.0
        self.ambient_R_ohm = None
        self.tracks = None

    def note_ambient(self, recordings) -> None:
        """Set ``ambient_R_ohm`` from the campaign ``recordings`` (:func:`ambient_resistance`) if not set."""
        if self.ambient_R_ohm is None:
            self.ambient_R_ohm = ambient_resistance(recordings, self)

    def __call__(self, rec):
        hit = self._by_id.get(id(rec))
        if hit is None or hit[0] is not rec:
            hit = self._by_id[id(rec)] = (rec, flux_linkage(rec))
        return hit[1]

    def note_tracks(self, camp) -> None:
        """Keep the campaign's resistance tracks (a :class:`~solenoid_fmu.measure.CampaignResistance`) for
        :meth:`tracked`."""
        self.tracks = camp
        self._tracked_by_id = {}

    def tracked(self, rec):
        """The eq.-4 flux of ``rec`` integrated with its resistance track R(t) (:meth:`note_tracks`), or None
        where it has none. The track is measured on the recording itself (current plateaus, cycle closure, its
        rests, the campaign's heating rate), so this flux does not depend on a model's heating parameters: a
        tenth of a kelvin off over a five-cycle triangle at 1.8 A moves the eq.-4 flux by several per cent."""
        track = None if self.tracks is None else self.tracks.track_for(rec)
        if track is None:
            return None
        hit = self._tracked_by_id.get(id(rec))
        if hit is None or hit[0] is not rec:
            hit = self._tracked_by_id[id(rec)] = (rec, flux_linkage(rec, resistance=track))
        return hit[1]


class CaseMemo:
    """Residual cases of (model tables, recording) pairs already simulated, by object identity.

    ``improve`` validates the model it started from on the recordings the loop simulated it on first:
    the same tables and recording objects, so the same cases (the simulation is deterministic).
    """

    def __init__(self):
        self._by_id: dict = {}

    def get(self, tables, rec) -> list | None:
        """The cases of ``rec`` simulated on ``tables`` (a list of 0 or 1), or None if not simulated."""
        hit = self._by_id.get((id(tables), id(rec)))
        if hit is None or hit[0] is not tables or hit[1] is not rec:
            return None
        return hit[2]

    def put(self, tables, rec, cases: list) -> None:
        self._by_id[(id(tables), id(rec))] = (tables, rec, cases)

    def put_all(self, tables, recs: list, cases: list) -> bool:
        """Keep ``cases``, simulated on ``tables`` from ``recs`` in their order (as :func:`cases_from_recordings`
        gives them), under each recording. Only where every recording gave one case (which case is whose is then
        certain); False, nothing kept, otherwise."""
        if len(cases) != len(recs):
            return False
        for rec, case in zip(recs, cases, strict=True):
            self.put(tables, rec, [case])
        return True


def recording_name(rec) -> str:
    """How reports name a recording: its file name, or its kind when it has no file."""
    return rec.path.name if rec.path is not None else rec.kind


def cases_from_recordings(fmu_path, recordings, progress=None, simulate=None,
                          flux_of=flux_linkage) -> list[ResidualCase]:
    """Run the FMU on each recording's measured inputs and collect the residuals.

    Current-driven runs (flux, force_stroke, ramp, eddy) give the flux residual where the
    recording has a voltage, and the force residual where it has a force. Voltage-driven runs
    (voltage_step) give the current and force residuals. See :func:`residual_case`.

    Parameters
    ----------
    fmu_path : path-like or None
        A solenoid-fmu FMU (driven with fmpy), or None when ``simulate`` is given.
    recordings : list of path-like or Recording
    progress : callable, optional
        Called with each file name before it is simulated.
    simulate : callable, optional
        ``simulate(recording, R_ohm) -> SimulationResult`` instead of the FMU (e.g.
        :func:`solenoid_fmu.fmu.simulate_model` in process).
    flux_of : callable, optional
        ``flux_of(recording) -> FluxResult``, the eq.-4 flux of a recording as read (default
        :func:`solenoid_fmu.measure.flux_linkage`; a :class:`FluxCache` computes it once, and its
        ``force_lead_samples`` put the simulated forces on the force channel's time base).
    """
    if simulate is None:
        def simulate(rec, R_ohm):
            return simulate_recording(fmu_path, rec, R_ohm=R_ohm, ambient_R_ohm=ambient)

    lead = float(getattr(flux_of, "force_lead_samples", 0.0))
    ambient = getattr(flux_of, "ambient_R_ohm", None)
    cases = []
    for item in recordings:
        rec = item if isinstance(item, Recording) else read_recording(item)
        if progress:
            progress(recording_name(rec))
        read = rec
        if rec.position_m is not None:  # drive the model with the position less its encoder jitter
            rec = dataclasses.replace(rec, position_m=conditioned_position(rec.position_m))
        # the flux does not depend on the position: that of the recording as read
        case = residual_case(rec, simulate, flux_of=lambda _rec, read=read: flux_of(read), force_lead_samples=lead,
                             ambient_R_ohm=ambient)
        if case is not None:
            cases.append(case)
    return cases


def _head_anchored(psi_meas, res, fr) -> tuple:
    """(measured flux, flux residual) anchored on the mean over the recording's head rest
    (``fr.head_rest_samples``, :func:`residual_case`), as given without one."""
    n = int(getattr(fr, "head_rest_samples", 0))
    if n < 2:
        return psi_meas, res
    shift = float(np.mean(res[:n]))
    return psi_meas - shift, res - shift


def residual_case(rec, simulate, flux_of=flux_linkage, force_lead_samples: float = 0.0,
                  ambient_R_ohm: float | None = None) -> ResidualCase | None:
    """Residuals of one recording against a simulator (None if it has no signal to compare).

    The flux residual compares like with like: the measured flux is paper eq. 4 applied to the
    measured voltage with the coil resistance ``R`` of the recording (header or estimate); the
    simulated one is the same integral of the simulated voltage, ``sum h (U_sim - R i)`` over the
    steps. For a model with constant resistance this is exactly the simulated flux; a model with
    coil heating then shows the same ``R(T)`` drift the measurement carries.

    Eq. 4 measures flux *changes*: its integration constant is only known when the recording
    starts at rest (zero current, demagnetized). Both fluxes are therefore anchored to the
    model's flux at the first sample (``Psi_sim(0)``, the simulator's start value from the first
    sample's current and position) and only their changes are compared, which is exact for a
    recording from rest and the honest comparison for one that starts energized (the report's
    flux plots say "anchored to the model at t = 0"). A recording that starts with a zero-current
    rest (``FluxResult.head_rest_samples``) is anchored on the mean over that rest instead: the model
    follows the current sensor's noise there (the steel's initial permeability turns 0.5 mA into
    about 0.5 mWb), and one sample's draw would shift the whole comparison by it (0.23 % of full scale
    on random-0's eddy recording; the exact model's pooled error there 0.235 -> 0.172 %). A recording
    without any zero-current rest has no measured voltage offset either: its flux residual is known
    up to ``a + b t`` and is projected orthogonal to that trend (``ResidualCase.detrended``).
    ``flux_of`` computes the eq.-4 flux (default :func:`solenoid_fmu.measure.flux_linkage`).

    ``force_lead_samples`` is the force channel's measured lead over the voltage and current
    (:mod:`solenoid_fmu.loop.force_timing`; 0: the channels are compared as sampled). A current-driven
    model is then driven by the current (and voltage) advanced by it
    (:func:`~solenoid_fmu.loop.force_timing.retimed`), its force compared as it comes, its flux delayed by it
    again to meet the measured one; the position, sampled at the stamp like the force, is not moved. A
    voltage-driven one (a voltage step, the armature at rest) is driven as recorded and its force advanced
    by the lead: its voltage held at the interval's mean is already what eq. 4 integrates, and advancing the
    voltage would smear the step over one more sample. ``ambient_R_ohm`` [ohm] is kept in the case (heating fit).
    """
    residuals, measured = {}, {}
    fr = None
    R = rec.coil_resistance_ohm
    if rec.voltage_V is not None and rec.kind != "voltage_step":
        fr = flux_of(rec)
        R = fr.R_ohm
    lag = force_lead_samples
    by_voltage = DRIVE_BY_KIND.get(rec.kind, "current") == "voltage"
    drive = rec if by_voltage else retimed(rec, lag)
    sim = simulate(drive, R)
    s = sim.recording

    def back(v):  # a simulated signal on the voltage's and current's time base
        return np.asarray(v, dtype=float) if drive is rec else shifted(rec.time_s, v, -lag)

    psi_sim = back(s.extra["psi_Wb"])
    detrended = ()
    if rec.force_N is not None:
        f_sim = s.force_N if drive is not rec else shifted(rec.time_s, s.force_N, lag)
        residuals["force_N"] = np.asarray(rec.force_N) - np.asarray(f_sim)
        measured["force_N"] = np.asarray(rec.force_N)
    if sim.drive_mode == "current":
        if rec.voltage_V is not None:
            if fr is None:
                fr = flux_of(rec)
                R = fr.R_ohm
            t = np.asarray(rec.time_s, dtype=float)
            i = np.asarray(drive.current_A, dtype=float)
            inc = np.diff(t) * (np.asarray(s.voltage_V)[1:] - R * i[1:])
            psi_app = back(psi_sim[0] + np.concatenate([[0.0], np.cumsum(inc)]))
            psi_meas = psi_sim[0] + fr.psi_Wb
            res = psi_meas - psi_app
            psi_meas, res = _head_anchored(psi_meas, res, fr)
            if fr.offset_uncertainty_Wb > OFFSET_UNCERTAINTY_SHARE * float(np.max(np.abs(psi_meas))):
                res = detrend(res, t)
                detrended = ("psi_Wb",)
            residuals["psi_Wb"] = res
            measured["psi_Wb"] = psi_meas
    else:
        residuals["current_A"] = np.asarray(rec.current_A) - back(s.current_A)
        measured["current_A"] = np.asarray(rec.current_A)
    if not residuals:
        return None
    return ResidualCase(recording_name(rec), np.asarray(rec.time_s), psi_sim, np.asarray(rec.current_A),
                        np.asarray(rec.positions_m()), R or 1.0, residuals, measured, rec.kind, sim.drive_mode,
                        "" if rec.path is None else str(rec.path), detrended, ambient_R_ohm)
