"""Fitting a play operator (:class:`~solenoid_fmu.realtime.hysteresis.PlayHysteresis`) to recorded series.

:func:`fit_play_to_series` fits the operator to input/output series such as flux triangles of
several amplitudes (the loop's hysteresis step). :func:`fit_weights_and_shape` is the alternating
non-negative least squares both fits (this one and the major-loop fit of
:mod:`.hysteresis_loop_fit`) solve. scipy is imported inside the fitting functions only, so
the operators of this subpackage run without it (``tests/test_hysteresis.py`` checks that).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .hysteresis import HysteresisError, PlayHysteresis, as_1d_finite, as_scalar, play_matrix

__all__ = ["PlaySeriesFit", "fit_play_to_series", "fit_weights_and_shape", "hat_basis", "unimodal_bases"]


def hat_basis(b: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Piecewise-linear interpolation matrix, shape (len(b), len(nodes)), clamped outside."""
    n = nodes.size
    idx = np.clip(np.searchsorted(nodes, b, side="right") - 1, 0, n - 2)
    t = np.clip((b - nodes[idx]) / (nodes[idx + 1] - nodes[idx]), 0.0, 1.0)
    Phi = np.zeros((b.size, n))
    rows = np.arange(b.size)
    Phi[rows, idx] = 1.0 - t
    Phi[rows, idx + 1] += t
    return Phi



def unimodal_bases(n: int) -> list:
    """For each mode ``p`` of ``n`` nodes, the matrix (n, m) whose non-negative combinations are exactly the
    non-negative sequences rising to node ``p`` and falling after it: the indicators of the node intervals
    ``[a, b]`` with ``a <= p <= b`` (every superlevel set of such a sequence is one of them)."""
    out = []
    for p in range(n):
        cols = [np.r_[np.zeros(a), np.ones(b - a + 1), np.zeros(n - 1 - b)] for a in range(p + 1) for b in range(p, n)]
        out.append(np.column_stack(cols))
    return out


def fit_weights_and_shape(S: np.ndarray, y: np.ndarray, Phi: np.ndarray | None,
                          row_w: np.ndarray, n_iter: int = 40, C: np.ndarray | None = None,
                          smooth: float = 0.0, unimodal: bool = False):
    """Alternating non-negative least squares for ``y ~ (Phi g) * (S w) [+ C c]``.

    ``w >= 0`` (K,), ``g >= 0`` (shape nodes) and an optional free coefficient vector ``c``
    for the columns ``C`` (a single-valued correction). Rows are weighted by ``row_w``.
    Without ``Phi`` the factor is 1 and one solve suffices. The scale is fixed by making
    the mean of ``g`` one. With ``unimodal``, ``g`` rises to one node and falls after it (the best mode of
    :func:`unimodal_bases` in each g step). Returns ``(w, g or None, c or None, weighted residual norm)``.
    """
    from scipy.optimize import lsq_linear, nnls  # lazy: the operators of realtime run without scipy

    K = S.shape[1]
    nc = 0 if C is None else C.shape[1]

    def solve_w(A):
        Aw = A * row_w[:, None]
        yw = y * row_w
        if smooth > 0.0 and K > 1:
            # Tikhonov rows: first differences of the weights, scaled to the data columns,
            # so the weight density spreads over the thresholds instead of a few spikes
            col = float(np.sqrt(np.mean(np.sum(Aw**2, axis=0))))
            D = np.diff(np.eye(K), axis=0) * (np.sqrt(smooth) * col)
            Aw = np.vstack([Aw, D])
            yw = np.concatenate([yw, np.zeros(K - 1)])
            if C is not None:
                Cw = np.vstack([C * row_w[:, None], np.zeros((K - 1, nc))])
        elif C is not None:
            Cw = C * row_w[:, None]
        if nc == 0:
            w, res = nnls(Aw, yw, maxiter=50 * max(K, 10))
            return w, None, res
        full = np.hstack([Aw, Cw])
        lb = np.concatenate([np.zeros(K), np.full(nc, -np.inf)])
        sol = lsq_linear(full, yw, bounds=(lb, np.full(K + nc, np.inf)), method="bvls")
        x = sol.x.copy()
        x[:K] = np.maximum(x[:K], 0.0)  # bvls may return -1e-16 at an active bound
        return x[:K], x[K:], float(np.linalg.norm(full @ x - yw))

    if Phi is None:
        w, c, res = solve_w(S)
        return w, None, c, res
    g = np.ones(Phi.shape[1])
    if C is not None:
        # start from the fit without the correction, so adding it can only lower the residual; a
        # single-valued error larger than the loops can leave nothing to that fit (then start from g = 1)
        try:
            _, g, _, _ = fit_weights_and_shape(S, y, Phi, row_w, n_iter=n_iter, smooth=smooth, unimodal=unimodal)
        except HysteresisError:
            g = np.ones(Phi.shape[1])
    bases = unimodal_bases(Phi.shape[1]) if unimodal else None
    prev = np.inf
    for _ in range(int(n_iter)):
        gb = Phi @ g
        w, c, res = solve_w(gb[:, None] * S)
        target = y if c is None else y - C @ c
        Aw = (S @ w)[:, None] * Phi * row_w[:, None]
        if unimodal:
            best = None
            for U in bases:
                coef, r = nnls(Aw @ U, target * row_w, maxiter=50 * max(U.shape[1], 10))
                if best is None or r < best[1]:
                    best = (U @ coef, r)
            g, res = best
        else:
            g, res = nnls(Aw, target * row_w, maxiter=50 * max(Phi.shape[1], 10))
        scale = float(np.mean(g))
        if not scale > 0.0:
            raise HysteresisError("the fitted hysteresis vanishes: the data show no loop")
        g /= scale
        w *= scale
        if prev - res <= 1e-9 * max(prev, 1e-300):
            break
        prev = res
    return w, g, c, res



class PlaySeriesFit(NamedTuple):
    """Result of :func:`fit_play_to_series`.

    Attributes
    ----------
    play : PlayHysteresis
        The fitted operator (in its neutral state at ``b = 0``).
    correction : tuple of two numpy.ndarray or None
        ``(b_nodes, dh_nodes)``: the fitted single-valued correction ``dh(b)`` (units of b and
        h, piecewise linear, constant beyond the ends), or None if not requested.
    rms : float
        RMS of the unweighted residual over all samples, units of h.
    """

    play: PlayHysteresis
    correction: tuple | None
    rms: float

    def predict(self, b_series, b0: float = 0.0) -> np.ndarray:
        """``h`` (units of h) along a series from the neutral state at ``b0``, correction included."""
        b = as_1d_finite("b_series", b_series, min_len=0)
        op = self.play.copy()
        op.reset(b0)
        h = op.run(b)
        if self.correction is not None:
            h = h + np.interp(b, self.correction[0], self.correction[1])
        return h


def fit_play_to_series(b_series, h_series, n_plays: int = 16, n_shape: int = 9,
                       thresholds=None, b0: float = 0.0, n_correction: int = 0,
                       sample_weights=None, smooth: float = 1e-3, unimodal_shape: bool = True) -> PlaySeriesFit:
    """Fit a play operator to recorded input/output series (e.g. several loop amplitudes).

    Parameters
    ----------
    b_series : sequence of array-like
        Input series (units of b), each starting from the neutral state at ``b0``
        (e.g. the flux linkage of each flux-triangle recording [Wb]).
    h_series : sequence of array-like
        Target hysteresis output of each series (units of h), the same lengths (e.g. the
        measured current minus the anhysteretic ``i_f(Psi, x)`` [A]).
    n_plays : int, optional
        Number of plays when ``thresholds`` is not given; then spread uniformly over
        ``(0, (max b - min b) / 2]`` of all series. Default 16.
    n_shape : int, optional
        Nodes of the shape factor ``g(b)`` over the range of ``b``; 0 for ``g = 1``. Default 9.
    thresholds : array-like, optional
        Play half-widths (units of b), overriding ``n_plays``.
    b0 : float, optional
        Input of the neutral start state of every series (units of b). Default 0.
    n_correction : int, optional
        If >= 2, also fit a single-valued correction ``dh(b)`` on that many nodes (free sign):
        for a target whose anhysteretic part is not exactly known. Default 0 (none).
    sample_weights : sequence of array-like, optional
        Non-negative weight per sample of each series. Default: all one.
    smooth : float, optional
        Weight of a penalty on the first differences of the play weights (relative to the data
        columns): spreads the weights over the thresholds instead of a few spikes, so minor
        loops of every size keep some hysteresis. Default 1e-3.
    unimodal_shape : bool, optional
        The shape factor ``g(b)`` rises to one node and falls after it (default): a steel's loops narrow
        towards saturation, and a free ``g`` fits whatever the widest loops' tips carry. On the demo campaign
        a free ``g`` fell to 0 at 0.21-0.28 Wb and rose again to 1.47 at the top (0.42 Wb): the model's force
        on the strokes was 1.0-1.2 % of full scale off where the same plays with that rise cut were 0.3 %
        (stop 49). False: any ``g >= 0``.

    Returns
    -------
    PlaySeriesFit
        The operator, the correction table (or None) and the RMS residual.

    Notes
    -----
    The target is linear in the weights for a fixed shape factor and linear in the shape
    factor for fixed weights, so the fit alternates non-negative least squares between the two
    (scipy, imported here only).
    """
    bs, hs, ws = _checked_series(b_series, h_series, sample_weights)
    b_all = np.concatenate(bs)
    y = np.concatenate(hs)
    row_w = np.concatenate(ws)
    b_min, b_max = float(b_all.min()), float(b_all.max())
    if not b_max > b_min:
        raise HysteresisError("the input b never changes: nothing to fit")
    b0 = as_scalar("b0", b0)
    r = _thresholds(thresholds, n_plays, b_min, b_max)
    S = np.vstack([b[:, None] - play_matrix(r, b, np.full(r.size, b0)) for b in bs])
    n_shape = int(n_shape)
    if n_shape == 1 or n_shape < 0:
        raise HysteresisError(f"n_shape must be 0 (no shape factor) or >= 2, got {n_shape}")
    nodes = np.linspace(b_min, b_max, n_shape) if n_shape else None
    Phi = hat_basis(b_all, nodes) if n_shape else None
    n_correction = int(n_correction)
    if n_correction == 1 or n_correction < 0:
        raise HysteresisError(f"n_correction must be 0 or >= 2, got {n_correction}")
    c_nodes = np.linspace(b_min, b_max, n_correction) if n_correction else None
    C = hat_basis(b_all, c_nodes) if n_correction else None
    w, g, c, _ = fit_weights_and_shape(S, y, Phi, row_w, C=C, smooth=float(smooth), unimodal=bool(unimodal_shape))
    play = PlayHysteresis(r, w, shape=None if g is None else (nodes, g))
    correction = None if c is None else (c_nodes, c)
    fit = PlaySeriesFit(play, correction, 0.0)
    resid = np.concatenate([fit.predict(b, b0) - h for b, h in zip(bs, hs, strict=True)])
    return PlaySeriesFit(play, correction, float(np.sqrt(np.mean(resid**2))))


def _checked_series(b_series, h_series, sample_weights):
    """The series of :func:`fit_play_to_series` as 1-D float arrays, checked: (b, h, weights) per series."""
    try:
        bs = [as_1d_finite(f"b_series[{j}]", b, min_len=2) for j, b in enumerate(b_series)]
        hs = [as_1d_finite(f"h_series[{j}]", h, min_len=2) for j, h in enumerate(h_series)]
    except TypeError:
        raise HysteresisError("b_series and h_series must be sequences of arrays") from None
    if not bs or len(bs) != len(hs):
        raise HysteresisError(f"need as many h series as b series (>= 1), got {len(bs)} and {len(hs)}")
    for j, (b, h) in enumerate(zip(bs, hs, strict=True)):
        if b.shape != h.shape:
            raise HysteresisError(f"series {j}: b has {b.size} samples, h has {h.size}")
    if sample_weights is None:
        ws = [np.ones_like(b) for b in bs]
    else:
        ws = [as_1d_finite(f"sample_weights[{j}]", w, min_len=0)
              for j, w in enumerate(sample_weights)]
        if len(ws) != len(bs) or any(w.shape != b.shape or np.any(w < 0)
                                     for w, b in zip(ws, bs, strict=True)):
            raise HysteresisError("sample_weights must be non-negative and shaped like b_series")
    return bs, hs, ws


def _thresholds(thresholds, n_plays: int, b_min: float, b_max: float) -> np.ndarray:
    """The play half-widths of :func:`fit_play_to_series`: ``thresholds`` checked, or ``n_plays`` spread
    uniformly over ``(0, (b_max - b_min) / 2]``."""
    if thresholds is None:
        n_plays = int(n_plays)
        if n_plays < 1:
            raise HysteresisError(f"n_plays must be >= 1, got {n_plays}")
        r = (b_max - b_min) / 2.0 * np.arange(1, n_plays + 1) / n_plays
    else:
        r = as_1d_finite("thresholds", thresholds)
        if np.any(r <= 0.0):
            raise HysteresisError("thresholds must all be > 0")
    return r
