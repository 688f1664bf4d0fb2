"""The FEM side of the identification: Psi(i) and its adjoint Jacobian for a parameter vector, and
the FEM flux and force of a given curve (for the report's before/after comparison).

:class:`FluxModel` counts every solve: nonlinear operating points (warm-started Newton), their
linear steps and the adjoint solves, so the cost of a fit is reported in sweeps.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from ..field import BHCurve, Solver, load_geometry, load_material

__all__ = ["FluxModel", "fem_flux", "fem_force_vs_stroke", "as_geometry", "as_curve"]


class FluxModel:
    """Psi(i) at one gap for a parameter vector, by warm-started FEM solves, and its Jacobian
    d Psi / d theta by one adjoint linear solve per current (counts every solve).

    Adjoint: at the converged solution u_k of current i_k the residual R(u, theta) = 0, so
    K_t du/dtheta = -dR/dtheta and dPsi/dtheta = w . du/dtheta = -lambda . dR/dtheta with
    K_t lambda = w (K_t is symmetric; w = psi_weights). dR/dtheta only involves the steel's
    reluctivity: dR_j/dtheta = int (grad phi_j . grad u) dnu/dtheta / r dA, hence
    dPsi/dtheta = -int (grad lambda . grad u) dnu/dtheta / r dA over the steel, with dnu/dtheta
    at the solution's B^2 by central differences of the (1 ms) curve. Checked against finite
    differences of full sweeps in the tests.
    """

    def __init__(self, geometry, x_m, i_A, curve_fn, mesh_size, start_curve):
        self.solver = Solver(geometry, start_curve, mesh_size)
        self.x_m = float(x_m)
        self.i_A = np.asarray(i_A, dtype=float)
        self._version = 0
        self.curve_fn = curve_fn  # parameters -> BHCurve (switchable between stages)
        self.u = [None] * len(self.i_A)
        self.solves = 0
        self.newton_steps = 0
        self.adjoint_solves = 0
        self.first_sweep_steps = 0
        self.sweeps = 0
        self._cache: tuple = (None, None, None)

    @property
    def curve_fn(self):
        """parameters -> BHCurve; setting it invalidates the cache."""
        return self._curve_fn

    @curve_fn.setter
    def curve_fn(self, fn):
        self._curve_fn = fn
        self._version += 1

    def psi(self, theta) -> np.ndarray:
        """Psi [Wb] at the currents for parameters ``theta`` (cached for the last theta)."""
        theta = np.asarray(theta, dtype=float)
        key = (self._version, theta.tobytes())
        if self._cache[0] == key:
            return self._cache[1].copy()
        self.solver.material = self.curve_fn(theta)
        out = np.empty(len(self.i_A))
        us = []
        u_prev = None
        steps = 0
        for k, i in enumerate(self.i_A):
            start = self.u[k] if self.u[k] is not None else u_prev
            sol = self.solver.solve(float(i), self.x_m, u0=start)
            self.solves += 1
            steps += max(sol.newton_iterations, 1)
            out[k] = sol.psi_Wb
            u_prev = sol.u
            us.append(sol.u)
        if self.sweeps == 0:
            self.first_sweep_steps = steps
        self.newton_steps += steps
        self.u = us
        self.sweeps += 1
        self._cache = (key, out.copy(), us)
        return out

    @property
    def equivalent_sweeps(self) -> float:
        return (self.newton_steps + self.adjoint_solves) / max(self.first_sweep_steps, 1)

    def jacobian(self, theta, h: float = 1e-4) -> np.ndarray:
        """d Psi / d theta [Wb per parameter unit], shape (currents, parameters)."""
        theta = np.asarray(theta, dtype=float)
        self.psi(theta)
        us = self._cache[2]
        s = self.solver
        cfg = s.config(self.x_m)
        P = len(theta)
        w = cfg.psi_weights.copy()
        w[s.dirichlet_mask] = 0.0
        pairs = []
        for p in range(P):
            e = np.zeros(P)
            e[p] = h
            pairs.append((self.curve_fn(theta + e), self.curve_fn(theta - e)))
        J = np.zeros((len(self.i_A), P))
        wr = cfg.w_over_r_s
        r2 = cfg.r2_s
        with threadpool_limits(limits=1):
            for k, i in enumerate(self.i_A):
                u = us[k]
                K, _ = s.tangent(cfg, u, float(i) * cfg.f_coil + cfg.f_fixed)
                lam = s.linear_solver.solve(K.data, K.indices, K.indptr, w)
                self.adjoint_solves += 1
                g = s.grad_steel(cfg, u)
                gl = s.grad_steel(cfg, lam)
                b2 = (g[0] ** 2 + g[1] ** 2) / r2
                dot = (g[0] * gl[0] + g[1] * gl[1]) * wr
                for p, (cp, cm) in enumerate(pairs):
                    J[k, p] = -np.sum(dot * (cp.nu_of_b2(b2)[0] - cm.nu_of_b2(b2)[0])) / (2 * h)
        return J

    def steel_H(self, theta, i_A: float) -> tuple[np.ndarray, np.ndarray]:
        """H [A/m] at the steel's quadrature points and their volumes [m^3] at current ``i_A``."""
        s = self.solver
        s.material = self.curve_fn(theta)
        k = int(np.argmin(np.abs(self.i_A - i_A)))
        sol = s.solve(float(i_A), self.x_m, u0=self.u[k])
        cfg = s.config(self.x_m)
        return s.material.H_of_B(cfg.steel_B(s.grad_steel(cfg, sol.u))).ravel(), cfg.vol_s.ravel()


def _warm_sweep(geometry, curve: BHCurve, mesh_size: float, points, quantity: str) -> np.ndarray:
    """``quantity`` of the FEM solution at each (i [A], x [m]) of ``points``, every solve warm-started
    from the previous one."""
    solver = Solver(geometry, curve, mesh_size)
    out = []
    u = None
    for i, x in points:
        sol = solver.solve(float(i), float(x), u0=u)
        u = sol.u
        out.append(getattr(sol, quantity))
    return np.array(out)


def fem_force_vs_stroke(geometry, curve: BHCurve, i_A: float, x_m, mesh_size: float) -> np.ndarray:
    """Co-energy force [N] (paper eq. 3) at current ``i_A`` [A] and gaps ``x_m`` [m] (FEM)."""
    return _warm_sweep(geometry, curve, mesh_size, ((i_A, x) for x in np.asarray(x_m, dtype=float)), "force_N")


def fem_flux(geometry, curve: BHCurve, i_A, x_m: float, mesh_size: float) -> np.ndarray:
    """Psi [Wb] at currents ``i_A`` [A] and gap ``x_m`` [m] (FEM, warm-started sweep)."""
    return _warm_sweep(geometry, curve, mesh_size, ((i, x_m) for i in np.asarray(i_A, dtype=float)), "psi_Wb")


def as_geometry(geometry):
    """A :class:`~solenoid_fmu.field.geometry.Geometry` as given, or loaded from a path (None: the packaged PS45)."""
    if geometry is None or isinstance(geometry, (str, Path)):
        return load_geometry(geometry)
    return geometry


def as_curve(material) -> BHCurve:
    """A :class:`~solenoid_fmu.field.BHCurve` as given, or loaded from a path (None: the literature curve)."""
    if material is None or isinstance(material, (str, Path)):
        return load_material(material)
    return material

