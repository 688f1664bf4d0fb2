r"""Run the solenoid FMU in libcosim (Open Simulation Platform) through ``libcosimpy``.

libcosim is a C++ co-simulation master (FMI Library underneath); ``pip install libcosimpy``.
The example exports the native FMU and the pythonfmu FMU from a maps directory, runs each in a
libcosim execution with constant inputs (1e-4 s steps, fixed gap) in the drive mode asked for, and
returns the last flux linkage and force. ``tests/test_importers.py`` compares them with fmpy.
Run::

    python examples/ex_libcosim.py [MAPS_DIR] [OUT_DIR]

``drive_mode`` is an FMI Integer (1 voltage, 2 current): libcosim ignores Enumeration variables.
The pythonfmu FMU runs here because this Python process has libpython loaded already; in a C++
host start it with ``LD_PRELOAD`` (see the README, "Which export to use when").
"""

from __future__ import annotations

import sys
from pathlib import Path

from solenoid_fmu.fmu import build_fmu

STEP_NS = 100_000  # 1e-4 s, libcosim counts time in nanoseconds


def run_libcosim(fmu_path, drive_mode: int, u: float, x_m: float, stop_s: float) -> dict:
    """Last ``psi_Wb`` [Wb] and ``F_N`` [N] of the FMU in libcosim with inputs held.

    Parameters
    ----------
    fmu_path : path-like
        A solenoid-fmu FMU (either backend).
    drive_mode : int
        1: ``u`` is the voltage ``U_V`` [V]; 2: ``u`` is the current ``i_A`` [A].
    u : float
        The drive input.
    x_m : float
        Working gap [m].
    stop_s : float
        End time [s].
    """
    import fmpy
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    vr = {v.name: v.valueReference for v in fmpy.read_model_description(str(fmu_path)).modelVariables}
    execution = CosimExecution.from_step_size(STEP_NS)
    index = execution.add_local_slave(CosimLocalSlave(str(fmu_path), "solenoid"))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    execution.integer_initial_value(index, vr["drive_mode"], int(drive_mode))
    execution.real_initial_value(index, vr["U_V" if drive_mode == 1 else "i_A"], float(u))
    execution.real_initial_value(index, vr["x_m"], float(x_m))
    execution.simulate_until(int(round(stop_s * 1e9)))
    psi, force = observer.last_real_values(index, [vr["psi_Wb"], vr["F_N"]])
    return {"psi_Wb": psi, "F_N": force}


def run(maps_dir="maps/ps45-literature", out_dir="build/ex_libcosim") -> dict:
    """Export both FMUs and run them in libcosim: {(backend, drive_mode): result of run_libcosim}."""
    out = Path(out_dir)
    fmus = {backend: build_fmu(maps_dir, out / f"solenoid-{backend}.fmu", backend=backend)
            for backend in ("c", "python")}
    results = {}
    for backend, drive, u in (("c", 1, 12.0), ("c", 2, 1.0), ("python", 1, 12.0)):
        results[(backend, drive)] = dict(run_libcosim(fmus[backend], drive, u, 1.5e-3, 0.05), fmu=fmus[backend], u=u)
    return results


if __name__ == "__main__":
    for key, res in run(*sys.argv[1:3]).items():
        print(f"{key[0]:>6} drive_mode {key[1]}: psi {res['psi_Wb']:.6f} Wb, F {res['F_N']:.4f} N")
