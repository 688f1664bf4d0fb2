"""Cost of one FMU ``doStep`` at 1e-4 s through fmpy, against an empty pythonfmu FMU in the same run.

Usage::

    python benchmarks/bench_fmu.py [MAPS_DIR]

MAPS_DIR defaults to ``maps/ps45-literature`` when it exists, else synthetic maps from
``tests/mapsfixture.py``. Both FMUs are loaded in this process and timed in alternating blocks;
the minimum over the blocks is reported (robust against other load on the machine). The printed
ratio ``model / empty`` shows what the model itself costs on top of the pythonfmu/fmpy call
chain; the goal is a ratio under 2. The full communication cycle (set 2 inputs, doStep, get 3
outputs) and the bare ``model.py`` step are printed too.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

EMPTY_SLAVE = '''
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class EmptySlave(Fmi2Slave):
    """Same call chain as the solenoid FMU, no model: the baseline of the benchmark."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.x = 0.0
        self.y = 0.0
        cont = Fmi2Variability.continuous
        self.register_variable(Real("u", causality=Fmi2Causality.input, variability=cont))
        self.register_variable(Real("x", causality=Fmi2Causality.input, variability=cont))
        self.register_variable(Real("y", causality=Fmi2Causality.output, variability=cont))

    def do_step(self, current_time, step_size):
        return True
'''


def _load(fmu_path: Path, inputs: dict[str, float]):
    import fmpy
    from fmpy.fmi2 import FMU2Slave

    md = fmpy.read_model_description(str(fmu_path))
    unzip = fmpy.extract(str(fmu_path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=fmu_path.stem)
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu.setReal([vr[k] for k in inputs], list(inputs.values()))
    fmu.exitInitializationMode()
    return fmu, vr, unzip


def _block(fmu, n: int, t0: float, h: float, cycle=None) -> float:
    t = t0
    start = time.perf_counter()
    if cycle is None:
        for _ in range(n):
            fmu.doStep(t, h)
            t += h
    else:
        in_vr, in_val, out_vr = cycle
        for _ in range(n):
            fmu.setReal(in_vr, in_val)
            fmu.doStep(t, h)
            fmu.getReal(out_vr)
            t += h
    return (time.perf_counter() - start) / n


def maps_for_bench(argv: list[str], tmp: Path) -> Path:
    """The maps a benchmark runs on: ``argv[1]``, else the shipped PS45 map, else synthetic maps in ``tmp``."""
    if len(argv) > 1:
        return Path(argv[1])
    if (ROOT / "maps" / "ps45-literature" / "maps.npz").exists():
        return ROOT / "maps" / "ps45-literature"
    sys.path.insert(0, str(ROOT / "tests"))
    import mapsfixture

    return mapsfixture.write_maps(tmp / "synthetic")


def main(argv: list[str]) -> int:
    from solenoid_fmu.fmu import build_fmu
    from solenoid_fmu.realtime import model as M

    h = 1e-4
    n_block, n_rep = 2000, 15
    with tempfile.TemporaryDirectory(prefix="bench_fmu_") as tmp:
        tmp = Path(tmp)
        maps_dir = maps_for_bench(argv, tmp)
        print(f"maps: {maps_dir}")
        model_fmu = build_fmu(maps_dir, tmp / "solenoid.fmu")
        from pythonfmu import FmuBuilder

        script = tmp / "empty_slave.py"
        script.write_text(EMPTY_SLAVE, encoding="utf-8")
        sys.path.insert(0, str(tmp))
        empty_fmu = Path(FmuBuilder.build_FMU(script, dest=tmp / "EmptySlave.fmu"))

        tab = M.load_tables(maps_dir)
        x_m = 0.5 * (tab.x_min_m + tab.x_max_m)
        U = 0.6 * (tab.resistance_ohm_20C or 10.0) * (tab.i_fem_max_A if tab.i_fem_max_A < 1e9 else 1.0)
        fm, vr_m, unzip_m = _load(model_fmu, {"U_V": U, "x_m": x_m})
        fe, vr_e, unzip_e = _load(empty_fmu, {"u": U, "x": x_m})
        cyc_m = ([vr_m["U_V"], vr_m["x_m"]], [U, x_m], [vr_m["i_out_A"], vr_m["F_N"], vr_m["psi_Wb"]])
        cyc_e = ([vr_e["u"], vr_e["x"]], [U, x_m], [vr_e["y"], vr_e["y"], vr_e["y"]])
        t_m = t_e = 0.0
        step_m, step_e, full_m, full_e = [], [], [], []
        _block(fm, 500, 0.0, h)
        _block(fe, 500, 0.0, h)
        t_m = t_e = 500 * h
        for _ in range(n_rep):
            step_e.append(_block(fe, n_block, t_e, h))
            t_e += n_block * h
            step_m.append(_block(fm, n_block, t_m, h))
            t_m += n_block * h
            full_e.append(_block(fe, n_block, t_e, h, cyc_e))
            t_e += n_block * h
            full_m.append(_block(fm, n_block, t_m, h, cyc_m))
            t_m += n_block * h
        for fmu in (fm, fe):
            fmu.terminate()
            fmu.freeInstance()
        shutil.rmtree(unzip_m, ignore_errors=True)
        shutil.rmtree(unzip_e, ignore_errors=True)

        model = M.SolenoidModel(tab, {"drive_mode": "voltage"})
        model.initialize(U, x_m)
        bare = []
        for _ in range(n_rep):
            t0 = time.perf_counter()
            for _ in range(n_block):
                model.step(h, U, x_m)
            bare.append((time.perf_counter() - t0) / n_block)

    ds_m, ds_e, cy_m, cy_e = min(step_m), min(step_e), min(full_m), min(full_e)
    print(f"doStep at h = {h:g} s (voltage mode, min over {n_rep} blocks of {n_block}):")
    print(f"  solenoid FMU : {ds_m * 1e6:8.2f} us")
    print(f"  empty FMU    : {ds_e * 1e6:8.2f} us")
    print(f"  ratio        : {ds_m / ds_e:8.2f}   (goal < 2)")
    print("full cycle (setReal 2 inputs + doStep + getReal 3 outputs):")
    print(f"  solenoid FMU : {cy_m * 1e6:8.2f} us")
    print(f"  empty FMU    : {cy_e * 1e6:8.2f} us")
    print(f"  ratio        : {cy_m / cy_e:8.2f}")
    print(f"model.py step alone (in-process): {min(bare) * 1e6:.2f} us")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
