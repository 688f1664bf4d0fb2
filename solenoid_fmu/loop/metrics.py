"""Validation metrics: how far a simulated signal is from the measured one, per recording and signal.

Metrics per recording and signal (:func:`signal_metrics`), with ``e = measured - simulated``:

* ``rms``   = sqrt(mean(e^2)), in the signal's unit (N, Wb, A);
* ``max``   = max |e|, in the signal's unit;
* ``nrmse`` = rms / (max(measured) - min(measured)): the RMS error as a share of the measured
  signal's range. The range, not the mean or the RMS, because these signals start and end near
  zero (a mean would blow up for a symmetric triangle) and the range is what a plot shows. When the
  measured signal is constant (zero range) ``nrmse`` is ``None`` (JSON ``null``): there is no scale
  to relate the error to, and a number would be arbitrary.

* ``nrmse_fs`` = min(rms / FS, 1): the RMS error as a share of the signal's *full scale per
  kind* (:func:`full_scales`): FS is the largest |measured| of that signal over the campaign's
  recordings of the same kind, but at least :data:`FULL_SCALE_FLOOR` of its largest |measured|
  over the whole campaign. Unlike ``nrmse`` it cannot blow up for a recording whose signal
  hardly changes (a force-stroke at constant current has a flux range near zero), and the cap
  at 1 keeps one broken recording from outweighing the others. The improve gate
  (:func:`solenoid_fmu.loop.gates.gate_error`) and the reports' mean errors use it.

* ``noise_rms`` = the residual's white noise (:func:`white_noise_rms`), in the signal's unit: the part of
  ``rms`` that no model of the signal can remove (the sensors' noise, and the input channel's noise as the
  model passes it on). Reported beside the error, not subtracted from it.

Samples where the measured or simulated value is not finite are left out and counted
(``n_excluded``); a simulation that is not finite anywhere gives ``None`` metrics.
"""

from __future__ import annotations

import numpy as np

from ..errors import SolenoidError

#: Compared signals in display order: (axis label, factor from SI to the plotted unit).
SIGNAL_LABELS = {
    "current_A": ("current i [A]", 1.0),
    "psi_Wb": ("flux linkage Psi [mWb]", 1e3),
    "force_N": ("force F [N]", 1.0),
    "voltage_V": ("voltage U [V]", 1.0),
}


#: A kind's full scale is at least this share of the signal's full scale over the whole campaign.
FULL_SCALE_FLOOR = 0.1


class ValidationError(SolenoidError):
    """Validation input is unusable (mismatched or empty signals, nothing to compare)."""


def full_scales(cases) -> dict:
    """Full scale per (kind, signal): max |measured| over the kind's recordings, floored.

    Parameters
    ----------
    cases : list of solenoid_fmu.loop.residuals.ResidualCase
        The campaign's residual cases (``kind``, ``measured``).

    Returns
    -------
    dict
        ``{(kind, signal): FS}`` in the signal's SI unit, ``FS >= FULL_SCALE_FLOOR x`` the largest
        |measured| of the signal over all cases (and > 0).
    """
    def peak(v):
        v = np.asarray(v, dtype=float)
        v = v[np.isfinite(v)]
        return float(np.max(np.abs(v))) if v.size else 0.0

    per_kind: dict = {}
    campaign: dict = {}
    for c in cases:
        for sig, meas in c.measured.items():
            m = peak(meas)
            key = (getattr(c, "kind", ""), sig)
            per_kind[key] = max(per_kind.get(key, 0.0), m)
            campaign[sig] = max(campaign.get(sig, 0.0), m)
    return {key: max(v, FULL_SCALE_FLOOR * campaign[key[1]], 1e-300) for key, v in per_kind.items()}


def nrmse_fs(rms, full_scale: float):
    """``min(rms / full_scale, 1)`` [1], or None without an rms (see the module docstring)."""
    if rms is None:
        return None
    return min(float(rms) / full_scale, 1.0)



def white_noise_rms(residual) -> float | None:
    """The white noise in a residual [its unit]: ``1.4826 MAD(diff2(e)) / sqrt(6)`` over its finite samples.

    Second differences ``e[k+1] - 2 e[k] + e[k-1]`` cancel what changes smoothly from one sample to the next
    (a model's error, offsets, slopes) and multiply the variance of white noise by 6; the median absolute
    deviation keeps the few large ones of a step or a spike from counting. None with fewer than 3 samples.
    """
    e = np.asarray(residual, dtype=float)
    e = e[np.isfinite(e)]
    if e.size < 3:
        return None
    d = np.diff(e, 2)
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(6.0))


def signal_metrics(measured, simulated) -> dict:
    """Error metrics of a simulated signal against the measured one.

    Parameters
    ----------
    measured, simulated : array-like, shape (n,)
        The same signal in the same SI unit (e.g. force [N], flux linkage [Wb], current [A]).

    Returns
    -------
    dict
        ``rms`` = sqrt(mean((measured - simulated)^2)) and ``max`` = max |measured - simulated|,
        both in the signal's unit; ``nrmse`` = rms / (max(measured) - min(measured)) [1], ``None``
        when the measured range is zero (a constant signal gives no scale); ``n`` samples used and
        ``n_excluded`` samples left out because either value is not finite. All metrics are
        ``None`` when no sample is finite; ``noise_rms`` the residual's white noise (:func:`white_noise_rms`).

    Raises
    ------
    ValidationError
        The arrays differ in length, are empty or not one-dimensional.
    """
    m = np.asarray(measured, dtype=float)
    s = np.asarray(simulated, dtype=float)
    if m.ndim != 1 or s.ndim != 1:
        raise ValidationError(f"signals must be one-dimensional, got shapes {m.shape} and {s.shape}")
    if m.shape != s.shape:
        raise ValidationError(f"measured and simulated differ in length: {m.size} vs {s.size} samples")
    if m.size == 0:
        raise ValidationError("no samples to compare (empty signals)")
    ok = np.isfinite(m) & np.isfinite(s)
    n = int(np.count_nonzero(ok))
    out = {"rms": None, "max": None, "nrmse": None, "noise_rms": None, "n": n, "n_excluded": int(m.size - n)}
    if n == 0:
        return out
    e = m[ok] - s[ok]
    rms = float(np.sqrt(np.mean(e * e)))
    span = float(np.max(m[ok]) - np.min(m[ok]))
    out["rms"] = rms
    out["max"] = float(np.max(np.abs(e)))
    out["nrmse"] = rms / span if span > 0 else None
    out["noise_rms"] = white_noise_rms(e)
    return out


def summarize(recordings: list[dict]) -> dict:
    """Per signal: mean and max nrmse and nrmse_fs over the recordings that have it."""
    out = {}
    for rec in recordings:
        for sig, met in rec["signals"].items():
            out.setdefault(sig, []).append(met)
    summary = {}
    for sig, mets in out.items():
        entry = {}
        for key in ("nrmse", "nrmse_fs"):
            good = [m.get(key) for m in mets if m.get(key) is not None]
            entry[f"{key}_mean"] = float(np.mean(good)) if good else None
            entry[f"{key}_max"] = float(np.max(good)) if good else None
        entry["n_recordings"] = len(mets)
        summary[sig] = entry
    return summary


def ordered_signals(signals) -> list[str]:
    return sorted(signals, key=lambda k: (list(SIGNAL_LABELS).index(k) if k in SIGNAL_LABELS else 99, k))


def validate_cases(cases) -> dict:
    """The validation result of residual cases (no FMU run).

    Parameters
    ----------
    cases : list of solenoid_fmu.loop.residuals.ResidualCase
        One per recording; simulated = ``measured[signal] - residuals[signal]``.

    Returns
    -------
    dict
        ``{"recordings": [{"file", "kind", "drive", "signals": {signal: metrics}}, ...],
        "summary": {signal: {"nrmse_mean", "nrmse_max", "nrmse_fs_mean", "nrmse_fs_max",
        "n_recordings"}}}``; metrics from :func:`signal_metrics` plus ``nrmse_fs`` (full scale
        per kind, :func:`full_scales`), signals keyed ``force_N``, ``psi_Wb``, ``current_A``.
    """
    fs = full_scales(cases)
    recordings = []
    for c in cases:
        signals = {}
        for sig in ordered_signals(c.residuals):
            if sig not in c.measured:
                raise ValidationError(f"{c.name}: residual {sig!r} has no measured signal")
            meas = np.asarray(c.measured[sig], dtype=float)
            res = np.asarray(c.residuals[sig], dtype=float)
            if meas.shape != res.shape:
                raise ValidationError(f"{c.name}: {sig}: {meas.size} measured vs {res.size} residual samples")
            signals[sig] = signal_metrics(meas, meas - res)
            signals[sig]["nrmse_fs"] = nrmse_fs(signals[sig]["rms"], fs[(getattr(c, "kind", ""), sig)])
        entry = {"file": c.name, "kind": getattr(c, "kind", ""), "drive": getattr(c, "drive", ""),
                 "signals": signals}
        if getattr(c, "path", ""):
            entry["path"] = c.path
        recordings.append(entry)
    return {"recordings": recordings, "summary": summarize(recordings)}


def fmt(v) -> str:
    """A metric for tables and figure titles: four significant digits, ``-`` for None."""
    return "-" if v is None else f"{v:.4g}"
