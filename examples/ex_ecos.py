r"""Run the solenoid FMU in Ecos (a C++ co-simulation engine, fmi4c underneath) through ``ecospy``.

``pip install ecospy tbb``: the ecospy 0.7 wheel links oneTBB's ``libtbb.so.12`` but does not ship
it; the ``tbb`` wheel puts it under ``<venv>/lib``, outside the loader's search path, so
:func:`load_ecospy` loads it globally before ``import ecospy`` (Debian's ``libtbb12`` works too).
The example exports the native FMU and the pythonfmu FMU from a maps directory, runs each in an Ecos
simulation with constant inputs (1e-4 s steps, fixed gap) in the drive mode asked for, and returns
the last flux linkage and force. ``tests/test_importers.py`` compares them with fmpy. Run::

    python examples/ex_ecos.py [MAPS_DIR] [OUT_DIR]

``drive_mode`` is an FMI Integer (1 voltage, 2 current): Ecos ignores Enumeration variables. Start
values go in as a named parameter set, applied while the FMU initializes. The pythonfmu FMU runs
here because this Python process has libpython loaded already; in a C++ host start it with
``LD_PRELOAD`` (see the README, "Which export to use when"). ``run_ecos(..., remote=True)`` runs the
FMU in Ecos's own C++ host process (``proxyfmu``): start that Python with :func:`remote_env`'s
environment, as ``tests/test_importers.py`` does.
"""

from __future__ import annotations

import ctypes
import importlib.metadata
import os
import shutil
import site
import sys
import sysconfig
from pathlib import Path

from solenoid_fmu.fmu import build_fmu

LIBTBB = "libtbb.so.12"


def libtbb_path() -> Path | None:
    """``libtbb.so.12`` of the ``tbb`` pip package (or under this Python's prefixes), None if absent."""
    try:
        dist = importlib.metadata.distribution("tbb")
        candidates = [Path(dist.locate_file(f)) for f in dist.files or () if f.name == LIBTBB]
    except importlib.metadata.PackageNotFoundError:
        candidates = []
    for prefix in dict.fromkeys((sys.prefix, sys.base_prefix, site.getuserbase())):
        candidates.append(Path(prefix) / "lib" / LIBTBB)
    return next((c.resolve() for c in candidates if c.is_file()), None)


def load_ecospy():
    """Import and return ``ecospy``, loading ``libtbb.so.12`` first when the ``tbb`` package has it.

    Raises
    ------
    ImportError
        ecospy is not installed, or its engine library cannot be loaded (the message says why).
    """
    lib = libtbb_path()
    if lib is not None:
        ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
    try:
        import ecospy
    except OSError as exc:  # the engine library (libecosc.so) failed to load
        raise ImportError(f"ecospy's engine does not load: {exc} (pip install tbb)") from exc
    return ecospy


def remote_env(bin_dir) -> dict:
    """Environment for a Python process whose Ecos runs FMUs in ``proxyfmu`` processes (C++ hosts).

    ``bin_dir`` gets an executable copy of ecospy's ``proxyfmu`` (the 0.7.2 wheel installs it without
    the execute bit) and goes first on ``PATH``; ``libtbb.so.12``'s folder goes on ``LD_LIBRARY_PATH``;
    this Python's libpython goes in ``LD_PRELOAD`` and its ``site-packages`` on ``PYTHONPATH``, so a
    pythonfmu FMU finds libpython and numpy in the C++ host.
    """
    ecospy = load_ecospy()
    bin_dir = Path(bin_dir)
    bin_dir.mkdir(parents=True, exist_ok=True)
    proxy = Path(shutil.copy2(Path(ecospy.__file__).parent / "binaries" / "proxyfmu", bin_dir / "proxyfmu"))
    proxy.chmod(0o755)
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(bin_dir), env.get("PATH", "")])
    libtbb = libtbb_path()
    if libtbb is not None:
        env["LD_LIBRARY_PATH"] = os.pathsep.join(filter(None, [str(libtbb.parent), env.get("LD_LIBRARY_PATH")]))
    libpython = Path(sysconfig.get_config_var("LIBDIR") or "", sysconfig.get_config_var("INSTSONAME") or "")
    env["LD_PRELOAD"] = ":".join(filter(None, [str(libpython), env.get("LD_PRELOAD")]))
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [*site.getsitepackages(), env.get("PYTHONPATH")]))
    return env


def run_ecos(fmu_path, drive_mode: int, u: float, x_m: float, stop_s: float, step_s: float = 1e-4,
             remote: bool = False) -> dict:
    """Last ``psi_Wb`` [Wb] and ``F_N`` [N] of the FMU in Ecos with inputs held.

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
        End time [s]; the run takes ``round(stop_s / step_s)`` fixed steps.
    step_s : float
        Communication step [s].
    remote : bool
        Run the FMU in a ``proxyfmu`` process (Ecos's C++ host) instead of this process; needs the
        environment of :func:`remote_env`.
    """
    ecospy = load_ecospy()
    start = {"solenoid::drive_mode": int(drive_mode),
             "solenoid::U_V" if drive_mode == 1 else "solenoid::i_A": float(u), "solenoid::x_m": float(x_m)}
    with ecospy.EcosSimulationStructure() as structure:
        structure.add_model("solenoid", f"proxyfmu://localhost?file={fmu_path}" if remote else str(fmu_path))
        structure.add_parameter_set("start", start)
        with ecospy.EcosSimulation(structure=structure, step_size=step_s) as sim:
            sim.init(parameter_set="start")
            sim.step(round(stop_s / step_s))  # a step count: step_until's float time stops one step short
            result = {"psi_Wb": sim.get_real("solenoid::psi_Wb"), "F_N": sim.get_real("solenoid::F_N")}
            sim.terminate()
    return result


def run(maps_dir="maps/ps45-literature", out_dir="build/ex_ecos") -> dict:
    """Export both FMUs and run them in Ecos: {(backend, drive_mode): result of run_ecos}."""
    out = Path(out_dir)
    fmus = {backend: build_fmu(maps_dir, out / f"solenoid-{backend}.fmu", backend=backend)
            for backend in ("c", "python")}
    results = {}
    for backend, drive, u in (("c", 1, 12.0), ("c", 2, 1.0), ("python", 1, 12.0)):
        results[(backend, drive)] = dict(run_ecos(fmus[backend], drive, u, 1.5e-3, 0.05), fmu=fmus[backend], u=u)
    return results


if __name__ == "__main__":
    for key, res in run(*sys.argv[1:3]).items():
        print(f"{key[0]:>6} drive_mode {key[1]}: psi {res['psi_Wb']:.6f} Wb, F {res['F_N']:.4f} N")
