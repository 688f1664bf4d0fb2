"""Validation: run the FMU on measured inputs and compare every output a recording has.

For each recording the FMU is driven by the recording's measured inputs
(:func:`solenoid_fmu.diagnose.cases_from_recordings`, which calls
:func:`solenoid_fmu.fmu.simulate_recording`): current-driven for ``flux``, ``force_stroke``,
``ramp`` and ``eddy``, voltage-driven for ``voltage_step``. The outputs compared:

============= =====================================================================================
signal        measured vs simulated
============= =====================================================================================
``force_N``   the measured force vs the FMU's F(Psi, x) (paper eq. 3), where the recording has force
``psi_Wb``    flux linkage from the measured voltage (paper eq. 4, offset removed) vs the FMU's Psi,
              for current-driven runs with a voltage column; both anchored to the model's Psi at
              the first sample (eq. 4 gives changes: a recording may start energized), and
              without any zero-current rest compared orthogonal to a linear trend (unknown offset)
``current_A`` the measured current vs the FMU's (paper eqs. 1-2), for voltage-driven runs
============= =====================================================================================

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
  (:func:`solenoid_fmu.improve._error`) and the reports' mean errors use it.

Samples where the measured or simulated value is not finite are left out and counted
(``n_excluded``); a simulation that is not finite anywhere gives ``None`` metrics.

Output (:func:`validate_cases`, :func:`validate`; JSON as printed by ``solenoid-fmu validate --json``)::

    {"recordings": [{"file": "01_flux_0p50A.csv", "kind": "flux", "drive": "current",
                     "signals": {"psi_Wb": {"rms": ..., "max": ..., "nrmse": ..., "n": ...}}}, ...],
     "summary": {"psi_Wb": {"nrmse_mean": ..., "nrmse_max": ..., "n_recordings": ...}, ...},
     "figures": ["report/01_flux_0p50A_overlay.png", ...]}

Command line: ``solenoid-fmu validate build/NAME.fmu RECORDING.csv... [--report DIR] [--json]``.
"""

from __future__ import annotations

import io
import json
import sys
from pathlib import Path

import numpy as np

from ..errors import FmuInputError, RecordingError, SolenoidError
from ..fileio import atomic_write_bytes, atomic_write_text

__all__ = [
    "SIGNAL_LABELS",
    "ValidationError",
    "add_cli",
    "plot_overlay",
    "plot_residual",
    "full_scales",
    "nrmse_fs",
    "signal_metrics",
    "validate",
    "validate_cases",
]

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
    cases : list of solenoid_fmu.diagnose.ResidualCase
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
        ``None`` when no sample is finite.

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
    out = {"rms": None, "max": None, "nrmse": None, "n": n, "n_excluded": int(m.size - n)}
    if n == 0:
        return out
    e = m[ok] - s[ok]
    rms = float(np.sqrt(np.mean(e * e)))
    span = float(np.max(m[ok]) - np.min(m[ok]))
    out["rms"] = rms
    out["max"] = float(np.max(np.abs(e)))
    out["nrmse"] = rms / span if span > 0 else None
    return out


def _summary(recordings: list[dict]) -> dict:
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


def _ordered(signals) -> list[str]:
    return sorted(signals, key=lambda k: (list(SIGNAL_LABELS).index(k) if k in SIGNAL_LABELS else 99, k))


def validate_cases(cases) -> dict:
    """The validation result of residual cases (no FMU run).

    Parameters
    ----------
    cases : list of solenoid_fmu.diagnose.ResidualCase
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
        for sig in _ordered(c.residuals):
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
    return {"recordings": recordings, "summary": _summary(recordings)}


# -- figures ------------------------------------------------------------------------------------------
def _stacked(case, title: str, residual: bool):
    from matplotlib.figure import Figure  # no pyplot: no global backend state (Agg via savefig)

    sigs = _ordered(case.residuals)
    fig = Figure(figsize=(8.0, 1.2 + 2.2 * len(sigs)), layout="constrained")
    axes = fig.subplots(len(sigs), 1, sharex=True, squeeze=False)[:, 0]
    t = np.asarray(case.time_s, dtype=float)
    for ax, sig in zip(axes, sigs, strict=True):
        label, k = SIGNAL_LABELS.get(sig, (sig, 1.0))
        meas = np.asarray(case.measured[sig], dtype=float)
        res = np.asarray(case.residuals[sig], dtype=float)
        if residual:
            ax.plot(t, res * k, color="tab:red", lw=0.8)
            ax.axhline(0.0, color="black", lw=0.6)
            ax.set_ylabel(label.replace(" [", " error [", 1) if "[" in label else f"{label} error")
            m = signal_metrics(meas, meas - res)
            ax.set_title(f"{sig}: rms {_fmt(m['rms'])}, max {_fmt(m['max'])}, nrmse {_fmt(m['nrmse'])}",
                         fontsize="small", loc="left")
        else:
            ax.plot(t, meas * k, color="black", lw=1.0, label="measured")
            ax.plot(t, (meas - res) * k, color="tab:blue", lw=1.0, ls="--", label="simulated (FMU)")
            ax.set_ylabel(label)
            ax.legend(fontsize="small", loc="best")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time t [s]")
    fig.suptitle(title)
    return fig


def _save_png(fig, path: Path) -> Path:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    return atomic_write_bytes(path, buf.getvalue())


def plot_overlay(case, path) -> Path:
    """Measured and simulated signals of one case in stacked axes against time [s], to a PNG.

    Parameters
    ----------
    case : solenoid_fmu.diagnose.ResidualCase
    path : path-like
        PNG file to write (atomically).
    """
    return _save_png(_stacked(case, f"{case.name}: measured vs simulated", residual=False), Path(path))


def plot_residual(case, path) -> Path:
    """Residual (measured - simulated) per signal of one case against time [s], to a PNG.

    Parameters
    ----------
    case : solenoid_fmu.diagnose.ResidualCase
    path : path-like
        PNG file to write (atomically).
    """
    return _save_png(_stacked(case, f"{case.name}: residual (measured - simulated)", residual=True), Path(path))


def _unique_stems(names: list[str]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for name in names:
        stem = Path(name).stem or "recording"
        n = seen.get(stem, 0) + 1
        seen[stem] = n
        out.append(stem if n == 1 else f"{stem}_{n}")
    return out


# -- the validation run -------------------------------------------------------------------------------
def _read_all(recordings) -> list:
    """Read every recording first, so a bad file fails before any simulation (all problems listed)."""
    from ..measure import Recording, read_recording

    recs, problems = [], []
    for item in recordings:
        if isinstance(item, Recording):
            recs.append(item)
            continue
        try:
            recs.append(read_recording(item))
        except RecordingError as exc:
            problems += exc.problems
    if problems:
        raise RecordingError("validate: recordings", problems)
    return recs


def validate(fmu_path, recordings, *, report_dir=None, progress=None) -> dict:
    """Run the FMU on each recording's measured inputs and compare every output it has.

    Parameters
    ----------
    fmu_path : path-like
        A solenoid-fmu FMU (``solenoid-fmu export``).
    recordings : list of path-like or solenoid_fmu.recordings.Recording
        Recordings (format v1). All are read before the first simulation.
    report_dir : path-like, optional
        When given: ``<stem>_overlay.png`` and ``<stem>_residual.png`` per recording and
        ``validation.json`` (the returned dict) are written there (atomically).
    progress : callable, optional
        Called with each file name before it is simulated.

    Returns
    -------
    dict
        As :func:`validate_cases`, each recording entry also with ``path`` and ``figures``
        (``{"overlay": path, "residual": path}``, empty without ``report_dir``); ``figures`` at
        the top level lists every figure path in recording order (overlay, residual). A
        recording with nothing to compare (no force, no voltage in a current-driven run) gets
        empty ``signals`` and a ``note``.

    Raises
    ------
    FmuInputError
        The FMU file does not exist or is not a solenoid-fmu FMU, or refused a recording.
    RecordingError
        A recording cannot be read or is malformed (every file's problems listed).
    ValidationError
        No recordings given.
    """
    from .diagnose import cases_from_recordings

    fmu_path = Path(fmu_path)
    if not fmu_path.is_file():
        raise FmuInputError(f"{fmu_path}: FMU file not found")
    recordings = list(recordings)
    if not recordings:
        raise ValidationError("validate needs at least one recording")
    recs = _read_all(recordings)
    names = [r.path.name if r.path is not None else f"{r.kind}.csv" for r in recs]
    stems = _unique_stems(names)
    out_dir = None if report_dir is None else Path(report_dir)
    entries, figures = [], []
    for rec, name, stem in zip(recs, names, stems, strict=True):
        found = cases_from_recordings(fmu_path, [rec], progress=progress)
        if not found:
            entry = {"file": name, "kind": rec.kind, "drive": "", "signals": {},
                     "note": "nothing to compare (no force; no voltage in a current-driven run)"}
            if rec.path is not None:
                entry["path"] = str(rec.path)
            entry["figures"] = {}
            entries.append(entry)
            continue
        case = found[0]
        entry = validate_cases([case])["recordings"][0]
        entry["file"] = name
        entry["figures"] = {}
        if out_dir is not None:
            ov = plot_overlay(case, out_dir / f"{stem}_overlay.png")
            rs = plot_residual(case, out_dir / f"{stem}_residual.png")
            entry["figures"] = {"overlay": str(ov), "residual": str(rs)}
            figures += [str(ov), str(rs)]
        entries.append(entry)
    result = {"fmu": str(fmu_path), "recordings": entries, "summary": _summary(entries), "figures": figures}
    if out_dir is not None:
        atomic_write_text(out_dir / "validation.json", json.dumps(result, indent=2) + "\n")
    return result


# -- command line -------------------------------------------------------------------------------------
def add_cli(sub) -> None:
    """Register ``solenoid-fmu validate``."""
    p = sub.add_parser(
        "validate", help="run the FMU on recordings' measured inputs; RMS, max and normalized errors per signal",
        description="Drive the FMU with each recording's measured inputs (current, or voltage for voltage_step) "
                    "and compare every output the recording has: force, flux linkage (from the measured "
                    "voltage, paper eq. 4), current. nrmse = RMS error / range of the measured signal.")
    p.add_argument("fmu", type=Path, help="the FMU (solenoid-fmu export)")
    p.add_argument("recordings", nargs="+", type=Path, help="recording CSV files (format v1)")
    p.add_argument("--report", type=Path, metavar="DIR",
                   help="write overlay and residual plots per recording and validation.json into DIR")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout (progress stays on stderr)")
    p.set_defaults(func=_cli_validate)


def _fmt(v) -> str:
    return "-" if v is None else f"{v:.4g}"


def _cli_validate(args) -> int:
    if args.report is not None:  # checked before the simulations, not after them
        from ..fileio import refuse_overwriting_inputs, require_directory

        refuse_overwriting_inputs(require_directory(args.report, "--report"), [args.fmu, *args.recordings], written=[])
    n = len(args.recordings)
    count = iter(range(1, n + 1))

    def progress(name):
        print(f"[{next(count)}/{n}] simulating {name} ...", file=sys.stderr, flush=True)

    result = validate(args.fmu, args.recordings, report_dir=args.report, progress=progress)
    if args.json:
        print(json.dumps(result))
        return 0
    w = max([len("file")] + [len(r["file"]) for r in result["recordings"]])
    print(f"{'file':<{w}}  {'signal':<10} {'rms':>11} {'max':>11} {'nrmse':>9}")
    for rec in result["recordings"]:
        if not rec["signals"]:
            print(f"{rec['file']:<{w}}  {rec.get('note', 'nothing to compare')}")
        for sig, m in rec["signals"].items():
            print(f"{rec['file']:<{w}}  {sig:<10} {_fmt(m['rms']):>11} {_fmt(m['max']):>11} {_fmt(m['nrmse']):>9}")
    for sig, s in result["summary"].items():
        print(f"{sig}: nrmse mean {_fmt(s['nrmse_mean'])}, max {_fmt(s['nrmse_max'])} "
              f"over {s['n_recordings']} recording(s)")
    if args.report is not None:
        print(f"wrote {args.report / 'validation.json'} and {len(result['figures'])} figure(s)")
    return 0
