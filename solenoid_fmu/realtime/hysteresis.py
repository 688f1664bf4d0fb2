"""Rate-independent magnetic hysteresis sub-models acting on a flux-like variable.

Both models (:class:`PlayHysteresis` here, :class:`~solenoid_fmu.realtime.preisach.PreisachHysteresis`
in :mod:`.preisach`) map a flux-like input ``b`` (the flux density B [T] of an Epstein sample, or
the coil flux linkage Psi [Wb] of the solenoid) to an extra field-like output ``h`` (an extra
field strength H [A/m], or an extra field-generating current [A]) that is added to a
single-valued anhysteretic curve::

    H = H_an(B) + h[B](t)            (Epstein sample)
    i_f = i_f(Psi, x) + h[Psi](t)    (solenoid, paper eq. 2 with hysteresis)

Writing the hysteresis as a function of the flux keeps the real-time model explicit: the flux is
the state of the lumped model (paper eq. 1), so the current follows from it without iteration.

``PlayHysteresis``
    The model the real-time FMU fits and carries: an inverse Prandtl-Ishlinskii operator, a
    weighted sum of *stop* operators ``s_r(b) = b - play_r(b)`` with non-negative weights,
    times a single-valued shape factor ``g(b) >= 0``::

        h = g(b) * sum_k w_k (b - play_{r_k}(b)),   w_k >= 0

    Each stop output stays within ``[-r, r]``: ``+r`` on an ascending branch once ``b`` has
    risen by ``2 r`` since the last reversal, ``-r`` on a descending one, so the ascending
    branch lies at larger H than the descending one at equal B, as in a measured B(H) loop.
    (A sum of *play* operators with non-negative weights turns the loop the wrong way round in
    the H(B) plane; the inverse of a Prandtl-Ishlinskii operator has negative play weights,
    which is the same thing as positive stop weights plus a linear term that ``H_an``
    absorbs.) The shape factor is needed for real steel: stops alone give a major-loop width in
    H that is largest at B = 0, measured loops are widest at the knee. The state is the K play
    outputs; the plays give rate independence, wiping out and return-point memory.
``PreisachHysteresis``
    The "truth" of the virtual test rig, a different model class so that fitting the play model
    to rig data is not circular: a classical Preisach operator ``P[b]`` with a continuous
    factorized Lorentzian or Gaussian density (evaluated exactly through its Everett function),
    taken with a negative sign and referenced to the mean ``Q(b)`` of its saturated major
    branches: ``h = A * (Q(b) - P[b])``. So ``h`` averages to zero on the major loop, is bounded
    by ``A`` and turns the same way as a measured B(H) loop in the H(B) plane.

Fitting lives apart (it is not FMU payload): :mod:`.hysteresis_fit` (the play operator to
input/output series, :func:`~solenoid_fmu.realtime.hysteresis_fit.fit_play_to_series`) and
:mod:`.hysteresis_loop_fit` (the anhysteretic curve and the play operator to one measured major
loop, and the comparison of the fitted loop with the measured one). Per-step cost of both models:
:mod:`.hysteresis_cost`.

:meth:`PlayHysteresis.step` is the real-time model's play step (:func:`.model.play_step`, the
arithmetic the FMU runs); this module imports only numpy, the standard library and ``model.py``.
"""

from __future__ import annotations

import math

import numpy as np

from .model import play_step

__all__ = [
    "HysteresisError",
    "PlayHysteresis",
    "as_1d_finite",
    "as_scalar",
    "loop_area",
    "play_matrix",
]


class HysteresisError(ValueError):
    """Bad parameters, state or data for a hysteresis model (names the offending value).

    A ``ValueError`` because this module must not import the package's error hierarchy (it ships
    inside the FMU on its own); callers in the package wrap it where a file is involved.
    """


def as_1d_finite(name: str, values, min_len: int = 1) -> np.ndarray:
    """Convert to a 1-D float64 array, refusing NaN/inf, wrong shape or too few points."""
    try:
        arr = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise HysteresisError(f"{name} must be numeric: {exc}") from None
    if arr.ndim != 1:
        raise HysteresisError(f"{name} must be one-dimensional, got shape {arr.shape}")
    if arr.size < min_len:
        raise HysteresisError(f"{name} needs at least {min_len} value(s), got {arr.size}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise HysteresisError(f"{name}[{bad[0]}] = {float(arr[bad[0]])!r} is not finite")
    return arr


def as_scalar(name: str, value) -> float:
    """A finite float or a clear error."""
    try:
        val = float(value)
    except (TypeError, ValueError):
        raise HysteresisError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(val):
        raise HysteresisError(f"{name} must be finite, got {val!r}")
    return val


def _monotone_segments(b: np.ndarray) -> list[tuple[int, int, int]]:
    """Split a series into monotone runs ``(start, stop, direction)``, ``stop`` exclusive.

    ``direction`` is +1 (non-decreasing) or -1 (non-increasing); equal neighbours join the run
    they continue, and a run ends at the sample where the input reverses. Used to evaluate
    rate-independent operators a run at a time.
    """
    n = b.size
    if n == 0:
        return []
    d = np.sign(np.diff(b))
    nz = np.flatnonzero(d)
    if nz.size == 0:
        return [(0, n, 1)]
    # carry the last non-zero direction over flat steps (leading flats take the first one)
    idx = np.maximum.accumulate(np.where(d != 0, np.arange(d.size), -1))
    idx[idx < 0] = nz[0]
    dirs = d[idx]
    # a reversal between step k-1 and step k: the run ends at sample k (inclusive)
    rev = np.flatnonzero(dirs[1:] != dirs[:-1]) + 1
    starts = np.concatenate([[0], rev])
    stops = np.concatenate([rev + 1, [n]])
    return [(int(a), int(z), int(dirs[a] if a < dirs.size else dirs[-1]))
            for a, z in zip(starts, stops, strict=True)]




def play_matrix(r: np.ndarray, b: np.ndarray, p0: np.ndarray) -> np.ndarray:
    """Play outputs after every sample, shape (N, K), from the start state ``p0`` (K,).

    Vectorised over monotone runs: on a non-decreasing run the play output is
    ``max(p_start, b - r)``, on a non-increasing run ``min(p_start, b + r)``; this equals the
    step-by-step clamp ``min(max(p, b - r), b + r)`` bit for bit.
    """
    P = np.empty((b.size, r.size))
    if b.size == 0:
        return P
    p = np.minimum(np.maximum(p0, b[0] - r), b[0] + r)  # first sample: a general clamp
    for start, stop, direction in _monotone_segments(b):
        seg = b[start:stop, None]
        if direction > 0:
            np.maximum(p[None, :], seg - r[None, :], out=P[start:stop])
        else:
            np.minimum(p[None, :], seg + r[None, :], out=P[start:stop])
        p = P[stop - 1]
    return P


class PlayHysteresis:
    """Inverse Prandtl-Ishlinskii hysteresis: ``h = g(b) * sum_k w_k (b - play_{r_k}(b))``.

    Parameters
    ----------
    thresholds : array-like, shape (K,)
        Play half-widths ``r_k > 0`` in units of ``b`` (T for B, Wb for Psi).
    weights : array-like, shape (K,)
        Non-negative weights ``w_k`` in units of ``h`` per unit of ``b`` (e.g. A/m per T, or
        A per Wb).
    shape : tuple of two array-like, optional
        ``(b_nodes, g_nodes)``: the output shape factor ``g(b) >= 0`` (dimensionless) as a
        piecewise-linear table over strictly increasing ``b_nodes`` (units of b), constant
        beyond the end nodes. Default: ``g = 1`` (the plain inverse Prandtl-Ishlinskii model).
    b0 : float, optional
        Input at which the operator starts in its neutral state (every stop at zero, so
        ``h = 0``), units of ``b``. Default 0.

    Notes
    -----
    Play operator (backlash) with half-width ``r``: ``p <- min(max(p, b - r), b + r)``. The
    stop output ``b - p`` lies in ``[-r, r]``: ``+r`` on an ascending branch once ``b`` has risen
    by ``2 r`` since the last reversal, ``-r`` on a descending one. With ``w_k >= 0`` the
    ascending branch of ``H = H_an(b) + h`` lies at larger H than the descending one (the
    orientation of a measured B(H) loop in the H(B) plane), and ``|h| <= g(b) sum_k w_k r_k``.

    The shape factor ``g(b)`` is a memoryless function of the input, so the model keeps every
    property of the Prandtl-Ishlinskii operator: rate independence, the wiping-out property
    and return-point memory; the state is the K play outputs. It lets the model follow real
    steel: a sum of stops alone gives a major-loop half-width in H that is concave in ``b``
    (largest at ``b = 0``), while measured loops are widest in H at the knee of the B(H) curve
    (on the Epstein loops of the tests the factor lowers the RMS B error from 2-3 % to below
    1 % of B_max).

    Along any monotone path the slope ``dH/db`` is at least
    ``H_an'(b) - |g'(b)| sum_k w_k r_k``; when that is positive (both saturated major branches
    rising) every branch, major or minor, is monotone, so the model is invertible.
    This is the hysteresis term added to the field-generating current of paper eq. (2); the
    anhysteretic part stays in the map ``i_f(Psi, x)``.
    """

    def __init__(self, thresholds, weights, shape=None, b0: float = 0.0):
        r = as_1d_finite("thresholds", thresholds)
        w = as_1d_finite("weights", weights)
        if r.shape != w.shape:
            raise HysteresisError(
                f"thresholds and weights differ in length: {r.size} vs {w.size}"
            )
        if np.any(r <= 0.0):
            k = int(np.flatnonzero(r <= 0.0)[0])
            raise HysteresisError(f"thresholds[{k}] = {float(r[k])!r}: play half-widths must be > 0")
        if np.any(w < 0.0):
            k = int(np.flatnonzero(w < 0.0)[0])
            raise HysteresisError(f"weights[{k}] = {float(w[k])!r}: weights must be >= 0")
        self._r = r.copy()
        self._w = w.copy()
        self._r.setflags(write=False)
        self._w.setflags(write=False)
        if shape is None:
            self._shape = None
            self._shape_b: tuple = ()
            self._shape_g: tuple = ()
        else:
            try:
                sb, sg = shape
            except (TypeError, ValueError):
                raise HysteresisError("shape must be a pair (b_nodes, g_nodes)") from None
            sb = as_1d_finite("shape b_nodes", sb, min_len=2)
            sg = as_1d_finite("shape g_nodes", sg, min_len=2)
            if sb.shape != sg.shape:
                raise HysteresisError(f"shape tables differ in length: {sb.size} vs {sg.size}")
            if np.any(np.diff(sb) <= 0.0):
                k = int(np.flatnonzero(np.diff(sb) <= 0.0)[0])
                raise HysteresisError(
                    f"shape b_nodes must increase strictly: b_nodes[{k}] = {float(sb[k])!r}, "
                    f"b_nodes[{k + 1}] = {float(sb[k + 1])!r}"
                )
            if np.any(sg < 0.0):
                k = int(np.flatnonzero(sg < 0.0)[0])
                raise HysteresisError(f"shape g_nodes[{k}] = {float(sg[k])!r}: the factor must be >= 0")
            sb.setflags(write=False)
            sg.setflags(write=False)
            self._shape = (sb, sg)
            # plain float tuples for the scalar lookup in step() (bisect, no numpy overhead)
            self._shape_b = tuple(sb.tolist())
            self._shape_g = tuple(sg.tolist())
        # step() runs the real-time model's play step on plain floats: parameters as tuples, the
        # state (the K play outputs) as a list it updates in place
        self._r_list = tuple(self._r.tolist())
        self._w_list = tuple(self._w.tolist())
        self._p = [0.0] * self._r.size
        self.reset(b0)

    # -- parameters ---------------------------------------------------------------------------
    @property
    def thresholds(self) -> np.ndarray:
        """Play half-widths ``r_k`` (read-only), units of ``b``."""
        return self._r

    @property
    def weights(self) -> np.ndarray:
        """Weights ``w_k >= 0`` (read-only), units of ``h`` per unit of ``b``."""
        return self._w

    @property
    def shape(self):
        """``(b_nodes, g_nodes)`` of the output shape factor (read-only arrays), or None (g = 1)."""
        return self._shape

    @property
    def n_plays(self) -> int:
        """Number of play operators K (the length of the state)."""
        return int(self._r.size)

    @property
    def stop_bound(self) -> float:
        """``sum_k w_k r_k``: the bound of ``|h| / g(b)``, units of ``h``."""
        return float(np.dot(self._w, self._r))

    def g(self, b):
        """Output shape factor ``g(b)`` (dimensionless), for a scalar or an array of inputs."""
        if self._shape is None:
            return np.ones_like(np.asarray(b, dtype=np.float64))
        return np.interp(b, self._shape[0], self._shape[1])

    # -- state ----------------------------------------------------------------------------------
    def reset(self, b0: float = 0.0) -> None:
        """Neutral state at input ``b0``: every play output equals ``b0``, so ``h = 0``."""
        self._p[:] = [as_scalar("b0", b0)] * len(self._p)

    def state(self) -> np.ndarray:
        """A copy of the play outputs ``p_k``, shape (K,), units of ``b``."""
        return np.array(self._p, dtype=np.float64)

    def set_state(self, state) -> None:
        """Restore play outputs from :meth:`state` (shape (K,), finite)."""
        p = as_1d_finite("state", state)
        if p.shape != self._r.shape:
            raise HysteresisError(f"state has {p.size} values, this model has {self._r.size} plays")
        self._p[:] = p.tolist()

    def copy(self) -> PlayHysteresis:
        """An independent model with the same parameters and state."""
        other = PlayHysteresis(self._r, self._w, shape=self._shape)
        other.set_state(self._p)
        return other

    # -- evaluation -----------------------------------------------------------------------------
    def step(self, b: float) -> float:
        """Advance to input ``b`` (units of ``b``) and return ``h`` (units of ``h``).

        The real-time model's play step (:func:`solenoid_fmu.realtime.model.play_step`, the
        arithmetic the FMU runs): a clamp and a multiply-add per play on plain floats, then a
        bisection in the shape table.
        """
        if not b - b == 0.0:  # NaN or inf (one comparison, no allocation)
            raise HysteresisError(f"input b = {b!r} is not finite")
        return play_step(self._p, self._r_list, self._w_list, self._shape_b, self._shape_g, float(b))

    def run(self, b_series) -> np.ndarray:
        """Advance through a series of inputs and return ``h`` at each one.

        Parameters
        ----------
        b_series : array-like, shape (N,)
            Input samples in order, units of ``b``. The state continues from the current one
            and is left at the last sample.

        Returns
        -------
        numpy.ndarray, shape (N,)
            ``h`` after each sample, units of ``h``.

        Notes
        -----
        Vectorised over monotone runs of the input. The play outputs (the state) after every
        sample are those of :meth:`step` bit for bit; ``h`` agrees with :meth:`step` to
        rounding (the order of the weighted sum differs), and a series split into pieces gives
        the same ``h`` bit for bit as the whole.
        """
        b = as_1d_finite("b_series", b_series, min_len=0)
        if b.size == 0:
            return np.empty(0)
        P = play_matrix(self._r, b, np.asarray(self._p))
        self._p[:] = P[-1].tolist()
        # weighted sum play by play (element-wise, so every sample is computed the same way
        # whatever the length of the series: splitting a run does not change a bit)
        acc = np.zeros_like(b)
        for k, wk in enumerate(self._w.tolist()):
            if wk != 0.0:
                acc += wk * (b - P[:, k])
        return self.g(b) * acc

    def stops(self, b_series) -> np.ndarray:
        """Stop outputs ``b - p_k`` after every sample, shape (N, K), units of b (advances the state)."""
        b = as_1d_finite("b_series", b_series, min_len=0)
        P = play_matrix(self._r, b, np.asarray(self._p))
        if b.size:
            self._p[:] = P[-1].tolist()
        return b[:, None] - P

    # -- serialisation --------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Parameters and state as plain JSON-able lists (units of ``b`` and ``h``)."""
        out = {
            "model": "inverse-prandtl-ishlinskii",
            "thresholds": self._r.tolist(),
            "weights": self._w.tolist(),
            "shape": None,
            "state": list(self._p),
        }
        if self._shape is not None:
            out["shape"] = {"b_nodes": self._shape[0].tolist(), "g_nodes": self._shape[1].tolist()}
        return out

    @classmethod
    def from_dict(cls, data: dict) -> PlayHysteresis:
        """Rebuild from :meth:`to_dict` output (state restored if present)."""
        try:
            shape = data.get("shape")
            if shape is not None:
                shape = (shape["b_nodes"], shape["g_nodes"])
            model = cls(data["thresholds"], data["weights"], shape=shape)
        except KeyError as exc:
            raise HysteresisError(f"play-hysteresis data lacks the key {exc.args[0]!r}") from None
        except AttributeError:
            raise HysteresisError("play-hysteresis data must be a mapping") from None
        if data.get("state") is not None:
            model.set_state(data["state"])
        return model

    def __repr__(self) -> str:
        return (
            f"PlayHysteresis(K={self._r.size}, r=[{self._r[0]:.4g}..{self._r[-1]:.4g}], "
            f"sum w r={self.stop_bound:.4g}, shape={'none' if self._shape is None else 'table'})"
        )



def loop_area(b, h) -> float:
    """Area enclosed by a closed path in the (b, h) plane, ``|closed integral of h db|``.

    Parameters
    ----------
    b, h : array-like, shape (N,)
        One cycle of the path (units of b and h); the path is closed from the last point back
        to the first.

    Returns
    -------
    float
        The enclosed area in units of b times h (J/m^3 for B [T] and H [A/m]; J for Psi [Wb]
        and current [A]: the energy lost per cycle).
    """
    b = as_1d_finite("b", b, min_len=3)
    h = as_1d_finite("h", h, min_len=3)
    if b.shape != h.shape:
        raise HysteresisError(f"b and h differ in length: {b.size} vs {h.size}")
    return float(0.5 * abs(np.dot(b, np.roll(h, -1)) - np.dot(h, np.roll(b, -1))))
