"""Cost of one step of the solenoid FMUs in three importers: fmpy, libcosim (libcosimpy) and Ecos (ecospy).

Usage::

    python benchmarks/bench_importers.py [MAPS_DIR]

MAPS_DIR defaults to ``maps/ps45-literature`` when it exists, else synthetic maps from
``tests/mapsfixture.py``. Both FMUs (``--backend c`` and ``--backend python``) are built from the
same maps in this run. Each importer runs each FMU for 10 ms in 1 us co-simulation steps (10 000
``doStep`` calls), voltage mode (12 V, gap 1.5 mm), in this process (the pythonfmu FMU finds
libpython loaded) except for Ecos proxyfmu. Printed per importer and FMU: wall time per step of the
stepping alone (instance set up and initialized beforehand; minimum over :data:`REPEATS` fresh
instances), and the last flux linkage's relative difference to fmpy's ``doStep`` loop on the same
FMU.

- fmpy ``doStep``: a Python loop of ``FMU2Slave.doStep`` (fmpy's ctypes call, nothing else);
- fmpy ``simulate_fmu``: the whole call (set-up, recording every step, results) divided by the steps;
- fmpy model exchange (native FMU only): ``simulate_fmu`` with CVode, output every 1 us, whole call;
- libcosim: ``CosimExecution.simulate_until`` with a last-value observer (reads every output each step);
- Ecos: ``EcosSimulation.step(n)``;
- Ecos proxyfmu: the same with the FMU in Ecos's ``proxyfmu`` process (a C++ host; one inter-process
  call per FMI call), run from a child Python with ``examples/ex_ecos.py``'s ``remote_env`` (libpython
  preloaded for the pythonfmu FMU).

An importer that is not installed is reported as such and skipped.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "examples"))

import ex_ecos  # noqa: E402  (the example's loader: libtbb.so.12 of the tbb wheel before ecospy)
from bench_fmu import maps_for_bench  # noqa: E402  (sibling benchmark script)

from solenoid_fmu.fmu import build_fmu  # noqa: E402

H_S = 1e-6
N_STEPS = 10_000  # 10 ms
REPEATS = 5
REMOTE_CHILD = "--ecos-remote-child"  # argv[1] of the child process that runs Ecos with proxyfmu
START = {"drive_mode": 1, "U_V": 12.0, "x_m": 1.5e-3}


def _fmpy_dostep(fmu) -> tuple[float, float]:
    """(seconds per step, last psi_Wb) of a Python loop of fmpy's doStep."""
    import fmpy
    from fmpy.fmi2 import FMU2Slave

    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzip = fmpy.extract(str(fmu))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="solenoid")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.setInteger([vr["drive_mode"]], [START["drive_mode"]])
    slave.setReal([vr["U_V"], vr["x_m"]], [START["U_V"], START["x_m"]])
    slave.exitInitializationMode()
    t0 = time.perf_counter()
    for k in range(N_STEPS):
        slave.doStep(currentCommunicationPoint=k * H_S, communicationStepSize=H_S)
    wall = time.perf_counter() - t0
    psi = slave.getReal([vr["psi_Wb"]])[0]
    slave.terminate()
    slave.freeInstance()
    return wall / N_STEPS, psi


def _fmpy_simulate(fmu, fmi_type="CoSimulation") -> tuple[float, float]:
    """(seconds per step, last psi_Wb) of one whole fmpy.simulate_fmu call with output every step."""
    import fmpy

    t0 = time.perf_counter()
    res = fmpy.simulate_fmu(str(fmu), fmi_type=fmi_type, stop_time=N_STEPS * H_S, step_size=H_S,
                            output_interval=H_S, output=["psi_Wb"], start_values=START)
    return (time.perf_counter() - t0) / N_STEPS, float(res["psi_Wb"][-1])


def _libcosim(fmu) -> tuple[float, float]:
    """(seconds per step, last psi_Wb) of libcosim's simulate_until after the initializing first step."""
    import fmpy
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    vr = {v.name: v.valueReference for v in fmpy.read_model_description(str(fmu)).modelVariables}
    step_ns = round(H_S * 1e9)
    execution = CosimExecution.from_step_size(step_ns)
    index = execution.add_local_slave(CosimLocalSlave(str(fmu), "solenoid"))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    execution.integer_initial_value(index, vr["drive_mode"], START["drive_mode"])
    execution.real_initial_value(index, vr["U_V"], START["U_V"])
    execution.real_initial_value(index, vr["x_m"], START["x_m"])
    execution.step(1)  # initializes the FMU and takes the first step
    t0 = time.perf_counter()
    execution.simulate_until(N_STEPS * step_ns)
    wall = time.perf_counter() - t0
    return wall / (N_STEPS - 1), observer.last_real_values(index, [vr["psi_Wb"]])[0]


def _ecos(fmu, remote: bool = False) -> tuple[float, float]:
    """(seconds per step, last psi_Wb) of Ecos's step(n) after init; ``remote``: FMU in a proxyfmu process."""
    ecospy = ex_ecos.load_ecospy()
    with ecospy.EcosSimulationStructure() as structure:
        structure.add_model("solenoid", f"proxyfmu://localhost?file={fmu}" if remote else str(fmu))
        structure.add_parameter_set("start", {f"solenoid::{k}": v for k, v in START.items()})
        with ecospy.EcosSimulation(structure=structure, step_size=H_S) as sim:
            sim.init(parameter_set="start")
            t0 = time.perf_counter()
            sim.step(N_STEPS)
            wall = time.perf_counter() - t0
            psi = sim.get_real("solenoid::psi_Wb")
            sim.terminate()
    return wall / N_STEPS, psi


def _ecos_remote(fmu) -> tuple[float, float]:
    """:func:`_ecos` with ``remote=True`` in a child Python started with ``ex_ecos.remote_env``."""
    with tempfile.TemporaryDirectory(prefix="bench_importers_remote_") as tmp:
        env = ex_ecos.remote_env(Path(tmp) / "bin")
        env["TMPDIR"] = tmp
        proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), REMOTE_CHILD, str(fmu)], env=env, cwd=tmp,
                              capture_output=True, text=True, check=True)  # cwd: proxyfmu logs to logs/ there
    return tuple(json.loads([line for line in proc.stdout.splitlines() if line.startswith("[")][-1]))


def _available() -> dict:
    """Importer name -> None if usable, else why not."""
    why = {}
    try:
        from libcosimpy.CosimLogging import CosimLogLevel, log_output_level

        log_output_level(CosimLogLevel.WARNING)  # libcosim logs every FMU load at debug level on stdout
        why["libcosim"] = None
    except ImportError as exc:
        why["libcosim"] = f"not installed ({exc})"
    try:
        ex_ecos.load_ecospy()
        why["Ecos"] = None
    except ImportError as exc:
        why["Ecos"] = f"not installed ({exc})"
    why["Ecos proxyfmu"] = why["Ecos"]
    return why


def main(argv: list[str]) -> int:
    if argv[1:2] == [REMOTE_CHILD]:
        print(json.dumps(_ecos(Path(argv[2]), remote=True)))
        return 0
    with tempfile.TemporaryDirectory(prefix="bench_importers_") as tmp:
        tmp = Path(tmp)
        maps_dir = maps_for_bench(argv, tmp)
        print(f"maps: {maps_dir}")
        print(f"run: {N_STEPS * H_S * 1e3:g} ms in {H_S * 1e6:g} us steps ({N_STEPS} steps), voltage mode, "
              f"minimum over {REPEATS} runs")
        fmus = {"native": build_fmu(maps_dir, tmp / "native.fmu", backend="c"),
                "pythonfmu": build_fmu(maps_dir, tmp / "python.fmu", backend="python")}
        why = _available()
        runs = [("fmpy doStep", "CS", _fmpy_dostep), ("fmpy simulate_fmu", "CS", _fmpy_simulate),
                ("fmpy simulate_fmu (CVode)", "ME", lambda fmu: _fmpy_simulate(fmu, "ModelExchange")),
                ("libcosim", "CS", _libcosim), ("Ecos", "CS", _ecos), ("Ecos proxyfmu", "CS", _ecos_remote)]
        print(f"{'importer':<27} {'backend':<10} {'if':<3} {'us/step':>9} {'psi vs fmpy doStep':>19}")
        for backend, fmu in fmus.items():
            ref = None
            for name, interface, run in runs:
                reason = why.get(name)
                if interface == "ME" and backend != "native":
                    continue  # the pythonfmu FMU is co-simulation only
                if reason:
                    print(f"{name:<27} {backend:<10} {interface:<3} skipped: {reason}")
                    continue
                timings = [run(fmu) for _ in range(REPEATS)]
                per_step = min(t for t, _ in timings)
                psi = timings[-1][1]
                ref = psi if ref is None else ref
                print(f"{name:<27} {backend:<10} {interface:<3} {per_step * 1e6:9.3f} {abs(psi / ref - 1):19.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
