"""The FEM's data at one gap x (:class:`GapConfig`): quadrature on the morphed mesh, Jacobians, unit sources.

Built and cached by :meth:`solenoid_fmu.field.fem.Solver.config`; ``solver`` below is that
:class:`~solenoid_fmu.field.fem.Solver` (its mesh, dofs, sources and coil).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .elements import UPPER_K, UPPER_L, inv2, upper_pairs
from .material import NU_0

__all__ = ["GapConfig", "scatter_vector"]


class GapConfig:
    """Everything that depends on the gap x: quadrature data on the morphed mesh."""

    def __init__(self, solver, x_m: float):
        from skfem import Basis, ElementTriP2, MeshTri  # loaded on first solve: importing the field stays cheaper

        mm = solver.mesh
        self.x_m = x_m
        self.p = mm.points_at(x_m)
        basis = Basis(MeshTri(self.p, mm.t), ElementTriP2(), intorder=4)
        self.basis = basis
        self.dx = basis.dx  # (nel, nq) quadrature weight * |detJ|
        self.r = basis.mapping.F(basis.X)[0]  # (nel, nq) radius of each quadrature point
        self.G = np.stack([basis.basis[k][0].grad for k in range(6)], axis=0)  # (6, 2, nel, nq)
        self.phi = np.stack([np.asarray(basis.basis[k][0]) for k in range(6)], axis=0)  # (6, nel, nq)
        self.w_over_r = self.dx / self.r
        # products of basis gradients grad phi_k . grad phi_l, contracted once per gap (k <= l, per point)
        self.GGu = upper_pairs(np.einsum("kdeq,ldeq->kleq", self.G, self.G))  # (nq, 21, nel)
        # element Jacobians of the affine map and their x-derivative along the morph velocity
        t = basis.mesh.t  # skfem may reorder the vertices within each element: use its order
        p = self.p
        self.J = np.array(
            [[p[0, t[1]] - p[0, t[0]], p[0, t[2]] - p[0, t[0]]], [p[1, t[1]] - p[1, t[0]], p[1, t[2]] - p[1, t[0]]]]
        )  # (2, 2, nel)
        self.Jinv = inv2(self.J)
        lam = np.array([1 - basis.X[0] - basis.X[1], basis.X[0], basis.X[1]])  # (3, nq) barycentric
        self.lam = lam
        # unit sources: f_coil = int J_coil(i=1 A) phi_k, f_fixed = int J from ampere_turn regions
        self.f_coil = solver.assemble_source(self, solver.coil_density_per_A)
        self.f_fixed = solver.assemble_source(self, solver.fixed_density)
        coil = solver.coil_elements
        self.psi_weights = scatter_vector(
            solver, self.phi[:, coil] * self.dx[coil][None], coil
        ) * (2 * np.pi * solver.geometry.coil.turns / solver.coil_area)
        self._split_linear(solver)

    def _split_linear(self, solver) -> None:
        """Newton's data split by material. Steel elements (``solver.steel_idx``): their gradients, radii and
        weights, contiguous (the tangent is assembled from them at every Newton step). The other elements
        (air, coil, brass: nu = NU_0) have a constant stiffness, assembled once per gap: ``A_lin`` (CSR on the
        solver's pattern, before the Dirichlet rows are set; its product with u is their residual) and
        ``A_lin_abs`` (the same with |entries| of each element matrix: their part of the residual's rounding
        floor, sum_e |K_e| |u_e|)."""
        st = solver.steel_idx
        self.G_s = np.ascontiguousarray(self.G[:, :, st])
        self.GGu_s = np.ascontiguousarray(self.GGu[:, :, st])
        self.r_s = self.r[st]
        self.r2_s = self.r[st] ** 2
        self.w_over_r_s = self.w_over_r[st]
        self.vol_s = 2 * np.pi * self.dx[st] * self.r[st]  # [m^3] per steel quadrature point
        lin = np.flatnonzero(~solver.steel)
        GGu_l = self.GGu[:, :, lin]
        wl = self.w_over_r[lin]
        K_u = GGu_l[0] * wl[:, 0]  # (21, nel_lin): summed one quadrature point at a time, as elements.py does
        for q in range(1, wl.shape[1]):
            K_u += GGu_l[q] * wl[:, q]
        K_u *= NU_0
        full = np.zeros((6, 6, lin.size))
        full[UPPER_K, UPPER_L] = K_u
        full[UPPER_L, UPPER_K] = K_u
        scatter = solver.scatter_of(lin)
        n = solver.ndofs
        shape = (n, n)
        data = np.bincount(scatter, weights=full.ravel(), minlength=solver.nnz)
        data_abs = np.bincount(scatter, weights=np.abs(full).ravel(), minlength=solver.nnz)
        self.A_lin = sp.csr_matrix((data, solver.pattern_indices, solver.pattern_indptr), shape=shape)
        self.A_lin_abs = sp.csr_matrix((data_abs, solver.pattern_indices, solver.pattern_indptr), shape=shape)

    def steel_B(self, g: np.ndarray) -> np.ndarray:
        """|B| [T] at the steel's quadrature points from :meth:`~solenoid_fmu.field.fem.Solver.grad_steel`'s ``g``."""
        return np.sqrt(g[0] ** 2 + g[1] ** 2) / self.r_s

    def velocity_L(self, vr: np.ndarray, vz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """L = dJ J^-1 (2, 2, nel) and dr/dx at quadrature points for vertex velocities (vr, vz).

        With g = J^-T g_ref: dg/dx = -L^T g and d(det J)/dx = det J tr(L).
        """
        t = self.basis.mesh.t
        dJ = np.array(
            [[vr[t[1]] - vr[t[0]], vr[t[2]] - vr[t[0]]], [vz[t[1]] - vz[t[0]], vz[t[2]] - vz[t[0]]]]
        )
        L = np.einsum("ijn,jkn->ikn", dJ, self.Jinv)
        dr_q = np.einsum("vn,vq->nq", vr[t], self.lam)
        return L, dr_q


def scatter_vector(solver, local: np.ndarray, elements: np.ndarray) -> np.ndarray:
    """Sum element contributions local (6, nsel, nq) over quadrature points into a global vector."""
    vals = local.sum(axis=-1)  # (6, nsel)
    return np.bincount(solver.dofs[:, elements].ravel(), weights=vals.ravel(), minlength=solver.ndofs)
