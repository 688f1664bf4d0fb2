"""The characteristic maps prepared for scalar lookups: PCHIP cell cubics and the one cell lookup.

Part of the FMU payload (:mod:`solenoid_fmu.realtime.model`): numpy and the standard library only.
:func:`cell_cubic` is the only place the cubic of a map cell is evaluated (the model's step, the
ROS2 stages and :class:`MapTables` all call it; the C model's ``psi_cell``/``eval3`` do the same
arithmetic).
"""

from __future__ import annotations

import bisect
import copy
import math

import numpy as np

from .definitions import NEWTON_MAX_ITER, NEWTON_TOL_REL, ModelMapsError
from .records import CoilRecord, EddyRecord, EffectsRecord, replace_meta


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



#: Positions in :attr:`MapTables.hot`: the cell cubics of i_f and F, and psi_max.
HOT_CI, HOT_CF, HOT_PSI_MAX = 0, 1, 5


def cell_cubic(C: list, hot: tuple, a: float, j: int, w: float) -> tuple[float, float]:
    """Value and d/dPsi of the cell cubics ``C`` at ``|Psi| = a`` (clamped to psi_max) in x cell ``(j, w)``.

    ``C`` is :attr:`MapTables.CI` or :attr:`MapTables.CF`; ``hot`` is :attr:`MapTables.hot`. The
    arithmetic of the module docstring of :mod:`solenoid_fmu.realtime.model` ("Map lookup"), which the
    generated C reproduces operation for operation.
    """
    _, _, nxc, kmax, inv, pm = hot
    if a > pm:
        a = pm
    sc = a * inv
    k = int(sc)
    if k > kmax:
        k = kmax
    t = sc - k
    q0, q1, q2, q3, e0, e1, e2, e3 = C[k * nxc + j]
    c1 = q1 + w * e1
    c2 = q2 + w * e2
    c3 = q3 + w * e3
    return (q0 + w * e0) + t * (c1 + t * (c2 + t * c3)), (c1 + t * (2.0 * c2 + 3.0 * t * c3)) * inv


def i_f_slope(hot: tuple, psi: float, j: int, w: float) -> tuple[float, float]:
    """``i_f`` [A] and ``d i_f / d Psi`` [A/Wb] at ``(psi, x cell (j, w))``; i_f is odd in Psi."""
    if psi < 0.0:
        v, d = cell_cubic(hot[HOT_CI], hot, -psi, j, w)
        return -v, d
    return cell_cubic(hot[HOT_CI], hot, psi, j, w)


def eval_cell(hot: tuple, psi: float, j: int, w: float) -> tuple[float, float, float]:
    """``i_f`` [A], ``d i_f / d Psi`` [A/Wb] and ``F`` [N] (even in Psi) at ``(psi, x cell (j, w))``."""
    a = -psi if psi < 0.0 else psi
    v, d = cell_cubic(hot[HOT_CI], hot, a, j, w)
    f = cell_cubic(hot[HOT_CF], hot, a, j, w)[0]
    return (-v if psi < 0.0 else v), d, f

def _checked_arrays(psi_Wb, x_m, i_f_A, force_N, extrapolated, where: str) -> tuple:
    """The map arrays as float arrays, after every check :class:`MapTables` makes (ModelMapsError)."""
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

    return psi, x, i_f, force, extrapolated


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
        The ``maps.json`` sidecar (coil, eddy, effects, provenance); kept as given, read through the
        typed records :attr:`coil`, :attr:`eddy`, :attr:`effects` (a coil or eddy value of the wrong type
        is refused here, naming ``where``, the file and the key). Other maps.json: :meth:`with_meta`.
    where : str
        Name used in error messages (the maps directory).
    i_fem_max_A : float, optional
        Largest current of the FEM sweep [A] (the maps' ``i_A[-1]``); beyond it the map is
        extrapolated and the model reports an event. Default: the coil's ``max_current_A``,
        else no limit.

    Notes
    -----
    The tables are kept as Python lists of floats: the scalar lookups of the real-time step are
    several times faster on lists than on numpy scalars.
    """

    def __init__(self, psi_Wb, x_m, i_f_A, force_N, extrapolated=None, meta=None, where="maps",
                 i_fem_max_A=None):
        psi, x, i_f, force, extrapolated = _checked_arrays(psi_Wb, x_m, i_f_A, force_N, extrapolated, where)
        dpsi = (psi[-1] - psi[0]) / (psi.size - 1)
        dx = np.diff(x)
        self.where = where
        self.meta = dict(meta) if meta else {}
        coil, _ = self._checked_records()  # a coil or eddy section of the wrong type: refused now, not in a step
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
            i_fem_max_A = coil.max_current_A
        self.i_fem_max_A = math.inf if i_fem_max_A is None else float(i_fem_max_A)
        self.extrapolated = None if extrapolated is None else extrapolated.copy()
        #: (CI, CF, n_x - 1, n_psi - 2, 1 / dpsi, psi_max): what :func:`cell_cubic` reads
        self.hot = (self.CI, self.CF, self.n_x - 1, self.n_psi - 2, self.inv_dpsi, self.psi_max_Wb)

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

    def i_f_and_slope(self, psi_Wb: float, j: int, w: float) -> tuple[float, float]:
        """``i_f(Psi, x)`` [A] and ``d i_f / d Psi`` [A/Wb] in x cell ``(j, w)`` (odd in Psi)."""
        return i_f_slope(self.hot, psi_Wb, j, w)

    def i_f_and_force(self, psi_Wb: float, j: int, w: float) -> tuple[float, float]:
        """``i_f(Psi, x)`` [A] and ``F(Psi, x)`` [N] in x cell ``(j, w)``."""
        v, _, f = eval_cell(self.hot, psi_Wb, j, w)
        return v, f

    def force_in_cell(self, psi_Wb: float, j: int, w: float) -> float:
        """``F(Psi, x)`` [N] in x cell ``(j, w)`` (even in Psi)."""
        return cell_cubic(self.CF, self.hot, abs(psi_Wb), j, w)[0]

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
        return solve_psi(self, float(i_A), j, w, 0.0)[0]

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

    # -- maps.json's metadata, typed (records.py) -----------------------------------------------
    @property
    def coil(self) -> CoilRecord:
        """maps.json's ``coil`` section (an empty record when the maps have none)."""
        return CoilRecord.from_dict(self.meta.get("coil"), self.where)

    @property
    def eddy(self) -> EddyRecord:
        """maps.json's ``eddy`` section (an empty record when the maps have none)."""
        return EddyRecord.from_dict(self.meta.get("eddy"), self.where)

    @property
    def effects(self) -> EffectsRecord:
        """maps.json's ``effects`` section (an empty record when the maps have none)."""
        return EffectsRecord.from_dict(self.meta.get("effects"), self.where)

    @property
    def name(self) -> str | None:
        """maps.json's ``name``, or None."""
        return self.meta.get("name")

    @property
    def provenance(self) -> dict:
        """maps.json's ``provenance`` (geometry, material, solver, code version: free-form), or ``{}``."""
        return self.meta.get("provenance") or {}

    @property
    def resistance_ohm_20C(self) -> float | None:
        """Coil resistance at 20 degC [ohm] from ``maps.json``, or None."""
        v = self.coil.resistance_ohm_20C
        return None if v is None else float(v)

    @property
    def G_eddy_S(self) -> float | None:
        """Eddy-current conductance [S] from ``maps.json``, or None when not identified."""
        v = self.eddy.G_eddy_S
        return None if v is None else float(v)

    def with_meta(self, **sections) -> MapTables:
        """These tables with other maps.json sections (the tables themselves unchanged and shared).

        Parameters
        ----------
        **sections
            Top-level sidecar keys and their new values: a record (``coil=CoilRecord(...)``,
            ``eddy=dataclasses.replace(tables.eddy, G_eddy_S=...)``) or plain data
            (``effects={...}``); :func:`~.records.replace_meta`.
        """
        new = copy.copy(self)
        new.meta = replace_meta(self.meta, **sections)
        new._checked_records()
        return new

    def _checked_records(self) -> tuple[CoilRecord, EddyRecord]:
        """The coil and eddy records (ModelMapsError naming the file and key when a value has the wrong type)."""
        return self.coil, self.eddy


def solve_psi(tab: MapTables, i_A: float, j: int, w: float, psi_guess: float) -> tuple[float, bool]:
    """Solve ``i_f(Psi, x) = i_A`` for Psi [Wb] (safeguarded Newton); returns (Psi, clamped)."""
    if i_A == 0.0:
        return 0.0, False
    target = abs(i_A)
    sign = -1.0 if i_A < 0.0 else 1.0
    # i_f at Psi >= 0 is the cell cubic itself (i_f_slope's positive branch): called directly, as this loop
    # is the hot path of a current-driven step (three Python calls per evaluation were a third of its time)
    hot = tab.hot
    CI = hot[HOT_CI]
    hi = tab.psi_max_Wb
    g_hi = cell_cubic(CI, hot, hi, j, w)[0] - target
    if g_hi <= 0.0:
        return sign * hi, g_hi < 0.0
    lo = 0.0
    y = abs(psi_guess)
    if not lo < y < hi:
        y = 0.5 * hi
    tol = NEWTON_TOL_REL * hi
    for _ in range(NEWTON_MAX_ITER):
        v, d = cell_cubic(CI, hot, y, j, w)  # 0 < y < psi_max
        g = v - target
        if g == 0.0:
            break
        if g < 0.0:
            lo = y
        else:
            hi = y
        y_new = y - g / d if d > 0.0 else 0.5 * (lo + hi)
        if not lo < y_new < hi:
            if abs(y_new - y) <= tol:
                break  # converged onto the bracket's end (rounding): y is the root; bisecting took ~40 steps
            y_new = 0.5 * (lo + hi)
        step = abs(y_new - y)
        y = y_new
        if step <= tol:
            break
    return sign * y, False

