"""The linear equations of a recording's resistance track and their weighted least squares.

The model and the equations (plateaus, cycle closures, the end rest, the priors) are described in
:mod:`solenoid_fmu.measure.resistance`, which builds the tracks from them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import RecordingError
from .branches import branch_on_grid, split_branches
from .conditioning import Conditioned, condition, noise_std
from .format import Recording

__all__ = ["TAU_MODEL_S", "NOISE_FLOOR_REL", "NO_HEADER_SIGMA_REL", "adc_noise",
           "PLATEAU_PARTS", "MIN_BRANCH", "PEAK_TOL", "Equations", "cumtrapz", "equations", "prepare",
           "start_R", "solve_wls", "data_block", "fit_one", "scale_of", "model_error"]

#: Shortest thermal time constant the adiabatic model is meant for [s] (sets its model error).
TAU_MODEL_S = 60.0
PLATEAU_PARTS = 4  # equations per plateau
MIN_BRANCH = 50  # samples a branch needs for closure (coarser ones interpolate the loop too roughly)
PEAK_TOL = 0.003  # peaks within 0.3 % (or 4 sigma of the current noise) count as the same height
#: Floor of the per-sample voltage noise, relative to the recording's largest |U|: a 24-bit ADC's step.
NOISE_FLOOR_REL = 2.0 ** -24
#: Relative 1-sigma of the prior of R at the start where the header has no coil_resistance_ohm (:func:`prepare`).
NO_HEADER_SIGMA_REL = 0.1


@dataclass
class Equations:
    """Linear equations ``g0 R0 + g1 c = y`` (+- sigma) of one recording, and what evaluates the track."""

    rec: Recording
    cond: Conditioned
    y: np.ndarray
    g: np.ndarray          # (m, 2)
    sigma: np.ndarray
    kinds: list[str]       # per equation: "plateau", "closure", "end"
    energy_J: np.ndarray
    B: np.ndarray          # (n, 2): B0, B1 per sample
    A: np.ndarray          # (n,)
    peak: int
    R_prior: float
    R_prior_sigma: float
    R_ref: float           # c = kappa R_ref
    R_prior_source: str = "header"  # what R_prior came from (:func:`prepare`)


def adc_noise(u: np.ndarray) -> float:
    """Floor of a channel's per-sample noise [V]: its quantization (the smallest step between samples over
    sqrt 12: a noise below the ADC's step reads as 0 in second differences), at least :data:`NOISE_FLOOR_REL`
    of its largest magnitude (the finest DAQ's resolution; unquantized clean data)."""
    steps = np.abs(np.diff(u))
    steps = steps[steps > 0]
    q = float(np.min(steps)) / math.sqrt(12.0) if steps.size else 0.0
    return max(q, NOISE_FLOOR_REL * float(np.max(np.abs(u))), 1e-300)


def cumtrapz(y: np.ndarray, t: np.ndarray) -> np.ndarray:
    out = np.zeros_like(y, dtype=float)
    out[1:] = np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))
    return out


def equations(rec: Recording, cond: Conditioned, R_t: np.ndarray, R_prior: float,
              R_prior_sigma: float, R_prior_source: str = "header") -> Equations:
    """All data equations of a recording, with the Joule energy from the current track ``R_t``."""
    t, uc, ic = cond.t, cond.uc, cond.ic
    E = cumtrapz(R_t * ic * ic, t)
    A = cumtrapz(uc, t)
    B = np.column_stack([cumtrapz(ic, t), cumtrapz(E * ic, t)])
    R_nom = float(np.median(R_t))
    sig_u = math.hypot(noise_std(rec.voltage_V), R_nom * cond.sigma_i)  # per sample [V]
    # noise below the ADC's step reads as 0 (flat second differences): floor it at the finest DAQ's resolution
    sig_u = max(sig_u, adc_noise(rec.voltage_V))
    ys, gs, ss, kinds = [], [], [], []

    def add(w: np.ndarray, idx: np.ndarray, sigma: float, kind: str):
        """Equation sum(w * Psi[idx]) = 0."""
        ys.append(float(w @ A[idx]))
        gs.append(w @ B[idx])
        ss.append(sigma)
        kinds.append(kind)

    # (a) plateaus: Psi at the end of each settled run equals Psi at its start
    mask = cond.plateau_mask()
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(np.int8), [0]))))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        cuts = np.linspace(a, b - 1, min(PLATEAU_PARTS, (b - a) // 8) + 1).round().astype(int)
        for lo, hi in zip(cuts[:-1], cuts[1:], strict=True):  # parts: R changes along a long hold
            add(np.array([1.0, -1.0]), np.array([hi, lo]), sig_u * cond.dt * math.sqrt(hi - lo), "plateau")
    # (b) closure of consecutive cycles with the same peak
    i_s = cond.i_s - cond.current_offset_A
    branches = split_branches(ic, i_s, np.zeros_like(ic), cond.thr, cond.k_smooth)
    asc, desc = branches[::2], branches[1::2]
    for k in range(len(desc) - 1):
        p0, p1 = desc[k].peak_A, desc[k + 1].peak_A
        if abs(p0 - p1) > max(PEAK_TOL * max(p0, p1), 4.0 * cond.sigma_i):
            continue
        grid = np.linspace(0.1, 0.9, 17) * min(p0, p1)
        pairs = [(desc[k], desc[k + 1])] + ([(asc[k], asc[k + 1])] if k >= 1 else [])
        for b0, b1 in pairs:
            if min(b0.stop - b0.start, b1.stop - b1.start) < MIN_BRANCH:
                continue
            rows = []
            for arr in (A, B[:, 0], B[:, 1]):
                d = branch_on_grid(ic[b0.start:b0.stop], arr[b0.start:b0.stop], grid) - \
                    branch_on_grid(ic[b1.start:b1.stop], arr[b1.start:b1.stop], grid)
                rows.append(d)
            ok = np.all(np.isfinite(np.vstack(rows)), axis=0)
            if ok.sum() < 5:
                continue
            n_between = 0.5 * ((b1.start + b1.stop) - (b0.start + b0.stop))
            # noise: the voltage noise integrated between the branches, and the current noise seen
            # through the branch slope dPsi/di, averaged over each branch's samples
            br = A[b0.start:b0.stop] - R_nom * B[b0.start:b0.stop, 0]
            slope = float(np.ptp(br)) / max(float(np.ptp(ic[b0.start:b0.stop])), 1e-12)
            n_br = max(1.0, 0.5 * ((b0.stop - b0.start) + (b1.stop - b1.start)))
            ys.append(float(np.mean(rows[0][ok])))
            gs.append(np.array([np.mean(rows[1][ok]), np.mean(rows[2][ok])]))
            ss.append(math.sqrt((sig_u * cond.dt) ** 2 * max(n_between, 1.0)
                                + 2.0 * (cond.sigma_i * slope) ** 2 / n_br + (slope * (p0 - p1)) ** 2))
            kinds.append("closure")
    # (c) end rest of a single-cycle recording: Psi_end - Psi_0 = remanence, small
    peak = int(np.argmax(i_s))
    if len(desc) == 1 and cond.head is not None and cond.tail is not None:
        n = t.size
        psi_hdr = A - B[:, 0] * R_prior
        lo, hi = max(0, peak - cond.k_smooth), min(n, peak + cond.k_smooth + 1)
        width = np.nanmax(np.abs(branch_on_grid(ic[desc[0].start:desc[0].stop], psi_hdr[desc[0].start:desc[0].stop],
                                                np.linspace(0.05, 0.95, 19) * desc[0].peak_A)
                                 - branch_on_grid(ic[asc[0].start:asc[0].stop], psi_hdr[asc[0].start:asc[0].stop],
                                                  np.linspace(0.05, 0.95, 19) * asc[0].peak_A)))
        sigma_end = max(float(width) if math.isfinite(width) else 0.0, 0.01 * abs(float(np.mean(psi_hdr[lo:hi]))))
        add(np.array([1.0, -1.0]), np.array([n - 1, 0]), sigma_end, "end")
    return Equations(rec=rec, cond=cond, y=np.array(ys), g=np.array(gs).reshape(-1, 2), sigma=np.array(ss),
                      kinds=kinds, energy_J=E, B=B, A=A, peak=peak, R_prior=R_prior, R_prior_sigma=R_prior_sigma,
                     R_ref=R_nom, R_prior_source=R_prior_source)


def prepare(rec: Recording, R_ohm: float | None, header_sigma_rel: float,
            source: str = "given R") -> tuple[Conditioned, float, float, str]:
    """The conditioned recording, the prior of R at the start [ohm], its 1-sigma [ohm] and what it came from
    (``Equations.R_prior_source``): ``R_ohm`` (``source``), else
    the header's ``coil_resistance_ohm`` (each +- ``header_sigma_rel``), else (recordings.md: the header key is
    optional) :func:`start_R`'s estimate from the recording's own plateaus or mean U/i, +-
    :data:`NO_HEADER_SIGMA_REL`: loose, so that the data decide where they pin R, and R0 stays defined (and
    its track reported not pinned) where they do not."""
    cond = condition(rec)
    R_prior = R_ohm if R_ohm is not None else rec.coil_resistance_ohm
    if R_prior is None:
        R_prior = start_R(rec, cond)
        return cond, R_prior, NO_HEADER_SIGMA_REL * R_prior, "rough R from the recording's mean U/i (no header R)"
    if not (math.isfinite(R_prior) and R_prior > 0):
        raise RecordingError(rec.label(), [f"resistance must be > 0 ohm, got {R_prior!r}"])
    return cond, R_prior, header_sigma_rel * R_prior, "header R" if R_ohm is None else source


def start_R(rec: Recording, cond: Conditioned) -> float:
    """A rough R [ohm] from the recording alone: the mean U/i over its current plateaus, else over all of it
    (the flux back at its start value at the end; off by the remanence)."""
    mask = cond.plateau_mask()
    sel = mask if mask.any() else slice(None)
    R = float(np.sum(cond.uc[sel] * cond.ic[sel]) / np.sum(cond.ic[sel] ** 2)) if mask.any() else \
        float(np.trapezoid(cond.uc, cond.t) / np.trapezoid(cond.ic, cond.t))
    if not (math.isfinite(R) and R > 0):
        raise RecordingError(rec.label(), ["no coil resistance: no header coil_resistance_ohm, and neither plateaus "
                                           "nor a closed excitation to estimate it from"])
    return R


def solve_wls(blocks: list[tuple[np.ndarray, np.ndarray]], n_par: int) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least squares of stacked (whitened design, whitened rhs) blocks: estimate and (JtJ)^-1.

    By the SVD of the whitened design itself, not of JtJ: near-noise-free data weigh their equations ~1e9
    against the priors, and JtJ's squared condition would drop the priors' directions as numerically zero."""
    J = np.vstack([b[0] for b in blocks]).reshape(-1, n_par)
    r = np.concatenate([b[1] for b in blocks])
    U, sv, Vt = np.linalg.svd(J, full_matrices=False)
    keep = sv > sv[0] * max(J.shape) * np.finfo(float).eps if sv.size else sv > 0
    inv = np.where(keep, 1.0 / np.where(keep, sv, 1.0), 0.0)
    theta = Vt.T @ (inv * (U.T @ r))
    return theta, (Vt.T * inv ** 2) @ Vt


def data_block(eq: Equations, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    sig = eq.sigma * scale
    return eq.g / sig[:, None], eq.y / sig


def fit_one(eq: Equations, kappa: float, kappa_sigma: float) -> tuple[np.ndarray, np.ndarray, float, int]:
    """(R0, c), unscaled covariance, chi^2 and dof of the data equations; kappa prior as ``c = kappa R_ref``."""
    blocks = [data_block(eq)]
    blocks.append((np.array([[1.0, 0.0]]) / eq.R_prior_sigma, np.array([eq.R_prior / eq.R_prior_sigma])))
    ks = kappa_sigma * eq.R_ref
    blocks.append((np.array([[0.0, 1.0]]) / ks, np.array([kappa * eq.R_ref / ks])))
    theta, cov = solve_wls(blocks, 2)
    res = (eq.g @ theta - eq.y) / eq.sigma
    dof = eq.y.size - (np.linalg.matrix_rank(eq.g) if eq.y.size else 0)
    return theta, cov, float(res @ res), int(dof)


def scale_of(chi2: float, dof: int) -> float:
    """Noise scale ``sqrt(chi^2 / dof)`` (NaN without dof)."""
    return math.sqrt(chi2 / dof) if dof > 0 else math.nan


def model_error(cov: np.ndarray, c: float, duration_s: float) -> np.ndarray:
    """``cov`` plus the adiabatic model's error: ``c`` uncertain by ``duration / (2 TAU_MODEL_S)`` (Newton
    cooling, neglected, bends R(t) by about that fraction of the heating), moving R0 along the direction the
    data leave free (the regression of R0 on c), so that what the data pin stays pinned."""
    m2 = (abs(c) * duration_s / (2.0 * TAU_MODEL_S)) ** 2
    v = np.array([cov[0, 1] / cov[1, 1] if cov[1, 1] > 0 else 0.0, 1.0])
    return cov + m2 * np.outer(v, v)
