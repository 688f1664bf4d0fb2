r"""One FEM operating point of the packaged PS45 solenoid: flux linkage and force (``sf.solve``).

Solves the axisymmetric nonlinear magnetostatics at a current and a working gap, then at twice
the current, and prints Psi and the force by co-energy and by Maxwell stress (two independent
ways to the same force; they agree to the discretization error). Run::

    python examples/ex_solve.py [I_A] [X_MM]
"""

from __future__ import annotations

import sys

import solenoid_fmu as sf


def run(i_A: float = 1.0, x_m: float = 1.5e-3, mesh_size: float = 1.0) -> dict:
    """Psi [Wb] and force [N] (co-energy, Maxwell stress) at ``i_A`` and ``2 i_A``, gap ``x_m`` [m]."""
    out = {}
    for key, i in (("one", i_A), ("two", 2.0 * i_A)):
        sol = sf.solve(i, x_m, mesh_size=mesh_size)
        out[key] = {"i_A": i, "psi_Wb": sol.psi_Wb, "F_coenergy_N": sol.force_coenergy_N,
                    "F_stress_N": sol.force_stress_N}
    return out


if __name__ == "__main__":
    i = float(sys.argv[1]) if len(sys.argv) > 1 else 1.0
    x = float(sys.argv[2]) * 1e-3 if len(sys.argv) > 2 else 1.5e-3
    for r in run(i, x).values():
        print(f"i = {r['i_A']:.3g} A: Psi = {r['psi_Wb'] * 1e3:.4f} mWb, F = {r['F_coenergy_N']:.3f} N "
              f"(co-energy), {r['F_stress_N']:.3f} N (Maxwell stress)")
