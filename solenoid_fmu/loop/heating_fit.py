"""Coil heating from the eq.-4 flux residual, and recordings corrected for it.

With the resistance measured before a run, coil heating leaves the eq.-4 flux drifting by
``int (R(T) - R) i dt`` (paper eq. 4 with one resistance per run). A run starts ``T_0`` above ambient (its
resistance over the campaign's coldest, :func:`solenoid_fmu.fmu.simulate.start_excess_K`) and within it the
heating sub-model's

    C_th dT/dt = R i^2 - (T + T_0) / R_th,    R(T) = R (1 + a T),  a = alpha / (1 + alpha T_0)

(the model's, less the ``a T`` in the heating: a few kelvin are ~1 % of it) gives, with ``tau = R_th C_th``
and ``K_tau[q](t) = int_0^t exp(-(t - s) / tau) q(s) ds``,

    T = (1 / C_th) K_tau[R i^2] - (T_0 / tau) K_tau[1],
    drift = (1 / C_th) a R int K_tau[R i^2] i dt - (1 / tau) a R T_0 int K_tau[1] i dt.

For a fixed ``tau`` the drift is linear in ``1 / C_th``; :func:`fit_heating` searches ``tau`` within
:data:`TAU_RANGE_S` (a log-scale grid, then scipy's bounded Brent between the best point's neighbours) for the
least squares over the flux residuals and takes ``C_th`` there and
``R_th = tau / C_th``, where the optimum lies inside the range and ``R_th`` inside :data:`R_TH_RANGE_K_PER_W`:
runs that start warm and cool measurably pin it. Otherwise (every run near ambient, or a residual that a
cooling does not explain) ``R_th`` keeps its default (:data:`R_TH_DEFAULT_K_PER_W`) and ``C_th`` is fitted with
``tau = R_th C_th`` (a few fixed-point passes). ``alpha`` is copper's unless the maps say otherwise.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..fmu import start_excess_K
from ..realtime import heating_alpha
from .signals import detrend
from .tables import ImproveError

#: R_th [K/W] the fit takes from the runs' cooling: a small solenoid on a metal fixture to one in free air.
#: Outside, the joint fit is taken for noise and R_th keeps its default.
R_TH_RANGE_K_PER_W = (0.1, 30.0)
#: R_th [K/W] where it cannot be fitted (the model's default; the cooling of a run's own rise is then small).
R_TH_DEFAULT_K_PER_W = 1.0
#: Thermal time constants R_th C_th [s] searched: seconds (a bare winding) to hours.
TAU_RANGE_S = (2.0, 2.0e4)


def _kernel(t: np.ndarray, q: np.ndarray, tau: float) -> np.ndarray:
    """``int_0^t exp(-(t - s) / tau) q(s) ds`` along ``t`` (left sums, as the model's explicit steps)."""
    span = float(t[-1] - t[0])
    if span / tau > 600.0:  # exp would underflow: step by step
        out = np.zeros_like(t)
        for k in range(1, t.size):
            h = t[k] - t[k - 1]
            out[k] = out[k - 1] * math.exp(-h / tau) + h * q[k]
        return out
    w = np.exp((t - t[-1]) / tau)
    return np.concatenate([[0.0], np.cumsum(np.diff(t) * (w * q)[1:])]) / w


class _Drifts:
    """The residual cases' flux drift per ``1 / C_th`` and per ``1 / tau`` for a given ``tau`` (module docstring)."""

    def __init__(self, cases, alpha: float):
        self.rows = []
        for c in cases:
            r = c.residuals.get("psi_Wb")
            if r is None:
                continue
            t0 = start_excess_K(c.R_ohm, c.ambient_R_ohm, alpha)
            self.rows.append((c, r, t0, heating_alpha(alpha, t0)))
        self.names = [c.name for c, *_ in self.rows]
        self.any_warm = any(abs(t0) > 0.0 for _, _, t0, _ in self.rows)

    def columns(self, tau: float) -> list:
        """Per case: (residual, drift per 1/C_th, drift per 1/tau)."""
        out = []
        for c, r, t0, a in self.rows:
            t, i, R = c.time_s, c.current_A, c.R_ohm
            dt = np.diff(t)
            heat = a * R * np.concatenate([[0.0], np.cumsum(dt * (_kernel(t, R * i * i, tau) * i)[1:])])
            cool = -a * R * t0 * np.concatenate([[0.0], np.cumsum(dt * (_kernel(t, np.ones_like(t), tau) * i)[1:])])
            if "psi_Wb" in c.detrended:
                heat, cool = detrend(heat, t), detrend(cool, t)
            out.append((r, heat, cool))
        return out

    def fit(self, tau: float, with_cooling: bool) -> tuple:
        """(1 / C_th, sum of squares) at ``tau``; the start excess cools with ``tau`` if ``with_cooling``."""
        num = den = 0.0
        cols = self.columns(tau)
        for r, heat, cool in cols:
            y = r - cool / tau if with_cooling else r
            num += float(heat @ y)
            den += float(heat @ heat)
        x = num / den if den > 0.0 else 0.0
        sse = sum(float(np.sum(((r - cool / tau if with_cooling else r) - x * heat) ** 2)) for r, heat, cool in cols)
        return x, sse


def _tau_search(drifts: _Drifts) -> tuple:
    """(tau, 1 / C_th) minimizing the squares over a log grid, refined between the grid's neighbours of its best
    point (scipy's bounded Brent); tau None at a bound of :data:`TAU_RANGE_S`."""
    from scipy.optimize import minimize_scalar  # lazy: heavy to import, only this fit needs it

    lo, hi = math.log(TAU_RANGE_S[0]), math.log(TAU_RANGE_S[1])
    grid = np.linspace(lo, hi, 41)
    sse = [drifts.fit(math.exp(g), True)[1] for g in grid]
    k = int(np.argmin(sse))
    if k in (0, grid.size - 1):
        return None, None
    best = minimize_scalar(lambda g: drifts.fit(math.exp(g), True)[1], bounds=(grid[k - 1], grid[k + 1]),
                           method="bounded", options={"xatol": 1e-4})
    tau = math.exp(float(best.x))
    return tau, drifts.fit(tau, True)[0]


def fit_heating(tables, effects, cases) -> tuple[dict, dict]:
    """``C_th`` and, where the runs' start temperatures show it, ``R_th`` from the eq.-4 flux residual of
    current-driven recordings (module docstring); (section, note)."""
    alpha = tables.coil.alpha_per_K
    drifts = _Drifts(cases, alpha)
    x0, _ = drifts.fit(math.inf, False)
    if not drifts.rows or x0 <= 0.0:
        raise ImproveError("heating: the flux residual does not drift with the dissipated energy")
    note = {"fitted_on": drifts.names}
    if drifts.any_warm:
        tau, x = _tau_search(drifts)
        R_th = tau * x if tau is not None and x > 0.0 else math.nan
        note["R_th_fitted"] = bool(R_TH_RANGE_K_PER_W[0] <= R_th <= R_TH_RANGE_K_PER_W[1])
        if note["R_th_fitted"]:
            note["R_th"] = f"fitted: runs that start above ambient cool measurably (tau {tau:.4g} s)"
            return {"C_th_J_per_K": float(1.0 / x), "R_th_K_per_W": float(R_th), "alpha_per_K": alpha}, note
        note["R_th"] = ("default: the runs' cooling gives no thermal time constant inside "
                        f"{TAU_RANGE_S[0]:g} .. {TAU_RANGE_S[1]:g} s with R_th inside "
                        f"{R_TH_RANGE_K_PER_W[0]:g} .. {R_TH_RANGE_K_PER_W[1]:g} K/W")
    else:
        note["R_th_fitted"] = False
        note["R_th"] = "default: no run starts measurably above ambient"
    x = x0
    for _ in range(4):  # tau = R_th C_th with the default R_th
        x_new = drifts.fit(R_TH_DEFAULT_K_PER_W / x, True)[0]
        if x_new <= 0.0:
            break
        x = x_new
    return {"C_th_J_per_K": float(1.0 / x), "R_th_K_per_W": R_TH_DEFAULT_K_PER_W, "alpha_per_K": alpha}, note


def heating_corrected(rec, heating: dict, R_ohm: float | None = None, T_start_excess_K: float = 0.0):
    """The recording with the coil heating's resistive voltage removed (for a heating-free eq.-4 flux).

    With the heating sub-model's parameters (``C_th_J_per_K``, ``R_th_K_per_W``, ``alpha_per_K``) the
    temperature rise along the recording is integrated from the measured current,
    ``C_th dT/dt = R (1 + a T) i^2 - (T + T_0) / R_th`` (``T_0 = T_start_excess_K``, the coil's temperature
    above ambient at the start [K]; ``a = alpha / (1 + alpha T_0)``), and ``R a T i`` is subtracted from the
    voltage, so that paper eq. 4 with the resistance measured before the run gives the flux of a coil at
    constant temperature. ``R_ohm`` [ohm] defaults to the header's resistance. Returns a new Recording (same
    kind, header noted); recordings without a voltage are returned unchanged.
    """
    if rec.voltage_V is None:
        return rec
    R = float(R_ohm if R_ohm is not None else rec.coil_resistance_ohm)
    C, Rth = heating["C_th_J_per_K"], heating["R_th_K_per_W"]
    alpha = heating_alpha(heating["alpha_per_K"], T_start_excess_K)
    t = np.asarray(rec.time_s, dtype=float)
    i = np.asarray(rec.current_A, dtype=float)
    T = np.zeros_like(t)
    for k in range(1, t.size):
        Tk = T[k - 1]
        T[k] = Tk + (t[k] - t[k - 1]) * (R * (1.0 + alpha * Tk) * i[k] ** 2 - (Tk + T_start_excess_K) / Rth) / C
    header = dict(rec.header)
    note = f"voltage corrected for coil heating (C_th {C:.4g} J/K)"
    header["notes"] = f"{header['notes']}; {note}" if header.get("notes") else note
    return replace(rec, voltage_V=np.asarray(rec.voltage_V, dtype=float) - R * alpha * T * i, header=header)
