"""Fitting the anhysteretic curve and a play operator to one measured major loop, and scoring the fit.

:func:`fit_play_to_loop` fits the anhysteretic curve (the mean of the branches, the paper's
commutation curve) and the play operator (with its shape factor, kept monotone) to one measured
major loop; :func:`evaluate_loop_fit` compares a fitted model's major loop with the measured one
(B error at equal H, coercive field, remanence). scipy is imported inside the fitting functions
only (see :mod:`.hysteresis_fit`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .hysteresis import HysteresisError, PlayHysteresis, as_1d_finite
from .hysteresis_fit import fit_weights_and_shape, hat_basis

__all__ = ["PlayLoopFit", "anhysteretic_h", "evaluate_loop_fit", "fit_play_to_loop"]


def anhysteretic_h(b, b_grid: np.ndarray, h_grid: np.ndarray) -> np.ndarray:
    """Anhysteretic curve ``H_an(b)`` from its table, linear inside, linear extrapolation outside.

    Parameters
    ----------
    b : float or array-like
        Flux-like input, units of ``b``.
    b_grid, h_grid : numpy.ndarray, shape (n,)
        The table: ``b_grid`` strictly increasing, ``h_grid`` increasing (units of b and h).

    Returns
    -------
    numpy.ndarray
        ``H_an(b)``, units of ``h``; extrapolated with the slope of the first/last interval.
    """
    b_arr = np.asarray(b, dtype=np.float64)
    h = np.interp(b_arr, b_grid, h_grid)
    lo_slope = (h_grid[1] - h_grid[0]) / (b_grid[1] - b_grid[0])
    hi_slope = (h_grid[-1] - h_grid[-2]) / (b_grid[-1] - b_grid[-2])
    h = np.where(b_arr < b_grid[0], h_grid[0] + lo_slope * (b_arr - b_grid[0]), h)
    h = np.where(b_arr > b_grid[-1], h_grid[-1] + hi_slope * (b_arr - b_grid[-1]), h)
    return h


class PlayLoopFit(NamedTuple):
    """Result of :func:`fit_play_to_loop`: unpacks as ``(b_grid, h_an), play = fit``.

    Attributes
    ----------
    anhysteretic : tuple of two numpy.ndarray
        ``(b_grid, h_an)``: the anhysteretic curve as a strictly increasing table over the
        loop's range (units of b and h).
    play : PlayHysteresis
        The fitted hysteresis operator (in its neutral state at ``b = 0``).
    """

    anhysteretic: tuple
    play: PlayHysteresis

    def h_total(self, b_series, play: PlayHysteresis | None = None) -> np.ndarray:
        """Full model ``H = H_an(b) + h[b]`` along a series (units of h).

        Runs on ``play`` if given (its state advances), else on a fresh copy of the fitted
        operator in its neutral state at ``b = 0``.
        """
        b = as_1d_finite("b_series", b_series, min_len=0)
        if play is None:
            play = self.play.copy()
            play.reset(0.0)
        b_grid, h_an = self.anhysteretic
        return anhysteretic_h(b, b_grid, h_an) + play.run(b)

    def major_loop(self, n_per_leg: int = 2000) -> dict:
        """Simulate the fitted model over its loop range from the neutral state at ``b = 0``.

        Drives ``b`` from 0 to the upper tip (first magnetization), down to the lower tip
        (descending branch) and back up (ascending branch), on a uniform grid of
        ``n_per_leg`` points plus every node of the tables (so the piecewise-linear branches
        are resolved at their knots).

        Returns
        -------
        dict
            ``"initial"``, ``"descending"``, ``"ascending"``: each a tuple ``(b, H)`` of
            arrays in units of b and h, in drive order.
        """
        b_grid, _ = self.anhysteretic
        b_lo, b_hi = float(b_grid[0]), float(b_grid[-1])
        fine = np.linspace(b_lo, b_hi, int(n_per_leg))
        if self.play.shape is not None:
            sb = self.play.shape[0]
            fine = np.union1d(fine, sb[(sb > b_lo) & (sb < b_hi)])
        fine = np.union1d(fine, b_grid)
        up0 = fine[fine >= 0.0]
        down = fine[::-1]
        b = np.concatenate([up0, down, fine])
        H = self.h_total(b)
        n0, n1 = up0.size, down.size
        return {
            "initial": (b[:n0], H[:n0]),
            "descending": (b[n0:n0 + n1], H[n0:n0 + n1]),
            "ascending": (b[n0 + n1:], H[n0 + n1:]),
        }

    def to_dict(self) -> dict:
        """JSON-able parameters: the anhysteretic table and the play operator."""
        b_grid, h_an = self.anhysteretic
        return {"b_grid": np.asarray(b_grid).tolist(), "h_an": np.asarray(h_an).tolist(),
                "play": self.play.to_dict()}

    @classmethod
    def from_dict(cls, data: dict) -> PlayLoopFit:
        """Rebuild from :meth:`to_dict` output."""
        try:
            b_grid = as_1d_finite("b_grid", data["b_grid"], min_len=2)
            h_an = as_1d_finite("h_an", data["h_an"], min_len=2)
            play = PlayHysteresis.from_dict(data["play"])
        except KeyError as exc:
            raise HysteresisError(f"loop-fit data lacks the key {exc.args[0]!r}") from None
        if b_grid.shape != h_an.shape or np.any(np.diff(b_grid) <= 0.0):
            raise HysteresisError("b_grid must be strictly increasing and as long as h_an")
        return cls((b_grid, h_an), play)


def _check_branch(name: str, H, B) -> tuple[np.ndarray, np.ndarray]:
    """A measured branch as arrays sorted by H, B strictly increasing with H."""
    H = as_1d_finite(f"H_{name}", H, min_len=4)
    B = as_1d_finite(f"B_{name}", B, min_len=4)
    if H.shape != B.shape:
        raise HysteresisError(f"{name} branch: H has {H.size} points, B has {B.size}")
    order = np.argsort(H, kind="stable")
    H, B = H[order], B[order]
    dH, dB = np.diff(H), np.diff(B)
    bad = np.flatnonzero((dH <= 0.0) | (dB <= 0.0))
    if bad.size:
        k = int(bad[0])
        raise HysteresisError(
            f"{name} branch: B must rise strictly with H; points {k} and {k + 1} are "
            f"(H={float(H[k])!r}, B={float(B[k])!r}) and (H={float(H[k + 1])!r}, B={float(B[k + 1])!r})"
        )
    return H, B


def _leg_stops(r: np.ndarray, b_hi: float, b_lo: float, b_eval: np.ndarray):
    """Stop outputs ``b - play_r(b)`` on the major-loop legs, evaluated at ``b_eval``.

    The operator starts neutral at 0, rises to ``b_hi``, falls to ``b_lo`` (descending leg)
    and rises to ``b_hi`` again (ascending leg). Returns ``(s_desc, s_asc)``, each of shape
    (len(b_eval), K). Exact: on a monotone leg the play output is a max/min of the leg start
    and the current input.
    """
    p_top = np.maximum(0.0, b_hi - r)  # after 0 -> b_hi from the neutral state
    p_desc = np.minimum(p_top[None, :], b_eval[:, None] + r[None, :])
    p_bottom = np.minimum(p_top, b_lo + r)
    p_asc = np.maximum(p_bottom[None, :], b_eval[:, None] - r[None, :])
    return b_eval[:, None] - p_desc, b_eval[:, None] - p_asc



def _monotone_shape(g0, r, w, G, M, Phi, half_width, mean_h, b_grid, row_w, Ha, Ba, Hd, Bd):
    """Refit the shape factor with every branch of the model kept monotone.

    For fixed weights the model's anhysteretic curve is ``H_an = mean - g(b) (M w)`` and any
    branch has slope ``dH/db >= H_an' - |g'| sum_k w_k r_k`` (see
    :class:`~solenoid_fmu.realtime.hysteresis.PlayHysteresis`), so requiring
    ``H_an' -+ g' S0 >= eps`` on every grid interval is a set of linear inequalities in the shape
    nodes: a small quadratic programme (scipy SLSQP). ``eps`` is a tenth of the
    smallest slope dH/dB of the measured branches. Returns ``g0`` unchanged when it already
    satisfies the constraints or when the programme fails.
    """
    from scipy.optimize import minimize  # lazy: the operators of realtime run without scipy

    s0 = float(np.dot(w, r))  # bound of |sum_k w_k s_k| in any state
    Mw = M @ w
    db = np.diff(b_grid)
    d_mean = np.diff(mean_h)
    PM = Phi * Mw[:, None]
    dPM = PM[1:] - PM[:-1]
    dPhi = Phi[1:] - Phi[:-1]
    slopes = np.concatenate([np.diff(Ha) / np.diff(Ba), np.diff(Hd) / np.diff(Bd)])
    eps = 0.1 * float(np.min(slopes))
    # constraints C g >= d  (both signs of g')
    C = np.vstack([-dPM - s0 * dPhi, -dPM + s0 * dPhi])
    d = np.concatenate([eps * db - d_mean, eps * db - d_mean])
    if np.all(C @ g0 >= d):
        return g0
    A = row_w[:, None] * ((G @ w)[:, None] * Phi)
    y = row_w * half_width
    scale = float(np.dot(y, y)) or 1.0
    cscale = np.maximum(np.abs(d), np.abs(C).max(axis=1) * float(np.max(g0)) + 1e-300)

    def fun(g):
        r = A @ g - y
        return 0.5 * float(np.dot(r, r)) / scale, (A.T @ r) / scale

    res = minimize(
        fun, g0, jac=True, method="SLSQP", bounds=[(0.0, None)] * g0.size,
        constraints=[{"type": "ineq", "fun": lambda g: (C @ g - d) / cscale,
                      "jac": lambda g: C / cscale[:, None]}],
        options={"maxiter": 500, "ftol": 1e-12},
    )
    g = np.maximum(res.x, 0.0)
    if not np.all(C @ g >= d - 1e-9 * cscale):
        return g0
    return g


def fit_play_to_loop(H_asc, B_asc, H_desc, B_desc, n_plays: int = 24, n_shape: int = 17,
                     n_grid: int = 200, smooth: float = 1e-3) -> PlayLoopFit:
    """Fit the anhysteretic curve and a play operator to one measured major loop.

    Parameters
    ----------
    H_asc, B_asc : array-like, shape (n_a,)
        Ascending branch: field-like values (units of h, e.g. A/m) and flux-like values
        (units of b, e.g. T); B must rise strictly with H.
    H_desc, B_desc : array-like, shape (n_d,)
        Descending branch, same units (any order; sorted by H internally).
    n_plays : int, optional
        Number of play operators K; thresholds spread uniformly over
        ``(0, (b_hi - b_lo) / 4]`` (larger ones only repeat smaller ones plus a linear term on
        a major loop). Default 24.
    n_shape : int, optional
        Nodes of the shape factor ``g(b)`` (uniform over the loop range); 0 for ``g = 1``, the
        plain inverse Prandtl-Ishlinskii model. Default 17.
    n_grid : int, optional
        Uniformly spaced B values added to the measured ones as rows of the fit and nodes of
        the anhysteretic table. Default 200.
    smooth : float, optional
        Weight of a penalty on the first differences of the play weights (relative to the data
        columns). A major loop alone hardly constrains how the weight is spread over the
        thresholds; the penalty spreads it (instead of one or two plays), so small minor
        loops keep a little hysteresis as in real steel. Default 1e-3 (costs no accuracy on the
        Epstein loops).

    Returns
    -------
    PlayLoopFit
        ``((b_grid, h_an), play)``: the anhysteretic curve ``H_an(b)`` (strictly increasing
        table over the loop's B range) and the fitted play operator
        (:class:`~solenoid_fmu.realtime.hysteresis.PlayHysteresis`).

    Notes
    -----
    The loop range ``[b_lo, b_hi]`` runs between the tips, where the two branches meet at
    their extreme H. On the model's major loop (drive 0 -> b_hi -> b_lo -> b_hi) the branches
    are ``H_an(b) + g(b) sum_k w_k s_k^{asc/desc}(b)``: their half-difference depends on the
    hysteresis parameters alone, their mean on ``H_an`` plus a known term. So ``w`` and ``g``
    come from a fit of the measured half-width ``(H_asc(B) - H_desc(B)) / 2`` by alternating
    non-negative least squares, each row weighted by the local slope dB/dH of the branches
    (so the fit minimises the B error at equal H, the error a loop comparison measures). Then
    ``H_an`` is the mean of the measured branches (the paper's commutation curve) minus the
    mean of the fitted stop terms. Finally the shape factor is refitted under linear
    constraints that keep ``H_an' - |g'| sum_k w_k r_k`` positive on every grid interval, which
    makes every branch of the model (major and minor) monotone, so B(H) stays well defined.
    Uses scipy (imported here only).

    A major loop says little about minor loops: with the thresholds below a quarter of the
    span, symmetric minor loops reach the full major-loop width at about a third of the
    saturation flux. Where loops of several amplitudes are recorded (the flux triangles of a
    test campaign), fit them together with
    :func:`~solenoid_fmu.realtime.hysteresis_fit.fit_play_to_series`.
    """
    Ha, Ba = _check_branch("ascending", H_asc, B_asc)
    Hd, Bd = _check_branch("descending", H_desc, B_desc)
    n_plays, n_shape, b_lo, b_hi = _loop_tips(Ba, Bd, n_plays, n_shape)
    span = b_hi - b_lo
    # rows of the fit and nodes of H_an: every measured B inside the loop, a uniform grid and
    # the nodes of the shape factor (so g is linear on every interval of the grid)
    nodes = np.linspace(b_lo, b_hi, n_shape) if n_shape else np.empty(0)
    b_grid, half_width, mean_h = _loop_grid(Ha, Ba, Hd, Bd, b_lo, b_hi, nodes, n_grid)
    r = span / 4.0 * np.arange(1, n_plays + 1) / n_plays
    s_desc, s_asc = _leg_stops(r, b_hi, b_lo, b_grid)
    G = 0.5 * (s_asc - s_desc)
    M = 0.5 * (s_asc + s_desc)

    row_w = _row_weights(Ha, Ba, Hd, Bd, b_grid)
    Phi = hat_basis(b_grid, nodes) if n_shape else None
    w, g_nodes, _, _ = fit_weights_and_shape(G, half_width, Phi, row_w, smooth=smooth)
    if g_nodes is not None:
        g_nodes = _monotone_shape(g_nodes, r, w, G, M, Phi, half_width, mean_h, b_grid, row_w,
                                  Ha, Ba, Hd, Bd)
    shape = None if g_nodes is None else (nodes, g_nodes)
    play = PlayHysteresis(r, w, shape=shape)

    h_an = mean_h - play.g(b_grid) * (M @ w)
    return PlayLoopFit((b_grid, _strictly_increasing(h_an)), play)


def _loop_tips(Ba: np.ndarray, Bd: np.ndarray, n_plays, n_shape):
    """The checked sizes of :func:`fit_play_to_loop` and the loop's tips ``b_lo``, ``b_hi``: where the two
    branches meet at their extreme H (the loop must enclose b = 0 and both branches reach both tips)."""
    n_plays = int(n_plays)
    n_shape = int(n_shape)
    if n_plays < 1:
        raise HysteresisError(f"n_plays must be >= 1, got {n_plays}")
    if n_shape == 1 or n_shape < 0:
        raise HysteresisError(f"n_shape must be 0 (no shape factor) or >= 2, got {n_shape}")
    # loop tips: where the branches meet at their extreme fields
    b_hi = float(0.5 * (Ba[-1] + Bd[-1]))
    b_lo = float(0.5 * (Ba[0] + Bd[0]))
    if not b_lo < 0.0 < b_hi:
        raise HysteresisError(
            f"the loop must enclose b = 0 (tips at {b_lo!r} and {b_hi!r}): a major loop is expected"
        )
    span = b_hi - b_lo
    for name, B in (("ascending", Ba), ("descending", Bd)):
        if B[0] > b_lo + 0.05 * span or B[-1] < b_hi - 0.05 * span:
            raise HysteresisError(
                f"{name} branch covers B = {float(B[0])!r}..{float(B[-1])!r}, not the loop "
                f"{b_lo!r}..{b_hi!r}: the two branches must end at the same tips"
            )
    return n_plays, n_shape, b_lo, b_hi


def _loop_grid(Ha, Ba, Hd, Bd, b_lo: float, b_hi: float, nodes: np.ndarray, n_grid):
    """The rows of :func:`fit_play_to_loop` (every measured B inside the loop, a uniform grid and the shape
    nodes), and there the measured half-width and mean of the branches in H."""
    inner = np.concatenate([Ba, Bd, np.linspace(b_lo, b_hi, int(n_grid)), nodes])
    b_grid = np.unique(np.clip(inner, b_lo, b_hi))
    Ha_g = np.interp(b_grid, Ba, Ha)
    Hd_g = np.interp(b_grid, Bd, Hd)
    half_width = 0.5 * (Ha_g - Hd_g)
    if np.max(half_width) <= 0.0:
        raise HysteresisError("the ascending branch never lies at larger H than the descending one")
    mean_h = 0.5 * (Ha_g + Hd_g)
    return b_grid, half_width, mean_h


def _row_weights(Ha, Ba, Hd, Bd, b_grid: np.ndarray) -> np.ndarray:
    """Row weights of :func:`fit_play_to_loop`: dB/dH of each branch at b (B error per H error), both
    branches counted."""
    def slope(Hb, Bb):
        return np.interp(b_grid, Bb, np.gradient(Bb, Hb))

    row_w = np.hypot(slope(Ha, Ba), slope(Hd, Bd))
    row_w = np.maximum(row_w, 1e-3 * row_w.max())
    return row_w


def _strictly_increasing(h_an: np.ndarray) -> np.ndarray:
    """``h_an`` made strictly increasing in place: the mean of two increasing branches increases; the stop
    term can flatten it only near the tips, where the measured branches are steep in H."""
    dh_min = 1e-9 * max(float(np.ptp(h_an)), 1e-300)
    for k in range(1, h_an.size):
        if h_an[k] <= h_an[k - 1]:
            h_an[k] = h_an[k - 1] + dh_min
    return h_an


def _branch_b_of_h(H_model: np.ndarray, B_model: np.ndarray, H_at: np.ndarray) -> np.ndarray:
    """Invert a simulated monotone branch to B(H) at the fields ``H_at`` (linear)."""
    order = np.argsort(H_model, kind="stable")
    Hs, Bs = H_model[order], B_model[order]
    keep = np.concatenate([[True], np.diff(Hs) > 0.0])
    return np.interp(H_at, Hs[keep], Bs[keep])


def _crossing(x: np.ndarray, y: np.ndarray) -> float:
    """The x where a monotone tabulated y(x) crosses zero (linear interpolation)."""
    order = np.argsort(y, kind="stable")
    return float(np.interp(0.0, y[order], x[order]))


def evaluate_loop_fit(fit: PlayLoopFit, H_asc, B_asc, H_desc, B_desc,
                      n_per_leg: int = 4000) -> dict:
    """Compare the fitted model's simulated major loop with a measured one (B error at equal H).

    Parameters
    ----------
    fit : PlayLoopFit
        From :func:`fit_play_to_loop`.
    H_asc, B_asc, H_desc, B_desc : array-like
        The measured branches (units of h and b).
    n_per_leg : int, optional
        Samples per simulated leg. Default 4000.

    Returns
    -------
    dict
        ``b_max`` (half the loop's B span), ``rms_b`` (RMS over all measured points of the
        model's B minus the measured B at the measured H), ``rms_b_rel`` (``rms_b / b_max``),
        ``max_b``, ``hc_measured``/``hc_model`` (coercive field: mean of ``|H|`` where the
        branches cross B = 0), ``br_measured``/``br_model`` (remanence: mean of ``|B|`` where
        the branches cross H = 0), their relative errors ``hc_rel_err`` and ``br_rel_err``,
        and ``monotone`` (True when H rises strictly with B along both simulated branches, so
        B(H) is well defined).
    """
    Ha, Ba = _check_branch("ascending", H_asc, B_asc)
    Hd, Bd = _check_branch("descending", H_desc, B_desc)
    loop = fit.major_loop(n_per_leg)
    bd, hd = loop["descending"]
    ba, ha = loop["ascending"]
    monotone = bool(np.all(np.diff(ha) > 0.0) and np.all(np.diff(hd) < 0.0))
    err = np.concatenate([_branch_b_of_h(ha, ba, Ha) - Ba, _branch_b_of_h(hd, bd, Hd) - Bd])
    b_grid = fit.anhysteretic[0]
    b_max = 0.5 * float(b_grid[-1] - b_grid[0])
    hc_meas = 0.5 * (abs(_crossing(Ha, Ba)) + abs(_crossing(Hd, Bd)))
    hc_mod = 0.5 * (abs(_crossing(ha, ba)) + abs(_crossing(hd, bd)))
    br_meas = 0.5 * (abs(_crossing(Ba, Ha)) + abs(_crossing(Bd, Hd)))
    br_mod = 0.5 * (abs(_crossing(ba, ha)) + abs(_crossing(bd, hd)))
    rms = float(np.sqrt(np.mean(err**2)))
    return {
        "b_max": b_max,
        "rms_b": rms,
        "rms_b_rel": rms / b_max,
        "max_b": float(np.max(np.abs(err))),
        "hc_measured": hc_meas,
        "hc_model": hc_mod,
        "hc_rel_err": abs(hc_mod - hc_meas) / hc_meas,
        "br_measured": br_meas,
        "br_model": br_mod,
        "br_rel_err": abs(br_mod - br_meas) / br_meas,
        "monotone": monotone,
    }
