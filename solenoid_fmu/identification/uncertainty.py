"""What the flux data identify: a linearized Bayesian analysis of B(H) (prior vs posterior).

The H range the data identify follows from :func:`B_uncertainty`; outside it the identified curve
keeps the start curve's shape.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "PRIOR_LN_CHI_STD",
    "FLUX_NOISE_FLOOR",
    "IDENTIFIED_SHRINK",
    "IDENTIFIED_B_STD",
    "B_uncertainty",
    "posterior_covariance",
    "identified_range",
]

#: Prior of the identifiability analysis: ln chi at each node known to +-0.3 (35 %) beforehand.
PRIOR_LN_CHI_STD = 0.3
#: Flux noise floor (relative to the peak) assumed for the uncertainty when the fit is better.
FLUX_NOISE_FLOOR = 1e-3
#: B counts as identified where the data shrink its prior uncertainty to this fraction or less
#: and its posterior 1-sigma is below IDENTIFIED_B_STD (relative).
IDENTIFIED_SHRINK = 0.25
IDENTIFIED_B_STD = 0.01


def B_uncertainty(model, theta, J_rel, sigma_rel, H) -> tuple[np.ndarray, np.ndarray]:
    """Relative 1-sigma uncertainty of B at field strengths H [A/m], before and after the data.

    Linearized Bayesian analysis: prior on ln chi at the nodes, independent with std
    :data:`PRIOR_LN_CHI_STD` (and on the tail slope); the flux data (Jacobian ``J_rel`` of the flux
    relative to the peak, noise ``sigma_rel``) give the posterior covariance
    (J^T J / sigma^2 + Lambda)^-1, mapped to B(H) by finite differences of the table.

    Returns
    -------
    prior_rel, posterior_rel : ndarray, shape (len(H),)
    """
    P = len(theta)
    Lam = _prior_precision(model, P)
    B0 = np.interp(H, *model.table(theta))
    G = np.empty((len(H), P))
    for p in range(P):
        e = np.zeros(P)
        e[p] = 1e-4
        G[:, p] = (np.interp(H, *model.table(theta + e)) - np.interp(H, *model.table(theta - e))) / 2e-4
    prior = np.linalg.inv(Lam)
    post = posterior_covariance(model, J_rel, sigma_rel)
    sd = [np.sqrt(np.maximum(np.einsum("hp,pq,hq->h", G, c, G), 0.0)) / B0 for c in (prior, post)]
    return sd[0], sd[1]


def _prior_precision(model, P: int, prior_std: float = PRIOR_LN_CHI_STD) -> np.ndarray:
    """The prior's precision in the parameters theta: ln chi at every node and the tail slope, independent,
    std ``prior_std`` (default :data:`PRIOR_LN_CHI_STD`; theta holds ln chi at the first node and the increments
    after it)."""
    m = len(model.H_nodes)
    A = np.zeros((m + 1, P))  # ln chi nodes and the tail slope as linear functions of theta
    A[:m, 0] = 1.0
    for j in range(1, m):
        A[j, 1 : j + 1] = 1.0
    A[m, m] = 1.0
    return A.T @ A / prior_std**2


def posterior_covariance(model, J_rel, sigma_rel, prior_std: float = PRIOR_LN_CHI_STD) -> np.ndarray:
    """Covariance of the parameters theta after the data: (J^T J / sigma^2 + Lambda)^-1 (:func:`B_uncertainty`),
    the prior's std on ln chi at every node ``prior_std``."""
    J_rel = np.asarray(J_rel, dtype=float)
    return np.linalg.inv(J_rel.T @ J_rel / sigma_rel**2 + _prior_precision(model, J_rel.shape[1], prior_std))


def identified_range(model, theta, J_rel, rms_rel, H_max) -> tuple[tuple[float, float], np.ndarray, np.ndarray]:
    """H range [A/m] the flux measurement identifies: the longest run of field strengths (up to the
    largest H the steel sees) where the data shrink the prior uncertainty of B to
    :data:`IDENTIFIED_SHRINK` or less and to :data:`IDENTIFIED_B_STD` (1 sigma, relative), with the
    flux noise max(fit RMS, noise floor)."""
    H = np.geomspace(model.H_nodes[0] / 5, max(H_max, model.H_nodes[0]), 80)
    prior, post = B_uncertainty(model, theta, J_rel, max(rms_rel, FLUX_NOISE_FLOOR), H)
    ok = (post < IDENTIFIED_SHRINK * prior) & (post < IDENTIFIED_B_STD)
    if not ok.any():
        return (0.0, 0.0), H, post
    best, run = (0, -1), None
    for k, flag in enumerate(ok):
        if flag and run is None:
            run = k
        if run is not None and (not flag or k == len(ok) - 1):
            end = k if flag else k - 1
            if end - run > best[1] - best[0]:
                best = (run, end)
            run = None
    return (float(H[best[0]]), float(H[best[1]])), H, post

