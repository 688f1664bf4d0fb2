r"""The virtual test rig's truth: a known model the paper's test campaign runs on.

The truth is richer than the real-time model, so that identification and the residual analysis
can be tested against a known answer. It is the characteristic maps from the FEM with a given
(true) B(H) curve, ``i_f(Psi, x)`` and ``F(Psi, x)`` (paper eqs. 2-3), plus any of the effects of
:mod:`solenoid_fmu.rig.effects` (hysteresis, eddy ladder, heating, friction; the DAQ's noise is
:mod:`solenoid_fmu.rig.daq`), each with physically sensible defaults, all settable.

Drive: the amplifier is a voltage source with a current loop (PI controller with anti-windup
and an output limit). The ``flux``, ``force_stroke``, ``ramp`` and ``eddy`` tests are
current-controlled; ``voltage_step`` is voltage-controlled. The model equations (SI)::

    U = R(T) i + dPsi/dt                                            (paper eq. 1)
    i = i_f(Psi, x) + i_hyst[Psi] + sum_k i_k                        (paper eq. 2, extended)
    tau_k di_k/dt = G_k dPsi/dt - i_k
    F = F(Psi, x)  (+ friction in the measured force)                (paper eq. 3)

integrated with the two-stage L-stable Rosenbrock method ROS2 (as :mod:`solenoid_fmu.realtime.model`)
on sub-steps of at most ``h_sub_max_s``; the hysteresis operator and the temperature are
advanced after each sub-step (explicit splitting; both change slowly on a sub-step).

Before each recording the rig demagnetizes the armature (decaying alternating current, not
recorded), as a real rig does before a flux measurement, and measures the coil resistance
(4-wire, written as ``coil_resistance_ohm`` with the temperature ``coil_temperature_C``).
Nothing in the recordings names the effects or the true material: a separate ``truth.json``
holds them (:func:`~solenoid_fmu.rig.read_truth`), for tests only; the pipeline never reads it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..realtime import ROS2_GAMMA, HysteresisError, MapTables, PreisachHysteresis
from .daq import TruthResult
from .effects import Effects
from .errors import RigError, positive
from .excitation import CampaignConfig, Excitation

__all__ = ["TruthModel"]


class TruthModel:
    """The rig's truth: FEM maps plus the chosen effects, integrated with their own states.

    Parameters
    ----------
    tables : MapTables
        The true characteristic maps ``i_f(Psi, x)``, ``F(Psi, x)`` (FEM with the true B(H)).
    effects : Effects
        Effects switched on.
    resistance_ohm_20C : float, optional
        Coil resistance at 20 degC [ohm]; default from the maps (coil.resistance_ohm_20C).
    alpha_per_K : float, optional
        Temperature coefficient of the resistance [1/K]; default from the maps, else copper.
    max_current_A : float, optional
        Coil's maximum current [A] (sets the default hysteresis width); default from the maps.
    h_sub_max_s : float
        Largest integration sub-step [s].
    """

    def __init__(self, tables: MapTables, effects: Effects | None = None, resistance_ohm_20C: float | None = None,
                 alpha_per_K: float | None = None, max_current_A: float | None = None,
                 h_sub_max_s: float = 5e-4):
        self.tables = tables
        self.effects = effects or Effects()
        coil = tables.coil
        R20 = resistance_ohm_20C if resistance_ohm_20C is not None else coil.resistance_ohm_20C
        if R20 is None:
            raise RigError("no coil resistance: give resistance_ohm_20C or maps with coil.resistance_ohm_20C")
        self.resistance_ohm_20C = positive("resistance_ohm_20C", R20)
        alpha = coil.alpha_per_K if alpha_per_K is None else alpha_per_K
        self.alpha_per_K = positive("alpha_per_K", alpha, allow_zero=True)
        imax = max_current_A if max_current_A is not None else coil.max_current_A
        if imax is None:
            raise RigError("no maximum current: give max_current_A or maps with coil.max_current_A")
        self.max_current_A = positive("max_current_A", imax)
        self.h_sub_max_s = positive("h_sub_max_s", h_sub_max_s)
        self.preisach = None
        hy = self.effects.hysteresis
        if hy is not None:
            width = hy.half_width_A if hy.half_width_A is not None else 0.03 * self.max_current_A
            sat = hy.saturation_Wb if hy.saturation_Wb is not None else tables.psi_max_Wb
            try:
                self.preisach = PreisachHysteresis.with_coercive(positive("hysteresis saturation_Wb", sat),
                                                                 positive("hysteresis half_width_A", width),
                                                                 b_c_rel=hy.b_c_rel, spread_rel=hy.spread_rel)
            except HysteresisError as exc:
                raise RigError(f"hysteresis: {exc}") from None
            slope_min = float(np.min(tables.tables()["i_f_slope_A"][1:])) * tables.inv_dpsi
            neg = self.preisach.max_negative_slope()
            if neg >= slope_min:
                raise RigError(f"hysteresis half-width {width:g} A is too large for these maps: the branches "
                               f"of Psi(i) would fold back (Preisach slope -{neg:.3g} A/Wb against the maps' "
                               f"smallest di_f/dPsi {slope_min:.3g} A/Wb); choose a smaller half_width_A")
        self.hysteresis_half_width_A = None if self.preisach is None else (
            hy.half_width_A if hy.half_width_A is not None else 0.03 * self.max_current_A)

    def R_ohm_at(self, T_C: float) -> float:
        """Coil resistance [ohm] at ``T_C`` [degC]: ``R20 (1 + alpha (T - 20))``."""
        return self.resistance_ohm_20C * (1.0 + self.alpha_per_K * (T_C - 20.0))

    def cool(self, T_C: float, pause_s: float, ambient_C: float) -> float:
        """Coil temperature [degC] after ``pause_s`` [s] without current (exponential cooling)."""
        he = self.effects.heating
        if he is None:
            return ambient_C
        return ambient_C + (T_C - ambient_C) * math.exp(-pause_s / he.time_constant_s)

    def simulate(self, exc: Excitation, cfg: CampaignConfig | None = None, T_start_C: float | None = None,
                 demagnetize: bool = True) -> TruthResult:
        """Run one excitation on the truth and return the true signals at the sample times.

        With ``exc.preroll_s > 0`` the unrecorded lead-in (see :class:`~solenoid_fmu.rig.Excitation`) is simulated
        first and its samples are dropped: the result starts energized at time 0.

        Parameters
        ----------
        exc : Excitation
            What the rig drives.
        cfg : CampaignConfig, optional
            Amplifier gains and limit, ambient temperature (default :class:`~solenoid_fmu.rig.CampaignConfig`).
        T_start_C : float, optional
            Coil temperature at the start [degC]; default the ambient.
        demagnetize : bool
            Reset the hysteresis to the AC-demagnetized state first (the rig does this before
            every recording).

        Returns
        -------
        TruthResult
        """
        if exc.preroll_s > 0.0:
            return self._simulate_with_preroll(exc, cfg, T_start_C, demagnetize)
        cfg = cfg or CampaignConfig()
        if exc.mode not in ("current", "voltage"):
            raise RigError(f"excitation {exc.name}: mode must be 'current' or 'voltage', got {exc.mode!r}")
        run = _Run(self, exc, cfg, T_start_C)
        pre = self.preisach
        if pre is not None and demagnetize:
            pre.reset(0.0)
        run.h_hyst = 0.0 if pre is None else pre.step(0.0)
        tab = self.tables
        t_samp = exc.times_s()
        ns = t_samp.size
        x_samp = exc.position_m(t_samp)
        out = {k: np.empty(ns) for k in ("U", "i", "psi", "F", "ih", "ie", "T")}
        R_start = self.R_ohm_at(run.T)
        T0 = run.T
        dt = 1.0 / exc.sample_rate_Hz
        n_sub = max(1, math.ceil(dt / self.h_sub_max_s - 1e-9))
        hs = dt / n_sub
        # The amplifier is digital: its reference (and the carriage position) is held over each
        # sub-step at the value of the sub-step's midpoint (precomputed, vectorized). A step in
        # the reference then acts exactly at its time when that is a sub-step boundary.
        t_mid = t_samp[:-1, None] + hs * (np.arange(n_sub)[None, :] + 0.5)
        ref_sub = exc.reference(t_mid)
        moving = len(exc.pos_m) > 1
        fixed_cell = tab.x_cell(float(x_samp[0]))
        x_sub = exc.position_m(t_mid) if moving else None
        _, _, U0, i0 = run.rhs(float(exc.reference(0.0)), run.y, tab.x_cell(float(x_samp[0])),
                               self.R_ohm_at(run.T))
        run.record(out, 0, U0, i0, x_samp[0])
        fric = np.zeros(ns)
        f_fric = 0.0
        i_prev = i0
        for k in range(1, ns):
            psi_start = run.y[0]
            ri_int, i_int, i_prev = run.substeps(ref_sub[k - 1], x_sub[k - 1] if moving else None, fixed_cell, hs,
                                                 i_prev)
            R = self.R_ohm_at(run.T)
            _, _, _, i = run.rhs(ref_sub[k - 1, n_sub - 1], run.y, tab.x_cell(float(x_samp[k])), R)
            ri_int += 0.5 * hs * R * (i_prev + i)
            i_int += 0.5 * hs * (i_prev + i)
            i_prev = i
            # Voltage and current channels are means over the sample interval (integrating
            # converters, the same anti-aliasing on both), so paper eq. 4 holds exactly for the
            # samples: U_mean - mean(R i) = (Psi_k - Psi_k-1) / dt.
            U = (run.y[0] - psi_start + ri_int) / dt
            run.record(out, k, U, i_int / dt, x_samp[k])
            f_fric = _dahl_friction(self.effects.friction, f_fric, x_samp[k] - x_samp[k - 1])
            fric[k] = f_fric
        return TruthResult(time_s=t_samp, voltage_V=out["U"], current_A=out["i"], psi_Wb=out["psi"],
                           force_N=out["F"] + fric, position_m=x_samp, force_magnetic_N=out["F"],
                           i_hyst_A=out["ih"], i_eddy_A=out["ie"], temperature_C=out["T"],
                           resistance_start_ohm=R_start, temperature_start_C=T0, temperature_end_C=run.T)

    def _simulate_with_preroll(self, exc: Excitation, cfg, T_start_C, demagnetize) -> TruthResult:
        """:meth:`simulate` of an excitation with a lead-in: simulate it, then drop its samples."""
        fs = exc.sample_rate_Hz
        n_pre = max(1, math.ceil(exc.preroll_s * fs - 1e-9))
        pre = n_pre / fs
        shift = tuple(float(t) + pre for t in exc.ref_t_s)
        moving = len(exc.pos_m) > 1
        ext = dataclasses.replace(
            exc, ref_t_s=(0.0, 0.5 * pre, *shift), ref_values=(0.0, exc.ref_values[0], *exc.ref_values),
            pos_t_s=(0.0, *(float(t) + pre for t in exc.pos_t_s)) if moving else exc.pos_t_s,
            pos_m=(exc.pos_m[0], *exc.pos_m) if moving else exc.pos_m, preroll_s=0.0)
        res = self.simulate(ext, cfg, T_start_C, demagnetize)
        n = exc.times_s().size
        cut = {f.name: getattr(res, f.name)[n_pre:n_pre + n] for f in dataclasses.fields(res)
               if isinstance(getattr(res, f.name), np.ndarray)}
        cut["time_s"] = exc.times_s()[:cut["current_A"].size]
        return dataclasses.replace(res, **cut)


def _dahl_friction(fr, f_fric: float, dx: float) -> float:
    """The friction force [N] after the armature moved by ``dx`` [m] (Dahl: it tends to the sliding force
    against the motion over the presliding displacement); unchanged at rest or without friction."""
    if fr is not None and fr.force_N > 0.0 and dx != 0.0:
        target = fr.force_N if dx > 0.0 else -fr.force_N
        return target + (f_fric - target) * math.exp(-abs(dx) / fr.presliding_m)
    return f_fric


class _Run:
    """One :meth:`TruthModel.simulate` run: the truth's ODE and its state while it runs.

    The state ``y = [Psi, z (PI integrator), i_1 .. i_n]`` (the eddy ladder's section currents), the
    coil temperature ``T`` [degC] and the hysteresis current ``h_hyst`` [A] (both advanced after each
    sub-step, see the module docstring).
    """

    def __init__(self, truth: TruthModel, exc: Excitation, cfg: CampaignConfig, T_start_C: float | None):
        tab = truth.tables
        self.truth, self.tab = truth, tab
        self.T = cfg.ambient_C if T_start_C is None else float(T_start_C)
        self.ambient = cfg.ambient_C
        ladder = truth.effects.eddy
        Gk = np.array(ladder.G_S) if ladder else np.zeros(0)
        tk = np.array(ladder.tau_s) if ladder else np.zeros(0)
        if not ladder and (tab.G_eddy_S or 0.0) > 0.0:
            # without the ladder the truth has the paper's single linear term of the maps (eq. 2),
            # i_eddy = G dPsi/dt, as one section fast enough to be instantaneous (ROS2 is L-stable)
            Gk, tk = np.array([float(tab.G_eddy_S)]), np.array([1e-6])
        self.nk = nk = Gk.size
        self.n_y = n_y = 2 + nk
        self.current_mode = exc.mode == "current"
        self.kp, self.ki, self.umax = cfg.amplifier_kp_V_per_A, cfg.amplifier_ki_V_per_As, cfg.amplifier_max_V
        self.y = np.zeros(n_y)
        self.h_hyst = 0.0
        self.eye = np.eye(n_y)
        self.di_base = np.zeros(n_y)
        self.di_base[2:] = 1.0
        self.inv_tk = 1.0 / tk if nk else tk
        self.G_over_tk = Gk * self.inv_tk if nk else Gk
        self.ladder_diag = np.diag(self.inv_tk) if nk else None

    def rhs(self, ref, yv, cell, R):
        """f(y), Jacobian, U [V], i [A] for reference ``ref`` (A or V) in x cell ``cell``."""
        n_y, nk = self.n_y, self.nk
        i_f, s = self.tab.i_f_and_slope(yv[0], cell[0], cell[1])
        i = i_f + self.h_hyst + (float(yv[2:].sum()) if nk else 0.0)
        J = np.zeros((n_y, n_y))
        di = self.di_base.copy()
        di[0] = s
        f = np.empty(n_y)
        if self.current_mode:
            err = ref - i
            u_raw = self.kp * err + yv[1]
            if -self.umax <= u_raw <= self.umax:
                U = u_raw
                dU = -self.kp * di
                dU[1] = 1.0
                f[1] = self.ki * err
                J[1] = -self.ki * di
            else:
                U = self.umax if u_raw > self.umax else -self.umax
                dU = np.zeros(n_y)
                f[1] = 0.0
        else:
            U = ref
            dU = np.zeros(n_y)
            f[1] = 0.0
        e = U - R * i
        de = dU - R * di
        f[0] = e
        J[0] = de
        if nk:
            f[2:] = self.G_over_tk * e - yv[2:] * self.inv_tk
            J[2:] = self.G_over_tk[:, None] * de[None, :]
            J[2:, 2:] -= self.ladder_diag
        return f, J, U, i

    def substeps(self, refs, xs, fixed_cell, hs: float, i_prev: float) -> tuple[float, float, float]:
        """ROS2 over the sub-steps of one sample interval (references ``refs``, positions ``xs`` or the
        ``fixed_cell``), hysteresis and temperature after each; returns the trapezoid integrals of ``R i`` and
        ``i`` from the first sub-step's end and the current at the last sub-step's start."""
        truth, tab, g = self.truth, self.tab, ROS2_GAMMA
        pre, heating = truth.preisach, truth.effects.heating
        ri_int = 0.0  # integral of R i over the sample interval [V s]
        i_int = 0.0  # integral of i over the sample interval [A s]
        for m in range(len(refs)):
            cell = tab.x_cell(float(xs[m])) if xs is not None else fixed_cell
            R = truth.R_ohm_at(self.T)
            f1, J, _, i_a = self.rhs(refs[m], self.y, cell, R)
            if m:
                ri_int += 0.5 * hs * R * (i_prev + i_a)
                i_int += 0.5 * hs * (i_prev + i_a)
            i_prev = i_a
            W = self.eye - (g * hs) * J
            k1 = np.linalg.solve(W, f1)
            f2 = self.rhs(refs[m], self.y + hs * k1, cell, R)[0]
            k2 = np.linalg.solve(W, f2 - 2.0 * k1)
            self.y = self.y + 1.5 * hs * k1 + 0.5 * hs * k2
            if pre is not None:
                self.h_hyst = pre.step(self.y[0])
            if heating is not None:
                P = i_a * i_a * R
                self.T += hs * (P - (self.T - self.ambient) / heating.R_th_K_per_W) / heating.C_th_J_per_K
        return ri_int, i_int, i_prev

    def record(self, out: dict, k: int, U: float, i: float, x_m: float) -> None:
        """The true signals of sample ``k`` into ``out``."""
        y = self.y
        out["U"][k] = U
        out["i"][k] = i
        out["psi"][k] = y[0]
        out["F"][k] = self.tab.force_N(y[0], x_m)
        out["ih"][k] = self.h_hyst
        out["ie"][k] = float(np.sum(y[2:]))
        out["T"][k] = self.T
