"""The eddy-current parameter G_eddy from fast recordings (paper sec. 5, fig. 14).

The model's eddy term (paper eq. 2 with the parameter the paper calls L_eddy) is
``i_eddy = G_eddy * dPsi/dt``. From an ``eddy`` recording (triangular currents at several rates):

- Psi(t) by paper eq. 4 (offset removed, :func:`solenoid_fmu.measure.flux_linkage`), and the
  induced voltage e = dPsi/dt;
- the field-generating current from the maps, i_f(Psi, x) (a measured flux up to 5 % of the map's flux
  span past its last node is extrapolated linearly, with a logged warning naming the recording);
- i_eddy = i - i_f(Psi, x), regressed on e through the origin: G_eddy = sum(e i_eddy) / sum(e^2),
  per recording (one rate each) and pooled, each with its R^2.

When the per-rate fits disagree (the conductance falls with rate: eddy currents with more than
one time constant) or the pooled R^2 is poor, a single G_eddy describes the data badly; the result
says so (``single_term_ok`` False and a message) rather than hiding it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SolenoidError
from ..measure import Recording, flux_linkage, read_recording, read_unipolar
from .interpolate import i_f_at
from .tables import CharacteristicMaps

#: Relative spread of the per-rate conductances above which one G_eddy is a poor description.
RATE_SPREAD_LIMIT = 0.2
#: Pooled R^2 below which one G_eddy is a poor description.
R2_LIMIT = 0.9
#: Pooled R^2 from which the eddy term counts as measured (:attr:`EddyFit.measurable`): it explains at
#: least half the variance of ``i - i_f`` in the fast recordings. Below it the fitted G is what other
#: effects leave (a hysteresis loop's current also changes sign with dPsi/dt: R^2 < 0 on such campaigns).
R2_MEASURABLE = 0.5
#: Rates must differ by this factor to split the fitted current into a rate-proportional and a
#: rate-independent part (:func:`rate_split`).
RATE_RATIO_SPLIT = 2.0


@dataclass
class EddyFit:
    """Result of :func:`fit_eddy` (SI units).

    Attributes
    ----------
    G_eddy_S : float
        Pooled conductance [S].
    r2 : float
        Pooled coefficient of determination of i_eddy vs dPsi/dt.
    per_recording : list of dict
        ``file``, ``rate_A_per_s`` (median |di/dt| on the ramps), ``G_eddy_S``, ``r2``, ``L_H`` (secant
        inductance ptp(Psi) / ptp(i)), ``dt_s`` (median sample interval).
    single_term_ok : bool
    message : str
    """

    G_eddy_S: float
    r2: float
    per_recording: list = field(default_factory=list)
    single_term_ok: bool = True
    message: str = ""

    @property
    def G_model_S(self) -> float:
        """The conductance for the model [S]: the fit where the recordings show an eddy current (:attr:`measurable`),
        else 0. A negative fit would feed energy in (the data scatter around zero); a positive one that is not
        measured is what a hysteresis loop's current leaves (it changes sign with dPsi/dt too), and in the model it
        would count that loop twice once the loop adds hysteresis: on DC03 #117 (heating and hysteresis, no eddy
        current; 0.74 mS, R^2 -0.49) the loop then took an eddy ladder only to refit that G to 0 (stop 48)."""
        return max(self.G_eddy_S, 0.0) if self.measurable else 0.0

    @property
    def measurable(self) -> bool:
        """True when the recordings show an eddy current: ``G_eddy_S > 0`` and either the pooled R^2 is at
        least :data:`R2_MEASURABLE` or the fitted current grows with the rate (:func:`rate_split`: its
        rate-proportional part at the fastest rate at least as large as its rate-independent part; a
        hysteresis loop's current does not grow with the rate, and it spoils R^2 where both are present) by a
        lag of at least one sample (:meth:`split_lag`)."""
        if not self.G_eddy_S > 0.0:
            return False
        if self.r2 >= R2_MEASURABLE:
            return True
        split = rate_split(self.per_recording)
        if split is None or not (split[0] > 0.0 and split[0] * split[2] >= split[1]):
            return False
        lag, dt = self.split_lag()
        return not (lag is not None and dt is not None and lag < dt)

    def split_lag(self) -> tuple[float | None, float | None]:
        """(tau [s], dt [s]): the lag of the current behind the flux that the rate split's conductance means,
        ``tau = G L`` (``i_eddy = G dPsi/dt = G L di/dt``, ``L`` the median secant inductance of the eddy
        recordings), and the finest sample interval among them. None where the recordings do not carry them.

        Where ``tau < dt`` the rate split does not count (:attr:`measurable`): the growth of a rate-independent
        loop's fitted current with the rate depends on which points of the loop the samples hit (up to 2x
        between a 2-cycle 4 ms trapezoid and slower triangles of the same loop, measured with exact maps and
        ideal sensors), and an eddy lag below one sample cannot be told from that. The eddy ladders of the
        randomized rig lag 1-1.6 ms; hysteresis alone gave 33-84 us beside samples of 130-260 us."""
        split = rate_split(self.per_recording)
        Ls = [float(p["L_H"]) for p in self.per_recording if math.isfinite(float(p.get("L_H", math.nan)))]
        dts = [float(p["dt_s"]) for p in self.per_recording if math.isfinite(float(p.get("dt_s", math.nan)))]
        lag = float(split[0] * np.median(Ls)) if split is not None and Ls else None
        return lag, (min(dts) if dts else None)

    def as_dict(self) -> dict:
        return {"G_eddy_S": self.G_eddy_S, "G_model_S": self.G_model_S, "r2": self.r2, "measurable": self.measurable,
                "per_recording": self.per_recording,
                "single_term_ok": self.single_term_ok, "message": self.message}


def rate_split(per_recording) -> tuple[float, float, float] | None:
    """(G [S], H [A], fastest rate [A/s]) of ``G_k rate_k = G rate_k + H`` over the recordings: the part of
    the eddy fits' current amplitude that grows with the current rate, and the part that does not (a
    rate-independent loop regressed on dPsi/dt gives ``G_k ~ 1 / rate_k``). None unless there are two
    recordings whose rates differ by at least :data:`RATE_RATIO_SPLIT`."""
    rates = np.array([float(p["rate_A_per_s"]) for p in per_recording])
    amp = np.array([float(p["G_eddy_S"]) for p in per_recording]) * rates
    ok = np.isfinite(rates) & np.isfinite(amp) & (rates > 0.0)
    rates, amp = rates[ok], amp[ok]
    if rates.size < 2 or rates.max() < RATE_RATIO_SPLIT * rates.min():
        return None
    G, H = np.linalg.lstsq(np.column_stack([rates, np.ones_like(rates)]), amp, rcond=None)[0]
    return float(G), float(H), float(rates.max())


def _fit_origin(e: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    ee = float(e @ e)
    if ee <= 0:
        return 0.0, 0.0
    g = float(e @ y) / ee
    ss = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(np.sum((y - g * e) ** 2)) / ss if ss > 0 else 0.0
    return g, r2


def eddy_samples(recording, maps) -> tuple[np.ndarray, np.ndarray, float, float, float]:
    """Induced voltage e = dPsi/dt [V] and eddy current i - i_f(Psi, x) [A] of one recording, its current
    rate [A/s] (median |di/dt| where the current moves), its secant inductance ``ptp(Psi) / ptp(i)`` [H] and
    its median sample interval [s]."""
    rec = recording
    if rec.voltage_V is None:
        raise SolenoidError(f"{rec.path}: an eddy fit needs a voltage_V column (paper eq. 4)")
    fl = flux_linkage(rec)
    if not fl.starts_at_rest or not fl.offset_measured:
        raise SolenoidError(f"{rec.path}: the eddy fit needs the absolute eq.-4 flux: the recording must start at "
                            "zero current and rest there (or at the end) for >= 10 ms "
                            f"({'starts energized' if not fl.starts_at_rest else 'no usable zero-current rest'})")
    t = np.asarray(rec.time_s, dtype=float)
    psi = np.asarray(fl.psi_Wb, dtype=float)
    e = np.gradient(psi, t)
    x = np.asarray(rec.positions_m(), dtype=float)
    i = np.asarray(rec.current_A, dtype=float) - fl.current_offset_A
    i_f = np.sign(psi) * i_f_at(maps, np.abs(psi), x, where=str(rec.path or 'eddy recording'))
    smooth = np.convolve(i, np.ones(5) / 5, mode="same") if len(i) >= 5 else i
    di = np.abs(np.gradient(smooth, t))
    moving = di > 0.5 * np.percentile(di, 99.5)  # ramps may be a small share of the record
    rate = float(np.median(di[moving])) if moving.any() else 0.0
    di_range = float(np.ptp(i))
    L = float(np.ptp(psi)) / di_range if di_range > 0 else math.nan
    return e, i - i_f, rate, L, float(np.median(np.diff(t)))


def fit_eddy(recordings, maps: CharacteristicMaps) -> EddyFit:
    """Fit G_eddy [S] from ``eddy`` recordings (other kinds are refused by name).

    Parameters
    ----------
    recordings : list of path-like or Recording
    maps : CharacteristicMaps
        The maps of the same solenoid (i_f(Psi, x)).
    """
    recs, _, left_out = read_unipolar(recordings)  # a rig's negative current mirrored, bipolar ones left out
    bad = [str(r.path) for r in recs if r.kind != "eddy"]
    if bad:
        raise SolenoidError(f"not eddy recordings: {', '.join(bad)}")
    if not recs and not left_out:
        raise SolenoidError("fit_eddy needs at least one eddy recording")
    per, E, Y = [], [], []
    for rec in recs:
        try:
            e, y, rate, L, dt = eddy_samples(rec, maps)
        except SolenoidError as exc:
            if "absolute eq.-4 flux" not in str(exc):
                raise
            left_out.append(str(exc))
            continue
        g, r2 = _fit_origin(e, y)
        per.append({"file": rec.path.name if rec.path else "", "rate_A_per_s": rate, "G_eddy_S": g, "r2": r2,
                    "L_H": L, "dt_s": dt})
        E.append(e)
        Y.append(y)
    if not E:
        raise SolenoidError("no eddy recording can be used: " + "; ".join(left_out))
    g, r2 = _fit_origin(np.concatenate(E), np.concatenate(Y))
    gs = np.array([p["G_eddy_S"] for p in per])
    spread = float(np.ptp(gs) / abs(g)) if len(gs) > 1 and g != 0 else 0.0
    ok = spread <= RATE_SPREAD_LIMIT and r2 >= R2_LIMIT
    if g < 0.0:
        msg = (f"the fitted G_eddy is negative ({g:.3g} S, R^2 {r2:.3f}): no measurable eddy current; "
               "the model uses G_eddy = 0")
    elif ok:
        msg = f"one G_eddy fits all rates (spread {spread:.0%}, R^2 {r2:.3f})"
    else:
        order = np.argsort([p["rate_A_per_s"] for p in per])
        trend = ", ".join(f"{per[k]['rate_A_per_s']:.3g} A/s: {per[k]['G_eddy_S'] * 1e3:.3g} mS" for k in order)
        msg = (f"a single G_eddy is a poor fit (spread {spread:.0%} over the rates, pooled R^2 {r2:.3f}): "
               f"{trend}; the eddy currents have more than one time constant")
    if left_out:
        msg += f"; left out {len(left_out)} recording(s): " + "; ".join(left_out)
    fit = EddyFit(g, r2, per, ok, msg)
    lag, dt = fit.split_lag()
    if r2 < R2_MEASURABLE and g > 0.0 and lag is not None and dt is not None and 0.0 < lag < dt:
        fit.message += (f"; the part of the current that grows with the rate means a lag of {lag * 1e6:.3g} us behind "
                        f"the flux, below one sample ({dt * 1e6:.3g} us): not counted as an eddy current")
    if g > 0.0 and not fit.measurable:
        fit.message += (f"; no eddy current measured (R^2 {r2:.3f} < {R2_MEASURABLE:g}, and no current growing with "
                        "the rate by a lag of at least one sample): the model uses G_eddy = 0")
    return fit


def with_fitted_eddy(maps: CharacteristicMaps, recordings) -> tuple[CharacteristicMaps, EddyFit]:
    """The one place the maps' G_eddy is set from recordings: :func:`fit_eddy` on ``recordings``, and the maps
    with its :attr:`EddyFit.G_model_S` (``eddy.source``: the recordings' file names; ``eddy.measured``:
    :attr:`EddyFit.measurable`, so that ``solenoid-fmu improve`` on the FMU alone has the pipeline's evidence).

    Parameters
    ----------
    maps : CharacteristicMaps
    recordings : list of path-like or Recording
        ``eddy`` recordings.

    Returns
    -------
    (CharacteristicMaps, EddyFit)
    """
    recs = [r if isinstance(r, Recording) else read_recording(r) for r in recordings]
    fit = fit_eddy(recs, maps)
    source = ", ".join(r.path.name if r.path is not None else r.kind for r in recs)
    return maps.with_eddy(fit.G_model_S, source=source, measured=bool(fit.measurable)), fit
