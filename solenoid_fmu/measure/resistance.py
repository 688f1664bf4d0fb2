r"""The coil resistance over time, estimated from a recording's own voltage and current.

Paper eq. 4 integrates ``U - R i``: at 2 A a 0.1 % error of R (12 ohm) integrates to ~0.01 Wb
per second, and the coil warms by several kelvin in a campaign. The header's
``coil_resistance_ohm`` was measured before the run, so it cannot follow that; the recording can.

Model (**adiabatic Joule heating**): within a recording (seconds; the coil's thermal time constant is
minutes) ``R(t) = R0 (1 + kappa E(t))`` with ``E(t) = int_0^t R(t') i^2 dt'`` [J] the Joule energy since
the first sample and ``kappa = alpha / C_th`` [1/J] (copper ``alpha`` = 0.00393 /K, ``C_th`` the
heat capacity). Unknowns per recording: ``R0`` [ohm] (R at the first sample) and ``c = R0 kappa``
[ohm/J]; the voltage offset comes first from the zero-current rests
(:func:`~solenoid_fmu.measure.conditioning.condition`). With the offset known, the flux
``Psi(t) = A(t) - R0 B0(t) - c B1(t)`` (``A = int U dt``, ``B0 = int i dt``, ``B1 = int E i dt``) is
linear in ``(R0, c)``, and every piece of information is a linear equation, solved by weighted
least squares:

(a) current plateaus (settled second half of a hold, |i| > 10 % of the peak, >= 50 ms): Psi does not
    change there, ``Psi(t_b) - Psi(t_a) = 0`` over each quarter of the settled part (R rises along a
    long hold); noise ``sigma_u dt sqrt(N)`` with ``sigma_u`` the voltage noise and R times the
    current noise;
(b) cycle-to-cycle closure: of two consecutive cycles with the same peak (within 0.3 %) the descending
    branches coincide as Psi(i), and so do the ascending ones from the second cycle on (the first
    starts demagnetized; branches of >= 50 samples): the mean of ``Psi_k(i) - Psi_k+1(i)`` over 10-90 %
    of the peak is 0; noise
    the voltage noise integrated over the time between the two branches, the current noise seen
    through the slope dPsi/di, and the slope times the difference of the two peaks (a loop from
    a higher turning point lies higher);
(c) the end rest of a single-cycle recording that starts and ends at rest: ``Psi_end - Psi_0`` is
    the remanence, bounded by the loop: a weak equation ``= 0 +- (the hysteresis width seen with
    the header R, at least 1 % of Psi at the peak)``;
(d) priors: the header R as ``R0`` with a relative uncertainty :data:`HEADER_SIGMA_REL` (measured before
    the run, maybe at another temperature, on another rig), and ``kappa = 0 +-``
    :data:`KAPPA_PRIOR_PER_J` (``C_th`` >= 10 J/K) unless a campaign value is given.

The covariance is scaled by the residual noise (``chi^2 / dof`` of the data equations when above 1),
and the model's own error is added: cooling (Newton, neglected) bends R(t) by about
``duration / (2 tau)`` of the heating, with ``tau`` >= :data:`TAU_MODEL_S`, so ``c`` is uncertain by at
least that fraction (moving ``R0`` the way the data leave free).
A track is ``pinned`` when the uncertainty it leaves in Psi at the highest peak is below
:data:`PINNED_REL` (0.3 %) of Psi there. :func:`campaign_resistance` fits one ``kappa`` for all
recordings of a campaign at a fixed stroke (per-recording ``R0``), so that multi-cycle and plateau
recordings pin it for single-cycle ones (:mod:`.resistance_campaign`). :func:`closure_problems` names
recordings whose loops do not close from cycle to cycle even with the best track.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .format import Recording
from .resistance_equations import (
    Equations,
    equations,
    fit_one,
    model_error,
    prepare,
    scale_of,
)

__all__ = ["HEADER_SIGMA_REL", "HEADER_OFF_SIGMAS", "KAPPA_PRIOR_PER_J", "PINNED_REL", "CLOSURE_FACTOR",
           "ResistanceTrack", "resistance_track", "closure_problems"]

#: Relative 1-sigma uncertainty of the header's ``coil_resistance_ohm`` as the prior of ``R0``.
HEADER_SIGMA_REL = 0.005
#: A recording's own data (cycle closures, plateaus) overrule its header's R when they pin R at the start
#: this many of their sigmas away from it (:attr:`ResistanceTrack.header_overruled`): the header's 0.5 % is a
#: prior, a three-cycle recording pins R to 0.01 %, and a header off by 0.1 % drifts that recording's eq.-4
#: flux by several per cent of the peak per cycle.
HEADER_OFF_SIGMAS = 5.0
#: 1-sigma of the prior ``kappa = 0`` [1/J]: copper's alpha over a heat capacity of 10 J/K.
KAPPA_PRIOR_PER_J = 0.00393 / 10.0
#: A track is pinned when it leaves Psi at the peak uncertain by less than this fraction.
PINNED_REL = 0.003
#: Closure residuals this many times what the noise explains are a data problem.
CLOSURE_FACTOR = 5.0


@dataclass
class ResistanceTrack:
    """R(t) of one recording (adiabatic Joule heating, see the module docstring) with its uncertainty.

    Attributes
    ----------
    label : str
        The recording's ``label()``.
    time_s, R_t_ohm, energy_J : numpy.ndarray, shape (n,)
        Sample times [s], the track R(t) [ohm] and the Joule energy since the first sample [J].
    R0_ohm, R0_sigma_ohm : float
        R at the first sample and its 1-sigma [ohm].
    R_end_ohm, R_end_sigma_ohm : float
        R at the last sample and its 1-sigma [ohm].
    kappa_per_J, kappa_sigma_per_J : float
        ``kappa = alpha / C_th`` [1/J] and its 1-sigma.
    kappa_source : str
        ``"recording"`` (this recording's data and the weak prior) or ``"campaign"`` (joint fit).
    psi_peak_Wb, psi_peak_sigma_Wb : float
        Psi at the highest current with this track [Wb] and the uncertainty the track leaves there.
    pinned : bool
        ``psi_peak_sigma_Wb < PINNED_REL |psi_peak_Wb|``.
    constraints : list of str
        The equations used (``"2 plateau(s)"``, ``"3 closure(s)"``, ``"end rest (weak)"``,
        ``"header R prior"``, ``"kappa prior"`` / ``"campaign kappa"``).
    header_R_ohm : float or None
        The header's coil_resistance_ohm.
    header_disagrees : bool
        The header R differs from the data's R0 by more than 2 combined sigmas.
    header_overruled : bool
        (property) The track is pinned and its R0 lies more than :data:`HEADER_OFF_SIGMAS` of its own sigmas
        from the header R, though within the header's prior (not ``header_disagrees``).
    closure_rms_Wb, closure_noise_Wb : float
        RMS residual of the closure equations with this track and what the noise explains [Wb]
        (NaN without closure equations).
    noise_scale : float
        ``sqrt(chi^2 / dof)`` of the data equations (>= 1 was applied to the covariance; NaN: no dof).
    why_not_pinned : str
        Plain English, empty when pinned.
    """

    label: str
    time_s: np.ndarray
    R_t_ohm: np.ndarray
    energy_J: np.ndarray
    R0_ohm: float
    R0_sigma_ohm: float
    R_end_ohm: float
    R_end_sigma_ohm: float
    kappa_per_J: float
    kappa_sigma_per_J: float
    kappa_source: str
    psi_peak_Wb: float
    psi_peak_sigma_Wb: float
    pinned: bool
    constraints: list[str]
    header_R_ohm: float | None
    header_disagrees: bool
    closure_rms_Wb: float
    closure_noise_Wb: float
    noise_scale: float
    why_not_pinned: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def header_off_sigmas(self) -> float | None:
        """How many of its own sigmas R at the start lies from the header R (None: no header R or no sigma)."""
        if self.header_R_ohm is None or not self.R0_sigma_ohm > 0:
            return None
        return abs(self.header_R_ohm - self.R0_ohm) / self.R0_sigma_ohm

    @property
    def header_overruled(self) -> bool:
        """The recording's own data overrule its header R: the track is pinned and R at the start lies more
        than :data:`HEADER_OFF_SIGMAS` of its own sigmas from the header's, though within the header's prior
        (else :attr:`header_disagrees` says so). The eq.-4 flux then wants the track, not the header R."""
        return bool(self.pinned and not self.header_disagrees and self.header_R_ohm is not None
                    and self.R0_sigma_ohm > 0
                    and abs(self.header_R_ohm - self.R0_ohm) > HEADER_OFF_SIGMAS * self.R0_sigma_ohm)

    def summary(self) -> dict:
        """JSON-able numbers (SI, NaN as None) and flags."""
        def num(v):
            return None if v is None or not math.isfinite(v) else float(v)
        return {"file": self.label, "R_start_ohm": num(self.R0_ohm), "R_start_sigma_ohm": num(self.R0_sigma_ohm),
                "R_end_ohm": num(self.R_end_ohm), "R_end_sigma_ohm": num(self.R_end_sigma_ohm),
                "kappa_per_J": num(self.kappa_per_J), "kappa_sigma_per_J": num(self.kappa_sigma_per_J),
                "kappa_source": self.kappa_source, "energy_J": num(float(self.energy_J[-1])),
                "psi_peak_sigma_Wb": num(self.psi_peak_sigma_Wb), "pinned": self.pinned,
                "constraints": list(self.constraints), "header_R_ohm": num(self.header_R_ohm),
                "header_disagrees": self.header_disagrees, "header_overruled": self.header_overruled,
                "closure_rms_Wb": num(self.closure_rms_Wb),
                "closure_noise_Wb": num(self.closure_noise_Wb), "why_not_pinned": self.why_not_pinned,
                "notes": list(self.notes)}


def track_of_fit(eq: Equations, theta: np.ndarray, cov: np.ndarray, noise_scale: float, kappa_source: str,
                 extra: list[str]) -> ResistanceTrack:
    """The track of one recording from its (R0, c) and their (scaled) covariance."""
    R0, c = float(theta[0]), float(theta[1])
    cov = model_error(cov, c, float(eq.cond.t[-1] - eq.cond.t[0]))
    E = eq.energy_J
    R_t = R0 + c * E
    gE = np.array([1.0, E[-1]])
    psi = eq.A - eq.B @ theta
    n, k = psi.size, eq.cond.k_smooth
    lo, hi = max(0, eq.peak - k), min(n, eq.peak + k + 1)
    psi_peak = float(np.mean(psi[lo:hi]))
    gp = np.mean(eq.B[lo:hi], axis=0)
    psi_sigma = math.sqrt(max(0.0, float(gp @ cov @ gp)))
    s0, sc = math.sqrt(max(cov[0, 0], 0.0)), math.sqrt(max(cov[1, 1], 0.0))
    kappa, kappa_sigma = c / R0, sc / R0
    counts = {kind: eq.kinds.count(kind) for kind in ("plateau", "closure", "end")}
    constraints = [f"{counts['plateau']} plateau(s)"] * bool(counts["plateau"]) + \
        [f"{counts['closure']} closure(s)"] * bool(counts["closure"]) + ["end rest (weak)"] * bool(counts["end"]) + \
        [f"{eq.R_prior_source} prior"] + extra
    cl = np.array([kd == "closure" for kd in eq.kinds], dtype=bool)
    cl_rms = cl_noise = math.nan
    if cl.any():
        cl_rms = float(np.sqrt(np.mean((eq.g[cl] @ theta - eq.y[cl]) ** 2)))
        cl_noise = float(np.sqrt(np.mean(eq.sigma[cl] ** 2)))
    pinned = bool(psi_sigma < PINNED_REL * abs(psi_peak))
    why = ""
    if not pinned:
        part0 = abs(gp[0]) * s0
        part1 = abs(gp[1]) * sc
        if part0 >= part1:
            src = f"rests on the {eq.R_prior_source} (+-{100 * eq.R_prior_sigma / eq.R_prior:.2g} %)" \
                if s0 > 0.5 * eq.R_prior_sigma else "is not pinned by the data"
            why = f"R at the start {src}"
        else:
            why = "the heating rate kappa is not pinned (no plateaus or closing cycles late enough to see it)"
        why = (f"Psi at the peak uncertain by {100 * psi_sigma / max(abs(psi_peak), 1e-300):.2g} % "
               f"(> {100 * PINNED_REL:.2g} %): {why}; data: {', '.join(constraints) or 'none'}")
    hdr = eq.rec.coil_resistance_ohm
    disagrees = bool(hdr is not None and abs(hdr - R0) > 2.0 * math.hypot(HEADER_SIGMA_REL * hdr, s0)
                     and s0 < 0.5 * HEADER_SIGMA_REL * hdr)
    notes = []
    if disagrees:
        notes.append(f"the header's coil_resistance_ohm {hdr:.4f} ohm disagrees with the data's R at the start "
                     f"{R0:.4f} +- {s0:.4f} ohm ({100 * (hdr / R0 - 1):+.2f} %; header uncertainty "
                     f"{100 * HEADER_SIGMA_REL:.2g} %): the data's value is used")
    if cl.any() and cl_rms > CLOSURE_FACTOR * cl_noise:
        notes.append(f"the loops do not close from cycle to cycle even with the best R track: closure residual "
                     f"{cl_rms * 1e3:.3g} mWb RMS against {cl_noise * 1e3:.3g} mWb from the noise")
    varE = float(gE @ cov @ gE)
    return ResistanceTrack(
        label=eq.rec.label(), time_s=eq.cond.t, R_t_ohm=R_t, energy_J=E, R0_ohm=R0, R0_sigma_ohm=s0,
        R_end_ohm=float(R_t[-1]), R_end_sigma_ohm=math.sqrt(max(varE, 0.0)), kappa_per_J=kappa,
        kappa_sigma_per_J=kappa_sigma, kappa_source=kappa_source, psi_peak_Wb=psi_peak,
        psi_peak_sigma_Wb=psi_sigma, pinned=pinned, constraints=constraints, header_R_ohm=hdr,
        header_disagrees=disagrees, closure_rms_Wb=cl_rms, closure_noise_Wb=cl_noise, noise_scale=noise_scale,
        why_not_pinned=why, notes=notes)


def own_fit(rec: Recording, R_ohm: float | None, kappa: float, kappa_sigma: float, header_sigma_rel: float,
            source: str = "given R"):
    """Equations and fit of one recording alone, the Joule energy iterated once with the fitted track; ``R_ohm``
    (+- ``header_sigma_rel``, named ``source``) the prior of R at the start, default the header's
    (:func:`~.resistance_equations.prepare`)."""
    cond, R_prior, R_sigma, source = prepare(rec, R_ohm, header_sigma_rel, source)
    R_t = np.full(cond.t.size, R_prior)
    for _ in range(2):
        eq = equations(rec, cond, R_t, R_prior, R_sigma, source)
        theta, cov, chi2, dof = fit_one(eq, kappa, kappa_sigma)
        R_t = theta[0] + theta[1] * eq.energy_J
    return eq, theta, cov, chi2, dof


def resistance_track(rec: Recording, R_ohm: float | None = None, *, kappa_per_J: float | None = None,
                     kappa_sigma_per_J: float | None = None,
                     header_sigma_rel: float = HEADER_SIGMA_REL) -> ResistanceTrack:
    """R(t) of one recording from its own voltage and current (model and equations: module docstring).

    Parameters
    ----------
    rec : Recording
        A recording with a ``voltage_V`` column.
    R_ohm : float, optional
        Prior of R at the start [ohm]; default the header's ``coil_resistance_ohm`` (neither: the data alone).
    kappa_per_J, kappa_sigma_per_J : float, optional
        A known heating rate ``alpha / C_th`` [1/J] and its 1-sigma (e.g. from :func:`campaign_resistance`);
        default ``0 +- KAPPA_PRIOR_PER_J`` (weak).
    header_sigma_rel : float
        Relative 1-sigma of the prior R [1].

    Returns
    -------
    ResistanceTrack

    Raises
    ------
    RecordingError
        No voltage; a zero current; no resistance in the header and none to estimate.
    """
    known = kappa_per_J is not None
    kappa = float(kappa_per_J) if known else 0.0
    ks = float(kappa_sigma_per_J) if kappa_sigma_per_J is not None else (0.0 if known else KAPPA_PRIOR_PER_J)
    ks = max(ks, 1e-12)
    return track_alone(own_fit(rec, R_ohm, kappa, ks, header_sigma_rel), known)


def track_alone(fit: tuple, kappa_given: bool = False) -> ResistanceTrack:
    """The track of one recording fitted alone (``fit``: what :func:`own_fit` returns), its covariance scaled
    by the residual noise where that is above 1."""
    eq, theta, cov, chi2, dof = fit
    ns = scale_of(chi2, dof)
    scale2 = max(1.0, ns * ns) if math.isfinite(ns) else 1.0
    return track_of_fit(eq, theta, cov * scale2, ns, "given" if kappa_given else "recording",
                        ["kappa given"] if kappa_given else ["kappa prior (weak)"])


def closure_problems(tracks: list[ResistanceTrack]) -> list[str]:
    """Recordings whose loops do not close from cycle to cycle even with their best R track.

    Parameters
    ----------
    tracks : list of ResistanceTrack

    Returns
    -------
    list of str
        One plain-English problem per recording whose closure residual (RMS over its closure
        equations) exceeds :data:`CLOSURE_FACTOR` times what the voltage and current noise explain.
    """
    out = []
    for tr in tracks:
        if math.isfinite(tr.closure_rms_Wb) and tr.closure_rms_Wb > CLOSURE_FACTOR * tr.closure_noise_Wb:
            out.append(f"{tr.label}: the loops do not close from cycle to cycle even with the best resistance "
                       f"track: closure residual {tr.closure_rms_Wb * 1e3:.3g} mWb RMS against "
                       f"{tr.closure_noise_Wb * 1e3:.3g} mWb that the noise explains (more than "
                       f"{CLOSURE_FACTOR:g}x): the data disagree with each other (a drifting offset or gain, "
                       "a moving armature, a changing coil)")
    return out
