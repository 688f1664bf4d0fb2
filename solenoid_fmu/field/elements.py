"""Element-level arithmetic of the FEM (quadratic triangles, 6 nodes): symmetric element matrices.

The element matrices of the magnetostatic tangent are symmetric; their 21 distinct entries (k <= l) are
summed over the quadrature points one point at a time with elementwise products, so the rounding is the
same on every CPU (no BLAS kernel, no einsum reduction order) and the matrix exactly symmetric.
"""

from __future__ import annotations

import numpy as np

__all__ = ["UPPER_K", "UPPER_L", "upper_pairs", "symmetric_matrices", "inv2"]

#: The 21 index pairs k <= l of a symmetric 6 x 6 element matrix, and each (k, l)'s place among them.
UPPER_K, UPPER_L = np.triu_indices(6)
_SYM_FULL = np.zeros((6, 6), dtype=np.intp)
_SYM_FULL[UPPER_K, UPPER_L] = _SYM_FULL[UPPER_L, UPPER_K] = np.arange(UPPER_K.size)


def upper_pairs(GG: np.ndarray) -> np.ndarray:
    """(nq, 21, nel) contiguous blocks of the k <= l entries of GG (6, 6, nel, nq)."""
    return np.ascontiguousarray(GG[UPPER_K, UPPER_L].transpose(2, 0, 1))


def symmetric_matrices(GGu: np.ndarray, a: np.ndarray, gG: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Secant and tangent element matrices (6, 6, nel) of the nonlinear magnetostatic problem:
    ``K_s[k, l] = sum_q a GG[k, l]`` and ``K = K_s + sum_q c gG[k] gG[l]`` with GGu from
    :func:`upper_pairs`, a and c (nel, nq) and gG (6, nel, nq)."""
    gq = np.ascontiguousarray(gG.transpose(2, 0, 1))  # (nq, 6, nel)
    gcq = gq * np.ascontiguousarray(c.T)[:, None, :]
    aq = np.ascontiguousarray(a.T)  # (nq, nel)
    Ks_u = GGu[0] * aq[0]
    Kn_u = gq[0][UPPER_K] * gcq[0][UPPER_L]
    for q in range(1, aq.shape[0]):
        Ks_u += GGu[q] * aq[q]
        Kn_u += gq[q][UPPER_K] * gcq[q][UPPER_L]
    return Ks_u[_SYM_FULL], (Ks_u + Kn_u)[_SYM_FULL]


def inv2(J: np.ndarray) -> np.ndarray:
    """Inverses of 2 x 2 matrices J (2, 2, n)."""
    det = J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]
    return np.array([[J[1, 1], -J[0, 1]], [-J[1, 0], J[0, 0]]]) / det
