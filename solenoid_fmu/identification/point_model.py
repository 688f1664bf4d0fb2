r"""The FEM side of the campaign identification: flux linkage and force at any set of operating
points (i, x) for a B(H) parameter vector, and their Jacobians, with every solve counted.

Flux points: Psi(i, x) by warm-started Newton (one sweep over the currents of each stroke) and
d Psi / d theta by the adjoint (one linear solve per point, as :class:`~.flux_model.FluxModel`).

Force points: F(i, x) is the solver's co-energy force (paper eq. 3, the exact x-derivative of the
discrete co-energy). Its sensitivity uses the envelope theorem twice: the co-energy
W'(i, x; theta) = -min_u Pi(u; theta) has dW'/dtheta = -int dw/dtheta dV at the solution (no
solve), and F = dW'/dx, so dF/dtheta = d/dx (dW'/dtheta), taken as a one-sided difference over
:data:`FORCE_FD_DX_M` (one warm-started solve per force point; the other side is the point's own
solution). A Gauss-Newton step tolerates the O(dx) error of that difference (~0.3 %); the residual
itself is the exact force.

Units: SI (i in A, x in m, Psi in Wb, F in N).
"""

from __future__ import annotations

import numpy as np

from ..field import Solver, single_threaded
from .point_pool import WorkerPool, split_by_stroke

__all__ = ["PointModel", "FORCE_FD_DX_M", "NEWTON_RTOL_IDENTIFY", "NEWTON_RTOL_FORCE_SENSITIVITY"]

#: Newton's relative residual target of the values here: Psi and F converge to ~2e-7 relative or better, four
#: orders below the measurements' uncertainty (0.2 %). Measured on PS45 (16 points, 0.25-2 A, 0.5-3 mm, warm-started
#: from another curve's solutions as the fit's steps are): values within 1.8e-7 (Psi) and 2.7e-7 (F) of those at
#: 1e-7, the flux Jacobian within 7e-7 of its largest entry; 14 % fewer Newton steps. In the identification the
#: last Newton step took a median residual of 5e-6 down to 1e-11 (VacoferS2 #16 of the tests): at 1e-7 half the
#: solves took it only to pass the target. (1e-7 until stop 53; the maps use the solver's 1e-9.)
NEWTON_RTOL_IDENTIFY = 1e-5
#: Newton's target for the two solutions of a force point's sensitivity (the point's own, polished from the
#: values' solution, and the one a step dx away): their difference over dx = 2 um amplifies a solution's error
#: ~1000-fold. At 1e-5 for both the force Jacobian moved by 0.26 % of its largest entry (1.4 % at 1e-4), as much
#: as the difference's truncation error (:data:`FORCE_FD_DX_M`); at 1e-7 it is the same as before.
NEWTON_RTOL_FORCE_SENSITIVITY = 1e-7
#: Step [m] of the one-sided difference in x of dW'/dtheta (force sensitivities), towards the larger gap
#: (the smaller one at the stroke's end). Its truncation error grows linearly with the step: against central
#: differences in the curve parameters 0.01-0.04 % at 1-2.5 mm and 0.24 % at 0.5 mm, 0.3 A (2.4 % at 20 um);
#: rounding stays below that down to 0.5 um (values converged to 1e-7). One solve per force point: the
#: central difference over +-20 um it replaces took two, 30 % of an identification's time.
FORCE_FD_DX_M = 2e-6
#: Flux densities on which the Jacobian tabulates the curve sensitivities d nu / d theta and d w / d theta
#: (:class:`_GridTable`), from 0 to the largest B of the points: 0.25 mT apart at 2 T (against 32768 points the
#: Jacobian differs by < 5e-4 of its largest entry per row at 2048).
GRID_POINTS = 8192


class PointModel:
    """Psi and F at operating points for parameters theta (see the module docstring).

    Parameters
    ----------
    geometry : Geometry
    points : sequence of (kind, i_A, x_m)
        ``kind`` is ``"psi"`` or ``"force"``.
    curve_fn : callable
        theta -> BHCurve (switchable between parameterizations; setting it clears the cache).
    mesh_size : float
    start_curve : BHCurve
        Any curve, to build the solver.
    workers : int
        More than 1: the points are solved in that many worker processes, whole strokes each
        (:mod:`.point_pool`, :mod:`.point_worker`; fewer where there are fewer strokes), with the same
        numbers as in this process. :meth:`close` stops them.
    """

    def __init__(self, geometry, points, curve_fn, mesh_size: float, start_curve, workers: int = 1):
        self.solver = Solver(geometry, start_curve, mesh_size)
        self.solver.rtol = NEWTON_RTOL_IDENTIFY
        self.solver.stress_force = False  # the fit uses the co-energy force (eq. 3) only
        self.kind = np.array([p[0] for p in points])
        self.i_A = np.array([float(p[1]) for p in points])
        self.x_m = np.array([float(p[2]) for p in points])
        if not set(self.kind) <= {"psi", "force"}:
            raise ValueError(f"point kinds must be 'psi' or 'force', got {sorted(set(self.kind))}")
        # evaluation order: by stroke, then current (warm starts along each stroke); at the same (i, x) the force
        # point first: a flux point there takes its solution (the force solve has the flux too)
        self.order = np.lexsort((self.kind == "psi", self.i_A, self.x_m))
        # every gap an evaluation and a Jacobian visit keeps its quadrature data (each force point adds its
        # +-dx: with the default 16 the demo campaign rebuilt them 420 times, 9 of its 125 s)
        lo_x, hi_x = geometry.stroke.min_m, geometry.stroke.max_m
        gaps = set(self.x_m.tolist()) | {_fd_gap(float(x), lo_x, hi_x) for x in self.x_m[self.kind == "force"]}
        self.solver.config_cache = max(self.solver.config_cache, len(gaps) + 1)
        self.u = [None] * len(points)
        self._version = 0
        self.curve_fn = curve_fn
        self.solves = 0
        self.newton_steps = 0
        self.adjoint_solves = 0
        self.evaluations = 0
        self.first_eval_steps = 0
        self._cache: tuple = (None, None)
        self.pool = None
        if workers > 1:
            groups = split_by_stroke(self.x_m, np.where(self.kind == "force", 2.0, 1.0), workers)
            if len(groups) > 1:
                pts = [(str(k), float(i), float(x)) for k, i, x in zip(self.kind, self.i_A, self.x_m, strict=True)]
                self.pool = WorkerPool(geometry, pts, mesh_size, start_curve, groups)

    def close(self) -> None:
        """Stop the worker processes, if any (the model still answers :meth:`steel_H` afterwards)."""
        if self.pool is not None:
            self.pool.close()
            self.pool = None

    def _ask(self, msg) -> list:
        """``msg`` to the workers; per worker (point indices, result); their solves counted here."""
        out = []
        for g, (result, counters) in zip(self.pool.groups, self.pool.ask_all(msg), strict=True):
            self.solves += counters[0]
            self.newton_steps += counters[1]
            self.adjoint_solves += counters[2]
            out.append((g, result))
        return out

    @property
    def curve_fn(self):
        return self._curve_fn

    @curve_fn.setter
    def curve_fn(self, fn):
        self._curve_fn = fn
        self._version += 1

    @property
    def n(self) -> int:
        return len(self.i_A)

    def _solve_all(self, theta) -> np.ndarray:
        if self.pool is not None:
            out = np.empty(self.n)
            steps0 = self.newton_steps
            for g, vals in self._ask(("values", self.curve_fn(theta))):
                out[g] = vals
            if self.evaluations == 0:
                self.first_eval_steps = self.newton_steps - steps0
            self.evaluations += 1
            return out
        s = self.solver
        s.material = self.curve_fn(theta)
        out = np.empty(self.n)
        steps = 0
        prev_x, u_prev, i_prev, sol = None, None, None, None
        for k in self.order:
            x, i = self.x_m[k], self.i_A[k]
            if x == prev_x and i == i_prev and self.kind[k] == "psi":  # the force point's solution has it
                out[k] = sol.psi_Wb
                self.u[k] = sol.u
                continue
            if x != prev_x:
                u_prev, i_prev = None, None
            start = self.u[k] if self.u[k] is not None else u_prev
            sol = s.solve(float(i), float(x), u0=start, i0_A=i_prev if start is u_prev else None,
                          forces=self.kind[k] == "force")
            self.solves += 1
            steps += max(sol.newton_iterations, 1)
            out[k] = sol.psi_Wb if self.kind[k] == "psi" else sol.force_coenergy_N
            self.u[k] = sol.u
            prev_x, u_prev, i_prev = x, sol.u, float(i)
        if self.evaluations == 0:
            self.first_eval_steps = steps
        self.evaluations += 1
        self.newton_steps += steps
        return out

    def values(self, theta) -> np.ndarray:
        """Psi [Wb] at ``psi`` points and F [N] at ``force`` points (cached for the last theta)."""
        theta = np.asarray(theta, dtype=float)
        key = (self._version, theta.tobytes())
        if self._cache[0] != key:
            self._cache = (key, self._solve_all(theta))
        return self._cache[1].copy()

    @property
    def equivalent_evaluations(self) -> float:
        """Newton steps plus adjoint solves in units of the first evaluation's Newton steps."""
        return (self.newton_steps + self.adjoint_solves) / max(self.first_eval_steps, 1)

    def _perturbed(self, theta, h):
        P = len(theta)
        pairs = []
        for p in range(P):
            e = np.zeros(P)
            e[p] = h
            pairs.append((self.curve_fn(theta + e), self.curve_fn(theta - e)))
        return pairs

    def _B_steel(self, cfg, u):
        """|B| [T] and volume [m^3] at the steel's quadrature points of solution u."""
        return cfg.steel_B(self.solver.grad_steel(cfg, u)), cfg.vol_s

    def point_fields(self) -> tuple[dict, list]:
        """What the Jacobian needs of each point's solution at the last evaluated curve, by point index:
        flux points ``{k: (|B| [T], adjoint weights)}`` at the steel's quadrature points, force points
        ``[(k, dx [m], (|B|, volumes) at x, (|B|, volumes) at x + dx)]`` (one solve each)."""
        s = self.solver
        with single_threaded():
            # flux points: adjoint (K_t lambda = psi weights), dPsi = -int grad(lambda).grad(u) dnu/r
            flux = {}
            for k in self.order:
                if self.kind[k] != "psi":
                    continue
                cfg = s.config(float(self.x_m[k]))
                u = self.u[k]
                w = cfg.psi_weights.copy()
                w[s.dirichlet_mask] = 0.0
                K, _ = s.tangent(cfg, u, float(self.i_A[k]) * cfg.f_coil + cfg.f_fixed)
                lam = s.linear_solver.solve(K.data, K.indices, K.indptr, w)
                self.adjoint_solves += 1
                g = s.grad_steel(cfg, u)
                gl = s.grad_steel(cfg, lam)
                b2 = (g[0] ** 2 + g[1] ** 2) / cfg.r2_s
                flux[int(k)] = (np.sqrt(b2), (g[0] * gl[0] + g[1] * gl[1]) * cfg.w_over_r_s)
            # force points: the steel's field at the point's own solution, polished to the sensitivity's target
            # (mostly by one Newton step or none), and one solve a step away warm-started from it
            lo_x, hi_x = s.geometry.stroke.min_m, s.geometry.stroke.max_m
            force = []
            s.rtol = NEWTON_RTOL_FORCE_SENSITIVITY
            try:
                for k in self.order:
                    if self.kind[k] != "force":
                        continue
                    x0 = float(self.x_m[k])
                    x = _fd_gap(x0, lo_x, hi_x)
                    if x == x0:
                        continue
                    own = s.solve(float(self.i_A[k]), x0, u0=self.u[k], forces=False)
                    sol = s.solve(float(self.i_A[k]), x, u0=own.u, forces=False)
                    self.u[k] = own.u
                    self.solves += 2
                    self.newton_steps += own.newton_iterations + max(sol.newton_iterations, 1)
                    force.append((int(k), x - x0, self._B_steel(s.config(x0), own.u),
                                  self._B_steel(s.config(x), sol.u)))
            finally:
                s.rtol = NEWTON_RTOL_IDENTIFY
        return flux, force

    def jacobian(self, theta, h: float = 1e-4) -> np.ndarray:
        """d value / d theta, shape (points, parameters) [Wb or N per parameter unit].

        Flux points: dPsi/dtheta = -int grad(lambda).grad(u) dnu/dtheta / r (adjoint), force points: the
        one-sided difference in x of dW'/dtheta = -int dw/dtheta dV (envelope theorem), with dnu/dtheta and
        dw/dtheta tabulated once per Jacobian (:class:`_GridTable`: one lookup per quadrature point instead of
        one per curve). The per-point fields come from :meth:`point_fields`, here or in the workers."""
        theta = np.asarray(theta, dtype=float)
        self.values(theta)
        if self.pool is None:
            flux, force = self.point_fields()
        else:
            flux, force = {}, []
            for g, (fl, fo) in self._ask(("fields",)):
                flux.update({g[k]: v for k, v in fl.items()})
                force += [(g[k], dx, f0, f1) for k, dx, f0, f1 in fo]
        pairs = self._perturbed(theta, h)
        J = np.zeros((self.n, len(theta)))
        with single_threaded():
            if flux:
                B_top = max(float(np.max(b)) for b, _ in flux.values())
                dnu = _GridTable(B_top, [lambda B, c=c: c.nu_of_b2(B * B)[0] for c in _flat(pairs)], h)
                for k, f in flux.items():
                    J[k] = -dnu.weighted(*f)
            if force:
                B_top = max(float(np.max(f[0])) for _, _, f0, f1 in force for f in (f0, f1))
                dw = _GridTable(B_top, [c.energy_density for c in _flat(pairs)], h)
                for k, dx, f0, f1 in force:
                    J[k] = (dw.weighted(*f0) - dw.weighted(*f1)) / dx
        J[self.kind == "force"] *= -1.0  # the force closes the gap x: F = -dW'/dx
        return J

    def steel_H(self, theta, i_A: float, x_m: float) -> tuple[np.ndarray, np.ndarray]:
        """H [A/m] at the steel's quadrature points and their volumes [m^3] at (i_A, x_m)."""
        s = self.solver
        s.material = self.curve_fn(theta)
        sol = s.solve(float(i_A), float(x_m), forces=False)
        cfg = s.config(float(x_m))
        return s.material.H_of_B(cfg.steel_B(s.grad_steel(cfg, sol.u))).ravel(), cfg.vol_s.ravel()


def _fd_gap(x0_m: float, lo_m: float, hi_m: float) -> float:
    """The gap [m] of the force sensitivity's one-sided difference at ``x0_m``: :data:`FORCE_FD_DX_M` towards the
    larger gap, towards the smaller one at the stroke's end (``lo_m`` .. ``hi_m``)."""
    return x0_m + FORCE_FD_DX_M if x0_m + FORCE_FD_DX_M <= hi_m else max(x0_m - FORCE_FD_DX_M, lo_m)


def _flat(pairs):
    """The curves of ``[(plus, minus), ...]`` in the order plus_0, minus_0, plus_1, ..."""
    return [c for pair in pairs for c in pair]


class _GridTable:
    """d f / d theta_p of a function f(B) of the curve, tabulated for every parameter on a uniform grid of
    :data:`GRID_POINTS` flux densities from 0 to just above ``B_top`` [T], and integrated against weights.

    ``fns`` are f of the curves plus_0, minus_0, plus_1, ... (:meth:`PointModel._perturbed`), so the
    table is the central difference ``(f_plus - f_minus) / 2h``. Between grid points it is interpolated
    linearly: an index by arithmetic, one lookup per quadrature point for all parameters, where evaluating
    each perturbed curve at each point's field took a binary search per curve (a third of a Jacobian)."""

    def __init__(self, B_top: float, fns, h: float):
        self.dB = max(B_top, 1e-6) * (1.0 + 1e-9) / (GRID_POINTS - 1)
        grid = np.arange(GRID_POINTS) * self.dB
        vals = np.array([f(grid) for f in fns])
        self.table = ((vals[0::2] - vals[1::2]) / (2 * h)).T  # (grid, parameter)

    def weighted(self, B, weights) -> np.ndarray:
        """sum over points of weights * d f / d theta at B, per parameter."""
        pos = np.clip(np.ravel(B) / self.dB, 0.0, GRID_POINTS - 1 - 1e-9)
        i0 = pos.astype(np.intp)
        f = pos - i0
        w = np.ravel(weights)
        acc = np.bincount(i0, w * (1.0 - f), GRID_POINTS) + np.bincount(i0 + 1, w * f, GRID_POINTS)
        return acc @ self.table
