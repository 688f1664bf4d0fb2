"""Classical Preisach hysteresis with a continuous density: the virtual test rig's truth.

A different model class from the play operator the real-time FMU fits
(:class:`~solenoid_fmu.realtime.hysteresis.PlayHysteresis`), so that fitting the play model to rig
data is not circular. Same convention: a flux-like input ``b`` maps to an extra field-like output
``h`` added to an anhysteretic curve (see :mod:`solenoid_fmu.realtime.hysteresis`).
"""

from __future__ import annotations

import numpy as np

from .hysteresis import HysteresisError, as_1d_finite, as_scalar

__all__ = ["PreisachHysteresis"]


class _UniformTable:
    """Linear interpolation on a uniform 1-D grid, clamped at the ends (scalar and array)."""

    __slots__ = ("x0", "inv_dx", "n", "y", "y_list")

    def __init__(self, x: np.ndarray, y: np.ndarray):
        self.x0 = float(x[0])
        self.inv_dx = (x.size - 1) / float(x[-1] - x[0])
        self.n = int(x.size)
        self.y = y
        self.y_list = y.tolist()

    def scalar(self, x: float) -> float:
        t = (x - self.x0) * self.inv_dx
        if t <= 0.0:
            return self.y_list[0]
        if t >= self.n - 1:
            return self.y_list[-1]
        i = int(t)
        y = self.y_list
        return y[i] + (t - i) * (y[i + 1] - y[i])

    def array(self, x: np.ndarray) -> np.ndarray:
        t = np.clip((np.asarray(x, dtype=np.float64) - self.x0) * self.inv_dx, 0.0, self.n - 1)
        i = np.minimum(t.astype(np.int64), self.n - 2)
        return self.y[i] + (t - i) * (self.y[i + 1] - self.y[i])


class PreisachHysteresis:
    """Classical Preisach model with a continuous density, used as the virtual rig's truth.

    ``h = amplitude * (Q(b) - P[b])``: ``P[b]`` in [-1, 1] is the classical Preisach operator
    (a continuum of relay hysterons switching up at ``b >= alpha`` and down at ``b <= beta``,
    ``alpha >= beta``, with a factorized density ``f(alpha - b_c) f(beta + b_c)`` on
    ``[-b_sat, b_sat]^2``) and ``Q(b)`` is the mean of its two saturated major-loop branches
    (a single-valued function). So ``h`` is zero on average on the saturated major loop (the
    commutation curve of ``H = H_an(b) + h`` is ``H_an``), zero beyond saturation, bounded by
    ``amplitude``, and its loop turns the way a measured B(H) loop does in the H(B) plane
    (larger ``h`` on ascending branches).

    Parameters
    ----------
    b_sat : float, optional
        Saturation input (units of b): the Preisach plane covers ``[-b_sat, b_sat]``; beyond it
        every relay is switched and ``h = 0``. Default 1.6 (T, electrical steel).
    b_c : float, optional
        Coercive-like width (units of b): the density peaks at ``alpha = b_c, beta = -b_c``.
        Default 0.25 (T).
    spread : float, optional
        Width of the density around its peak (units of b): Lorentzian half-width or Gaussian
        standard deviation. Default 0.3 (T).
    amplitude : float, optional
        Scale of ``h`` (units of h). Default 100.0 (A/m, the coercive field of a soft steel
        is 50-300 A/m).
    density : {"lorentzian", "gaussian"}, optional
        Shape ``f`` of the factorized density. Default "lorentzian" (Bertotti's choice).
    n_table : int, optional
        Points of the 1-D tables of the Everett function. Default 4001.
    b0 : float, optional
        Input of the initial AC-demagnetized state (see :meth:`reset`). Default 0.

    Notes
    -----
    A different model class from the play operator
    (:class:`~solenoid_fmu.realtime.hysteresis.PlayHysteresis`) on purpose: fitting the play model
    to rig data must not be circular. The operator is evaluated exactly for the continuous
    density (no relay grid) with the Everett function ``E(alpha, beta)``, the density mass of
    the triangle ``beta <= beta' <= alpha' <= alpha``, which factorizes into 1-D tables:
    ``E = H1(alpha) - H1(beta) - G(beta) (Fa(alpha) - Fa(beta))``. The state is the stack of
    alternating dominant input extrema (Mayergoyz): a new extremum is pushed at each reversal
    and wiped out when the input passes the previous one, which gives the wiping-out property,
    congruent minor loops and rate independence. The loop area grows with the amplitude of a
    symmetric cycle because the density is positive.

    Along a saturated major branch ``dh/db`` can be as low as ``-max_negative_slope()``; the
    anhysteretic curve the term is added to must be steeper than that for the branches of the
    full model to stay monotone.
    """

    def __init__(self, b_sat: float = 1.6, b_c: float = 0.25, spread: float = 0.3,
                 amplitude: float = 100.0, density: str = "lorentzian", n_table: int = 4001,
                 b0: float = 0.0):
        b_sat = as_scalar("b_sat", b_sat)
        b_c = as_scalar("b_c", b_c)
        spread = as_scalar("spread", spread)
        amplitude = as_scalar("amplitude", amplitude)
        if b_sat <= 0.0:
            raise HysteresisError(f"b_sat must be > 0, got {b_sat!r}")
        if not 0.0 <= b_c < b_sat:
            raise HysteresisError(f"b_c must lie in [0, b_sat) = [0, {b_sat!r}), got {b_c!r}")
        if spread <= 0.0:
            raise HysteresisError(f"spread must be > 0, got {spread!r}")
        if amplitude < 0.0:
            raise HysteresisError(f"amplitude must be >= 0, got {amplitude!r}")
        if density not in ("lorentzian", "gaussian"):
            raise HysteresisError(f"density must be 'lorentzian' or 'gaussian', got {density!r}")
        if int(n_table) != n_table or int(n_table) < 101:
            raise HysteresisError(f"n_table must be an integer >= 101, got {n_table!r}")
        self.b_sat, self.b_c, self.spread, self.amplitude = b_sat, b_c, spread, amplitude
        self.density, self.n_table = density, int(n_table)

        x = np.linspace(-b_sat, b_sat, self.n_table)
        if density == "lorentzian":
            f = 1.0 / (1.0 + ((x - b_c) / spread) ** 2)  # density along alpha
            g = 1.0 / (1.0 + ((x + b_c) / spread) ** 2)  # density along beta
        else:
            f = np.exp(-0.5 * ((x - b_c) / spread) ** 2)
            g = np.exp(-0.5 * ((x + b_c) / spread) ** 2)
        dx = x[1] - x[0]

        def cumtrapz(y):
            out = np.zeros_like(y)
            out[1:] = np.cumsum(0.5 * (y[1:] + y[:-1]) * dx)
            return out

        Fa = cumtrapz(f)
        G = cumtrapz(g)
        H1 = cumtrapz(f * G)
        total = H1[-1] - H1[0] - G[0] * (Fa[-1] - Fa[0])  # E(b_sat, -b_sat)
        self._Fa = _UniformTable(x, Fa / total)
        self._G = _UniformTable(x, G)
        self._H1 = _UniformTable(x, H1 / total)
        # mean of the saturated major branches: Q(b) = E(b, -b_sat) - E(b_sat, b)
        self._Q = _UniformTable(x, self._everett_array(x, np.full_like(x, -b_sat))
                                - self._everett_array(np.full_like(x, b_sat), x))
        self._x = x
        self._ext: list[float] = []
        self._u = 0.0
        self._cache = 0.0
        self.reset(b0)

    @classmethod
    def with_coercive(cls, b_sat: float, h_c: float, b_c_rel: float = 0.15,
                      spread_rel: float = 0.2, **kwargs) -> PreisachHysteresis:
        """A model whose saturated major loop has the half-width ``h_c`` at ``b = 0``.

        Parameters
        ----------
        b_sat : float
            Saturation input (units of b), e.g. the flux linkage at the largest current [Wb].
        h_c : float
            Half-width of the saturated major loop at ``b = 0`` (units of h), e.g. a coercive
            field [A/m] or a current [A].
        b_c_rel, spread_rel : float, optional
            ``b_c`` and ``spread`` as fractions of ``b_sat``. Defaults 0.15 and 0.2.
        **kwargs
            Passed on (``density``, ``n_table``, ``b0``).
        """
        b_sat = as_scalar("b_sat", b_sat)
        h_c = as_scalar("h_c", h_c)
        if h_c <= 0.0:
            raise HysteresisError(f"h_c must be > 0, got {h_c!r}")
        unit = cls(b_sat=b_sat, b_c=b_c_rel * b_sat, spread=spread_rel * b_sat, amplitude=1.0,
                   **kwargs)
        return cls(b_sat=b_sat, b_c=b_c_rel * b_sat, spread=spread_rel * b_sat,
                   amplitude=h_c / unit.major_half_width_at_zero(), **kwargs)

    # -- Everett function -----------------------------------------------------------------------
    def _everett(self, a: float, b: float) -> float:
        """Density mass of the triangle beta' in [b, alpha'], alpha' <= a (scalar, normalized)."""
        if a <= b:
            return 0.0
        return (self._H1.scalar(a) - self._H1.scalar(b)
                - self._G.scalar(b) * (self._Fa.scalar(a) - self._Fa.scalar(b)))

    def _everett_array(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        e = (self._H1.array(a) - self._H1.array(b)
             - self._G.array(b) * (self._Fa.array(a) - self._Fa.array(b)))
        return np.where(a > b, e, 0.0)

    def _update_cache(self) -> None:
        """Output part fixed by the extremum stack (everything but the current leg)."""
        E = self._ext
        c = -1.0
        for j in range(1, len(E), 2):  # maxima sit at odd positions
            c += 2.0 * self._everett(E[j], E[j - 1])
            if j + 1 < len(E):
                c -= 2.0 * self._everett(E[j], E[j + 1])
        self._cache = c

    def _p_of(self, u: float) -> float:
        E = self._ext
        if len(E) % 2:  # ends with a minimum: rising leg
            return self._cache + 2.0 * self._everett(u, E[-1])
        return self._cache - 2.0 * self._everett(E[-1], u)

    # -- state ----------------------------------------------------------------------------------
    def reset(self, b0: float = 0.0, n_levels: int = 200) -> None:
        """AC-demagnetized state at ``b0``: an alternating input decaying from saturation onto ``b0``.

        Parameters
        ----------
        b0 : float
            Final input (units of b).
        n_levels : int
            Number of decaying extrema (their spacing is about ``2 b_sat / n_levels``).
        """
        b0 = as_scalar("b0", b0)
        n_levels = max(int(n_levels), 2)
        self._ext = [-self.b_sat]
        self._u = -self.b_sat
        amps = 2.0 * self.b_sat * (1.0 - np.arange(n_levels) / n_levels)
        for k, a in enumerate(amps.tolist()):
            self._advance(b0 + a if k % 2 == 0 else b0 - a)
        self._advance(b0)
        self._update_cache()

    def state(self) -> np.ndarray:
        """A copy of the state: ``[last input, extremum_0, extremum_1, ...]`` (units of b)."""
        return np.array([self._u, *self._ext], dtype=np.float64)

    def set_state(self, state) -> None:
        """Restore a state from :meth:`state` (checks that the extrema alternate and nest)."""
        s = as_1d_finite("Preisach state", state, min_len=2)
        u, ext = float(s[0]), s[1:].tolist()
        if ext[0] != -self.b_sat:
            raise HysteresisError(f"Preisach state must start at -b_sat = {-self.b_sat!r}, got {ext[0]!r}")
        for j in range(1, len(ext)):
            ok = ext[j] > ext[j - 1] if j % 2 else ext[j] < ext[j - 1]
            if j >= 2:
                ok = ok and (ext[j] < ext[j - 2] if j % 2 else ext[j] > ext[j - 2])
            if not ok:
                raise HysteresisError(f"Preisach state: extremum {j} = {ext[j]!r} breaks the nesting")
        if not -self.b_sat <= u <= self.b_sat:
            raise HysteresisError(f"Preisach state: last input {u!r} outside [-b_sat, b_sat]")
        self._ext = ext
        self._u = u
        self._update_cache()

    # -- evaluation -----------------------------------------------------------------------------
    def _advance(self, b: float) -> tuple[float, bool]:
        """Move the input to ``b`` (clamped to saturation) and update the extremum stack.

        Returns the clamped input and whether the stack changed (the cache is not updated).
        """
        bs = self.b_sat
        u = float(b)
        if not u - u == 0.0:
            raise HysteresisError(f"input b = {b!r} is not finite")
        u = bs if u > bs else (-bs if u < -bs else u)
        E = self._ext
        changed = False
        if len(E) % 2:  # rising leg
            if u < self._u:  # reversal: the previous input is a maximum
                E.append(self._u)
                changed = True
        elif u > self._u:  # falling leg, reversal: the previous input is a minimum
            E.append(self._u)
            changed = True
        if len(E) % 2:  # rising: wipe out maxima that the input passes
            while len(E) >= 3 and u >= E[-2]:
                del E[-2:]
                changed = True
        else:  # falling: wipe out minima that the input passes
            while len(E) >= 2 and u <= E[-2]:
                if len(E) == 2:
                    del E[-1]  # down to negative saturation
                else:
                    del E[-2:]
                changed = True
        self._u = u
        return u, changed

    def step(self, b: float) -> float:
        """Advance to input ``b`` (units of b) and return ``h`` (units of h)."""
        u, changed = self._advance(b)
        if changed:
            self._update_cache()
        return self.amplitude * (self._Q.scalar(u) - self._p_of(u))

    def run(self, b_series) -> np.ndarray:
        """Advance through a series of inputs (units of b); ``h`` after each (units of h)."""
        b = as_1d_finite("b_series", b_series, min_len=0)
        step = self.step
        return np.array([step(v) for v in b.tolist()], dtype=np.float64)

    def major_half_width_at_zero(self) -> float:
        """Half the gap between the saturated major branches at ``b = 0`` (units of h)."""
        # ascending from -b_sat: P = -1 + 2 E(0, -b_sat); descending from b_sat: 1 - 2 E(b_sat, 0)
        p_asc = -1.0 + 2.0 * self._everett(0.0, -self.b_sat)
        p_desc = 1.0 - 2.0 * self._everett(self.b_sat, 0.0)
        return 0.5 * self.amplitude * (p_desc - p_asc)

    def max_negative_slope(self) -> float:
        """Largest ``-dh/db`` on the saturated major branches (units of h per unit of b)."""
        x = self._x
        p_asc = -1.0 + 2.0 * self._everett_array(x, np.full_like(x, -self.b_sat))
        h_asc = self.amplitude * (self._Q.array(x) - p_asc)
        return float(max(0.0, -np.min(np.diff(h_asc) / np.diff(x))))

    def to_dict(self) -> dict:
        """Parameters as JSON-able values (the state is not included)."""
        return {"model": "preisach", "b_sat": self.b_sat, "b_c": self.b_c, "spread": self.spread,
                "amplitude": self.amplitude, "density": self.density, "n_table": self.n_table}

    @classmethod
    def from_dict(cls, data: dict) -> PreisachHysteresis:
        """Rebuild from :meth:`to_dict` output."""
        keys = ("b_sat", "b_c", "spread", "amplitude")
        missing = [k for k in keys if k not in data]
        if missing:
            raise HysteresisError(f"Preisach data lacks the key(s) {missing}")
        return cls(**{k: data[k] for k in keys}, density=data.get("density", "lorentzian"),
                   n_table=data.get("n_table", 4001))

    def __repr__(self) -> str:
        return (f"PreisachHysteresis(b_sat={self.b_sat:.4g}, b_c={self.b_c:.4g}, "
                f"spread={self.spread:.4g}, amplitude={self.amplitude:.4g}, "
                f"density={self.density!r})")
