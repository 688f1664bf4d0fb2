"""Validation figures: measured and simulated signals, and their residual, of one residual case (PNG bytes;
:func:`solenoid_fmu.loop.validate` writes them and keeps them for the report)."""

from __future__ import annotations

import io

import numpy as np

from .metrics import SIGNAL_LABELS, fmt, ordered_signals, signal_metrics


def _stacked(case, title: str, residual: bool):
    # lazy: matplotlib is heavy and only figures need it; no pyplot: no global backend state (Agg via savefig)
    from matplotlib.figure import Figure

    sigs = ordered_signals(case.residuals)
    height = 1.2 + 2.2 * len(sigs)
    fig = Figure(figsize=(8.0, height))
    # fixed margins [inch] for the title, the axis labels and each axes' title: matplotlib's constrained layout
    # measured every text of the figure first and took half of a figure's time (56 figures in a pipeline run)
    fig.subplots_adjust(left=1.0 / 8.0, right=1.0 - 0.2 / 8.0, top=1.0 - 0.6 / height, bottom=0.55 / height,
                        hspace=0.45 / 1.95)
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
            ax.set_title(f"{sig}: rms {fmt(m['rms'])}, max {fmt(m['max'])}, nrmse {fmt(m['nrmse'])}",
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


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    return buf.getvalue()


def overlay_png(case) -> bytes:
    """Measured and simulated signals of one case in stacked axes against time [s], as PNG bytes.

    Parameters
    ----------
    case : solenoid_fmu.loop.residuals.ResidualCase
    """
    return _png(_stacked(case, f"{case.name}: measured vs simulated", residual=False))


def residual_png(case) -> bytes:
    """Residual (measured - simulated) per signal of one case against time [s], as PNG bytes (same parameters)."""
    return _png(_stacked(case, f"{case.name}: residual (measured - simulated)", residual=True))
