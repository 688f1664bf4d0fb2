"""Figures of the measurement: Psi(i) branches and commutation curve of one recording."""

from __future__ import annotations

from pathlib import Path

from ..fileio import save_figure
from .flux import FluxResult

__all__ = ["plot_flux"]


def plot_flux(result: FluxResult, path, title: str | None = None) -> Path:
    """Draw Psi(i): ascending and descending branches and the commutation curve, to a PNG.

    Parameters
    ----------
    result : FluxResult
        From :func:`flux_linkage`.
    path : str or pathlib.Path
        Image file to write (format from the suffix).
    title : str, optional
        Figure title.

    Returns
    -------
    pathlib.Path
    """
    # matplotlib is heavy (about 0.5 s): loaded only when a figure is drawn; no pyplot, no global backend state
    from matplotlib.figure import Figure

    path = Path(path)
    fig = Figure(figsize=(6.4, 4.8), layout="constrained")
    ax = fig.add_subplot()
    if result.branches:
        for br in result.branches:
            up = br.direction == "ascending"
            ax.plot(br.i_A, br.psi_Wb * 1e3, lw=0.8, color="tab:red" if up else "tab:blue",
                    label=f"{br.direction} (peak {br.peak_A:.2f} A)")
    else:
        ax.plot(result.current_A, result.psi_Wb * 1e3, lw=0.8, color="tab:gray", label="Psi(i)")
    if result.commutation_i_A.size:
        ax.plot(result.commutation_i_A, result.commutation_psi_Wb * 1e3, color="black", lw=1.6,
                label="commutation curve (branch mean)")
    ax.set_xlabel("current i [A]")
    ax.set_ylabel("flux linkage Psi [mWb]")
    ax.grid(True, alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    if len(handles) > 8:  # many peaks: one legend entry per kind of line
        wanted = {}
        for h, lab in zip(handles, labels, strict=True):
            wanted.setdefault(lab.split(" (")[0], h)
        handles, labels = list(wanted.values()), list(wanted)
    ax.legend(handles, labels, fontsize="small")
    ax.set_title(title or f"R = {result.R_ohm:.4g} ohm ({result.resistance_method})")
    save_figure(fig, path, dpi=120)
    return path


