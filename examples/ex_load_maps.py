r"""Read a maps directory and query it both ways (``sf.load_maps``, paper eqs. 2-3).

Forward, from the FEM sweep: Psi(i, x) and F(i, x). Inverse, as the real-time model uses them:
the field-generating current i_f(Psi, x) and the force F(Psi, x). Going forward and back must
return the current and the force one started from. Run::

    python examples/ex_load_maps.py [MAPS_DIR]
"""

from __future__ import annotations

import sys

import numpy as np

import solenoid_fmu as sf


def run(maps_dir="maps/ps45-literature", n: int = 5) -> dict:
    """Round trip i -> Psi(i, x) -> i_f(Psi, x) and F(i, x) vs F(Psi(i, x), x) on an n x n grid.

    Returns the grid (``i_A``, ``x_m``, ``psi_Wb``) and the round-trip current [A] and force [N].
    """
    maps = sf.load_maps(maps_dir)
    i_top = float(maps.i_A[-1])
    i, x = np.meshgrid(np.linspace(0.1, 0.8, n) * i_top, np.linspace(maps.x_m[0], maps.x_m[-1], n))
    i, x = i.ravel(), x.ravel()
    psi = sf.psi_at(maps, i, x)
    return {"name": maps.name, "i_A": i, "x_m": x, "psi_Wb": psi, "i_back_A": sf.i_f_at(maps, psi, x),
            "F_ix_N": sf.force_at(maps, i, x), "F_psix_N": sf.force_psi_at(maps, psi, x), "i_top_A": i_top}


if __name__ == "__main__":
    r = run(*sys.argv[1:2])
    print(f"{r['name']}: max |i_f(Psi(i, x), x) - i| = {np.max(np.abs(r['i_back_A'] - r['i_A'])):.2e} A, "
          f"max |F(Psi, x) - F(i, x)| = {np.max(np.abs(r['F_psix_N'] - r['F_ix_N'])):.2e} N")
