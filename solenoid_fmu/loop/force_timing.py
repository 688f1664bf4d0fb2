"""The force channel's timing against the voltage and current channels, measured from the recordings.

A rig's channels need not sample at the same instant. Ours (:mod:`solenoid_fmu.rig.daq`) records voltage
and current as means over the sample interval (integrating converters: paper eq. 4 then holds exactly for
the samples) and the force at the sample's time stamp; the model, driven by the interval means, then lags
the force channel by half a sample period. Other rigs have other filters. In a fast transient (a voltage
step sampled at 1-2 kHz) half a sample is a force error of 1-2 % of full scale while the current rises,
as large as the effects the loop looks for, and it is the same in every model: a floor of the validation.

:func:`measure_force_timing` measures the *lead* ``s`` of the force channel in sample periods: sample ``k``
of the force is the force at ``t_k + s dt_k`` on the time base of the voltage and current (``dt_k`` the local
sample period). It is measured model-free: on every recording with force and voltage and the armature at
rest (a ramp, a voltage step), the force the maps give for the eq.-4 flux, ``F(Psi(t), x)``, is shifted by
``s`` samples until it matches the measured force best, with the shapes of a force offset, a gain error of
the maps and the eq.-4 flux's own errors (an offset, a drift, the coil heating's drift; :func:`_nuisance`)
projected out per recording: eddy currents, hysteresis and heating act on the flux, which eq. 4 measures,
not on ``F(Psi, x)``. Only time-shapes that move the force sooner or later are left: that is the lead. A
lead in samples, not in seconds, because integrating converters make it a fraction of the sample period at
any sample rate. The force is taken to be sampled at its stamp.

Where the lead is significant (at least :data:`SIGNIFICANCE` standard errors, and at least
:data:`MIN_LEAD_SAMPLES`) the loop compares with it (:func:`solenoid_fmu.loop.residuals.residual_case`): a
current-driven model is driven with the current and voltage advanced by ``s`` samples (:func:`retimed`), so
that its force is the force the channel samples, and its flux is delayed by ``s`` again (:func:`shifted`) to
meet eq. 4's; the position, sampled at the stamp like the force, is not moved. A voltage-driven one (a step at
rest) has its force advanced instead. It is the measurement's timing, as eq. 4's offsets are its voltage
offsets, and it is applied to every model alike.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SolenoidError
from ..measure import armature_moves
from .tables import tables_from_fmu

#: The lead is applied when it is at least this many standard errors from zero ...
SIGNIFICANCE = 4.0
#: ... and at least this many sample periods.
MIN_LEAD_SAMPLES = 0.05
#: Leads searched [sample periods]; beyond them a misfit is not a channel timing.
LEAD_RANGE = (-3.0, 3.0)
#: The armature counts as at rest when its position varies by less than this [m] or by no more than its sensor's
#: noise (:func:`~solenoid_fmu.measure.armature_moves`).
AT_REST_M = 10e-6


@dataclass(frozen=True)
class ForceTiming:
    """The force channel's lead over the voltage and current channels (module docstring).

    Attributes
    ----------
    lead_samples : float
        Measured lead ``s`` [sample periods] (0 without a recording to measure it on).
    se_samples : float
        Its standard error [sample periods] (inf without one).
    applied : bool
        Significant: the loop compares the forces on the force channel's time base (module docstring).
    recordings : dict
        Per recording used: its own lead [sample periods] (None where its force does not move).
    note : str
        Why the lead is or is not applied.
    """

    lead_samples: float = 0.0
    se_samples: float = math.inf
    applied: bool = False
    recordings: dict = field(default_factory=dict)
    note: str = "no recording with force and voltage and the armature at rest"

    @property
    def used_lead_samples(self) -> float:
        """The lead the comparison uses [sample periods]: ``lead_samples`` if applied, else 0."""
        return self.lead_samples if self.applied else 0.0

    def as_dict(self) -> dict:
        return {"lead_samples": self.lead_samples, "se_samples": self.se_samples if math.isfinite(self.se_samples)
                else None, "applied": self.applied, "recordings": dict(self.recordings), "note": self.note}


def shifted(time_s, values, lead_samples: float) -> np.ndarray:
    """A sampled signal (any unit) at ``t_k + lead_samples dt_k`` (linear interpolation, held at the ends;
    ``dt_k`` the local sample period of ``time_s`` [s]); negative ``lead_samples`` delay it."""
    t = np.asarray(time_s, dtype=float)
    f = np.asarray(values, dtype=float)
    if lead_samples == 0.0 or t.size < 2:
        return f
    return np.interp(t + lead_samples * np.gradient(t), t, f)


def retimed(rec, lead_samples: float):
    """The recording with its voltage and current advanced by ``lead_samples`` (on the force's time base):
    a model driven by it gives the force as the force channel samples it, while the position, sampled
    at the time stamp like the force, stays as it is. The first sample stays too: the model starts from
    the state the recording's first current gives (the anchor of the flux comparison)."""
    if lead_samples == 0.0:
        return rec
    t = rec.time_s

    def advanced(v):
        out = shifted(t, v, lead_samples)
        out[0] = v[0]
        return out

    return dataclasses.replace(rec, current_A=advanced(rec.current_A),
                               voltage_V=None if rec.voltage_V is None else advanced(rec.voltage_V))


def _series(tables, rec, flux_of):
    """(t, measured F, F(Psi, x) of the eq.-4 flux, Psi) of a recording at rest with force and voltage, or None."""
    if rec.force_N is None or rec.voltage_V is None or rec.kind == "force_stroke":
        return None
    x = np.asarray(rec.positions_m(), dtype=float)
    if x.size < 8 or (float(np.ptp(x)) > AT_REST_M and armature_moves(x)):
        return None
    try:
        fr = flux_of(rec)
    except SolenoidError:
        return None
    t = np.asarray(rec.time_s, dtype=float)
    x0 = float(np.median(x))
    psi = tables.psi_of_current(float(fr.current_A[0]), x0) + np.asarray(fr.psi_Wb, dtype=float)
    dpsi = 1e-4 * max(float(np.max(np.abs(psi))), 1e-9)
    # F(Psi, x) and F at Psi -+ dpsi per sample (the maps' scalar lookup; 0.02 s a campaign)
    f_lo, f_map, f_hi = np.array([[tables.force_N(float(p) + d, x0) for d in (-dpsi, 0.0, dpsi)] for p in psi]).T
    slope = (f_hi - f_lo) / (2 * dpsi)
    f = np.asarray(rec.force_N, dtype=float)
    ok = np.isfinite(f) & np.isfinite(f_map) & np.isfinite(slope)
    if np.count_nonzero(ok) < 8 or not ok.all():
        return None
    return t, f, f_map, _nuisance(t, np.asarray(fr.current_A, dtype=float), f_map, slope)


def _nuisance(t, i, f_map, slope) -> np.ndarray:
    """The shapes a lead must not absorb, columns: a force offset, a gain error of the maps (``F``), and the
    force errors ``dF/dPsi x dPsi`` of the eq.-4 flux's own errors ``dPsi``: an offset, a drift (a voltage
    offset left over) and the drift of coil heating, ``int i (int i^2 dt) dt`` (the resistance rising with
    the heat put in, eq. 4 integrating it with the resistance measured before the run)."""
    from scipy.integrate import cumulative_trapezoid  # heavy; only the loop needs it

    heat = cumulative_trapezoid(i * i, t, initial=0.0)
    drift = cumulative_trapezoid(i * heat, t, initial=0.0)
    span = max(float(np.ptp(t)), 1e-300)
    cols = [np.ones_like(t), f_map, slope, slope * (t - t[0]) / span, slope * drift]
    return np.column_stack([c / max(float(np.max(np.abs(c))), 1e-300) for c in cols])


def _projector(basis):
    """Projection orthogonal to the columns of ``basis``."""
    q, _ = np.linalg.qr(basis)
    return lambda v: v - q @ (q.T @ v)


def measure_force_timing(tables, recordings, flux_of) -> ForceTiming:
    """Measure the force channel's lead (module docstring) on ``recordings``.

    Parameters
    ----------
    tables : MapTables
        The maps whose ``F(Psi, x)`` is compared (any maps of the solenoid: their static errors are projected out).
    recordings : list of Recording
    flux_of : callable
        ``flux_of(recording) -> FluxResult`` (eq. 4; e.g. a :class:`~solenoid_fmu.loop.residuals.FluxCache`).
    """
    from scipy.optimize import minimize_scalar  # heavy; only the loop needs it

    data = []
    for rec in recordings:
        s = _series(tables, rec, flux_of)
        if s is not None:
            t, f, f_map, basis = s
            data.append((rec, t, _projector(basis), f, f_map))
    if not data:
        return ForceTiming()

    def misfit(lead, items=data):
        return sum(float(np.sum(p(f - shifted(t, fm, lead)) ** 2)) for _, t, p, f, fm in items)

    def best(items):
        grid = np.arange(LEAD_RANGE[0], LEAD_RANGE[1] + 1e-9, 0.25)
        g0 = float(grid[int(np.argmin([misfit(g, items) for g in grid]))])
        lo, hi = max(LEAD_RANGE[0], g0 - 0.25), min(LEAD_RANGE[1], g0 + 0.25)
        return float(minimize_scalar(lambda s: misfit(s, items), bounds=(lo, hi), method="bounded",
                                     options={"xatol": 1e-4}).x)

    lead = best(data)
    num, n, den, rho_num, rho_den = 0.0, 0, 0.0, 0.0, 0.0
    per = {}
    for rec, t, p, f, fm in data:
        e = p(f - shifted(t, fm, lead))
        d = p(np.gradient(shifted(t, fm, lead), t) * np.gradient(t))
        num += float(e @ e)
        n += e.size
        den += float(d @ d)
        rho_num += float(e[1:] @ e[:-1])
        rho_den += float(e @ e)
        per[rec.path.name if rec.path is not None else rec.kind] = (round(best([(rec, t, p, f, fm)]), 4)
                                                                    if float(d @ d) > 0.0 else None)
    if den <= 0.0:
        return ForceTiming(recordings=per, note="the force does not move in the recordings at rest")
    rho = min(max(rho_num / rho_den, 0.0), 0.95) if rho_den > 0.0 else 0.0
    se = math.sqrt(num / max(n - 5 * len(data) - 1, 1) * (1.0 + rho) / (1.0 - rho) / den)
    applied = abs(lead) >= SIGNIFICANCE * se and abs(lead) >= MIN_LEAD_SAMPLES
    at_edge = min(abs(lead - LEAD_RANGE[0]), abs(lead - LEAD_RANGE[1])) < 1e-3
    if at_edge:
        applied = False
    note = (f"force channel leads the voltage and current by {lead:.3g} +- {se:.2g} sample periods "
            f"({len(data)} recording(s) at rest): "
            + ("at the edge of the searched range, not a channel timing: not applied" if at_edge
               else "the model is driven on the force's time base" if applied
               else "not significant: the channels are compared as sampled"))
    return ForceTiming(lead, se, applied, per, note)


def timing_of_fmu(fmu_path, recordings, flux_of) -> ForceTiming:
    """:func:`measure_force_timing` with the maps an FMU carries, its lead set on ``flux_of`` (a
    :class:`~solenoid_fmu.loop.residuals.FluxCache`) for the comparisons that follow; an FMU whose maps
    cannot be read gives no lead (the note says why)."""
    try:
        timing = measure_force_timing(tables_from_fmu(fmu_path), recordings, flux_of)
    except SolenoidError as exc:
        timing = ForceTiming(note=f"not measured: {exc}")
    flux_of.force_lead_samples = timing.used_lead_samples
    return timing
