"""Plots of the characteristic maps (PNG, matplotlib): the paper's figures 12 and 13, Psi(i) and F(x)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..fileio import save_figure
from .interpolate import force_at, psi_at
from .tables import CharacteristicMaps

__all__ = ["plot_maps"]


def plot_maps(maps: CharacteristicMaps, directory) -> list[Path]:
    """PNG plots like the paper's figures 12 and 13, plus Psi(i) and F(x) per operating point.

    Files: ``force_psi_x.png`` (F over Psi and x, fig. 12), ``i_f_psi_x.png`` (i_f over Psi and x,
    fig. 13), ``psi_i_per_x.png`` (Psi(i) per position, FEM points and interpolant),
    ``force_x_per_i.png`` (F over x per current). Extrapolated parts are drawn grey/dashed.

    Returns
    -------
    list of Path
    """
    import matplotlib  # lazy on purpose: matplotlib is heavy and only the plots need it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import cm

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    out = []
    colors = cm.viridis(np.linspace(0, 1, len(maps.x_m)))
    for fname, table, zlabel, title in (
        ("force_psi_x.png", maps.force_N, "force F [N]", "F(Psi, x) (cf. paper fig. 12)"),
        ("i_f_psi_x.png", maps.i_f_A, "field current i_f [A]", "i_f(Psi, x) (cf. paper fig. 13)"),
    ):
        out.append(_plot_table(plt, cm, maps, table, zlabel, title, colors, directory / fname))
    out.append(_plot_psi_force_of_i(plt, maps, colors, directory / "psi_i_per_x.png"))
    out.append(_plot_force_of_x(plt, cm, maps, directory / "force_x_per_i.png"))
    return out


def _plot_table(plt, cm, maps: CharacteristicMaps, table: np.ndarray, zlabel: str, title: str, colors,
                path: Path) -> Path:
    """One table over (Psi, x): a surface (extrapolated grey) and a curve per position (extrapolated dashed)."""
    X, P = np.meshgrid(maps.x_m * 1e3, maps.psi_Wb * 1e3)
    ext = maps.extrapolated > 0
    fig = plt.figure(figsize=(12, 5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    face = cm.viridis((table - table.min()) / max(np.ptp(table), 1e-300))
    face[ext] = (0.75, 0.75, 0.75, 0.6)
    stride = max(1, len(maps.psi_Wb) // 60)
    ax.plot_surface(X[::stride], P[::stride], table[::stride], facecolors=face[::stride],
                    rstride=1, cstride=1, linewidth=0, antialiased=False, shade=False)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("Psi [mWb]")
    ax.set_zlabel(zlabel)
    ax.set_title(title + "; grey = extrapolated")
    ax2 = fig.add_subplot(1, 2, 2)
    for j, x in enumerate(maps.x_m):
        inside = ~ext[:, j]
        ax2.plot(maps.psi_Wb[inside] * 1e3, table[inside, j], color=colors[j], label=f"{x * 1e3:.2f} mm")
        ax2.plot(maps.psi_Wb[~inside] * 1e3, table[~inside, j], color=colors[j], ls="--", lw=0.8)
    ax2.set_xlabel("flux linkage Psi [mWb]")
    ax2.set_ylabel(zlabel)
    ax2.grid(True, alpha=0.3)
    ax2.legend(fontsize=6, ncol=2, title="x")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


def _plot_psi_force_of_i(plt, maps: CharacteristicMaps, colors, path: Path) -> Path:
    """Psi(i) and F(i) per position: the FEM points and the interpolant."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    ii = np.linspace(maps.i_A[0], maps.i_A[-1], 200)
    for j, x in enumerate(maps.x_m):
        axes[0].plot(ii, psi_at(maps, ii, x) * 1e3, color=colors[j], label=f"{x * 1e3:.2f} mm")
        axes[0].plot(maps.i_A, maps.psi_ix_Wb[:, j] * 1e3, ".", color=colors[j], ms=3)
        axes[1].plot(ii, force_at(maps, ii, x), color=colors[j])
        axes[1].plot(maps.i_A, maps.force_ix_N[:, j], ".", color=colors[j], ms=3)
    axes[0].set_xlabel("current i [A]")
    axes[0].set_ylabel("flux linkage Psi [mWb]")
    axes[0].set_title("Psi(i) per position: FEM points, interpolant")
    axes[0].legend(fontsize=6, ncol=2, title="x")
    axes[1].set_xlabel("current i [A]")
    axes[1].set_ylabel("force F [N]")
    axes[1].set_title("F(i) per position (co-energy)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


def _plot_force_of_x(plt, cm, maps: CharacteristicMaps, path: Path) -> Path:
    """F over the stroke per current (co-energy and Maxwell stress), the working range shaded."""
    fig, ax = plt.subplots(figsize=(7, 5))
    xx = np.linspace(maps.x_m[0], maps.x_m[-1], 200)
    currents = np.linspace(maps.i_A[0], maps.i_A[-1], 6)[1:]
    for c, i in zip(cm.plasma(np.linspace(0, 0.85, len(currents))), currents, strict=True):
        ax.plot(xx * 1e3, force_at(maps, i, xx), color=c, label=f"{i:.2f} A")
        ax.plot(xx * 1e3, force_at(maps, i, xx, stress=True), color=c, ls=":", lw=0.8)
    stroke = maps.metadata.get("stroke", {})
    if "working_min_m" in stroke:
        ax.axvspan(stroke["working_min_m"] * 1e3, stroke["working_max_m"] * 1e3, color="0.9", zorder=0,
                   label="working range")
    ax.set_xlabel("working gap x [mm]")
    ax.set_ylabel("force F [N]")
    ax.set_title("force over stroke (solid: co-energy, dotted: Maxwell stress)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


