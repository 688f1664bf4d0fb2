"""Signal conditioning shared by the diagnosis, the residuals and the effect fits.

:func:`lowpass` (a first-order filter on any time grid: the eddy signature and the eddy ladder),
:func:`detrend` (a residual known only up to ``a + b t``) and :func:`conditioned_position` (an
encoder's position without the reversals its jitter fakes).
"""

from __future__ import annotations

import math

import numpy as np


def lowpass(x: np.ndarray, t: np.ndarray, tau: float) -> np.ndarray:
    """First-order low-pass y' = (x - y)/tau, exact for piecewise-constant x (any time grid)."""
    y = np.empty_like(x)
    acc = 0.0
    dt = np.diff(t, prepend=t[0])
    a = np.exp(-dt / tau)
    if x.dtype == np.float64 and x.ndim == 1 and a.dtype == np.float64:
        # over Python floats: the same IEEE arithmetic without a numpy scalar per sample
        out = []
        for ak, xk in zip(a.tolist(), x.tolist(), strict=False):
            acc = ak * acc + (1 - ak) * xk
            out.append(acc)
        y[:] = out
        return y
    for k in range(len(x)):
        acc = a[k] * acc + (1 - a[k]) * x[k]
        y[k] = acc
    return y


def detrend(y: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``y`` (shape (n,) or (n, p)) less its least-squares fit by ``a + b t`` (per column)."""
    t = np.asarray(t, dtype=float)
    if t.size < 3:
        return np.zeros_like(y)
    tc = (t - t.mean()) / max(float(np.ptp(t)), 1e-30)
    basis = np.column_stack([np.ones_like(tc), tc])
    coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
    return y - basis @ coef


def conditioned_position(x_m: np.ndarray) -> np.ndarray:
    """A measured armature position [m] without the reversals its noise fakes.

    Position encoders jitter by their noise and resolution; the model's friction (a Dahl state
    driven by position changes, like the rig's) would take every jitter for a reversal and lose
    its force. The position is passed through a play operator of half-width
    ``r = 3 sigma + q`` (``sigma``: robust noise from second differences, ``q``: the encoder
    step, the smallest non-zero change) and shifted back by ``r`` in the direction of the last
    motion: while the armature moves, this is the measured position's running extreme (within
    the noise of the true one); while it stands, the position it stopped at. Positions that never
    move beyond ``r`` come back unchanged.
    """
    x = np.asarray(x_m, dtype=float)
    if x.size < 5 or not np.all(np.isfinite(x)):
        return x
    d = np.abs(np.diff(x))
    nz = d[d > 0]
    if nz.size == 0:
        return x
    d2 = np.diff(x, 2)
    sigma = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / math.sqrt(6.0)
    r = 3.0 * sigma + float(np.min(nz))
    if not 0.0 < r < 0.25 * float(np.ptp(x)):
        return x
    out = np.empty_like(x)
    y = float(x[0])
    direction = 0.0
    for k, v in enumerate(x.tolist()):
        if v - r > y:
            y, direction = v - r, 1.0
        elif v + r < y:
            y, direction = v + r, -1.0
        out[k] = y + r * direction
    return out
