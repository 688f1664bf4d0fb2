"""Figures of the identification report, like the paper's figs. 10, 11 and 15-17.

Each function draws one figure from data the report computed (:mod:`solenoid_fmu.identification.report`) and
returns its PNG (bytes): the report writes the files and keeps the figures in memory for the pipeline's report.
"""

from __future__ import annotations

import io

import numpy as np

from .result import IdentificationResult

__all__ = ["plot_flux_fit", "plot_bh", "plot_force_stroke", "plot_flux_other_strokes"]


def _pyplot():
    """matplotlib.pyplot on the Agg backend, imported when a figure is drawn (matplotlib takes about
    0.5 s to load, and identifying without a report draws nothing)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _png(plt, fig) -> bytes:
    """The figure as PNG (110 dpi), closed."""
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def _finish_comparison(plt, fig, ax, xlabel: str, ylabel: str, title: str) -> bytes:
    """Legend entries of the two FEM line styles, labels, and the PNG of a measured-vs-FEM figure."""
    ax.plot([], [], "kx--", label="FEM, start curve")
    ax.plot([], [], "ko:", label="FEM, identified")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    return _png(plt, fig)


def plot_flux_fit(r: IdentificationResult, summary: dict) -> bytes:
    """Fig. 10: measured commutation Psi(i), FEM with the start and the identified curve."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    mc = r.extra.get("measured_commutation")
    if mc:
        ax.plot(mc["i_A"], np.array(mc["psi_Wb"]) * 1e3, "k-", lw=1, label="measured (commutation curve)")
    def errs(key):
        e = summary[key]
        return f"RMS {e['rms_rel_peak'] * 100:.2f} %, weighted {e['rms_weighted_rel_peak'] * 100:.2f} %"

    ax.plot(r.i_A, r.psi_before_Wb * 1e3, "s--", ms=4, label=f"FEM, start curve ({errs('flux_error_before')})")
    ax.plot(r.i_A, r.psi_after_Wb * 1e3, "o-", ms=4, label=f"FEM, identified ({errs('flux_error_after')})")
    w = np.asarray(r.extra.get("weights", np.ones(len(r.i_A))))
    low = w < 0.5
    if low.any():
        ax.plot(r.i_A[low], r.psi_meas_Wb[low] * 1e3, "o", mfc="none", mec="k", ms=8,
                label="weight < 0.5 (wide hysteresis loop)")
    ax.set_xlabel("i [A]")
    ax.set_ylabel("Psi [mWb]")
    ax.set_title(f"Flux linkage at x = {r.x_m * 1e3:g} mm (cf. paper fig. 10)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _png(plt, fig)


def plot_bh(r: IdentificationResult) -> bytes:
    """Fig. 11: B(H) before and after, identified H range shaded, 1-sigma band of B."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    H = np.geomspace(10.0, 3e5, 300)
    B1 = r.curve.B_of_H(H)
    ax.semilogx(H, r.start_curve.B_of_H(H), "--", label=f"start ({r.start_curve.name})")
    ax.semilogx(H, B1, "-", label="identified")
    unc = r.extra.get("B_uncertainty")
    if unc:
        sd = np.interp(H, unc["H_A_per_m"], unc["rel_1sigma"], left=np.nan, right=np.nan)
        ax.fill_between(H, B1 * (1 - sd), B1 * (1 + sd), color="C1", alpha=0.2, lw=0, label="1-sigma (linearized)")
    lo, hi = r.identified_H_range_A_per_m
    if hi > 0:
        ax.axvspan(max(lo, 10.0), hi, color="0.85", zorder=0, label="identified H range")
    ax.set_xlabel("H [A/m]")
    ax.set_ylabel("B [T]")
    ax.set_ylim(0, max(2.4, float(B1.max()) * 1.05))
    ax.set_title("B(H) before and after identification (cf. paper fig. 11)")
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3, which="both")
    return _png(plt, fig)


def plot_force_stroke(curves) -> bytes:
    """Figs. 15-17, force: per ``force_stroke`` recording ``(k, fc, xs, f0, f1)``: colour index,
    measured curve (:func:`~solenoid_fmu.identification.measured.force_stroke_curve`), strokes [m]
    of the FEM points and the FEM force [N] with the start and the identified curve."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for k, fc, xs, f0, f1 in curves:
        x = fc["x_m"]
        c = f"C{k % 10}"
        ax.plot(x * 1e3, fc["force_N"], "-", color=c, lw=1, label=f"measured {fc['i_A']:.2g} A")
        ax.plot(xs * 1e3, f0, "x--", color=c, lw=0.8, ms=4)
        ax.plot(xs * 1e3, f1, "o:", color=c, lw=0.8, ms=4)
    return _finish_comparison(plt, fig, ax, "x [mm]", "F [N]", "Force vs stroke (cf. paper figs. 15-17)")


def plot_flux_other_strokes(curves) -> bytes:
    """Figs. 15-17, flux: per other stroke ``(k, cc, i_sel, p0, p1)``: colour index, measured
    commutation curve, currents [A] of the FEM points and the FEM flux [Wb] with both curves."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for k, cc, i_sel, p0, p1 in curves:
        c = f"C{k % 10}"
        ax.plot(cc.i_A, cc.psi_Wb * 1e3, "-", color=c, lw=1, label=f"measured x = {cc.position_m * 1e3:g} mm")
        ax.plot(i_sel, p0 * 1e3, "x--", color=c, ms=4)
        ax.plot(i_sel, p1 * 1e3, "o:", color=c, ms=4)
    return _finish_comparison(plt, fig, ax, "i [A]", "Psi [mWb]",
                              "Flux linkage at other strokes (cf. paper figs. 15-17)")
