r"""Export the solenoid FMU from a maps directory and drive it with a 10 A/s current ramp (fmpy).

The FMU runs current-driven (``drive_mode = 2``): the ramp rises at 10 A/s to the coil's rated
current, holds for 50 ms and falls back at 10 A/s, at a fixed working gap. Plotted: the current
and the force over time, and the force over the current (the eddy currents make the rising and
falling branches differ). Run::

    python examples/ex_fmu_ramp.py [MAPS_DIR] [OUT_DIR]

``MAPS_DIR`` defaults to ``maps/ps45-literature`` (built by ``solenoid-fmu maps``). The function
:func:`run` returns the numbers that ``tests/test_fmu.py`` checks: the force at the peak flux
equals the map's ``F(Psi, x)`` (paper eq. 3) and, once the eddy currents have died out during
the hold, the static map value at the held current.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from solenoid_fmu.fmu import build_fmu
from solenoid_fmu.realtime.model import DRIVE_CURRENT, load_tables

RATE_A_PER_S = 10.0
HOLD_S = 0.05
STEP_S = 1e-4


def run(maps_dir="maps/ps45-literature", out_dir="build/ex_fmu_ramp", show_plot=False) -> dict:
    """Export the FMU, simulate the ramp with ``fmpy.simulate_fmu`` and plot F and i.

    Parameters
    ----------
    maps_dir : path-like
        Maps directory (``maps.npz`` + ``maps.json``).
    out_dir : path-like
        Where the FMU and ``ex_fmu_ramp.png`` are written.
    show_plot : bool
        Open the figure window as well.

    Returns
    -------
    dict
        ``fmu`` (Path), ``x_m`` [m], ``i_peak_A`` [A], ``psi_peak_Wb`` [Wb], ``F_peak_N`` [N] (at
        the largest flux), ``F_hold_end_N`` [N] (end of the hold), ``U_minus_Ri_rise_V`` [V] (mean
        induced voltage while the current rises), ``result`` (the fmpy result array).
    """
    import fmpy

    maps_dir, out_dir = Path(maps_dir), Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tab = load_tables(maps_dir)
    fmu = build_fmu(maps_dir, out_dir / f"{maps_dir.name}.fmu")
    i_peak = float(tab.coil.max_current_A or 1.0)
    x_m = 0.5 * (tab.x_min_m + tab.x_max_m)
    t_rise = i_peak / RATE_A_PER_S
    t_end = 2.0 * t_rise + HOLD_S
    corners = [(0.0, 0.0), (t_rise, i_peak), (t_rise + HOLD_S, i_peak), (t_end, 0.0)]
    signal = np.array([(t, 0.0, i, x_m) for t, i in corners],  # U_V is unused in current mode
                      dtype=[("time", float), ("U_V", float), ("i_A", float), ("x_m", float)])
    res = fmpy.simulate_fmu(str(fmu), start_time=0.0, stop_time=t_end, step_size=STEP_S,
                            output_interval=STEP_S, start_values={"drive_mode": DRIVE_CURRENT}, input=signal,
                            output=["i_out_A", "U_out_V", "F_N", "psi_Wb", "i_eddy_A"])
    t, i, U, force, psi = res["time"], res["i_out_A"], res["U_out_V"], res["F_N"], res["psi_Wb"]
    k_peak = int(np.argmax(psi))
    k_hold = int(np.searchsorted(t, t_rise + HOLD_S - 0.5 * STEP_S))
    md = fmpy.read_model_description(str(fmu))
    R = next(float(v.start) for v in md.modelVariables if v.name == "R_ohm")  # coil resistance [ohm]
    rise = (t > 0.1 * t_rise) & (t < 0.9 * t_rise)
    out = {
        "fmu": fmu, "x_m": x_m, "i_peak_A": i_peak, "psi_peak_Wb": float(psi[k_peak]),
        "F_peak_N": float(force[k_peak]), "F_hold_end_N": float(force[k_hold]),
        "U_minus_Ri_rise_V": float(np.mean(U[rise] - R * i[rise])), "result": res,
    }
    _plot(t, i, force, out_dir / "ex_fmu_ramp.png", x_m, show_plot)
    return out


def _plot(t, i, force, png: Path, x_m: float, show_plot: bool) -> None:
    import matplotlib

    if not show_plot:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    a1.plot(t, i, label="i [A]")
    a1.set_xlabel("t [s]")
    a1.set_ylabel("i [A]")
    b1 = a1.twinx()
    b1.plot(t, force, color="C1", label="F [N]")
    b1.set_ylabel("F [N]")
    a1.set_title(f"10 A/s ramp at x = {x_m * 1e3:.2f} mm")
    a2.plot(i, force)
    a2.set_xlabel("i [A]")
    a2.set_ylabel("F [N]")
    a2.set_title("force over current (eddy currents open the loop)")
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    if show_plot:
        plt.show()
    plt.close(fig)


if __name__ == "__main__":
    args = sys.argv[1:]
    r = run(*(args[:2] or ["maps/ps45-literature"]), show_plot=True)
    print(f"FMU: {r['fmu']}")
    print(f"peak: i = {r['i_peak_A']:.3f} A, Psi = {r['psi_peak_Wb'] * 1e3:.2f} mWb, "
          f"F = {r['F_peak_N']:.2f} N")
    print(f"end of hold: F = {r['F_hold_end_N']:.2f} N; mean induced voltage while rising "
          f"{r['U_minus_Ri_rise_V']:.3f} V")
