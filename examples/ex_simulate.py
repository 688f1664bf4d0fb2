r"""Drive an FMU with a recording's inputs (``sf.simulate``): a 12 V step at a fixed gap.

Makes a voltage-step recording (the measured current left as zeros: the FMU computes it), runs
the FMU on it and returns the simulated current. After the step the current settles at U / R
(Ohm's law: the flux stops changing), with the time constant of the coil's inductance. Run::

    python examples/ex_simulate.py [MAPS_DIR] [OUT_DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import solenoid_fmu as sf


def run(maps_dir="maps/ps45-literature", out_dir="build/ex_simulate", U_V: float = 12.0,
        duration_s: float = 0.5, backend: str = "c", R_ohm: float | None = None) -> dict:
    """Simulated current [A] of a ``U_V`` step held for ``duration_s`` [s]; the coil resistance
    ``R_ohm`` [ohm] defaults to the maps' ``coil.resistance_ohm_20C``."""
    maps = sf.load_maps(maps_dir)
    R = R_ohm if R_ohm is not None else (maps.metadata.get("coil") or {}).get("resistance_ohm_20C")
    if R is None:
        raise SystemExit(f"{maps_dir}: maps.json has no coil.resistance_ohm_20C; give R_ohm")
    R = float(R)
    x = float(np.mean(maps.x_m))
    t = np.arange(0.0, duration_s, 1e-4)
    u = np.where(t > 0.01, U_V, 0.0)
    rec = sf.make_recording("voltage_step", "example", t, np.zeros_like(t), voltage_V=u, force_N=np.zeros_like(t),
                            position_m=np.full_like(t, x), coil_resistance_ohm=R)
    fmu = sf.export_fmu(maps_dir, Path(out_dir) / f"ex_simulate-{backend}.fmu", backend=backend)
    sim = sf.simulate(fmu, rec, drive="voltage")
    return {"time_s": t, "U_V": U_V, "R_ohm": R, "result": sim}


if __name__ == "__main__":
    r = run(*sys.argv[1:3])
    print(f"i(end) = {r['result'].recording.current_A[-1]:.4f} A, U/R = {r['U_V'] / r['R_ohm']:.4f} A")
