r"""The real-time lumped solenoid model, paper eqs. (1)-(3) with the eddy-current term.

This module imports only numpy and the standard library: it is copied verbatim into every FMU
(as ``solenoid_model_<hash>.py``) and must not import anything from ``solenoid_fmu``. The
equations (SI units throughout)::

    U = R i + dPsi/dt                          paper eq. (1)
    i = i_f(Psi, x) + i_eddy,  i_eddy = G dPsi/dt   paper eq. (2), G = G_eddy [S] (the paper's L_eddy)
    F = F(Psi, x)                              paper eq. (3)

The state is the flux linkage ``Psi`` [Wb]; ``x`` [m] is the armature working gap (an input);
``F`` [N] is positive when it pulls the armature towards the pole (closing the gap).

Drive modes
-----------
``voltage`` (1): input ``U`` [V]. Eliminating ``i`` gives the ODE
``(1 + R G) dPsi/dt = U - R i_f(Psi, x)``. Outputs ``i``, ``dPsi/dt``, ``i_eddy``, ``F`` are
the instantaneous values at the communication point.

``current`` (2): input ``i`` [A]. With ``G > 0`` the ODE is ``G dPsi/dt = i - i_f(Psi, x)``;
with ``G = 0`` the relation is algebraic, ``i_f(Psi, x) = i``, solved by a safeguarded Newton
iteration. The outputs ``dPsi/dt``, ``U = R i + dPsi/dt`` and ``i_eddy = G dPsi/dt`` are the
exact means over the last communication step, ``dPsi/dt = (Psi(t+h) - Psi(t)) / h``: with a
held input current an instantaneous value would miss the flux jump at each communication point
(and would be zero in the algebraic case), while the mean is the voltage whose integral gives
the flux (the same relation the test rig uses, paper eq. 4). ``Psi`` and ``F`` are
instantaneous. Before the first step the instantaneous values are reported.

Inputs are held constant over a communication step (zero-order hold, FMI 2.0 co-simulation
without input interpolation). Outputs after a step are computed with the inputs of that step:
no output depends directly on an input set at the same communication point.

Map lookup (reproduce exactly in generated code)
------------------------------------------------
The maps are ``i_f(Psi, x)`` and ``F(Psi, x)`` on a regular flux grid ``psi_k = k dpsi``
(``k = 0 .. n_psi - 1``) times a strictly increasing gap grid ``x_j``. Along ``Psi`` the tables
are interpolated by a monotone piecewise cubic Hermite (PCHIP, C1 in ``Psi``; monotone data give
a monotone ``i_f``, so the inverse is unique); along ``x`` linearly. When the maps are loaded,
the node slopes (scaled by ``dpsi``, :func:`pchip_scaled_slopes`) are turned into the cubic
coefficients ``c0..c3`` of every cell and their differences ``e0..e3`` to the next x column
(:func:`cell_coefficients`); generated C embeds these arrays (:meth:`MapTables.tables`) rather
than recomputing them.

For ``Psi < 0`` the solenoid's symmetry is used (no remanence in the lumped map):
``i_f(-Psi, x) = -i_f(Psi, x)`` and ``F(-Psi, x) = F(Psi, x)``. Then, with ``a = |Psi|``
clamped to ``[0, psi_max]`` and ``x`` clamped to ``[x_0, x_last]``::

    s = a * inv_dpsi;  k = min(int(s), n_psi - 2);  t = s - k
    j = index of the x cell (bisect, clamped to 0 .. n_x - 2);  w = (x - x_j) * inv_dx_j
    (q0..q3, e0..e3) = coefficients of cell (k, j);  c_i = q_i + w * e_i
    value = c0 + t (c1 + t (c2 + t c3))
    d value / d Psi = (c1 + t (2 c2 + 3 t c3)) * inv_dpsi

Integrator
----------
Per communication step ``h`` the model takes ``n = max(1, ceil(h / h_sub_max - 1e-9))`` equal
sub-steps. An ODE sub-step is the two-stage, second-order, L-stable Rosenbrock method ROS2
(Verwer, Spee, Blom and Hundsdorfer 1999, gamma = 1 + 1/sqrt(2)) applied to
``m dPsi/dt = f(Psi) = b - c i_f(Psi, x)`` (voltage mode ``m = 1 + R G, b = U, c = R``;
current mode ``m = G, b = i, c = 1``)::

    W  = m + gamma * hs * c * di_f/dPsi(Psi_n)
    k1 = f(Psi_n) / W
    k2 = (f(Psi_n + hs k1) - 2 m k1) / W
    Psi_{n+1} = Psi_n + 1.5 hs k1 + 0.5 hs k2

It is linearly implicit, so its work is fixed (two map lookups per sub-step, no iteration; the
first lookup of a step reuses the output evaluation that ended the previous step when Psi and
the x cell are unchanged, which gives bit-identical values), it stays stable for any sub-step
(L-stable) and remains well defined for ``m -> 0``. The algebraic
case (current mode, ``G = 0``) solves ``i_f(Psi, x) = i`` once per communication step with a
Newton iteration safeguarded by bisection on ``[0, psi_max]`` (at most ``NEWTON_MAX_ITER``
iterations, stop when the update is below ``NEWTON_TOL_REL * psi_max``). Both paths have a
bounded amount of work per communication step, a requirement of real-time execution.

Out-of-map operation
--------------------
``x`` outside ``[x_0, x_last]`` and ``|Psi|`` beyond ``psi_max`` are clamped (the flux state
itself is held at ``+-psi_max``, so it does not wind up). Each excursion is reported once, when
it begins, as an event in :attr:`SolenoidModel.events` (the FMU turns each into one FMI log
message); it is reported again only after the value has returned into the map. Entering the
part of the map that lies beyond the FEM data (``|i_f|`` above the sweep's largest current
``i_A[-1]``, where the maps are linearly extrapolated) is reported the same way. A NaN or
infinite input, ``R <= 0`` or ``G < 0`` raises :class:`ModelInputError` and leaves the state
untouched.

State and parameters
--------------------
The full internal state is a flat list of floats (:meth:`SolenoidModel.get_state`,
:meth:`SolenoidModel.set_state`, names in :data:`STATE_NAMES`), so that a rollback is exact.
Parameters are a dict (:data:`DEFAULT_PARAMS`). Future effects (hysteresis play operators,
thermal state, eddy-current ladder, friction) append their states to the state vector (bumping
:data:`STATE_LAYOUT`) and add switchable parameters with defaults that keep today's behaviour.
"""

from __future__ import annotations

import bisect
import hashlib
import io
import json
import math
import os
import zipfile

import numpy as np

__all__ = [
    "COPPER_ALPHA_PER_K",
    "DEFAULT_PARAMS",
    "DRIVE_CURRENT",
    "DRIVE_VOLTAGE",
    "EFFECT_NAMES",
    "EFFECT_STATE_NAMES",
    "MAPS_SCHEMA",
    "MAPS_SCHEMA_VERSION",
    "MAX_SUBSTEPS",
    "MapTables",
    "ModelError",
    "ModelInputError",
    "ModelMapsError",
    "NEWTON_MAX_ITER",
    "NEWTON_TOL_REL",
    "ROS2_GAMMA",
    "SolenoidModel",
    "STATE_LAYOUT",
    "STATE_NAMES",
    "cell_coefficients",
    "effects_data",
    "load_tables",
    "pchip_scaled_slopes",
    "MAPS_JSON",
    "MAPS_NPZ",
    "read_maps_dir",
]

#: Schema name and version of a maps directory (``maps.json``) this model reads.
MAPS_SCHEMA = "solenoid-fmu-maps"
MAPS_SCHEMA_VERSION = 1
#: The two files of a maps directory (:func:`read_maps_dir`).
MAPS_JSON = "maps.json"
MAPS_NPZ = "maps.npz"
#: Folder in a map directory holding the earlier whole pair while a writer replaces it (maps.io.save_maps).
MAPS_PREVIOUS = ".maps-previous"
#: Most elements one array of a maps.npz may declare (a 1000 x 1000 grid is far beyond any sweep).
MAPS_MAX_ARRAY_ELEMENTS = 10_000_000

#: Drive modes (also the FMU enumeration values).
DRIVE_VOLTAGE = 1
DRIVE_CURRENT = 2
_DRIVE_NAMES = {"voltage": DRIVE_VOLTAGE, "current": DRIVE_CURRENT}

#: ROS2 parameter gamma = 1 + 1/sqrt(2).
ROS2_GAMMA = 1.0 + 1.0 / math.sqrt(2.0)
#: Newton iteration limits for the algebraic case (current mode, G = 0).
NEWTON_MAX_ITER = 60
NEWTON_TOL_REL = 1e-12

#: Layout version of the state vector; bumped whenever states are added.
STATE_LAYOUT = 1
#: Names of the state vector entries, in order (flags are 0.0 or 1.0).
STATE_NAMES = (
    "state_layout",  # STATE_LAYOUT
    "time_s",  # model time [s]
    "psi_Wb",  # flux linkage [Wb], the ODE state
    "initialized",  # 1.0 once initialize() has run
    "excursion_psi",  # |Psi| held at psi_max
    "excursion_x",  # x clamped to the map's gap range
    "excursion_extrapolated",  # (Psi, x) beyond the FEM data of the map
    "out_i_A",  # outputs held since the last communication point
    "out_U_V",
    "out_F_N",
    "out_dpsi_dt_V",
    "out_i_eddy_A",
)
_IDX = {name: k for k, name in enumerate(STATE_NAMES)}

#: Parameters and their defaults; ``None`` means "take the value from maps.json".
DEFAULT_PARAMS = {
    "R_ohm": None,  # coil resistance at 20 degC [ohm] (maps.json coil.resistance_ohm_20C)
    "G_eddy_S": None,  # eddy-current conductance [S] (maps.json eddy.G_eddy_S, 0 if null)
    "drive_mode": "voltage",  # "voltage" / "current" (or DRIVE_VOLTAGE / DRIVE_CURRENT)
    "Psi0_Wb": 0.0,  # initial flux linkage [Wb] (ignored in current mode with G = 0)
    "h_sub_max_s": 1e-4,  # largest internal sub-step [s]
    # switchable effect sub-models (issue 7); None = "as maps.json's effects section says"
    "hysteresis_on": None,  # magnetic hysteresis (play operator on Psi, extra current [A])
    "hyst_gain": 1.0,  # factor on the hysteresis current [-]
    "eddy_ladder_on": None,  # frequency-dependent eddy currents (R-L sections beside G_eddy)
    "heating_on": None,  # coil heating: R(T) with a first-order thermal model
    "C_th_J_per_K": None,  # heat capacity of the coil [J/K]
    "R_th_K_per_W": None,  # thermal resistance to ambient [K/W]
    "alpha_per_K": None,  # temperature coefficient of R [1/K]
    "friction_on": None,  # friction in the force output (Dahl model in x)
    "friction_N": None,  # sliding friction force [N]
    "presliding_m": None,  # presliding displacement of the Dahl model [m]
}

#: Temperature coefficient of copper's resistance at 20 degC [1/K]; the one value every module uses.
COPPER_ALPHA_PER_K = 0.00393

#: Names of the effect sub-models (the ``effects`` section of maps.json; issue 7).
EFFECT_NAMES = ("hysteresis", "eddy_ladder", "heating", "friction")
#: Defaults of the effect scalars when the effects section leaves them out.
_EFFECT_DEFAULTS = {"C_th_J_per_K": 300.0, "R_th_K_per_W": 1.0, "alpha_per_K": COPPER_ALPHA_PER_K, "friction_N": 0.0,
                    "presliding_m": 20e-6}
_SWITCHES = {"hysteresis_on": "hysteresis", "eddy_ladder_on": "eddy_ladder", "heating_on": "heating",
             "friction_on": "friction"}
_EFFECT_SCALARS = {"C_th_J_per_K": ("heating", "C_th_J_per_K"), "R_th_K_per_W": ("heating", "R_th_K_per_W"),
                   "alpha_per_K": ("heating", "alpha_per_K"), "friction_N": ("friction", "force_N"),
                   "presliding_m": ("friction", "presliding_m")}
#: Names of the effect states appended to the state vector when the maps carry effects
#: (followed by one ``ladder_k`` per eddy section and one ``play_k`` per hysteresis play).
EFFECT_STATE_NAMES = ("T_rise_K", "F_friction_N", "x_prev_m", "i_hyst_A")

#: Severity of the excursion events (FMI log status names).
_EVENT_SEVERITY = {
    "psi": "warning",
    "x": "warning",
    "extrapolated": "warning",
}


class ModelError(Exception):
    """Base class of the errors this module raises (it cannot import the package's errors)."""


#: Most sub-steps one communication step may take (as the native FMU's MAX_SUBSTEPS): beyond it the
#: step is refused, never run for hours.
MAX_SUBSTEPS = 1.0e7


class ModelInputError(ModelError, ValueError):
    """An input or parameter is invalid: NaN or infinite, ``R <= 0``, ``G < 0``, bad mode."""


class ModelMapsError(ModelError):
    """The maps directory is missing, malformed, or breaks what the model needs."""


def pchip_scaled_slopes(y, *, symmetry: str) -> np.ndarray:
    """Monotone (PCHIP) node slopes of a table on a regular grid, scaled by the spacing.

    Parameters
    ----------
    y : array-like, shape (n, m)
        Table values; axis 0 is the regular grid (``n >= 2``), each column is interpolated
        separately.
    symmetry : {"odd", "even"}
        Symmetry of the data about the first node, which sits at zero: ``"odd"`` for
        ``i_f(Psi)`` (slope at zero from the mirrored secant, i.e. the first secant),
        ``"even"`` for ``F(Psi)`` (slope zero at zero).

    Returns
    -------
    numpy.ndarray, shape (n, m)
        ``m_k = dpsi * dy/dPsi`` at each node, in the units of ``y``. Interior nodes: the
        harmonic mean of the two adjacent secants when they have the same sign, else 0
        (Fritsch-Butland, the PCHIP rule on a uniform grid); last node: the last secant.
    """
    y = np.asarray(y, dtype=float)
    if y.ndim != 2 or y.shape[0] < 2:
        raise ModelMapsError(f"pchip_scaled_slopes needs a (n >= 2, m) table, got shape {y.shape}")
    s = np.diff(y, axis=0)  # scaled secants, shape (n-1, m)
    m = np.zeros_like(y)
    a, b = s[:-1], s[1:]
    same = (a * b) > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        hm = np.where(same, 2.0 * a * b / np.where(same, a + b, 1.0), 0.0)
    m[1:-1] = hm
    m[-1] = s[-1]
    if symmetry == "odd":
        m[0] = s[0]
    elif symmetry == "even":
        m[0] = 0.0
    else:
        raise ModelMapsError(f"symmetry must be 'odd' or 'even', got {symmetry!r}")
    return m


def cell_coefficients(y, m) -> np.ndarray:
    """Cubic coefficients of every cell of a Hermite table, and their differences along x.

    Parameters
    ----------
    y : array-like, shape (n, nx)
        Node values on the regular grid (axis 0) for each x column.
    m : array-like, shape (n, nx)
        Node slopes scaled by the grid spacing (:func:`pchip_scaled_slopes`).

    Returns
    -------
    numpy.ndarray, shape (n - 1, nx - 1, 8)
        For cell ``k`` and x cell ``j``: ``c0 = y_k``, ``c1 = m_k``,
        ``c2 = 3 (y_k+1 - y_k) - 2 m_k - m_k+1``, ``c3 = 2 (y_k - y_k+1) + m_k + m_k+1`` of column
        ``j``, then ``e_i = c_i(column j + 1) - c_i(column j)``. The lookup evaluates
        ``c_i + w e_i`` and ``c0 + t (c1 + t (c2 + t c3))`` with ``t`` the position in the cell.
    """
    y = np.asarray(y, dtype=float)
    m = np.asarray(m, dtype=float)
    y0, y1, m0, m1 = y[:-1], y[1:], m[:-1], m[1:]
    c = np.stack([y0, m0, 3.0 * (y1 - y0) - 2.0 * m0 - m1, 2.0 * (y0 - y1) + m0 + m1], axis=-1)
    e = c[:, 1:, :] - c[:, :-1, :]
    return np.concatenate([c[:, :-1, :], e], axis=-1)


def _cell_tuples(coef: np.ndarray) -> list:
    """Flatten (n - 1, nx - 1, 8) coefficients into a list of 8-tuples of Python floats."""
    return [tuple(row) for row in coef.reshape(-1, 8).tolist()]


class MapTables:
    """Characteristic maps ``i_f(Psi, x)`` and ``F(Psi, x)`` prepared for scalar lookups.

    Parameters
    ----------
    psi_Wb : array-like, shape (n_psi,)
        Regular flux-linkage grid from 0 [Wb].
    x_m : array-like, shape (n_x,)
        Strictly increasing working-gap grid [m].
    i_f_A : array-like, shape (n_psi, n_x)
        Field-generating current ``i_f(Psi, x)`` [A] (paper eq. 2), strictly increasing in Psi.
    force_N : array-like, shape (n_psi, n_x)
        Force ``F(Psi, x)`` [N] (paper eq. 3), positive closing the gap.
    extrapolated : array-like, shape (n_psi, n_x), optional
        1.0 where the node lies beyond the FEM data of its column (kept for reference).
    meta : dict, optional
        The ``maps.json`` sidecar (coil, eddy, provenance); kept as given.
    where : str
        Name used in error messages (the maps directory).
    i_fem_max_A : float, optional
        Largest current of the FEM sweep [A] (the maps' ``i_A[-1]``); beyond it the map is
        extrapolated and the model reports an event. Default: ``meta["coil"]["max_current_A"]``,
        else no limit.

    Notes
    -----
    The tables are kept as Python lists of floats: the scalar lookups of the real-time step are
    several times faster on lists than on numpy scalars.
    """

    def __init__(self, psi_Wb, x_m, i_f_A, force_N, extrapolated=None, meta=None, where="maps",
                 i_fem_max_A=None):
        psi = np.asarray(psi_Wb, dtype=float)
        x = np.asarray(x_m, dtype=float)
        i_f = np.asarray(i_f_A, dtype=float)
        force = np.asarray(force_N, dtype=float)
        problems = []
        if psi.ndim != 1 or psi.size < 3:
            problems.append(f"psi_Wb must be 1-D with at least 3 points, got shape {psi.shape}")
        if x.ndim != 1 or x.size < 2:
            problems.append(f"x_m must be 1-D with at least 2 points, got shape {x.shape}")
        if problems:
            raise ModelMapsError(f"{where}: " + "; ".join(problems))
        shape = (psi.size, x.size)
        for name, arr in (("i_f_A", i_f), ("force_N", force)):
            if arr.shape != shape:
                problems.append(f"{name} has shape {arr.shape}, expected (n_psi, n_x) = {shape}")
        if extrapolated is not None:
            extrapolated = np.asarray(extrapolated, dtype=float)
            if extrapolated.shape != shape:
                problems.append(f"extrapolated has shape {extrapolated.shape}, expected {shape}")
        if problems:
            raise ModelMapsError(f"{where}: " + "; ".join(problems))
        for name, arr in (("psi_Wb", psi), ("x_m", x), ("i_f_A", i_f), ("force_N", force)):
            bad = np.argwhere(~np.isfinite(arr))
            if bad.size:
                problems.append(f"{name} has {len(bad)} non-finite value(s), first at index {tuple(bad[0])}")
        if problems:
            raise ModelMapsError(f"{where}: " + "; ".join(problems))
        dpsi = (psi[-1] - psi[0]) / (psi.size - 1)
        if not dpsi > 0.0:
            raise ModelMapsError(f"{where}: psi_Wb must increase, got {psi[0]} .. {psi[-1]} Wb")
        if abs(psi[0]) > 1e-12 * psi[-1]:
            raise ModelMapsError(f"{where}: psi_Wb must start at 0 Wb, starts at {psi[0]!r} Wb")
        dev = np.max(np.abs(np.diff(psi) - dpsi))
        if dev > 1e-9 * dpsi:
            raise ModelMapsError(f"{where}: psi_Wb must be a regular grid; spacing deviates by {dev:.3g} Wb")
        dx = np.diff(x)
        if np.any(dx <= 0.0):
            k = int(np.argmax(dx <= 0.0))
            raise ModelMapsError(f"{where}: x_m must be strictly increasing; x_m[{k + 1}] = {x[k + 1]!r} m "
                                 f"<= x_m[{k}] = {x[k]!r} m")
        di = np.diff(i_f, axis=0)
        if np.any(di <= 0.0):
            k, j = (int(v) for v in np.argwhere(di <= 0.0)[0])
            raise ModelMapsError(
                f"{where}: i_f_A must increase strictly with Psi (unique current for each flux); "
                f"at x = {x[j]:.6g} m it goes from {i_f[k, j]:.6g} A to {i_f[k + 1, j]:.6g} A "
                f"between Psi = {psi[k]:.6g} and {psi[k + 1]:.6g} Wb")
        scale = float(np.max(np.abs(i_f)))
        j0 = int(np.argmax(np.abs(i_f[0])))
        if abs(i_f[0, j0]) > 1e-6 * scale:
            raise ModelMapsError(f"{where}: i_f_A at Psi = 0 must be 0 A (no remanence); it is "
                                 f"{i_f[0, j0]:.6g} A at x = {x[j0]:.6g} m")

        self.where = where
        self.meta = dict(meta) if meta else {}
        self.n_psi = int(psi.size)
        self.n_x = int(x.size)
        self.dpsi_Wb = float(dpsi)
        self.inv_dpsi = 1.0 / self.dpsi_Wb
        self.psi_max_Wb = float(dpsi * (psi.size - 1))
        self.x_m = [float(v) for v in x]
        self.x_min_m = self.x_m[0]
        self.x_max_m = self.x_m[-1]
        self.inv_dx = [1.0 / float(v) for v in dx]
        self._i_f_np = i_f.copy()
        self._force_np = force.copy()
        m_if = pchip_scaled_slopes(i_f, symmetry="odd")
        m_f = pchip_scaled_slopes(force, symmetry="even")
        self._m_if_np = m_if
        self._m_f_np = m_f
        self._coef_if = cell_coefficients(i_f, m_if)
        self._coef_f = cell_coefficients(force, m_f)
        self.CI = _cell_tuples(self._coef_if)  # index k * (n_x - 1) + j
        self.CF = _cell_tuples(self._coef_f)
        # Largest current of the FEM sweep: beyond it the map is extrapolated (event).
        if i_fem_max_A is None:
            i_fem_max_A = (self.meta.get("coil") or {}).get("max_current_A")
        self.i_fem_max_A = math.inf if i_fem_max_A is None else float(i_fem_max_A)
        self.extrapolated = None if extrapolated is None else extrapolated.copy()
        self._hot = (self.CI, self.CF, self.n_x - 1, self.n_psi - 2, self.inv_dpsi, self.psi_max_Wb)

    # -- scalar lookups ------------------------------------------------------------------------
    def x_cell(self, x_m: float) -> tuple[int, float, bool]:
        """Cell of the gap grid for ``x_m`` [m].

        Returns
        -------
        j : int
            Cell index, ``0 <= j <= n_x - 2``.
        w : float
            Weight of column ``j + 1`` (0 .. 1) for linear interpolation in x.
        clamped : bool
            True when ``x_m`` lay outside ``[x_0, x_last]`` and was clamped.
        """
        xs = self.x_m
        clamped = False
        if x_m <= xs[0]:
            clamped = x_m < xs[0]
            return 0, 0.0, clamped
        if x_m >= xs[-1]:
            clamped = x_m > xs[-1]
            return self.n_x - 2, 1.0, clamped
        j = bisect.bisect_right(xs, x_m) - 1
        if j > self.n_x - 2:
            j = self.n_x - 2
        return j, (x_m - xs[j]) * self.inv_dx[j], clamped

    def _cubic(self, C, a, j, w):
        """Value and d/dPsi of the cell cubics C at |Psi| = a (clamped) in x cell (j, w)."""
        if a > self.psi_max_Wb:
            a = self.psi_max_Wb
        sc = a * self.inv_dpsi
        k = int(sc)
        if k > self.n_psi - 2:
            k = self.n_psi - 2
        t = sc - k
        q0, q1, q2, q3, e0, e1, e2, e3 = C[k * (self.n_x - 1) + j]
        c0 = q0 + w * e0
        c1 = q1 + w * e1
        c2 = q2 + w * e2
        c3 = q3 + w * e3
        return c0 + t * (c1 + t * (c2 + t * c3)), (c1 + t * (2.0 * c2 + 3.0 * t * c3)) * self.inv_dpsi

    def i_f_and_slope(self, psi_Wb: float, j: int, w: float) -> tuple[float, float]:
        """``i_f(Psi, x)`` [A] and ``d i_f / d Psi`` [A/Wb] in x cell ``(j, w)`` (odd in Psi)."""
        if psi_Wb < 0.0:
            v, d = self._cubic(self.CI, -psi_Wb, j, w)
            return -v, d
        return self._cubic(self.CI, psi_Wb, j, w)

    def i_f_and_force(self, psi_Wb: float, j: int, w: float) -> tuple[float, float]:
        """``i_f(Psi, x)`` [A] and ``F(Psi, x)`` [N] in x cell ``(j, w)``."""
        v, _, f = _eval(self._hot, psi_Wb, j, w)
        return v, f

    def force_in_cell(self, psi_Wb: float, j: int, w: float) -> float:
        """``F(Psi, x)`` [N] in x cell ``(j, w)`` (even in Psi)."""
        return self._cubic(self.CF, abs(psi_Wb), j, w)[0]

    def i_f_A(self, psi_Wb: float, x_m: float) -> float:
        """Field-generating current ``i_f(Psi, x)`` [A], paper eq. (2); inputs clamped to the map."""
        j, w, _ = self.x_cell(float(x_m))
        return self.i_f_and_slope(float(psi_Wb), j, w)[0]

    def di_f_dpsi(self, psi_Wb: float, x_m: float) -> float:
        """``d i_f / d Psi`` [A/Wb] at ``(Psi, x)`` (the inverse differential inductance)."""
        j, w, _ = self.x_cell(float(x_m))
        return self.i_f_and_slope(float(psi_Wb), j, w)[1]

    def force_N(self, psi_Wb: float, x_m: float) -> float:
        """Force ``F(Psi, x)`` [N], paper eq. (3); positive closing the gap; inputs clamped."""
        j, w, _ = self.x_cell(float(x_m))
        return self.force_in_cell(float(psi_Wb), j, w)

    def psi_of_current(self, i_A: float, x_m: float) -> float:
        """Inverse map: ``Psi`` [Wb] with ``i_f(Psi, x) = i_A``, clamped to ``+-psi_max``."""
        j, w, _ = self.x_cell(float(x_m))
        return _solve_psi(self, float(i_A), j, w, 0.0)[0]

    def tables(self) -> dict:
        """The exact arrays the lookups use (for generated code), as float64 numpy arrays.

        Returns
        -------
        dict
            ``dpsi_Wb``, ``psi_max_Wb``, ``x_m`` (n_x,), ``i_f_A`` and ``i_f_slope_A``
            (n_psi, n_x; slope scaled by dpsi), ``force_N`` and ``force_slope_N``,
            ``i_f_coef`` and ``force_coef`` (n_psi - 1, n_x - 1, 8: the cell cubics
            ``c0..c3`` of column j and their differences ``e0..e3`` to column j + 1, as used by
            the lookup), ``i_fem_max_A`` (float).
        """
        return {
            "dpsi_Wb": self.dpsi_Wb,
            "psi_max_Wb": self.psi_max_Wb,
            "x_m": np.array(self.x_m),
            "i_f_A": self._i_f_np.copy(),
            "i_f_slope_A": self._m_if_np.copy(),
            "force_N": self._force_np.copy(),
            "force_slope_N": self._m_f_np.copy(),
            "i_f_coef": self._coef_if.copy(),
            "force_coef": self._coef_f.copy(),
            "i_fem_max_A": self.i_fem_max_A,
        }

    @property
    def resistance_ohm_20C(self) -> float | None:
        """Coil resistance at 20 degC [ohm] from ``maps.json``, or None."""
        v = (self.meta.get("coil") or {}).get("resistance_ohm_20C")
        return None if v is None else float(v)

    @property
    def G_eddy_S(self) -> float | None:
        """Eddy-current conductance [S] from ``maps.json``, or None when not identified."""
        v = (self.meta.get("eddy") or {}).get("G_eddy_S")
        return None if v is None else float(v)


def _solve_psi(tab: MapTables, i_A: float, j: int, w: float, psi_guess: float) -> tuple[float, bool]:
    """Solve ``i_f(Psi, x) = i_A`` for Psi [Wb] (safeguarded Newton); returns (Psi, clamped)."""
    if i_A == 0.0:
        return 0.0, False
    target = abs(i_A)
    sign = -1.0 if i_A < 0.0 else 1.0
    hi = tab.psi_max_Wb
    g_hi = tab.i_f_and_slope(hi, j, w)[0] - target
    if g_hi <= 0.0:
        return sign * hi, g_hi < 0.0
    lo = 0.0
    y = abs(psi_guess)
    if not lo < y < hi:
        y = 0.5 * hi
    tol = NEWTON_TOL_REL * hi
    for _ in range(NEWTON_MAX_ITER):
        v, d = tab.i_f_and_slope(y, j, w)
        g = v - target
        if g == 0.0:
            break
        if g < 0.0:
            lo = y
        else:
            hi = y
        y_new = y - g / d if d > 0.0 else 0.5 * (lo + hi)
        if not lo < y_new < hi:
            y_new = 0.5 * (lo + hi)
        step = abs(y_new - y)
        y = y_new
        if step <= tol:
            break
    return sign * y, False


def _first_non_finite(obj, where: str = ""):
    """(key path, value) of the first NaN or infinite number in parsed JSON ``obj``, or None."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return where or "(top level)", obj
    items = obj.items() if isinstance(obj, dict) else enumerate(obj) if isinstance(obj, list) else ()
    for key, value in items:
        found = _first_non_finite(value, f"{where}[{key}]" if isinstance(key, int) else
                                  f"{where}.{key}" if where else str(key))
        if found is not None:
            return found
    return None


def _npz_member_problems(raw: bytes, shapes) -> list:
    """Problems of the members of a maps.npz read from their .npy headers (not their data): a dtype that
    is not numeric or boolean, a shape other than maps.json's ``arrays.shapes`` says, or more than
    :data:`MAPS_MAX_ARRAY_ELEMENTS` elements (a small file must not make the reader allocate gigabytes)."""
    problems = []
    with zipfile.ZipFile(io.BytesIO(raw)) as zf:
        for info in zf.infolist():
            name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            with zf.open(info) as fh:
                try:
                    version = np.lib.format.read_magic(fh)
                    if version == (1, 0):
                        shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
                    else:
                        shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
                except ValueError as exc:
                    problems.append(f"member {name!r}: not a .npy array ({exc})")
                    continue
            if dtype.kind not in "fiub":
                problems.append(f"member {name!r}: dtype {dtype} is not numeric")
            n = int(np.prod(shape, dtype=np.float64))
            if n > MAPS_MAX_ARRAY_ELEMENTS:
                problems.append(f"member {name!r}: declares {n} elements (shape {shape}), more than "
                                f"{MAPS_MAX_ARRAY_ELEMENTS}")
            elif isinstance(shapes, dict) and name in shapes and list(shape) != list(shapes[name]):
                problems.append(f"{name} has shape {tuple(shape)}, expected {tuple(shapes[name])} "
                                f"(maps.json arrays.shapes)")
    return problems


def maps_pair_consistent(maps_dir) -> bool:
    """True if ``maps_dir`` holds ``maps.json`` and ``maps.npz`` written together: the sidecar parses and
    records the npz file's sha256, and it matches."""
    try:
        with open(os.path.join(maps_dir, MAPS_JSON), encoding="utf-8") as fh:
            meta = json.load(fh)
        with open(os.path.join(maps_dir, MAPS_NPZ), "rb") as fh:
            digest = hashlib.sha256(fh.read()).hexdigest()
    except (OSError, ValueError):
        return False
    entry = meta.get("arrays") if isinstance(meta, dict) else None
    return isinstance(entry, dict) and entry.get("sha256") == digest


def read_maps_dir(maps_dir, check_meta=None) -> tuple:
    """Read a maps directory as stored: the ``maps.json`` sidecar and the ``maps.npz`` arrays.

    The one reader of the maps file format: :func:`load_tables` (the model, also inside every FMU)
    and ``solenoid_fmu.maps.load_maps`` (which adds the checks of what the content means) build on it.
    It refuses, naming the file: a missing file, JSON that is not valid (with its line), NaN or
    Infinity anywhere in the sidecar, a schema or schema version other than :data:`MAPS_SCHEMA`
    :data:`MAPS_SCHEMA_VERSION`, a ``maps.npz`` whose sha256 is not the one the sidecar records under
    ``"arrays"`` (files without that entry, written by other tools in the shared format, are
    accepted), members that are not numeric, larger than :data:`MAPS_MAX_ARRAY_ELEMENTS` or shaped
    other than the sidecar says (checked on their headers before any data is read), and pickles.
    A pair that does not match because its writer was killed between its two renames is read from
    the earlier whole pair the writer kept in :data:`MAPS_PREVIOUS` (so a reader sees the old or the
    new maps, whole).

    Parameters
    ----------
    maps_dir : str or path-like
        Directory holding ``maps.json`` and ``maps.npz``.
    check_meta : callable, optional
        ``check_meta(meta, json_path)``, called once the sidecar's schema is checked and before the
        npz is read; it raises to refuse the sidecar.

    Returns
    -------
    meta : dict
        The sidecar as parsed.
    arrays : dict
        The npz members by name, as stored (numeric ndarrays).

    Raises
    ------
    ModelMapsError
    """
    maps_dir = os.fspath(maps_dir)
    json_path = os.path.join(maps_dir, MAPS_JSON)
    npz_path = os.path.join(maps_dir, MAPS_NPZ)
    if not os.path.isdir(maps_dir):
        raise ModelMapsError(f"{maps_dir}: no such map directory")
    for p in (json_path, npz_path):
        if not os.path.isfile(p):
            raise ModelMapsError(f"{p}: missing (a map directory holds {MAPS_JSON} and {MAPS_NPZ})")
    try:
        with open(json_path, encoding="utf-8") as fh:
            meta = json.load(fh)
    except json.JSONDecodeError as exc:
        raise ModelMapsError(f"{json_path}:{exc.lineno}: not valid JSON: {exc.msg}") from None
    except UnicodeDecodeError:
        raise ModelMapsError(f"{json_path}: not UTF-8 text") from None
    except OSError as exc:
        raise ModelMapsError(f"{json_path}: cannot be read: {exc.strerror}") from None
    if not isinstance(meta, dict):
        raise ModelMapsError(f"{json_path}: top level must be a JSON object")
    bad = _first_non_finite(meta)
    if bad is not None:
        raise ModelMapsError(f"{json_path}: {bad[0]} = {bad[1]!r} is not a finite number (NaN and Infinity are "
                             "not JSON and would reach the FMU)")
    if meta.get("schema") != MAPS_SCHEMA:
        raise ModelMapsError(f"{json_path}: schema is {meta.get('schema')!r}, expected {MAPS_SCHEMA!r}: "
                             "not a map file")
    version = meta.get("schema_version")
    if version != MAPS_SCHEMA_VERSION or isinstance(version, bool):
        raise ModelMapsError(
            f"{json_path}: schema_version {version!r} is not supported; this reader reads schema_version "
            f"{MAPS_SCHEMA_VERSION} (rebuild the maps with `solenoid-fmu maps`)")
    if check_meta is not None:
        check_meta(meta, json_path)
    try:
        with open(npz_path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise ModelMapsError(f"{npz_path}: cannot be read: {exc.strerror}") from None
    entry = meta.get("arrays") if isinstance(meta.get("arrays"), dict) else {}
    recorded = entry.get("sha256")
    digest = hashlib.sha256(raw).hexdigest()
    if isinstance(recorded, str) and digest != recorded:
        previous = os.path.join(maps_dir, MAPS_PREVIOUS)
        if maps_pair_consistent(previous):  # a writer was killed between its renames: the earlier pair
            return read_maps_dir(previous, check_meta)
        raise ModelMapsError(f"{npz_path}: sha256 {digest[:12]}... does not match the {recorded[:12]}... recorded "
                             f"in {MAPS_JSON}; the two files were not written together")
    try:
        problems = _npz_member_problems(raw, entry.get("shapes"))
    except zipfile.BadZipFile as exc:
        raise ModelMapsError(f"{npz_path}: not a npz (zip) file: {exc}") from None
    if problems:
        raise ModelMapsError("\n".join([f"{npz_path}: {len(problems)} problem(s)"] + [f"  - {p}" for p in problems]))
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as data:
            arrays = {k: np.array(data[k]) for k in data.files}
    except ValueError as exc:  # object arrays refused by allow_pickle=False, corrupt members
        raise ModelMapsError(f"{npz_path}: cannot read arrays without pickle: {exc}") from None
    except Exception as exc:  # zipfile.BadZipFile, EOFError, OSError and friends
        raise ModelMapsError(f"{npz_path}: not a readable npz file: {type(exc).__name__}: {exc}") from None
    return meta, arrays


def load_tables(maps_dir) -> MapTables:
    """Read a maps directory (``maps.npz`` + ``maps.json``, :func:`read_maps_dir`) into :class:`MapTables`.

    Parameters
    ----------
    maps_dir : str or path-like
        Directory holding ``maps.npz`` (loaded with ``allow_pickle=False``) and ``maps.json``.

    Returns
    -------
    MapTables

    Raises
    ------
    ModelMapsError
        Missing files, wrong schema or version, missing arrays, or maps the model cannot use.
    """
    meta, arrays = read_maps_dir(maps_dir)
    npz_path = os.path.join(os.fspath(maps_dir), MAPS_NPZ)
    missing = [k for k in ("psi_Wb", "x_m", "i_f_A", "force_N") if k not in arrays]
    if missing:
        raise ModelMapsError(f"{npz_path}: missing array(s) {', '.join(missing)}")
    i_sweep = arrays.get("i_A")
    i_fem_max = float(np.max(i_sweep)) if i_sweep is not None and np.size(i_sweep) else None
    return MapTables(arrays["psi_Wb"], arrays["x_m"], arrays["i_f_A"], arrays["force_N"],
                     extrapolated=arrays.get("extrapolated"), meta=meta, where=os.fspath(maps_dir),
                     i_fem_max_A=i_fem_max)


def _finite(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ModelInputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ModelInputError(f"{name} must be finite, got {v!r}")
    return v


class SolenoidModel:
    """The lumped real-time solenoid model (paper eqs. 1-3), one instance per simulated coil.

    Parameters
    ----------
    tables : MapTables
        The characteristic maps.
    params : dict, optional
        Overrides of :data:`DEFAULT_PARAMS`: ``R_ohm`` [ohm] (> 0, at 20 degC), ``G_eddy_S`` [S]
        (>= 0), ``drive_mode`` ("voltage"/"current" or 1/2), ``Psi0_Wb`` [Wb],
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
        self._end_cache = (math.nan, -1, math.nan, 0.0, 0.0)
        self._state = [0.0] * len(STATE_NAMES)
        self._state[0] = float(STATE_LAYOUT)
        self._fx_data = effects_data(tables)
        self._fx_on = False
        n_lad = len((self._fx_data.get("eddy_ladder") or {}).get("G_S", ()))
        n_play = len((self._fx_data.get("hysteresis") or {}).get("thresholds", ()))
        self._fx_names = (EFFECT_STATE_NAMES + tuple(f"ladder_{k}" for k in range(n_lad))
                          + tuple(f"play_{k}" for k in range(n_play))) if self._fx_data else ()
        self._fx = [0.0] * len(self._fx_names)
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
            or an unknown drive mode.
        """
        new = dict(self.params)
        for key, value in kwargs.items():
            if key not in DEFAULT_PARAMS:
                raise ModelInputError(f"unknown parameter {key!r}; known: {', '.join(DEFAULT_PARAMS)}")
            if key == "R_ohm":
                if value is None:
                    value = self.tables.resistance_ohm_20C
                    if value is None:
                        raise ModelInputError("R_ohm not given and maps.json has no coil.resistance_ohm_20C")
                v = _finite("R_ohm", value)
                if v <= 0.0:
                    raise ModelInputError(f"R_ohm must be > 0 ohm, got {v!r}")
                new[key] = v
            elif key == "G_eddy_S":
                if value is None:
                    value = self.tables.G_eddy_S or 0.0
                v = _finite("G_eddy_S", value)
                if v < 0.0:
                    raise ModelInputError(f"G_eddy_S must be >= 0 S, got {v!r}")
                new[key] = v
            elif key == "drive_mode":
                new[key] = _drive_code(value)
            elif key == "Psi0_Wb":
                new[key] = _finite("Psi0_Wb", value)
            elif key == "h_sub_max_s":
                v = _finite("h_sub_max_s", value)
                if v <= 0.0:
                    raise ModelInputError(f"h_sub_max_s must be > 0 s, got {v!r}")
                new[key] = v
            elif key in _SWITCHES:
                name = _SWITCHES[key]
                on = (name in self._fx_data) if value is None else bool(value)
                if on and name not in self._fx_data:
                    raise ModelInputError(f"{key}: the maps carry no {name!r} effect (maps.json 'effects')")
                new[key] = on
            elif key == "hyst_gain":
                v = _finite(key, value)
                if v < 0.0:
                    raise ModelInputError(f"hyst_gain must be >= 0, got {v!r}")
                new[key] = v
            elif key in _EFFECT_SCALARS:
                if value is None:
                    sect, field = _EFFECT_SCALARS[key]
                    value = (self._fx_data.get(sect) or {}).get(field, _EFFECT_DEFAULTS[key])
                v = _finite(key, value)
                if v < 0.0 or (v == 0.0 and key in ("C_th_J_per_K", "R_th_K_per_W", "presliding_m")):
                    raise ModelInputError(f"{key} must be > 0 (>= 0 for alpha and friction), got {v!r}")
                new[key] = v
        self.params = new
        self._fx_on = any(new.get(k) for k in _SWITCHES)
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
        if len(s) != n or s[0] != float(STATE_LAYOUT):
            raise ModelInputError(f"state vector has {len(s)} entries and layout {s[0] if s else None!r}; "
                                  f"this model expects {n} entries, layout {STATE_LAYOUT}")
        for k, v in enumerate(s):
            if k in (_IDX["time_s"], _IDX["psi_Wb"]) or k >= len(STATE_NAMES):
                if not math.isfinite(v):
                    raise ModelInputError(f"state {self.state_names()[k]} must be finite, got {v!r}")
        self._state = s[: len(STATE_NAMES)]
        self._fx = s[len(STATE_NAMES):]
        self._x_cache = (math.nan, (0, 0.0, False))
        self._end_cache = (math.nan, -1, math.nan, 0.0, 0.0)
        self.events = []

    @property
    def time_s(self) -> float:
        """Model time [s]."""
        return self._state[1]

    @property
    def psi_Wb(self) -> float:
        """Flux linkage [Wb] (the state)."""
        return self._state[2]

    @property
    def initialized(self) -> bool:
        """True once :meth:`initialize` has run."""
        return self._state[3] != 0.0

    @property
    def i_A(self) -> float:
        """Coil current [A] (input echo in current mode)."""
        return self._state[7]

    @property
    def U_V(self) -> float:
        """Coil voltage [V] (input echo in voltage mode; step mean in current mode)."""
        return self._state[8]

    @property
    def F_N(self) -> float:
        """Magnetic force [N], positive closing the gap (paper eq. 3)."""
        return self._state[9]

    @property
    def dpsi_dt_V(self) -> float:
        """Induced voltage dPsi/dt [V] (instantaneous in voltage mode, step mean in current mode)."""
        return self._state[10]

    @property
    def i_eddy_A(self) -> float:
        """Eddy current G dPsi/dt [A] (paper eq. 2)."""
        return self._state[11]

    @property
    def out_of_map(self) -> bool:
        """True while x or Psi is clamped to the map."""
        return self._state[4] != 0.0 or self._state[5] != 0.0

    def outputs(self) -> dict:
        """All outputs at the last communication point, by name (units in the names)."""
        s = self._state
        out = {"i_A": s[7], "U_V": s[8], "F_N": s[9], "psi_Wb": s[2], "dpsi_dt_V": s[10],
               "i_eddy_A": s[11], "out_of_map": self.out_of_map}
        if self._fx_names:
            out["i_hyst_A"] = self.i_hyst_A
            out["T_rise_K"] = self.T_rise_K
        return out

    # -- simulation ----------------------------------------------------------------------------
    def _set_flag(self, s: list, name: str, on: bool, i_f_A: float = 0.0, x_m: float = 0.0) -> None:
        """Set an excursion flag; when it rises, queue one event (message built only then)."""
        k = _IDX[name]
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
            self.events.append((kind, _EVENT_SEVERITY[kind], msg))
        s[k] = 1.0 if on else 0.0

    def _finish(self, s: list, psi: float, psi_clamped: bool, i_f: float, x_m: float, xc: bool) -> None:
        """Update the three excursion flags at the end of a step (cheap when nothing changes)."""
        if xc != (s[5] != 0.0):
            self._set_flag(s, "excursion_x", xc, x_m=x_m)
        if psi_clamped != (s[4] != 0.0):
            self._set_flag(s, "excursion_psi", psi_clamped)
        ext = (not psi_clamped) and abs(i_f) > self.tables.i_fem_max_A * (1.0 + 1e-9)
        if ext != (s[6] != 0.0):
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
        u = _finite("U_V" if mode == DRIVE_VOLTAGE else "i_A", u)
        x_m = _finite("x_m", x_m)
        t0_s = _finite("t0_s", t0_s)
        tab = self.tables
        p = self.params
        R, G = p["R_ohm"], p["G_eddy_S"]
        s = [0.0] * len(STATE_NAMES)
        s[0] = float(STATE_LAYOUT)
        self.events = []
        j, w, xc = tab.x_cell(x_m)
        pm = tab.psi_max_Wb
        if mode == DRIVE_CURRENT and G == 0.0:
            psi, pc = _solve_psi(tab, u, j, w, 0.0)
        else:
            psi = p["Psi0_Wb"]
            pc = abs(psi) > pm
            if pc:
                psi = math.copysign(pm, psi)
        i_f, force = tab.i_f_and_force(psi, j, w)
        if mode == DRIVE_VOLTAGE:
            dpsi = (u - R * i_f) / (1.0 + R * G)
            s[7], s[8] = i_f + G * dpsi, u
        else:
            dpsi = (u - i_f) / G if G > 0.0 else 0.0
            s[7], s[8] = u, R * u + dpsi
        s[1], s[2], s[3] = t0_s, psi, 1.0
        s[9], s[10], s[11] = force, dpsi, G * dpsi
        self._finish(s, psi, pc, i_f, x_m, xc)
        self._state = s
        if self._fx_names:
            fx = [0.0] * len(self._fx_names)
            fx[2] = x_m
            n_lad = len((self._fx_data.get("eddy_ladder") or {}).get("G_S", ()))
            for k in range(4 + n_lad, len(fx)):
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
        if s[3] == 0.0:
            raise ModelInputError("step() before initialize()")
        voltage, R, G, m, c, inv_hsub = self._fast
        h = float(h_s)
        u = float(u)
        x_m = float(x_m)
        # x - x == 0 is False for NaN and +-inf: one cheap test for "finite"
        if not (h > 0.0 and h - h == 0.0 and u - u == 0.0 and x_m - x_m == 0.0):
            if not (h > 0.0 and math.isfinite(h)):
                raise ModelInputError(f"communication step must be finite and > 0 s, got {h_s!r}")
            if not math.isfinite(u):
                raise ModelInputError(f"input {'U_V' if voltage else 'i_A'} = {u!r} is not finite")
            raise ModelInputError(f"input x_m = {x_m!r} is not finite")
        if t_s is not None:
            t_s = float(t_s)
            if not t_s - t_s == 0.0:
                raise ModelInputError(f"step start time {t_s!r} is not finite")
        if h * inv_hsub > MAX_SUBSTEPS:  # also inf: h_sub_max_s = 1e-300 would never finish
            raise ModelInputError(f"step h = {h!r} s needs more than {MAX_SUBSTEPS:.0f} sub-steps of h_sub_max_s = "
                                  f"{1.0 / inv_hsub!r} s; take shorter communication steps or raise h_sub_max_s")
        if self._fx_on:
            self._step_fx(h, u, x_m, t_s)
            return
        tab = self.tables
        hot = tab._hot
        xcache = self._x_cache
        if x_m == xcache[0]:
            j, w, xc = xcache[1]
        else:
            cell = tab.x_cell(x_m)
            self._x_cache = (x_m, cell)
            j, w, xc = cell
        s = list(s)
        psi0 = s[2]
        if m == 0.0:  # current mode without eddy currents: algebraic
            psi, pc = _solve_psi(tab, u, j, w, psi0)
        else:
            n = math.ceil(h * inv_hsub - 1e-9)
            if n < 1:
                n = 1
            end = self._end_cache  # i_f and slope at psi0 from the end of the last step
            if end[0] == psi0 and end[1] == j and end[2] == w:
                v0, d0 = end[3], end[4]
            else:
                v0, d0, _ = _eval(hot, psi0, j, w)
            psi, pc = _ros2(hot, psi0, v0, d0, m, u, c, h / n, n, j, w)
        i_f, d_end, force = _eval(hot, psi, j, w)
        self._end_cache = (psi, j, w, i_f, d_end)
        if voltage:
            dpsi = (u - R * i_f) / m
            s[7] = i_f + G * dpsi
            s[8] = u
        else:
            dpsi = (psi - psi0) / h
            s[7] = u
            s[8] = R * u + dpsi
        s[1] = (s[1] if t_s is None else t_s) + h
        s[2] = psi
        s[9] = force
        s[10] = dpsi
        s[11] = G * dpsi
        lim = tab.i_fem_max_A * (1.0 + 1e-9)
        ext = (not pc) and (i_f > lim or -i_f > lim)
        if xc != (s[5] != 0.0) or pc != (s[4] != 0.0) or ext != (s[6] != 0.0):
            self._finish(s, psi, pc, i_f, x_m, xc)
        self._state = s


    # -- effect sub-models (issue 7) ---------------------------------------------------------------
    @property
    def i_hyst_A(self) -> float:
        """Hysteresis current [A] of the play operator (0 without the effect)."""
        return self._fx[3] if self._fx else 0.0

    @property
    def T_rise_K(self) -> float:
        """Coil temperature rise since initialization [K] (0 without heating)."""
        return self._fx[0] if self._fx else 0.0

    def _step_fx(self, h: float, u: float, x_m: float, t_s) -> None:
        """One communication step with effect sub-models switched on (inputs already checked).

        Equations (SI), extending paper eqs. (1)-(3)::

            U = R(T) i + e,   e = dPsi/dt,   R(T) = R (1 + alpha T)
            i = i_f(Psi, x) + i_h + G e + sum_k i_k
            tau_k di_k/dt = G_k e - i_k                   (eddy ladder sections)
            i_h = gain * g(Psi) * sum_j w_j (Psi - play_j(Psi))   (hysteresis, play operator)
            C_th dT/dt = R(T) i^2 - T / R_th              (heating, T = rise above start)
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
        hot = tab._hot
        voltage = p["drive_mode"] == DRIVE_VOLTAGE
        R0, G0 = p["R_ohm"], p["G_eddy_S"]
        j, w, xc = tab.x_cell(x_m)
        lad = self._fx_data.get("eddy_ladder") if p["eddy_ladder_on"] else None
        n_lad_all = len((self._fx_data.get("eddy_ladder") or {}).get("G_S", ()))
        Gk = lad["G_S"] if lad else ()
        tk = lad["tau_s"] if lad else ()
        ik = fx[4: 4 + len(Gk)]
        hy = self._fx_data.get("hysteresis") if p["hysteresis_on"] else None
        plays = fx[4 + n_lad_all:]
        gain = p["hyst_gain"]
        heat = p["heating_on"]
        alpha, Cth, Rth = p["alpha_per_K"], p["C_th_J_per_K"], p["R_th_K_per_W"]
        T, ih = fx[0], fx[3]
        n = max(1, math.ceil(h / p["h_sub_max_s"] - 1e-9))
        hs = h / n
        gh = ROS2_GAMMA * hs
        psi0 = s[2]
        psi = psi0
        pc = False
        nl = len(Gk)
        for _ in range(n):
            R = R0 * (1.0 + alpha * T) if heat else R0
            m = 1.0 + R * G0 if voltage else G0
            c = R if voltage else 1.0
            psi_a = psi
            if m == 0.0 and nl == 0:
                psi, pc = _solve_psi(tab, u - ih, j, w, psi)
            else:
                v, d, _ = _eval(hot, psi, j, w)
                a = [tk[k] + gh for k in range(nl)]
                den = m + gh * c * d + sum(gh * c * Gk[k] / a[k] for k in range(nl))
                f0 = u - c * (v + ih + sum(ik))
                r = [-ik[k] for k in range(nl)]
                z0 = (f0 - gh * c * sum(r[k] / a[k] for k in range(nl))) / den
                z = [(r[k] + Gk[k] * z0) / a[k] for k in range(nl)]
                p2 = psi + hs * z0
                i2 = [ik[k] + hs * z[k] for k in range(nl)]
                v2 = _eval(hot, p2, j, w)[0]
                f0 = u - c * (v2 + ih + sum(i2)) - 2.0 * m * z0
                r = [-i2[k] - 2.0 * (tk[k] * z[k] - Gk[k] * z0) for k in range(nl)]
                q0 = (f0 - gh * c * sum(r[k] / a[k] for k in range(nl))) / den
                q = [(r[k] + Gk[k] * q0) / a[k] for k in range(nl)]
                psi = psi + 1.5 * hs * z0 + 0.5 * hs * q0
                ik = [ik[k] + 1.5 * hs * z[k] + 0.5 * hs * q[k] for k in range(nl)]
                pm = tab.psi_max_Wb
                if psi > pm:
                    psi, pc = pm, True
                elif psi < -pm:
                    psi, pc = -pm, True
            if heat:
                i_sub = (u - (psi - psi_a) / hs) / R if voltage else u
                T += hs * (R * i_sub * i_sub - T / Rth) / Cth
            if hy is not None:
                ih = gain * play_step(plays, hy["r"], hy["w"], hy["gb"], hy["gg"], psi)
        i_f, d_end, force = _eval(hot, psi, j, w)
        self._end_cache = (math.nan, -1, math.nan, 0.0, 0.0)
        R = R0 * (1.0 + alpha * T) if heat else R0
        sik = sum(ik)
        if voltage:
            dpsi = (u - R * (i_f + ih + sik)) / (1.0 + R * G0)
            s[7] = i_f + ih + G0 * dpsi + sik
            s[8] = u
        else:
            dpsi = (psi - psi0) / h
            s[7] = u
            s[8] = R * u + dpsi
        ffr = fx[1]
        if p["friction_on"]:
            dx = x_m - fx[2]
            if dx != 0.0:
                fc = p["friction_N"]
                target = fc if dx > 0.0 else -fc
                ffr = target + (ffr - target) * math.exp(-abs(dx) / p["presliding_m"])
        s[1] = (s[1] if t_s is None else t_s) + h
        s[2] = psi
        s[9] = force + ffr
        s[10] = dpsi
        s[11] = G0 * dpsi + sik
        fx[0], fx[1], fx[2], fx[3] = T, ffr, x_m, ih
        fx[4: 4 + nl] = ik
        fx[4 + n_lad_all:] = plays
        self._finish(s, psi, pc, i_f, x_m, xc)
        self._state = s
        self._fx = fx


def effects_data(tables: MapTables) -> dict:
    """The ``effects`` section of maps.json, checked and prepared for the step (SI units).

    Keys (each optional): ``hysteresis`` {thresholds [Wb], weights [A/Wb], shape {b_nodes [Wb],
    g_nodes [-]} or null}, ``eddy_ladder`` {G_S [S], tau_s [s]}, ``heating`` {C_th_J_per_K,
    R_th_K_per_W, alpha_per_K}, ``friction`` {force_N, presliding_m}.
    """
    raw = tables.meta.get("effects") or {}
    where = f"{tables.where}: maps.json effects"
    if not isinstance(raw, dict):
        raise ModelMapsError(f"{where}: must be an object")
    out = {}
    for name, data in raw.items():
        if name not in EFFECT_NAMES:
            raise ModelMapsError(f"{where}: unknown effect {name!r}; known: {', '.join(EFFECT_NAMES)}")
        if data is None:
            continue
        if not isinstance(data, dict):
            raise ModelMapsError(f"{where}.{name}: must be an object")
        try:
            if name == "hysteresis":
                r = [float(v) for v in data["thresholds"]]
                wts = [float(v) for v in data["weights"]]
                shape = data.get("shape") or {}
                gb = [float(v) for v in shape.get("b_nodes", ())]
                gg = [float(v) for v in shape.get("g_nodes", ())]
                ok = (len(r) == len(wts) >= 1 and all(v > 0 for v in r) and all(v >= 0 for v in wts)
                      and len(gb) == len(gg) and all(gb[k + 1] > gb[k] for k in range(len(gb) - 1))
                      and all(math.isfinite(v) for v in r + wts + gb + gg))
                if not ok:
                    raise ValueError("finite thresholds > 0 and weights >= 0 of equal length, finite increasing "
                                     "shape nodes and factors")
                out[name] = {"r": r, "w": wts, "gb": gb, "gg": gg, "thresholds": r}
            elif name == "eddy_ladder":
                G = [float(v) for v in data["G_S"]]
                tau = [float(v) for v in data["tau_s"]]
                if not (len(G) == len(tau) >= 1 and all(0 <= v < math.inf for v in G)
                        and all(0 < v < math.inf for v in tau)):
                    raise ValueError("finite G_S >= 0 and tau_s > 0 of equal length")
                out[name] = {"G_S": G, "tau_s": tau}
            else:
                vals = {k: float(v) for k, v in data.items()}
                if any(not math.isfinite(v) or v < 0 for v in vals.values()):
                    raise ValueError("values must be finite and >= 0")
                out[name] = vals
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelMapsError(f"{where}.{name}: {exc}") from None
    return out


def play_step(plays: list, r: list, wts: list, gb: list, gg: list, b: float) -> float:
    """Advance the play operators to input ``b`` (in place) and return ``g(b) sum w (b - p)``.

    The inverse Prandtl-Ishlinskii operator of ``solenoid_fmu.realtime.hysteresis.PlayHysteresis``
    (same arithmetic, scalar form, no numpy).
    """
    acc = 0.0
    for k in range(len(r)):
        lo = b - r[k]
        hi = b + r[k]
        q = plays[k]
        if q < lo:
            q = lo
        elif q > hi:
            q = hi
        plays[k] = q
        acc += wts[k] * (b - q)
    if not gb:
        return acc
    if b <= gb[0]:
        g = gg[0]
    elif b >= gb[-1]:
        g = gg[-1]
    else:
        jj = bisect.bisect_right(gb, b) - 1
        g = gg[jj] + (b - gb[jj]) / (gb[jj + 1] - gb[jj]) * (gg[jj + 1] - gg[jj])
    return g * acc


def _eval(hot: tuple, psi: float, j: int, w: float) -> tuple[float, float, float]:
    """``i_f`` [A], ``d i_f / d Psi`` [A/Wb] and ``F`` [N] at ``(psi, x cell (j, w))``.

    Same arithmetic as :meth:`MapTables._cubic` (inlined: real-time hot path).
    """
    CI, CF, nxc, kmax, inv, pm = hot
    a = -psi if psi < 0.0 else psi
    if a > pm:
        a = pm
    sc = a * inv
    k = int(sc)
    if k > kmax:
        k = kmax
    t = sc - k
    idx = k * nxc + j
    q0, q1, q2, q3, e0, e1, e2, e3 = CI[idx]
    c1 = q1 + w * e1
    c2 = q2 + w * e2
    c3 = q3 + w * e3
    v = (q0 + w * e0) + t * (c1 + t * (c2 + t * c3))
    d = (c1 + t * (2.0 * c2 + 3.0 * t * c3)) * inv
    q0, q1, q2, q3, e0, e1, e2, e3 = CF[idx]
    f = (q0 + w * e0) + t * ((q1 + w * e1) + t * ((q2 + w * e2) + t * (q3 + w * e3)))
    return (-v if psi < 0.0 else v), d, f


def _ros2(hot: tuple, psi: float, v: float, d: float, m: float, b: float, c: float, hs: float, n: int,
          j: int, w: float) -> tuple[float, bool]:
    """``n`` ROS2 sub-steps of ``hs`` [s] for ``m dPsi/dt = b - c i_f(Psi, x)``; returns (Psi, clamped).

    ``v, d`` are ``i_f`` and ``d i_f / d Psi`` at the start value ``psi`` (from the previous
    step's output evaluation). The lookups are inlined (same arithmetic as
    :meth:`MapTables._cubic`) because this loop is the real-time hot path.
    """
    CI, _, nxc, kmax, inv, pm = hot
    g = ROS2_GAMMA
    clamped = False
    for sub in range(n):
        if sub:
            # stage 1 of a later sub-step: value and slope at psi
            a = -psi if psi < 0.0 else psi
            if a > pm:
                a = pm
            sc = a * inv
            k = int(sc)
            if k > kmax:
                k = kmax
            t = sc - k
            q0, q1, q2, q3, e0, e1, e2, e3 = CI[k * nxc + j]
            c1 = q1 + w * e1
            c2 = q2 + w * e2
            c3 = q3 + w * e3
            v = (q0 + w * e0) + t * (c1 + t * (c2 + t * c3))
            d = (c1 + t * (2.0 * c2 + 3.0 * t * c3)) * inv
            if psi < 0.0:
                v = -v
        W = m + g * hs * c * d
        k1 = (b - c * v) / W
        # stage 2: value at psi + hs k1
        p2 = psi + hs * k1
        a = -p2 if p2 < 0.0 else p2
        if a > pm:
            a = pm
        sc = a * inv
        k = int(sc)
        if k > kmax:
            k = kmax
        t = sc - k
        q0, q1, q2, q3, e0, e1, e2, e3 = CI[k * nxc + j]
        v2 = (q0 + w * e0) + t * ((q1 + w * e1) + t * ((q2 + w * e2) + t * (q3 + w * e3)))
        if p2 < 0.0:
            v2 = -v2
        k2 = (b - c * v2 - 2.0 * m * k1) / W
        psi = psi + 1.5 * hs * k1 + 0.5 * hs * k2
        if psi > pm:
            psi, clamped = pm, True
        elif psi < -pm:
            psi, clamped = -pm, True
    return psi, clamped


def _drive_code(value) -> int:
    if isinstance(value, str):
        code = _DRIVE_NAMES.get(value.strip().lower())
        if code is None:
            raise ModelInputError(f"drive_mode must be 'voltage' or 'current', got {value!r}")
        return code
    try:
        code = int(value)
    except (TypeError, ValueError):
        raise ModelInputError(f"drive_mode must be 'voltage'/'current' or 1/2, got {value!r}") from None
    if code not in (DRIVE_VOLTAGE, DRIVE_CURRENT) or code != value:
        raise ModelInputError(f"drive_mode must be {DRIVE_VOLTAGE} (voltage) or {DRIVE_CURRENT} (current), "
                              f"got {value!r}")
    return code
