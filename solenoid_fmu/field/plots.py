"""Figures of the field solution: flux lines and |B| over the geometry."""

from __future__ import annotations

import numpy as np

from ..fileio import save_figure
from .fem import Solution, Solver

__all__ = ["plot_field"]


def plot_field(solver: Solver, sol: Solution, path, n_lines: int = 30) -> None:
    """Draw flux lines (contours of u = rA) and |B| over the geometry into a PNG file."""
    # matplotlib is heavy (about 0.5 s to load): imported only when a figure is drawn
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation

    cfg = solver.config(sol.x_m)
    p = cfg.p * 1e3
    tri = Triangulation(p[0], p[1], solver.mesh.t.T)
    g = solver.grad(cfg, sol.u)
    B = np.sqrt(g[0] ** 2 + g[1] ** 2) / cfg.r
    Bel = B.mean(axis=1)
    fig, ax = plt.subplots(figsize=(6, 8))
    tpc = ax.tripcolor(tri, facecolors=Bel, cmap="viridis", shading="flat")
    fig.colorbar(tpc, ax=ax, label="|B| [T]")
    u_v = sol.u[: solver.mesh.n_vertices]
    if np.ptp(u_v) > 0:
        ax.tricontour(tri, u_v, levels=n_lines, colors="w", linewidths=0.5)
    for reg in solver.geometry.regions:
        poly = reg.polygon_at(sol.x_m) * 1e3
        ax.plot(*np.vstack([poly, poly[:1]]).T, "k-", lw=0.6)
    ax.set_xlim(0, min(40, p[0].max()))
    d = solver.geometry.domain
    zc = [reg.polygon_at(sol.x_m)[:, 1] for reg in solver.geometry.regions]
    zlo, zhi = min(z.min() for z in zc) * 1e3, max(z.max() for z in zc) * 1e3
    ax.set_ylim(max(d.z_min_m * 1e3, zlo - 8), min(d.z_max_m * 1e3, zhi + 8))
    ax.set_aspect("equal")
    ax.set_xlabel("r [mm]")
    ax.set_ylabel("z [mm]")
    ax.set_title(
        f"{solver.geometry.name}: i = {sol.i_A:g} A, x = {sol.x_m * 1e3:g} mm\n"
        f"Psi = {sol.psi_Wb * 1e3:.2f} mWb, F = {sol.force_N:.2f} N"
    )
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)
