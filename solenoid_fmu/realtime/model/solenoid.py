"""The lumped real-time solenoid model (paper eqs. 1-3 with the eddy term and the effect sub-models).

Part of the FMU payload (:mod:`solenoid_fmu.realtime.model`): numpy and the standard library only.
The equations, drive modes, lookup and integrator are described in that package's docstring.
"""

from __future__ import annotations

import math

from .definitions import (
    DEFAULT_PARAMS,
    DRIVE_CURRENT,
    DRIVE_VOLTAGE,
    EFFECT_STATE_NAMES,
    EFFECT_SWITCHES,
    EVENT_SEVERITY,
    FX_F_FRICTION_N,
    FX_I_HYST_A,
    FX_LAD,
    FX_T_RISE_K,
    FX_X_PREV_M,
    MAX_SUBSTEPS,
    ST_EXCURSION_EXTRAPOLATED,
    ST_EXCURSION_PSI,
    ST_EXCURSION_X,
    ST_INITIALIZED,
    ST_OUT_DPSI_DT_V,
    ST_OUT_F_N,
    ST_OUT_I_A,
    ST_OUT_I_EDDY_A,
    ST_OUT_U_V,
    ST_PSI_WB,
    ST_STATE_LAYOUT,
    ST_TIME_S,
    STATE_INDEX,
    STATE_LAYOUT,
    STATE_NAMES,
    ModelInputError,
    finite_float,
    heating_alpha,
)
from .effects import effects_data
from .integrate import dahl_friction, fx_substeps, plain_sum, ros2
from .params import checked_param
from .tables import MapTables, eval_cell, solve_psi

#: The end-of-step lookup cache when it holds nothing: (Psi, j, w, i_f, d i_f / d Psi).
_NO_END = (math.nan, -1, math.nan, 0.0, 0.0)


class SolenoidModel:
    """The lumped real-time solenoid model (paper eqs. 1-3), one instance per simulated coil.

    Parameters
    ----------
    tables : MapTables
        The characteristic maps.
    params : dict, optional
        Overrides of :data:`DEFAULT_PARAMS`: ``R_ohm`` [ohm] (> 0, at the start before self-heating; default the
        maps' at 20 degC), ``G_eddy_S`` [S] (>= 0), ``drive_mode`` ("voltage"/"current" or 1/2), ``Psi0_Wb`` [Wb],
        ``h_sub_max_s`` [s] (> 0). Unknown keys are refused.

    Attributes
    ----------
    i_A, U_V, F_N, psi_Wb, dpsi_dt_V, i_eddy_A : float
        Outputs at the last communication point (see the module docstring for which are means).
    out_of_map : bool
        True while ``x`` or ``Psi`` is clamped to the map.
    events : list of tuple (str, str, str)
        ``(kind, severity, message)`` of excursions that began; the caller drains the list.

    Notes
    -----
    Paper eqs. (1)-(3); see the module docstring for the integrator and the lookup.
    """

    def __init__(self, tables: MapTables, params: dict | None = None):
        self.tables = tables
        self.params = {}
        self.events = []
        self._x_cache = (math.nan, (0, 0.0, False))
        self._end_cache = _NO_END
        self._state = [0.0] * len(STATE_NAMES)
        self._state[ST_STATE_LAYOUT] = float(STATE_LAYOUT)
        self._fx_data = effects_data(tables)
        self._fx_on = False
        n_lad = len((self._fx_data.get("eddy_ladder") or {}).get("G_S", ()))
        n_play = len((self._fx_data.get("hysteresis") or {}).get("thresholds", ()))
        self._fx_names = (EFFECT_STATE_NAMES + tuple(f"ladder_{k}" for k in range(n_lad))
                          + tuple(f"play_{k}" for k in range(n_play))) if self._fx_data else ()
        self._fx = [0.0] * len(self._fx_names)
        self._fx_play = FX_LAD + n_lad  # index of the first play in the effect states
        self.set_params(**{k: v for k, v in DEFAULT_PARAMS.items()})
        if params:
            self.set_params(**params)

    # -- parameters ----------------------------------------------------------------------------
    def set_params(self, **kwargs) -> None:
        """Set parameters (validated; on error nothing changes).

        Parameters
        ----------
        **kwargs
            Any of the keys of :data:`DEFAULT_PARAMS`.

        Raises
        ------
        ModelInputError
            Unknown key, non-finite value, ``R_ohm <= 0``, ``G_eddy_S < 0``, ``h_sub_max_s <= 0``,
            an unknown drive mode, or ``1 + alpha_per_K T_start_excess_K <= 0``.
        """
        new = dict(self.params)
        for key, value in kwargs.items():
            new[key] = checked_param(key, value, self.tables, self._fx_data)
        if not 1.0 + new.get("alpha_per_K", 0.0) * new.get("T_start_excess_K", 0.0) > 0.0:
            raise ModelInputError(f"alpha_per_K {new['alpha_per_K']!r} and T_start_excess_K "
                                  f"{new['T_start_excess_K']!r} give the coil no positive resistance at ambient "
                                  "(1 + alpha T_0 <= 0)")
        self.params = new
        self._fx_on = any(new.get(k) for k in EFFECT_SWITCHES)
        if "R_ohm" in new and "G_eddy_S" in new and "drive_mode" in new and "h_sub_max_s" in new:
            R, G = new["R_ohm"], new["G_eddy_S"]
            voltage = new["drive_mode"] == DRIVE_VOLTAGE
            # (voltage?, R, G, m, c, 1 / h_sub_max) for the step's hot path
            self._fast = (voltage, R, G, (1.0 + R * G) if voltage else G, R if voltage else 1.0,
                          1.0 / new["h_sub_max_s"])

    @property
    def drive_mode(self) -> str:
        """``"voltage"`` or ``"current"``."""
        return "voltage" if self.params["drive_mode"] == DRIVE_VOLTAGE else "current"

    # -- state ---------------------------------------------------------------------------------
    def state_names(self) -> tuple:
        """Names of the state vector entries: :data:`STATE_NAMES`, then the effect states (if any)."""
        return STATE_NAMES + self._fx_names

    def get_state(self) -> list:
        """The full internal state as a new list of floats (order: :meth:`state_names`)."""
        return list(self._state) + list(self._fx)

    def set_state(self, state) -> None:
        """Restore a state from :meth:`get_state` exactly; pending events are dropped.

        Raises
        ------
        ModelInputError
            Wrong length or layout version, or a non-finite time or flux.
        """
        s = [float(v) for v in state]
        n = len(STATE_NAMES) + len(self._fx_names)
        if len(s) != n or s[ST_STATE_LAYOUT] != float(STATE_LAYOUT):
            layout = s[ST_STATE_LAYOUT] if s else None
            raise ModelInputError(f"state vector has {len(s)} entries and layout {layout!r}; "
                                  f"this model expects {n} entries, layout {STATE_LAYOUT}")
        for k, v in enumerate(s):
            if k in (ST_TIME_S, ST_PSI_WB) or k >= len(STATE_NAMES):
                if not math.isfinite(v):
                    raise ModelInputError(f"state {self.state_names()[k]} must be finite, got {v!r}")
        self._state = s[: len(STATE_NAMES)]
        self._fx = s[len(STATE_NAMES):]
        self._x_cache = (math.nan, (0, 0.0, False))
        self._end_cache = _NO_END
        self.events = []

    @property
    def time_s(self) -> float:
        """Model time [s]."""
        return self._state[ST_TIME_S]

    @property
    def psi_Wb(self) -> float:
        """Flux linkage [Wb] (the state)."""
        return self._state[ST_PSI_WB]

    @property
    def initialized(self) -> bool:
        """True once :meth:`initialize` has run."""
        return self._state[ST_INITIALIZED] != 0.0

    @property
    def i_A(self) -> float:
        """Coil current [A] (input echo in current mode)."""
        return self._state[ST_OUT_I_A]

    @property
    def U_V(self) -> float:
        """Coil voltage [V] (input echo in voltage mode; step mean in current mode)."""
        return self._state[ST_OUT_U_V]

    @property
    def F_N(self) -> float:
        """Magnetic force [N], positive closing the gap (paper eq. 3)."""
        return self._state[ST_OUT_F_N]

    @property
    def dpsi_dt_V(self) -> float:
        """Induced voltage dPsi/dt [V] (instantaneous in voltage mode, step mean in current mode)."""
        return self._state[ST_OUT_DPSI_DT_V]

    @property
    def i_eddy_A(self) -> float:
        """Eddy current G dPsi/dt [A] (paper eq. 2)."""
        return self._state[ST_OUT_I_EDDY_A]

    @property
    def out_of_map(self) -> bool:
        """True while x or Psi is clamped to the map."""
        return self._state[ST_EXCURSION_PSI] != 0.0 or self._state[ST_EXCURSION_X] != 0.0

    def outputs(self) -> dict:
        """All outputs at the last communication point, by name (units in the names)."""
        s = self._state
        out = {"i_A": s[ST_OUT_I_A], "U_V": s[ST_OUT_U_V], "F_N": s[ST_OUT_F_N], "psi_Wb": s[ST_PSI_WB],
               "dpsi_dt_V": s[ST_OUT_DPSI_DT_V], "i_eddy_A": s[ST_OUT_I_EDDY_A], "out_of_map": self.out_of_map}
        if self._fx_names:
            out["i_hyst_A"] = self.i_hyst_A
            out["T_rise_K"] = self.T_rise_K
        return out

    # -- simulation ----------------------------------------------------------------------------
    def _set_flag(self, s: list, name: str, on: bool, i_f_A: float = 0.0, x_m: float = 0.0) -> None:
        """Set an excursion flag; when it rises, queue one event (message built only then)."""
        k = STATE_INDEX[name]
        if on and s[k] == 0.0:
            tab = self.tables
            kind = name.split("_", 1)[1]
            if kind == "x":
                msg = (f"x_m = {x_m:.6g} m is outside the map's gap range [{tab.x_min_m:.6g}, "
                       f"{tab.x_max_m:.6g}] m; the lookups use the nearest edge until x returns into "
                       "the range")
            elif kind == "psi":
                msg = (f"|Psi| reached the map limit psi_max = {tab.psi_max_Wb:.6g} Wb (coil current beyond "
                       f"the maps' range); Psi is held at the limit until the drive lets it return")
            else:
                msg = (f"|i_f| = {abs(i_f_A):.6g} A is beyond the current range of the FEM sweep "
                       f"({tab.i_fem_max_A:.6g} A); the map is linearly extrapolated there")
            self.events.append((kind, EVENT_SEVERITY[kind], msg))
        s[k] = 1.0 if on else 0.0

    def _finish(self, s: list, psi: float, psi_clamped: bool, i_f: float, x_m: float, xc: bool) -> None:
        """Update the three excursion flags at the end of a step (cheap when nothing changes)."""
        if xc != (s[ST_EXCURSION_X] != 0.0):
            self._set_flag(s, "excursion_x", xc, x_m=x_m)
        if psi_clamped != (s[ST_EXCURSION_PSI] != 0.0):
            self._set_flag(s, "excursion_psi", psi_clamped)
        ext = (not psi_clamped) and abs(i_f) > self.tables.i_fem_max_A * (1.0 + 1e-9)
        if ext != (s[ST_EXCURSION_EXTRAPOLATED] != 0.0):
            self._set_flag(s, "excursion_extrapolated", ext, i_f_A=i_f)

    def initialize(self, u: float, x_m: float, t0_s: float = 0.0) -> None:
        """Set the start state at ``t0_s`` [s] and compute the outputs there.

        Parameters
        ----------
        u : float
            The drive input: ``U`` [V] in voltage mode, ``i`` [A] in current mode.
        x_m : float
            Working gap [m].
        t0_s : float
            Start time [s].

        Raises
        ------
        ModelInputError
            NaN or infinite input.
        """
        mode = self.params["drive_mode"]
        u = finite_float("U_V" if mode == DRIVE_VOLTAGE else "i_A", u)
        x_m = finite_float("x_m", x_m)
        t0_s = finite_float("t0_s", t0_s)
        tab = self.tables
        p = self.params
        R, G = p["R_ohm"], p["G_eddy_S"]
        s = [0.0] * len(STATE_NAMES)
        s[ST_STATE_LAYOUT] = float(STATE_LAYOUT)
        self.events = []
        j, w, xc = tab.x_cell(x_m)
        pm = tab.psi_max_Wb
        if mode == DRIVE_CURRENT and G == 0.0:
            psi, pc = solve_psi(tab, u, j, w, 0.0)
        else:
            psi = p["Psi0_Wb"]
            pc = abs(psi) > pm
            if pc:
                psi = math.copysign(pm, psi)
        i_f, force = tab.i_f_and_force(psi, j, w)
        if mode == DRIVE_VOLTAGE:
            dpsi = (u - R * i_f) / (1.0 + R * G)
            s[ST_OUT_I_A], s[ST_OUT_U_V] = i_f + G * dpsi, u
        else:
            dpsi = (u - i_f) / G if G > 0.0 else 0.0
            s[ST_OUT_I_A], s[ST_OUT_U_V] = u, R * u + dpsi
        s[ST_TIME_S], s[ST_PSI_WB], s[ST_INITIALIZED] = t0_s, psi, 1.0
        s[ST_OUT_F_N], s[ST_OUT_DPSI_DT_V], s[ST_OUT_I_EDDY_A] = force, dpsi, G * dpsi
        self._finish(s, psi, pc, i_f, x_m, xc)
        self._state = s
        if self._fx_names:
            fx = [0.0] * len(self._fx_names)
            fx[FX_X_PREV_M] = x_m
            for k in range(self._fx_play, len(fx)):
                fx[k] = psi  # plays neutral at the start flux (demagnetized state)
            self._fx = fx

    def step(self, h_s: float, u: float, x_m: float, t_s: float | None = None) -> None:
        """Advance one communication step of ``h_s`` [s] with the inputs held.

        Parameters
        ----------
        h_s : float
            Communication step [s], > 0.
        u : float
            The drive input over the step: ``U`` [V] (voltage mode) or ``i`` [A] (current mode).
        x_m : float
            Working gap over the step [m].
        t_s : float, optional
            Start time of the step [s] (the master's communication point); default: model time.

        Raises
        ------
        ModelInputError
            NaN or infinite input, ``h_s <= 0``, or the model not initialized. The state is
            left untouched.
        """
        s = self._state
        if s[ST_INITIALIZED] == 0.0:
            raise ModelInputError("step() before initialize()")
        voltage, R, G, m, c, inv_hsub = self._fast
        h = float(h_s)
        u = float(u)
        x_m = float(x_m)
        # x - x == 0 is False for NaN and +-inf: one cheap test for "finite"
        if not (h > 0.0 and h - h == 0.0 and u - u == 0.0 and x_m - x_m == 0.0):
            _refuse_step_inputs(h_s, h, u, x_m, voltage)
        if t_s is not None:
            t_s = float(t_s)
            if not t_s - t_s == 0.0:
                raise ModelInputError(f"step start time {t_s!r} is not finite")
        if h * inv_hsub > MAX_SUBSTEPS:  # also inf: h_sub_max_s = 1e-300 would never finish
            raise ModelInputError(f"step h = {h!r} s needs more than {MAX_SUBSTEPS:.0f} sub-steps of h_sub_max_s = "
                                  f"{1.0 / inv_hsub!r} s; take shorter communication steps or raise h_sub_max_s")
        if self._fx_on:
            self._step_fx(h, u, x_m, t_s)
        else:
            self._step_plain(h, u, x_m, t_s)

    def _x_cell_cached(self, x_m: float) -> tuple:
        """:meth:`MapTables.x_cell` of ``x_m``, remembered for the next step with the same gap."""
        cached_x, cell = self._x_cache
        if x_m == cached_x:
            return cell
        cell = self.tables.x_cell(x_m)
        self._x_cache = (x_m, cell)
        return cell

    def _step_plain(self, h: float, u: float, x_m: float, t_s) -> None:
        """One communication step without effect sub-models (inputs already checked)."""
        voltage, R, G, m, c, inv_hsub = self._fast
        tab = self.tables
        hot = tab.hot
        j, w, xc = self._x_cell_cached(x_m)
        s = list(self._state)
        psi0 = s[ST_PSI_WB]
        if m == 0.0:  # current mode without eddy currents: algebraic
            psi, pc = solve_psi(tab, u, j, w, psi0)
        else:
            n = math.ceil(h * inv_hsub - 1e-9)
            if n < 1:
                n = 1
            e_psi, e_j, e_w, e_v, e_d = self._end_cache  # i_f and slope at psi0 from the end of the last step
            if e_psi == psi0 and e_j == j and e_w == w:
                v0, d0 = e_v, e_d
            else:
                v0, d0, _ = eval_cell(hot, psi0, j, w)
            psi, pc = ros2(hot, psi0, v0, d0, m, u, c, h / n, n, j, w)
        i_f, d_end, force = eval_cell(hot, psi, j, w)
        self._end_cache = (psi, j, w, i_f, d_end)
        if voltage:
            dpsi = (u - R * i_f) / m
            s[ST_OUT_I_A] = i_f + G * dpsi
            s[ST_OUT_U_V] = u
        else:
            dpsi = (psi - psi0) / h
            s[ST_OUT_I_A] = u
            s[ST_OUT_U_V] = R * u + dpsi
        s[ST_TIME_S] = (s[ST_TIME_S] if t_s is None else t_s) + h
        s[ST_PSI_WB] = psi
        s[ST_OUT_F_N] = force
        s[ST_OUT_DPSI_DT_V] = dpsi
        s[ST_OUT_I_EDDY_A] = G * dpsi
        lim = tab.i_fem_max_A * (1.0 + 1e-9)
        ext = (not pc) and (i_f > lim or -i_f > lim)
        if (xc != (s[ST_EXCURSION_X] != 0.0) or pc != (s[ST_EXCURSION_PSI] != 0.0)
                or ext != (s[ST_EXCURSION_EXTRAPOLATED] != 0.0)):
            self._finish(s, psi, pc, i_f, x_m, xc)
        self._state = s

    # -- effect sub-models ---------------------------------------------------------------------
    @property
    def i_hyst_A(self) -> float:
        """Hysteresis current [A] of the play operator (0 without the effect)."""
        return self._fx[FX_I_HYST_A] if self._fx else 0.0

    @property
    def T_rise_K(self) -> float:
        """Coil temperature rise since initialization [K] (0 without heating)."""
        return self._fx[FX_T_RISE_K] if self._fx else 0.0

    def _step_fx(self, h: float, u: float, x_m: float, t_s) -> None:
        """One communication step with effect sub-models switched on (inputs already checked).

        Equations (SI), extending paper eqs. (1)-(3)::

            U = R(T) i + e,   e = dPsi/dt,   R(T) = R (1 + alpha T / (1 + alpha T_0))
            i = i_f(Psi, x) + i_h + G e + sum_k i_k
            tau_k di_k/dt = G_k e - i_k                   (eddy ladder sections)
            i_h = gain * g(Psi) * sum_j w_j (Psi - play_j(Psi))   (hysteresis, play operator)
            C_th dT/dt = R(T) i^2 - (T + T_0) / R_th      (heating, T = rise above start,
                                                           T_0 = T_start_excess_K above ambient)
            F = F(Psi, x) + F_fr,  F_fr -> +-F_c over |dx| ~ presliding (Dahl, sign of dx)

        The flux and the ladder currents are integrated together by ROS2 in mass-matrix form
        ``M y' = f(y)`` (the arrow-shaped system is solved in O(sections)); hysteresis and
        temperature are updated after every sub-step from the new flux (explicit, they change
        slowly with respect to a sub-step), friction once per communication step from the change
        of ``x``. Current drive with ``G = 0`` and no ladder solves ``i_f(Psi) = i - i_h``.
        """
        p = self.params
        fx = list(self._fx)
        s = list(self._state)
        tab = self.tables
        cfg = self._fx_settings()
        voltage, R0, G0 = cfg["voltage"], cfg["R0"], cfg["G0"]
        j, w, xc = tab.x_cell(x_m)
        nl = len(cfg["Gk"])
        play0 = self._fx_play
        plays = fx[play0:]
        n = max(1, math.ceil(h / p["h_sub_max_s"] - 1e-9))
        psi0 = s[ST_PSI_WB]
        psi, pc, ik, T, ih = fx_substeps(tab, cfg, u, j, w, psi0, fx[FX_LAD: FX_LAD + nl], plays,
                                         fx[FX_T_RISE_K], fx[FX_I_HYST_A], n, h / n)
        i_f, d_end, force = eval_cell(tab.hot, psi, j, w)
        self._end_cache = _NO_END
        R = R0 * (1.0 + cfg["alpha"] * T) if cfg["heat"] else R0
        sik = plain_sum(ik)
        if voltage:
            dpsi = (u - R * (i_f + ih + sik)) / (1.0 + R * G0)
            s[ST_OUT_I_A] = i_f + ih + G0 * dpsi + sik
            s[ST_OUT_U_V] = u
        else:
            dpsi = (psi - psi0) / h
            s[ST_OUT_I_A] = u
            s[ST_OUT_U_V] = R * u + dpsi
        ffr = fx[FX_F_FRICTION_N]
        if p["friction_on"]:
            ffr = dahl_friction(ffr, x_m - fx[FX_X_PREV_M], p["friction_N"], p["presliding_m"])
        s[ST_TIME_S] = (s[ST_TIME_S] if t_s is None else t_s) + h
        s[ST_PSI_WB] = psi
        s[ST_OUT_F_N] = force + ffr
        s[ST_OUT_DPSI_DT_V] = dpsi
        s[ST_OUT_I_EDDY_A] = G0 * dpsi + sik
        fx[FX_T_RISE_K], fx[FX_F_FRICTION_N], fx[FX_X_PREV_M], fx[FX_I_HYST_A] = T, ffr, x_m, ih
        fx[FX_LAD: FX_LAD + nl] = ik
        fx[play0:] = plays
        self._finish(s, psi, pc, i_f, x_m, xc)
        self._state = s
        self._fx = fx

    def _fx_settings(self) -> dict:
        """What :func:`~.integrate.fx_substeps` needs of the parameters and the effect data."""
        p = self.params
        lad = self._fx_data.get("eddy_ladder") if p["eddy_ladder_on"] else None
        return {"voltage": p["drive_mode"] == DRIVE_VOLTAGE, "R0": p["R_ohm"], "G0": p["G_eddy_S"],
                "heat": p["heating_on"], "alpha": heating_alpha(p["alpha_per_K"], p["T_start_excess_K"]),
                "Cth": p["C_th_J_per_K"],
                "Rth": p["R_th_K_per_W"], "T0": p["T_start_excess_K"],
                "Gk": lad["G_S"] if lad else (), "tk": lad["tau_s"] if lad else (),
                "hy": self._fx_data.get("hysteresis") if p["hysteresis_on"] else None, "gain": p["hyst_gain"]}


def _refuse_step_inputs(h_s, h: float, u: float, x_m: float, voltage: bool) -> None:
    """Raise the :class:`ModelInputError` that names the first input of a step that is not finite."""
    if not (h > 0.0 and math.isfinite(h)):
        raise ModelInputError(f"communication step must be finite and > 0 s, got {h_s!r}")
    if not math.isfinite(u):
        raise ModelInputError(f"input {'U_V' if voltage else 'i_A'} = {u!r} is not finite")
    raise ModelInputError(f"input x_m = {x_m!r} is not finite")
