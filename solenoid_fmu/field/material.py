"""Soft-magnetic material: the initial magnetization curve B(H), checked and made fit for Newton.

A table (CSV ``H_A_per_m,B_T``) is first checked against the physics the paper states (sec. 2.3
and 4.2): B rising with H; the differential permeability dB/dH rising to one inflection point of
B(H), then falling towards mu0. A table that breaks this is refused with the point where it breaks;
a relative tolerance (``tol``, default 10 % on the chord permeabilities, i.e. about 0.2 % scatter
in H on a 0.05 T table) lets real, slightly noisy tables pass.

The checked table is then turned into a curve that Newton's method can rely on. The differential
reluctivity ``nu_d(B) = dH/dB`` is piecewise linear in B on the table's B values and bounded,
by construction, between ``1/(mu0*mu_r_max)`` and ``1/mu0``; its last value is ``1/mu0`` so the
curve continues beyond the last point with slope mu0 and a continuous derivative. The knot values
are a bounded least-squares fit of the table's H (relative weights, with a small smoothness
penalty), so the curve passes through clean tables to within ~0.1 % and smooths noisy ones.
H(B) is then piecewise quadratic and C1, the energy density w(B) = int_0^B H dB' piecewise cubic,
and the reluctivity nu(B^2) = H/B with its derivative d nu / d(B^2) follows exactly.

Every slope the solver meets is therefore between mu0 and mu0*mu_r_max: the magnetic energy is
strictly convex with a bounded Hessian, and Newton with a line search on the energy converges from
any start.
"""

from __future__ import annotations

import csv
import hashlib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from ..errors import MaterialError
from ..fileio import atomic_write_text

MU_0 = 4e-7 * np.pi  # vacuum permeability [H/m] (the classical value; 1e-9 relative to CODATA)
NU_0 = 1.0 / MU_0
MU_R_MAX = 1.0e5  # upper bound of the differential relative permeability the solver accepts


@dataclass(frozen=True, eq=False)
class BHCurve:
    """A smooth, monotone B(H) curve with bounded slopes, evaluated as H(B) for the FEM.

    Build it with :func:`bh_curve_from_table` or :func:`load_material`.

    Attributes
    ----------
    B_T : ndarray, shape (n,)
        Knots in flux density [T], starting at 0.
    nu_d : ndarray, shape (n,)
        Differential reluctivity dH/dB at the knots [A/(m T)]; the last one is 1/mu0.
    H_A_per_m : ndarray, shape (n,)
        H at the knots [A/m] of the smoothed curve.
    table_H_A_per_m, table_B_T : ndarray
        The table the curve was made from.
    name, source_path, sha256 : provenance of the table.
    """

    B_T: np.ndarray
    nu_d: np.ndarray
    H_A_per_m: np.ndarray
    table_H_A_per_m: np.ndarray
    table_B_T: np.ndarray
    name: str = "material"
    source_path: Path | None = None
    sha256: str = ""
    _w: np.ndarray = field(default=None, repr=False)

    def __post_init__(self):
        B, nu, H = self.B_T, self.nu_d, self.H_A_per_m
        dB = np.diff(B)
        s = np.diff(nu) / dB
        w = np.concatenate([[0.0], np.cumsum(H[:-1] * dB + nu[:-1] * dB**2 / 2 + s * dB**3 / 6)])
        object.__setattr__(self, "_w", w)
        object.__setattr__(self, "_s", np.concatenate([s, [0.0]]))

    # -- evaluation (all vectorized, B may have any shape) ------------------------------------
    def _segment(self, B):
        k = np.clip(np.searchsorted(self.B_T, B, side="right") - 1, 0, len(self.B_T) - 1)
        return k, B - self.B_T[k]

    def H_of_B(self, B_T):
        """Field strength H [A/m] at flux density ``B_T`` (>= 0) [T]."""
        B = np.abs(np.asarray(B_T, dtype=float))
        k, t = self._segment(B)
        return self.H_A_per_m[k] + self.nu_d[k] * t + self._s[k] * t**2 / 2

    def dH_dB(self, B_T):
        """Differential reluctivity dH/dB [A/(m T)] at ``B_T`` [T]."""
        B = np.abs(np.asarray(B_T, dtype=float))
        k, t = self._segment(B)
        return self.nu_d[k] + self._s[k] * t

    def energy_density(self, B_T):
        """Magnetic energy density w(B) = int_0^B H dB' [J/m^3]."""
        B = np.abs(np.asarray(B_T, dtype=float))
        k, t = self._segment(B)
        H, nu, s = self.H_A_per_m[k], self.nu_d[k], self._s[k]
        return self._w[k] + H * t + nu * t**2 / 2 + s * t**3 / 6

    def nu_of_b2(self, b2):
        """Reluctivity nu = H/B [m/H] and its derivative d nu / d(B^2) at ``b2`` = B^2 [T^2].

        Returns
        -------
        nu, dnu_db2 : ndarray
            ``dnu_db2 = (dH/dB - nu) / (2 B^2)``, set to 0 where B < 1e-12 T.
        """
        b2 = np.asarray(b2, dtype=float)
        B = np.sqrt(b2)
        k, t = self._segment(B)
        nu_k, s = self.nu_d[k], self._s[k]
        # H/B on the first segment written so that B -> 0 is exact: H = nu_0 B + s B^2 / 2.
        safe = np.where(B > 1e-12, B, 1.0)
        H = self.H_A_per_m[k] + nu_k * t + s * t**2 / 2
        nu = np.where(B > 1e-12, H / safe, self.nu_d[0])
        dHdB = nu_k + s * t
        dnu = np.where(B > 1e-12, (dHdB - nu) / (2 * safe**2), 0.0)
        return nu, dnu

    def B_of_H(self, H_A_per_m):
        """Flux density B [T] at field strength ``H_A_per_m`` (>= 0) [A/m] (exact inverse)."""
        H = np.abs(np.asarray(H_A_per_m, dtype=float))
        k = np.clip(np.searchsorted(self.H_A_per_m, H, side="right") - 1, 0, len(self.B_T) - 1)
        a, b, c = self._s[k] / 2, self.nu_d[k], self.H_A_per_m[k] - H
        # root of a t^2 + b t + c = 0 with t >= 0, written stably (a may be 0 or negative)
        disc = np.sqrt(np.maximum(b * b - 4 * a * c, 0.0))
        t = (-2 * c) / (b + disc)
        return self.B_T[k] + t

    def mu_r_differential(self, B_T):
        """Differential relative permeability (dB/dH)/mu0 at ``B_T``."""
        return 1.0 / (MU_0 * self.dH_dB(B_T))

    def table(self, n: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(H [A/m], B [T]) of the smoothed curve: at its knots, or ``n`` points dense in log H."""
        if n <= 0:
            return self.H_A_per_m.copy(), self.B_T.copy()
        H = np.concatenate([[0.0], np.geomspace(max(self.H_A_per_m[1], 1e-3), self.H_A_per_m[-1], n - 1)])
        return H, self.B_of_H(H)


def check_bh_table(H, B, tol: float = 0.10, where: str = "B(H) table") -> None:
    """Check a B(H) table against the physics of an initial magnetization curve.

    Parameters
    ----------
    H, B : array-like, shape (n,)
        Field strength [A/m] and flux density [T], starting at or above (0, 0).
    tol : float
        Relative tolerance on the monotonicity of the differential permeability (noise).
    where : str
        Name of the source used in the message (file name).

    Raises
    ------
    MaterialError
        Naming the point (1-based table row and its H, B) where the physics breaks.
    """
    H = np.asarray(H, dtype=float)
    B = np.asarray(B, dtype=float)

    def at(k):
        return f"{where}: point {k + 1} (H = {H[k]:g} A/m, B = {B[k]:g} T)"

    if H.shape != B.shape or H.ndim != 1:
        raise MaterialError(f"{where}: H and B must be two columns of equal length")
    if len(H) < 3:
        raise MaterialError(f"{where}: needs at least 3 points, has {len(H)}")
    bad = np.flatnonzero(~(np.isfinite(H) & np.isfinite(B)))
    if bad.size:
        raise MaterialError(f"{at(bad[0])}: not a finite number")
    if H[0] < 0 or B[0] < 0:
        raise MaterialError(f"{at(0)}: an initial curve starts at H >= 0, B >= 0")
    for k in range(1, len(H)):
        if not H[k] > H[k - 1]:
            raise MaterialError(f"{at(k)}: H does not rise (previous H = {H[k - 1]:g} A/m)")
        if not B[k] > B[k - 1]:
            raise MaterialError(f"{at(k)}: B does not rise with H (previous B = {B[k - 1]:g} T)")
    mu = np.diff(B) / np.diff(H) / MU_0  # chord relative permeabilities, segment k between k, k+1
    if np.any(mu > MU_R_MAX):
        k = int(np.argmax(mu > MU_R_MAX))
        raise MaterialError(f"{at(k + 1)}: differential mu_r = {mu[k]:.4g} exceeds {MU_R_MAX:g}")
    if mu[-1] < 1 - tol:
        raise MaterialError(
            f"{at(len(H) - 1)}: slope below mu0 (mu_r = {mu[-1]:.4g}); saturation tends to mu0 from above"
        )
    # Unimodality with noise: the best unimodal fit of log(mu) (isotonic up to a peak, antitonic
    # after it); the table breaks the physics where it deviates from that fit by more than tol.
    y = np.log(mu)
    fit, peak = unimodal_fit(y)
    dev = y - fit
    k = int(np.argmax(np.abs(dev)))
    if abs(dev[k]) > np.log1p(tol):
        side = "before" if k < peak else "after"
        what = "rise to" if k < peak else "fall after"
        raise MaterialError(
            f"{at(k + 1)}: permeability {mu[k]:.4g} (relative to mu0) is {abs(dev[k]) * 100:.0f} % off the best "
            f"curve with one inflection point ({side} the inflection near B = {B[peak + 1]:g} T); the "
            f"permeability must {what} one inflection point (tolerance {tol * 100:g} %)"
        )


def _isotonic(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares non-decreasing fit of y (pool adjacent violators), and the squared error of the
    fit of every prefix ``y[:k + 1]`` (PAVA's stack after element k is that prefix's fit). O(len(y))."""
    s: list[float] = []  # block sums, sums of squares, counts
    q: list[float] = []
    n: list[int] = []
    err = np.empty(len(y))
    sse = 0.0
    for k, v in enumerate(np.asarray(y, dtype=float)):
        s.append(float(v))
        q.append(float(v) * float(v))
        n.append(1)
        while len(s) > 1 and s[-2] * n[-1] > s[-1] * n[-2]:
            a, b, c = s.pop(), q.pop(), n.pop()
            sse -= (b - a * a / c) + (q[-1] - s[-1] ** 2 / n[-1])
            s[-1] += a
            q[-1] += b
            n[-1] += c
            sse += q[-1] - s[-1] ** 2 / n[-1]
        err[k] = sse
    return np.repeat(np.array(s) / np.array(n, dtype=float), n), err


def unimodal_fit(y: np.ndarray) -> tuple[np.ndarray, int]:
    """Best (least squares: the L2 projection onto unimodal sequences) fit of y rising to one peak then
    falling; returns (fit, peak index). Exact: the best split into a non-decreasing head ``y[:p + 1]``
    and a non-increasing tail, every split's error from one pass each way. O(len(y))."""
    y = np.asarray(y, dtype=float)
    if len(y) == 0:
        return y.copy(), 0
    _, up = _isotonic(y)  # up[p]: error of the rising fit of y[:p + 1]
    _, down = _isotonic(y[::-1])
    down = down[::-1]  # down[p]: error of the falling fit of y[p:]
    total = up.copy()
    total[:-1] += down[1:]
    p = int(np.argmin(total))
    fit = np.concatenate([_isotonic(y[: p + 1])[0], _isotonic(y[p + 1 :][::-1])[0][::-1]])
    return fit, int(np.argmax(fit))


def bh_curve_from_table(
    H,
    B,
    name: str = "material",
    tol: float = 0.10,
    check: bool = True,
    smoothing: float = 1.0,
    source_path: Path | None = None,
    sha256: str = "",
) -> BHCurve:
    """Check a B(H) table and build the Newton-safe :class:`BHCurve` from it.

    Parameters
    ----------
    H, B : array-like, shape (n,)
        The table [A/m], [T]. A first point (0, 0) is added if missing.
    name : str
        Used in messages and provenance.
    tol : float
        Noise tolerance of :func:`check_bh_table`.
    check : bool
        Run the physics check (turn off only for curves that are physical by construction).
    smoothing : float
        Weight of the second-difference penalty on the reluctivity knots (relative).
    """
    from scipy.optimize import lsq_linear  # heavy (about 0.5 s): loaded on first use

    H = np.asarray(H, dtype=float).ravel()
    B = np.asarray(B, dtype=float).ravel()
    if H.size and (H[0] > 0 or B[0] > 0):
        H = np.concatenate([[0.0], H])
        B = np.concatenate([[0.0], B])
    if check:
        check_bh_table(H, B, tol=tol, where=name)
    n = len(B)
    dB = np.diff(B)
    # Unknowns: nu_0 .. nu_{n-2}; nu_{n-1} = 1/mu0. H_k = sum_{j<k} (nu_j + nu_{j+1}) dB_j / 2.
    A = np.zeros((n - 1, n))
    for k in range(1, n):
        A[k - 1, :k] += dB[:k] / 2
        A[k - 1, 1 : k + 1] += dB[:k] / 2
    rhs = H[1:].copy()
    weight = 1.0 / (1e-3 * H[1:] + 1e-3 * H[1])  # ~0.1 % relative
    A_fixed = A[:, -1] * NU_0
    Aw = (A[:, :-1]) * weight[:, None]
    bw = (rhs - A_fixed) * weight
    # smoothness: second differences of log-ish scaled nu (relative to the chord values)
    chord = np.diff(H) / dB
    scale = np.concatenate([chord, [NU_0]])[:-1]
    m = n - 1
    if m >= 3 and smoothing > 0:
        D = np.zeros((m - 2, m))
        for k in range(m - 2):
            D[k, k : k + 3] = np.array([1.0, -2.0, 1.0]) / scale[k + 1]
        Aw = np.vstack([Aw, np.sqrt(smoothing) * D])
        bw = np.concatenate([bw, np.zeros(m - 2)])
    lo = NU_0 / MU_R_MAX
    res = lsq_linear(Aw, bw, bounds=(lo, NU_0), method="bvls")
    nu = np.concatenate([res.x, [NU_0]])
    Hk = np.concatenate([[0.0], np.cumsum((nu[:-1] + nu[1:]) * dB / 2)])
    return BHCurve(
        B_T=B.copy(),
        nu_d=nu,
        H_A_per_m=Hk,
        table_H_A_per_m=H,
        table_B_T=B,
        name=name,
        source_path=source_path,
        sha256=sha256,
    )


def default_material_path() -> Path:
    """Path of the packaged literature curve of 9SMnPb28 (PS45's steel)."""
    return Path(str(resources.files("solenoid_fmu") / "data" / "materials" / "9SMnPb28-literature.csv"))


def read_bh_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a two-column CSV ``H_A_per_m,B_T`` (header line required); names file and line on error."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise MaterialError(f"{path}: not a text (UTF-8) CSV file: byte {exc.start} cannot be decoded") from None
    rows = list(csv.reader(line for line in text.splitlines() if not line.startswith("#")))
    if not rows:
        raise MaterialError(f"{path}: empty file")
    header = [c.strip() for c in rows[0]]
    if header[:2] != ["H_A_per_m", "B_T"]:
        raise MaterialError(f"{path}:1: header must be 'H_A_per_m,B_T', got {','.join(header)!r}")
    H, B = [], []
    for lineno, row in enumerate(rows[1:], start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) < 2:
            raise MaterialError(f"{path}:{lineno}: needs two columns, got {row!r}")
        try:
            H.append(float(row[0]))
            B.append(float(row[1]))
        except ValueError:
            raise MaterialError(f"{path}:{lineno}: not a number: {','.join(row)!r}") from None
    return np.array(H), np.array(B)


def load_material(path: str | Path | None = None, tol: float = 0.10) -> BHCurve:
    """Read a B(H) CSV, check the physics and build the curve (default: the literature 9SMnPb28)."""
    path = Path(path) if path is not None else default_material_path()
    H, B = read_bh_csv(path)
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    return bh_curve_from_table(H, B, name=path.name, tol=tol, source_path=path.resolve(), sha256=sha)


def write_bh_csv(path: str | Path, H, B, comment: str = "") -> Path:
    """Write a B(H) table as CSV ``H_A_per_m,B_T`` (atomically: temp file, then rename)."""
    lines = [f"# {line}" for line in comment.splitlines()] + ["H_A_per_m,B_T"]
    lines += [f"{h:.9g},{b:.9g}" for h, b in zip(np.asarray(H), np.asarray(B), strict=True)]
    return atomic_write_text(path, "\n".join(lines) + "\n")


def linear_material(mu_r: float = 1.0) -> BHCurve:
    """A linear material B = mu0*mu_r*H (for analytic checks), as a :class:`BHCurve` without checks."""
    B = np.array([0.0, 1.0, 2.0])
    nu = np.full(3, NU_0 / mu_r)
    nu[-1] = NU_0 / mu_r
    H = np.concatenate([[0.0], np.cumsum(nu[:-1] * np.diff(B))])
    curve = BHCurve(B, nu, H, H, B, name=f"linear mu_r={mu_r:g}")
    return curve

