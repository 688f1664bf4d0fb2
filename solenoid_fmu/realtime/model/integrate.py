"""The integrators of a communication step: ROS2 sub-steps of the flux, and of the flux with the effects.

Part of the FMU payload (:mod:`solenoid_fmu.realtime.model`): the standard library only. The equations
are in the module docstring of :mod:`solenoid_fmu.realtime.model` ("Integrator") and in
:meth:`solenoid_fmu.realtime.model.SolenoidModel.step`; the C model (``fmu/c/sol_step.c``) does the same
arithmetic in the same order.
"""

from __future__ import annotations

import math

from .definitions import ROS2_GAMMA
from .play import play_step
from .tables import HOT_CI, HOT_PSI_MAX, MapTables, cell_cubic, i_f_slope, solve_psi


def plain_sum(values) -> float:
    """Sum left to right from 0.0, as the C model's loops add. Not :func:`sum`: from Python 3.12 it
    compensates the rounding of floats (Neumaier), which would break the bit-for-bit equality with C."""
    acc = 0.0
    for v in values:
        acc += v
    return acc


def ros2(hot: tuple, psi: float, v: float, d: float, m: float, b: float, c: float, hs: float, n: int,
         j: int, w: float) -> tuple[float, bool]:
    """``n`` ROS2 sub-steps of ``hs`` [s] for ``m dPsi/dt = b - c i_f(Psi, x)``; returns (Psi, clamped).

    ``v, d`` are ``i_f`` and ``d i_f / d Psi`` at the start value ``psi`` (from the previous
    step's output evaluation); ``hot`` is :attr:`MapTables.hot`.
    """
    g = ROS2_GAMMA
    CI, pm = hot[HOT_CI], hot[HOT_PSI_MAX]
    clamped = False
    for sub in range(n):
        if sub:  # stage 1 of a later sub-step: value and slope at psi (i_f_slope, one call less: hot path)
            if psi < 0.0:
                v, d = cell_cubic(CI, hot, -psi, j, w)
                v = -v
            else:
                v, d = cell_cubic(CI, hot, psi, j, w)
        W = m + g * hs * c * d
        k1 = (b - c * v) / W
        p2 = psi + hs * k1  # stage 2: value at psi + hs k1
        v2 = -cell_cubic(CI, hot, -p2, j, w)[0] if p2 < 0.0 else cell_cubic(CI, hot, p2, j, w)[0]
        k2 = (b - c * v2 - 2.0 * m * k1) / W
        psi = psi + 1.5 * hs * k1 + 0.5 * hs * k2
        if psi > pm:
            psi, clamped = pm, True
        elif psi < -pm:
            psi, clamped = -pm, True
    return psi, clamped


def ros2_ladder(hot: tuple, psi: float, ik: list, b: float, c: float, m: float, ih: float, hs: float,
                Gk: list, tk: list, j: int, w: float) -> tuple[float, list, bool]:
    """One ROS2 sub-step of the flux and the eddy-ladder currents in mass-matrix form ``M y' = f(y)``.

    ``m dPsi/dt = b - c (i_f(Psi) + ih + sum_k i_k)``, ``tau_k di_k/dt = G_k dPsi/dt - i_k``; the
    arrow-shaped system is solved in O(sections). Returns (Psi, ladder currents, clamped).

    Each sum over the sections is :func:`plain_sum`'s (left to right from 0.0) written out as a loop: this
    runs once per sub-step, where a generator per sum cost more than the arithmetic (same operations, same
    order: ``gh * c * x`` is ``(gh * c) * x``).
    """
    nl = len(Gk)
    gh = ROS2_GAMMA * hs
    ghc = gh * c
    v, d = i_f_slope(hot, psi, j, w)
    if not nl:  # no ladder: the sums below over no sections are plain_sum's 0.0
        den = m + ghc * d + 0.0
        z0 = (b - c * (v + ih + 0.0) - ghc * 0.0) / den
        v2 = i_f_slope(hot, psi + hs * z0, j, w)[0]
        q0 = (b - c * (v2 + ih + 0.0) - 2.0 * m * z0 - ghc * 0.0) / den
        psi = psi + 1.5 * hs * z0 + 0.5 * hs * q0
        pm = hot[HOT_PSI_MAX]
        if psi > pm:
            return pm, [], True
        if psi < -pm:
            return -pm, [], True
        return psi, [], False
    a = [tk[k] + gh for k in range(nl)]
    s_g = s_i = s_r = 0.0
    for k in range(nl):
        s_g += ghc * Gk[k] / a[k]
        s_i += ik[k]
        s_r += -ik[k] / a[k]
    den = m + ghc * d + s_g
    f0 = b - c * (v + ih + s_i)
    z0 = (f0 - ghc * s_r) / den
    z = [(-ik[k] + Gk[k] * z0) / a[k] for k in range(nl)]
    i2 = [ik[k] + hs * z[k] for k in range(nl)]
    v2 = i_f_slope(hot, psi + hs * z0, j, w)[0]
    s_i = 0.0
    for x in i2:
        s_i += x
    f0 = b - c * (v2 + ih + s_i) - 2.0 * m * z0
    r = [-i2[k] - 2.0 * (tk[k] * z[k] - Gk[k] * z0) for k in range(nl)]
    s_r = 0.0
    for k in range(nl):
        s_r += r[k] / a[k]
    q0 = (f0 - ghc * s_r) / den
    psi = psi + 1.5 * hs * z0 + 0.5 * hs * q0
    ik = [ik[k] + 1.5 * hs * z[k] + 0.5 * hs * ((r[k] + Gk[k] * q0) / a[k]) for k in range(nl)]
    pm = hot[HOT_PSI_MAX]
    if psi > pm:
        return pm, ik, True
    if psi < -pm:
        return -pm, ik, True
    return psi, ik, False


def fx_substeps(tab: MapTables, fx: dict, u: float, j: int, w: float, psi: float, ik: list, plays: list,
                T: float, ih: float, n: int, hs: float) -> tuple:
    """``n`` sub-steps of ``hs`` [s] with the effects of ``fx`` (:meth:`SolenoidModel._fx_settings`).

    The flux (and the ladder currents) by :func:`ros2_ladder`, or by :func:`solve_psi` in current
    drive with ``G = 0`` and no ladder; then the temperature rise (explicit Euler) and the play
    operators (``plays``, updated in place) from the new flux. Returns (Psi, clamped, ladder
    currents, T, i_hyst).
    """
    voltage, R0, G0, heat, alpha = fx["voltage"], fx["R0"], fx["G0"], fx["heat"], fx["alpha"]
    Gk, tk, hy = fx["Gk"], fx["tk"], fx["hy"]
    pc = False
    for _ in range(n):
        R = R0 * (1.0 + alpha * T) if heat else R0
        m = 1.0 + R * G0 if voltage else G0
        c = R if voltage else 1.0
        psi_a = psi
        if m == 0.0 and not Gk:
            psi, pc = solve_psi(tab, u - ih, j, w, psi)
        else:
            psi, ik, clamped = ros2_ladder(tab.hot, psi, ik, u, c, m, ih, hs, Gk, tk, j, w)
            pc = pc or clamped
        if heat:
            i_sub = (u - (psi - psi_a) / hs) / R if voltage else u
            T += hs * (R * i_sub * i_sub - (T + fx["T0"]) / fx["Rth"]) / fx["Cth"]
        if hy is not None:
            ih = fx["gain"] * play_step(plays, hy["r"], hy["w"], hy["gb"], hy["gg"], psi)
    return psi, pc, ik, T, ih


def dahl_friction(f_N: float, dx_m: float, fc_N: float, presliding_m: float) -> float:
    """The Dahl friction force [N] after a move of ``dx_m`` [m]: it tends to ``+-fc_N`` (sign of the move)
    over a distance of order ``presliding_m`` [m]; unchanged without a move."""
    if dx_m == 0.0:
        return f_N
    target = fc_N if dx_m > 0.0 else -fc_N
    return target + (f_N - target) * math.exp(-abs(dx_m) / presliding_m)
