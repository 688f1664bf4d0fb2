r"""Axisymmetric nonlinear magnetostatics of a solenoid: flux linkage Psi(i, x) and force F(i, x).

Formulation
-----------
The unknown is the flux function :math:`u = r A_\varphi` (second-order Lagrange elements on the
morphed triangle mesh of :mod:`solenoid_fmu.field.mesh`); :math:`2\pi u` is the flux through the circle
of radius r. With :math:`B = |\nabla u| / r`, the energy functional

.. math:: \Pi(u) = 2\pi \iint \left[ r\, w(B) - J u \right] \, dr\, dz, \qquad w(B)=\int_0^B H\,dB'

is strictly convex (the B(H) curve's slopes are bounded, :mod:`solenoid_fmu.field.material`), and its
minimizer solves :math:`-\nabla\cdot(\nu/r\,\nabla u) = J`. Newton's method on
:math:`\nu(B^2)` with an Armijo line search on :math:`\Pi` converges from any start; a previous
solution is a warm start. u = 0 on the axis and on the air box (sides listed in
``[domain] natural`` keep the natural condition instead). J = turns * i / coil area in the coil.

Outputs
-------
- ``psi_Wb`` = (turns / coil area) * integral over the coil of :math:`2\pi u` (paper eq. 4's Psi).
- ``force_coenergy_N``: :math:`F = -\partial W'/\partial x|_i` (paper eq. 3) computed exactly on
  the discrete level: the vertex positions are affine in x (mesh morph), so by the envelope
  theorem :math:`-dW'/dx = \partial\Pi/\partial x` at fixed nodal values, an element sum of the
  derivative of the energy density and of the Jacobians along the morph velocity. This is the
  force the maps carry: it is consistent with Psi (both derive from one discrete co-energy).
- ``force_stress_N``: Maxwell stress on the armature in its volume ("eggshell") form:
  the same virtual-work sum, but with a velocity field that is 1 on the armature, falls to 0 across
  the surrounding air and is 0 on every other body, so only air elements (linear, B^2/2mu0)
  contribute: :math:`F = -\int_{air} T : \nabla g\,dV`. Independent of the morph.

Sign: the force is positive when it pulls the armature towards the pole (closing the gap x).
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from ..errors import SolverError
from .current_sweep import sweep_gap
from .eggshell import EGGSHELL_M as EGGSHELL_M
from .eggshell import eggshell_weight
from .elements import symmetric_matrices
from .geometry import Geometry
from .linear_solver import SPDSolver
from .material import NU_0, BHCurve
from .mesh import MorphMesh, build_mesh
from .quadrature import GapConfig, scatter_vector
from .solution import Solution
from .threads import single_threaded

#: Gaps whose quadrature data a solver keeps (about 10 MB each at mesh size 2.0).
CONFIG_CACHE = 16

#: Newton settings (tolerances relative to the source norm / the solution norm). Converged means
#: |r| <= max(NEWTON_RTOL |f|, NEWTON_FLOOR_FACTOR eps | |K_s| |u| + |f| |) (2-norms over the free dofs): the
#: residual r = K_s(u) u - f (K_s the secant stiffness it is assembled from) cannot be computed more exactly than
#: eps (|K_s| |u| + |f|) per row, its rounding floor; the residual stagnates at ~0.15 x that floor (PS45, PARDISO
#: and SuperLU), so a target of 10 x the floor is reached whatever the CPU's rounding path.
NEWTON_RTOL = 1e-9
NEWTON_FLOOR_FACTOR = 10.0
NEWTON_MAXIT = 40
#: The line search's Armijo test on the energy allows an increase up to this many eps x (sum |r w dA| + |f| . |u|),
#: the rounding level of the computed energy (measured < 1 x): closer to the minimum the predicted decrease is
#: below it and comparing energies is noise (an approximate Armijo condition, Hager & Zhang 2005). The solution is
#: then within ~sqrt(64 eps) = 1e-7 in the energy norm, where the full Newton step converges quadratically.
NEWTON_ENERGY_ROUNDING = 64.0
#: A Newton stall is accepted as converged (with a logged note) when the relative residual has stopped
#: decreasing below this: the residual after an update shrunk to ``NEWTON_STALL_UPDATE`` of the solution norm
#: still misses the target, or the iteration limit is reached and the best iterate's residual is below it. At a
#: residual of 7e-6 Psi and F differ from the fully converged ones by 3e-8 and 4e-8 relative (PS45, i = 0.632 A,
#: x = 2.787 mm), far below the maps' 0.05 % interpolation target.
NEWTON_STALL_RTOL = 1e-5
NEWTON_STALL_UPDATE = 1e-12
#: Load steps of the retry after a failed Newton solve: the current is ramped in this many equal steps
#: from the neighbour's solution (when given) or from zero, each step warm-started from the one before.
RETRY_LOAD_STEPS = (4, 16)

log = logging.getLogger(__name__)


class _NewtonFailure(SolverError):
    """Newton did not converge at one point (the retry in :meth:`Solver.solve` may still recover it)."""


class Solver:
    """Nonlinear axisymmetric magnetostatic solver for one geometry, material and mesh.

    Parameters
    ----------
    geometry : Geometry
    material : BHCurve
        The steel's B(H) curve (all ``steel`` regions).
    mesh_size : float
        Mesh-size knob of :func:`solenoid_fmu.field.mesh.build_mesh` (1 = default accuracy).
    mesh : MorphMesh, optional
        A mesh built before (``mesh_size`` is then only recorded).
    linear_backend : str, optional
        "MKL PARDISO" or "SuperLU" for the Newton systems (default: the faster one installed).

    Notes
    -----
    Holds the mesh, the sparsity pattern and the per-position quadrature data (cached for the last
    position), so a sweep over currents at one x costs one Newton solve per current.
    """

    def __init__(self, geometry: Geometry, material: BHCurve, mesh_size: float = 1.0, mesh: MorphMesh = None,
                 linear_backend: str | None = None):
        from skfem import Basis, ElementTriP2, MeshTri  # loaded on first solve: importing the field stays cheaper

        self.geometry = geometry
        self.material = material
        self.mesh_size = mesh_size
        self.mesh = mesh if mesh is not None else build_mesh(geometry, mesh_size)
        mm = self.mesh
        basis0 = Basis(MeshTri(mm.p_ref, mm.t), ElementTriP2(), intorder=4)
        self.dofs = basis0.element_dofs  # (6, nel)
        self.ndofs = basis0.N
        self.nel = mm.n_triangles
        # materials per element
        names = mm.region_names
        steel_regions = [k for k, r in enumerate(geometry.regions) if r.material == "steel"]
        self.steel = np.isin(mm.region, steel_regions)
        self.steel_idx = np.flatnonzero(self.steel)
        self.dofs_s = np.ascontiguousarray(self.dofs[:, self.steel_idx])  # (6, steel elements)
        coil_k = names.index(geometry.coil.region)
        self.coil_elements = np.flatnonzero(mm.region == coil_k)
        self.coil_area = geometry.region(geometry.coil.region).area_m2
        dens = np.zeros(self.nel)
        dens[self.coil_elements] = geometry.coil.turns / self.coil_area
        self.coil_density_per_A = dens
        fixed = np.zeros(self.nel)
        for k, reg in enumerate(geometry.regions):
            if reg.ampere_turns:
                fixed[mm.region == k] = reg.ampere_turns / reg.area_m2
        self.fixed_density = fixed
        # Dirichlet dofs: the axis always; box sides unless natural
        d = geometry.domain
        tol = 1e-9

        def on_dirichlet(x):
            r, z = x
            hit = r < tol
            if "outer" not in d.natural:
                hit |= r > d.r_max_m - tol
            if "bottom" not in d.natural:
                hit |= z < d.z_min_m + tol
            if "top" not in d.natural:
                hit |= z > d.z_max_m - tol
            return hit

        facets = basis0.mesh.facets_satisfying(on_dirichlet, boundaries_only=True)
        self.dirichlet = basis0.get_dofs(facets).all()
        # the moving (armature) elements and the eggshell weight for the Maxwell-stress force
        self.moving_elements = np.isin(mm.region, [k for k, r in enumerate(geometry.regions) if r.moves])
        self._pattern(linear_backend)
        self._configs: dict[float, GapConfig] = {}  # the last config_cache gaps, oldest first
        #: Gaps whose quadrature data are kept (default :data:`CONFIG_CACHE`; a caller that returns to more
        #: gaps, like the identification's force points and their +-dx, raises it).
        self.config_cache = CONFIG_CACHE
        self.solves = 0
        #: Relative residual target of Newton; None: NEWTON_RTOL (callers that need less, e.g. the
        #: identification, raise it).
        self.rtol: float | None = None
        #: Whether a solve with forces also evaluates the Maxwell-stress force (NaN when not; callers that use
        #: only the co-energy force, e.g. the identification, turn it off: half of the forces' cost).
        self.stress_force = True

    # -- sparsity pattern and scatter --------------------------------------------------------
    def _pattern(self, linear_backend: str | None):
        n = self.ndofs
        rows = np.repeat(self.dofs[:, None, :], 6, axis=1)  # (6, 6, nel): row = dof k
        cols = np.repeat(self.dofs[None, :, :], 6, axis=0)
        key = rows.ravel().astype(np.int64) * n + cols.ravel()
        uniq, inv = np.unique(key, return_inverse=True)
        self._scatter = inv
        r = uniq // n
        c = uniq % n
        self._indices = c.astype(np.int32)
        self._indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=n))]).astype(np.int32)
        self.nnz = self._nnz = len(uniq)  # the stiffness pattern (CSR), public for GapConfig's constant part
        self.pattern_indices, self.pattern_indptr = self._indices, self._indptr
        isdir = np.zeros(n, dtype=bool)
        isdir[self.dirichlet] = True
        self._dir_mask = isdir[r] | isdir[c]
        self._dir_diag = np.flatnonzero(isdir[r] & (r == c))
        self.dirichlet_mask = isdir
        self.linear_solver = SPDSolver(self._indptr, self._indices, n, linear_backend)
        self._scatter_s = self.scatter_of(self.steel_idx)

    def scatter_of(self, elements: np.ndarray) -> np.ndarray:
        """Places in the CSR data of the (6, 6) element-matrix entries of ``elements``, raveled (k, l, element)."""
        return self._scatter.reshape(6, 6, self.nel)[:, :, elements].ravel()

    def assemble_source(self, cfg: GapConfig, density: np.ndarray) -> np.ndarray:
        """Load vector of a current density per element ``density`` [A/m^2] at the gap of ``cfg``."""
        sel = np.flatnonzero(density)
        if sel.size == 0:
            return np.zeros(self.ndofs)
        local = cfg.phi[:, sel] * (cfg.dx[sel] * density[sel, None])[None]
        return scatter_vector(self, local, sel)

    def config(self, x_m: float) -> GapConfig:
        """Quadrature data at gap ``x_m`` (cached for the last ``config_cache`` gaps asked for: the
        identification returns to the same strokes and force offsets at every evaluation)."""
        cfg = self._configs.pop(x_m, None)
        if cfg is None:
            cfg = GapConfig(self, x_m)
            while len(self._configs) >= self.config_cache:
                self._configs.pop(next(iter(self._configs)))
        self._configs[x_m] = cfg  # most recent last
        return cfg

    # -- material evaluation -----------------------------------------------------------------
    def _nu(self, b2: np.ndarray):
        nu = np.full_like(b2, NU_0)
        dnu = np.zeros_like(b2)
        s = self.steel
        nu[s], dnu[s] = self.material.nu_of_b2(b2[s])
        return nu, dnu

    def _energy_density(self, b2: np.ndarray) -> np.ndarray:
        w = b2 * (NU_0 / 2)
        s = self.steel
        w[s] = self.material.energy_density(np.sqrt(b2[s]))
        return w

    def grad(self, cfg: GapConfig, u: np.ndarray) -> np.ndarray:
        """Gradient (d/dr, d/dz) of the flux function ``u`` at the quadrature points of ``cfg``,
        shape (2, elements, points); |B| = |grad u| / r."""
        ue = u[self.dofs]  # (6, nel)
        return np.einsum("ke,kdeq->deq", ue, cfg.G)  # (2, nel, nq)

    def grad_steel(self, cfg: GapConfig, u: np.ndarray) -> np.ndarray:
        """:meth:`grad` at the steel elements only (``self.steel_idx``), shape (2, steel elements, points)."""
        return np.einsum("ke,kdeq->deq", u[self.dofs_s], cfg.G_s)

    def _energy(self, cfg: GapConfig, u: np.ndarray, f: np.ndarray, with_scale: bool = False):
        """The energy functional / 2 pi; with ``with_scale``, also sum |r w dA| + |f| . |u| (its rounding scale).
        Element by element (u . A_lin u / 2 sums terms that cancel: its rounding blinds the line search)."""
        g = self.grad(cfg, u)
        b2 = (g[0] ** 2 + g[1] ** 2) / cfg.r**2
        w = cfg.dx * cfg.r * self._energy_density(b2)
        e = float(np.sum(w) - f @ u)
        return (e, float(np.sum(np.abs(w)) + np.abs(f) @ np.abs(u))) if with_scale else e

    # -- Newton --------------------------------------------------------------------------------
    def solve(self, i_A: float, x_m: float, u0: np.ndarray | None = None, i0_A: float | None = None,
              forces: bool = True, guess: np.ndarray | None = None) -> Solution:
        """Solve one operating point (see :meth:`_solve`); BLAS and MKL run single-threaded here,
        which is 2-3x faster for these sizes than letting threads contend (and lets sweeps use
        one process per core).

        When Newton does not converge, the point is retried by load stepping in current
        (``RETRY_LOAD_STEPS``): from ``u0`` at ``i0_A`` [A] (the neighbour's solution and its current,
        when both are given), then from zero; each step is warm-started from the one before and damped
        by the Armijo line search. Only when every retry fails does it raise :class:`SolverError`,
        naming x [mm] and i [A]; a recovered point carries a ``note`` and is logged (INFO).
        With ``forces=False`` the two forces are not evaluated (NaN; about 8 % of a solve): for callers
        that need the flux or the field only. ``guess``: Newton's first iterate when it is not ``u0`` (a
        prediction, such as :meth:`sweep`'s extrapolation; the retry still steps from ``u0`` at ``i0_A``).
        """
        with single_threaded():
            try:
                return self._solve(i_A, x_m, u0 if guess is None else guess, forces)
            except _NewtonFailure as exc:
                first = exc
            return self._retry(i_A, x_m, u0, i0_A, first, forces)

    def sweep(self, x_m: float, i_A) -> dict:
        """Psi and F at one gap [m] for a list of currents [A], warm-started along the list: see
        :func:`~.current_sweep.sweep_gap`."""
        return sweep_gap(self, x_m, i_A)

    def _retry(self, i_A: float, x_m: float, u0, i0_A, first: _NewtonFailure, forces: bool = True) -> Solution:
        """Load stepping in current after the failed solve ``first`` (see :meth:`solve`)."""
        starts = [("the neighbour's solution", u0, float(i0_A))] if u0 is not None and i0_A is not None else []
        starts.append(("zero", None, 0.0))
        tried = []
        for label, u_start, i_start in starts:
            for n in RETRY_LOAD_STEPS:
                tried.append(f"{n} steps from {label} at {i_start:g} A")
                u, iterations = u_start, 0
                try:
                    for k in range(1, n + 1):
                        sol = self._solve(i_start + (i_A - i_start) * k / n, x_m, u, forces and k == n)
                        u, iterations = sol.u, iterations + sol.newton_iterations
                except _NewtonFailure:
                    continue
                sol.newton_iterations = iterations
                sol.note = (f"recovered by load stepping in current ({tried[-1]}) after: {first}"
                            + (f"; {sol.note}" if sol.note else ""))
                log.info("FEM point i = %g A, x = %g mm %s", i_A, x_m * 1e3, sol.note)
                return sol
        raise SolverError(f"{first}; the retries by load stepping in current ({'; '.join(tried)}) did not "
                          "converge either")

    def _solve(self, i_A: float, x_m: float, u0: np.ndarray | None = None, forces: bool = True) -> Solution:
        """Solve one operating point.

        Parameters
        ----------
        i_A : float
            Coil current [A].
        x_m : float
            Working air gap [m]; must lie in the geometry's stroke range.
        u0 : ndarray, optional
            Warm start (a previous solution's ``u``; any position).

        Raises
        ------
        SolverError
            When the input is invalid; ``_NewtonFailure`` (a SolverError) when Newton does not converge
            (with the residual history). A stall below ``NEWTON_STALL_RTOL`` is accepted (see there).
        """
        if not np.isfinite(i_A) or not np.isfinite(x_m):
            raise SolverError(f"current and gap must be finite, got i = {i_A!r} A, x = {x_m!r} m")
        st = self.geometry.stroke
        if not st.min_m - 1e-12 <= x_m <= st.max_m + 1e-12:
            raise SolverError(
                f"gap x = {x_m * 1e3:g} mm is outside the stroke {st.min_m * 1e3:g}..{st.max_m * 1e3:g} mm"
            )
        cfg = self.config(x_m)
        f = i_A * cfg.f_coil + cfg.f_fixed
        u = np.zeros(self.ndofs) if u0 is None else np.array(u0, dtype=float)
        u[self.dirichlet] = 0.0
        fnorm = np.linalg.norm(f[~self.dirichlet_mask])
        self.solves += 1
        if fnorm == 0.0:
            u[:] = 0.0
            it, history, floor, note = 0, [], 0.0, ""
        else:
            u, it, history, floor, note = self._newton(cfg, u, f, fnorm, i_A, x_m)
        psi = float(cfg.psi_weights @ u)
        w_co = -2 * np.pi * self._energy(cfg, u, f) if fnorm else 0.0
        dens = i_A * self.coil_density_per_A + self.fixed_density
        F_co = F_st = float("nan")
        if forces:
            F_co = self._force_virtual_work(cfg, u, dens, self.mesh.dr_dx, self.mesh.dz_dx)
            if self.stress_force:
                F_st = (self._force_virtual_work(cfg, u, dens, np.zeros(self.mesh.n_vertices),
                                                 eggshell_weight(self, cfg)) if self.moving_elements.any() else 0.0)
        return Solution(i_A, x_m, u, psi, F_co, F_st, w_co, it, history, residual_floor=floor, note=note)

    def _newton(self, cfg: GapConfig, u: np.ndarray, f: np.ndarray, fnorm: float, i_A: float, x_m: float):
        """Newton's iterations of :meth:`_solve` from ``u`` (a nonzero load ``f``, its free-dof norm ``fnorm``):
        the solution, the iterations, the relative residuals, the rounding floor and the note of a stall."""
        free = ~self.dirichlet_mask
        history = []
        it = 0
        note = ""
        floor = 0.0
        energy, scale = self._energy(cfg, u, f, with_scale=True)
        best, tiny_update = (np.inf, u, 0.0), False
        for it in range(1, NEWTON_MAXIT + 1):
            K, res, floor_rows = self._newton_system(cfg, u, f)
            rnorm = np.linalg.norm(res[free]) / fnorm
            floor = np.finfo(float).eps * np.linalg.norm(floor_rows[free]) / fnorm
            history.append(rnorm)
            if rnorm <= max(self.rtol or NEWTON_RTOL, NEWTON_FLOOR_FACTOR * floor):
                it -= 1
                break
            if tiny_update and rnorm < NEWTON_STALL_RTOL:  # judged on the residual after the tiny update
                it -= 1
                note = self._stall_note(i_A, x_m, rnorm, floor,
                                       f"after an update below {NEWTON_STALL_UPDATE:g} of the solution")
                break
            if rnorm < best[0]:
                best = (rnorm, u, floor)
            du = self.linear_solver.solve(K.data, K.indices, K.indptr, -res)
            # Armijo backtracking on the convex energy, blind to its rounding (NEWTON_ENERGY_ROUNDING)
            slope = res @ du
            step = 1.0
            for _ in range(30):
                trial = u + step * du
                e_trial, s_trial = self._energy(cfg, trial, f, with_scale=True)
                rounding = NEWTON_ENERGY_ROUNDING * np.finfo(float).eps * max(scale, s_trial)
                if e_trial <= energy + 1e-4 * step * slope + rounding or step < 1e-8:
                    break
                step *= 0.5
            u, energy, scale = trial, e_trial, s_trial
            tiny_update = step * np.linalg.norm(du) <= NEWTON_STALL_UPDATE * max(np.linalg.norm(u), 1e-30)
        else:
            if best[0] >= NEWTON_STALL_RTOL:
                raise _NewtonFailure(
                    f"Newton did not converge at i = {i_A:g} A, x = {x_m * 1e3:g} mm after {NEWTON_MAXIT} "
                    f"iterations; relative residuals: {', '.join(f'{h:.2e}' for h in history)}"
                )
            _, u, floor = best
            note = self._stall_note(i_A, x_m, best[0], floor, f"best of {NEWTON_MAXIT} iterations")
        return u, it, history, floor, note

    def _stall_note(self, i_A: float, x_m: float, rnorm: float, floor: float, why: str) -> str:
        """Log and return the note of a Newton stall accepted as converged (see ``NEWTON_STALL_RTOL``)."""
        target = max(self.rtol or NEWTON_RTOL, NEWTON_FLOOR_FACTOR * floor)
        note = (f"Newton stopped at relative residual {rnorm:.2e} ({why}; target {target:.2g}, rounding floor "
                f"{floor:.2g}); accepted as converged: below the stall tolerance {NEWTON_STALL_RTOL:g}")
        log.info("FEM point i = %g A, x = %g mm: %s", i_A, x_m * 1e3, note)
        return note

    def tangent(self, cfg: GapConfig, u: np.ndarray, f: np.ndarray):
        """Newton system at ``u`` for the load vector ``f``: the tangent stiffness (CSR, symmetric
        positive definite, Dirichlet rows set to the identity) and the residual (0 on Dirichlet dofs)."""
        return self._newton_system(cfg, u, f)[:2]

    def _newton_system(self, cfg: GapConfig, u: np.ndarray, f: np.ndarray):
        """:meth:`tangent` and, per dof, |K_s| |u| + |f|: the residual's rounding floor / eps (K_s the secant
        stiffness, whose product with u the residual's element sums add up)."""
        # the steel's element matrices at u; the other elements' constant part comes assembled (GapConfig)
        g = self.grad_steel(cfg, u)  # (2, steel elements, nq)
        r2 = cfg.r2_s
        nu, dnu = self.material.nu_of_b2((g[0] ** 2 + g[1] ** 2) / r2)
        gG = np.einsum("deq,kdeq->keq", g, cfg.G_s)  # (6, nel_s, nq): g . grad phi_k
        a = cfg.w_over_r_s * nu
        c = cfg.w_over_r_s * 2 * dnu / r2
        K_s, K = symmetric_matrices(cfg.GGu_s, a, gG, c)  # (6, 6, nel_s) secant (res_loc = K_s u_e) and tangent
        res_loc = np.einsum("keq,eq->ke", gG, a)
        dofs = self.dofs_s.ravel()
        res = cfg.A_lin @ u + np.bincount(dofs, weights=res_loc.ravel(), minlength=self.ndofs) - f
        floor_loc = np.einsum("kle,le->ke", np.abs(K_s), np.abs(u[self.dofs_s]))
        floor_rows = (cfg.A_lin_abs @ np.abs(u) + np.bincount(dofs, weights=floor_loc.ravel(), minlength=self.ndofs)
                      + np.abs(f))
        data = cfg.A_lin.data + np.bincount(self._scatter_s, weights=K.ravel(), minlength=self._nnz)
        data[self._dir_mask] = 0.0
        data[self._dir_diag] = 1.0
        res[self.dirichlet_mask] = 0.0
        A = sp.csr_matrix((data, self._indices, self._indptr), shape=(self.ndofs, self.ndofs))
        return A, res, floor_rows

    def _force_virtual_work(self, cfg, u, density, vr, vz) -> float:
        """dPi/dx at fixed nodal values for vertex velocity (vr, vz): the force closing the gap [N].

        ``density`` is the current density per element [A/m^2] of this solve.
        """
        L, dr_q = cfg.velocity_L(vr, vz)
        g = self.grad(cfg, u)
        r = cfg.r
        b2 = (g[0] ** 2 + g[1] ** 2) / r**2
        nu, _ = self._nu(b2)
        w = self._energy_density(b2)
        trL = L[0, 0] + L[1, 1]  # (nel,)
        dg = -np.einsum("jie,jeq->ieq", L, g)  # -L^T g
        db2 = 2 * (g[0] * dg[0] + g[1] * dg[1]) / r**2 - 2 * b2 * dr_q / r
        u_q = np.einsum("ke,keq->eq", u[self.dofs], cfg.phi)
        integrand = trL[:, None] * (r * w - density[:, None] * u_q) + dr_q * w + r * nu / 2 * db2
        return float(2 * np.pi * np.sum(cfg.dx * integrand))


# -- module-level conveniences -------------------------------------------------------------------
_SOLVERS: dict = {}


def get_solver(geometry: Geometry, material: BHCurve, mesh_size: float = 1.0) -> Solver:
    """A cached :class:`Solver` for (geometry, material, mesh_size) in this process."""
    key = (id(geometry), geometry.sha256, id(material), material.sha256, float(mesh_size))
    if key not in _SOLVERS:
        if len(_SOLVERS) > 4:
            _SOLVERS.clear()
        _SOLVERS[key] = Solver(geometry, material, mesh_size)
    return _SOLVERS[key]


def solve_point(geometry: Geometry, material: BHCurve, i_A: float, x_m: float, mesh_size: float = 1.0) -> Solution:
    """Solve one operating point (current ``i_A`` [A], gap ``x_m`` [m]) with a cached solver."""
    return get_solver(geometry, material, mesh_size).solve(i_A, x_m)


def sweep_currents(geometry: Geometry, material: BHCurve, x_m: float, i_A, mesh_size: float = 1.0) -> dict:
    """Psi and F at one gap for a list of currents with a cached solver: see :meth:`Solver.sweep`."""
    return get_solver(geometry, material, mesh_size).sweep(x_m, i_A)


__all__ = ["Solver", "Solution", "solve_point", "sweep_currents", "get_solver"]
